"""Positional and directional virtual lights, shared and per-light coefficients:
synthetic solutions made from known lights, the gradient, the extremes."""

import numpy as np
import pytest
import trimesh

from fitting import FitOptions, fit, shade
from fitting.data import fit_data, relative_error
from fitting.mixed import (
    Parameters,
    Problem,
    SceneGeometry,
    evaluate,
    fit_mixed,
    model_colours,
    objective,
    refine,
)
from fitting.model import FittedModel, FittedObject, shade_arrays
from fitting.results import Lights, LightsFit
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.scene import geometry

MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 30.0, "emission": [0.0, 0.0, 0.0]}


def plane(n=9, size=2.0):
    """A square of (n x n) vertices in z = 0 facing +z, centred on the origin."""
    x = np.linspace(-size / 2, size / 2, n)
    xx, yy = np.meshgrid(x, x)
    positions = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(n * n)])
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            faces += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    normals = np.tile([0.0, 0.0, 1.0], (n * n, 1))
    return positions, np.array(faces), normals


def sphere(subdivisions=2):
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    positions = np.asarray(s.vertices)
    return positions, np.asarray(s.faces), positions / np.linalg.norm(positions, axis=1, keepdims=True)


def synthetic(mesh, light_pos, shininess, per_light=True, grid=14, scale=1.0, rng=None):
    """A one-object solution whose radiance is exactly a virtual-light model."""
    rng = np.random.default_rng(7) if rng is None else rng
    positions, faces, normals = mesh
    tangents = geometry.tangents(normals)
    k = len(light_pos)
    emitted = rng.uniform(0.0, 0.2, (len(positions), 3))
    specular = rng.uniform(0.3, 1.0, (len(positions), k, 3) if per_light else (len(positions), 3))
    rgb = np.ones((k, 3)) if per_light else rng.uniform(0.5, 2.0, (k, 3))
    local = directions.grid_directions(grid)
    bitangents = np.cross(normals, tangents)
    views = local[None, :, :1] * tangents[:, None] + local[None, :, 1:2] * bitangents[:, None] + local[None, :, 2:] * normals[:, None]
    coefficient = specular[:, None] if per_light else specular[:, None]
    radiance = scale * shade_arrays(emitted[:, None], coefficient, normals[:, None], positions[:, None],
                                    (np.asarray(light_pos, float), rgb, np.full(k, float(shininess))), views)
    obj = ObjectSolution(
        name="thing", positions=positions.astype(np.float32), normals=normals.astype(np.float32),
        tangents=tangents.astype(np.float32), faces=faces.astype(np.int32), directions=local.astype(np.float32),
        radiance=radiance.astype(np.float32), material=MATERIAL,
    )
    return Solution(objects=(obj,), settings={}, stats={}, scene="synthetic")


def problem_of(solution, per_light=True, bounds=(1.0, 1e4)):
    data = fit_data(solution.objects[0])
    return Problem.make(data, None, per_light, SceneGeometry.of_solution(solution), bounds)


def error_of(problem, fit):
    return relative_error(problem.data, model_colours(problem, fit.lights(), fit.emitted, fit.specular))["relative_rms"]


def test_shade_of_a_point_light_by_hand():
    # one vertex at (1, 0, 0), normal +z, a point light at (1, 0, 2) straight above, eye along +z:
    # l = (0, 0, 1), w = (0, 0, 1), h = (0, 0, 2), n.h/|h| = 1: the full lobe, 0.5 * 2 * 0.25 = 0.25
    obj = FittedObject(
        name="p", positions=np.array([[1.0, 0, 0], [2, 0, 0], [1, 1, 0]], np.float32),
        normals=np.tile(np.float32([0, 0, 1]), (3, 1)), faces=np.array([[0, 1, 2]], np.int32),
        emitted=np.zeros((3, 3), np.float32), specular=np.full((3, 1, 3), 0.25, np.float32),
        light_pos=np.array([[1.0, 0, 2, 1]], np.float32), light_rgb=np.full((1, 3), 2.0, np.float32),
        shininess=np.array([10.0], np.float32),
    )
    model = FittedModel(objects=(obj,))
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    got = shade(model, "p", up)
    assert np.allclose(got[0], 0.5)
    # vertex (2, 0, 0): l = normalize(-1, 0, 2), h = l + (0, 0, 1); c = n.h / |h|
    to_light = np.array([-1.0, 0.0, 2.0]) / np.sqrt(5.0)
    h = to_light + np.array([0.0, 0.0, 1.0])
    c = h[2] / np.linalg.norm(h)
    assert np.allclose(got[1], 0.5 * c**10)
    # the same light made distant (w = 0, towards +z) lights both vertices fully
    far = FittedModel(objects=(FittedObject(**{**obj.__dict__, "light_pos": np.array([[0, 0, 1, 0]], np.float32)}),))
    assert np.allclose(shade(far, "p", up), 0.5)


def test_a_point_light_behind_or_at_the_surface_gives_no_nan():
    positions, faces, normals = plane(3)
    for light in ([0.0, 0.0, -1.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1e-30, 1.0]):
        out = shade_arrays(np.zeros((9, 1, 3)), np.ones((9, 1, 3)), normals[:, None], positions[:, None],
                           (np.array([light]), np.ones((1, 3)), np.array([50.0])),
                           np.tile([0.0, 0.0, 1.0], (9, 5, 1)))
        assert np.isfinite(out).all()
    # below the surface: seen from above, the half vector is zero straight over it (no light)
    # and far from the normal elsewhere (the formula has no n.l gate: only the lobe's tail)
    behind = shade_arrays(np.zeros((9, 1, 3)), np.ones((9, 1, 3)), normals[:, None], positions[:, None],
                          (np.array([[0.0, 0.0, -1.0, 1.0]]), np.ones((1, 3)), np.array([50.0])),
                          np.tile([0.0, 0.0, 1.0], (9, 1, 1)))
    assert behind[4].max() == 0.0 and behind.max() < 1e-15


def _gradient_setup(per_light):
    truth = np.array([[0.4, 0.3, 1.8, 1.0], [0.6, -0.8, 0.0, 0.0]])
    truth[1, :3] /= np.linalg.norm(truth[1, :3])
    solution = synthetic(sphere(1), truth, 20.0, per_light=per_light, grid=8)
    problem = problem_of(solution, per_light)
    start = evaluate(problem, truth + [[0.2, -0.1, 0.3, 0], [0.1, 0.2, 0.1, 0]], np.full((2, 3), 1.3), np.array([14.0, 25.0]))
    params = Parameters(kinds=start.pos[:, 3].copy(), per_light_exponents=True, fit_rgb=not per_light, scale=1.0,
                        centre=problem.centre, size=problem.size)
    return problem, start, params, params.pack(start)


def _central(f, x, i):
    step = 1e-6 * max(1.0, abs(x[i]))
    up, down = x.copy(), x.copy()
    up[i] += step
    down[i] -= step
    return (f(up) - f(down)) / (2 * step)


@pytest.mark.parametrize("per_light", [True, False])
def test_partial_gradient_against_central_differences(per_light):
    """The kernel's gradient at fixed coefficients: point and distant lights, colours, exponents."""
    from fitting.lobes import mixed_loss_and_gradient
    from fitting.mixed import coefficients

    problem, start, params, x = _gradient_setup(per_light)
    _, grad = objective(problem, params, start.rgb, x)
    lights, _ = params.unpack(x, start.rgb)
    e, s, _ = coefficients(problem, lights)
    coef = np.ascontiguousarray(s if s.ndim == 3 else s[:, None, :])

    def loss(xx):
        partial = np.zeros((problem.data.n_vertices, 2, 7))
        return mixed_loss_and_gradient(problem.data.normals, problem.data.views, params.unpack(xx, start.rgb)[0],
                                       problem.samples, e, coef, partial)

    for i in range(len(x)):
        assert grad[i] == pytest.approx(_central(loss, x, i), rel=1e-6, abs=1e-12), i


def test_reduced_gradient_against_central_differences(monkeypatch):
    """Variable projection: the partial gradient at the optimal coefficients is the
    gradient of the reduced objective (shared coefficients: [1, B] per vertex, well
    conditioned). Caps are lifted: a coefficient held at a cap that moves with the
    lights breaks the identity, which is why the caps bind only for lobes far sharper
    than the samples."""
    import fitting.mixed

    monkeypatch.setattr(fitting.mixed, "CAP_FACTOR", 1e12)
    problem, start, params, x = _gradient_setup(False)
    _, grad = objective(problem, params, start.rgb, x)
    for i in range(len(x)):
        numeric = _central(lambda xx: objective(problem, params, start.rgb, xx)[0], x, i)
        assert grad[i] == pytest.approx(numeric, rel=2e-4, abs=1e-9 * max(1.0, abs(grad).max())), i


def test_a_point_light_over_a_plane_is_found():
    # on a plane a distant light's highlight stays put while a point light's moves: only a point light fits
    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(11), light, 40.0, grid=16)
    problem = problem_of(solution)
    found = fit_mixed(problem, 1, 40.0, light_kind="auto", iterations=80)
    assert found.pos[0, 3] == 1.0
    assert np.linalg.norm(found.pos[0, :3] - light[0, :3]) < 0.01 * problem.size
    assert error_of(problem, found) < 1e-3
    directional_only = fit_mixed(problem, 1, 40.0, light_kind="directional", iterations=80)
    assert error_of(problem, directional_only) > 10 * error_of(problem, found)


def test_mixed_kinds_on_a_sphere():
    near = [0.5, 0.4, 2.0, 1.0]
    far = np.array([-0.7, 0.1, 0.7])
    far /= np.linalg.norm(far)
    truth = np.array([near, [*far, 0.0]])
    solution = synthetic(sphere(2), truth, 30.0, grid=14)
    problem = problem_of(solution)
    found = fit_mixed(problem, 2, 30.0, light_kind="auto", iterations=120)
    assert error_of(problem, found) < 1e-3
    point = found.pos[found.pos[:, 3] == 1]
    distant = found.pos[found.pos[:, 3] == 0]
    assert len(point) == 1 and len(distant) == 1
    assert np.linalg.norm(point[0, :3] - near[:3]) < 0.01 * problem.size
    assert np.degrees(np.arccos(np.clip(distant[0, :3] @ far, -1, 1))) < 0.5


def test_auto_keeps_a_very_far_light_directional():
    direction = np.array([0.3, 0.2, 0.93])
    direction /= np.linalg.norm(direction)
    truth = np.array([[*(1e7 * direction), 1.0]])  # a point light ten million object sizes away
    solution = synthetic(sphere(2), truth, 30.0)
    problem = problem_of(solution)
    found = fit_mixed(problem, 1, 30.0, light_kind="auto", iterations=60)
    assert found.pos[0, 3] == 0.0
    assert np.degrees(np.arccos(np.clip(found.pos[0, :3] @ direction, -1, 1))) < 0.5
    assert error_of(problem, found) < 1e-3
    # forced positional, it converges to the directional answer: far away, about the same error
    forced = fit_mixed(problem, 1, 30.0, light_kind="positional", iterations=60)
    assert np.linalg.norm(forced.pos[0, :3] - problem.centre) > 100 * problem.size
    assert error_of(problem, forced) < 5e-3


def test_a_point_light_close_to_the_surface():
    light = np.array([[0.1, 0.05, 0.15, 1.0]])  # 0.15 above a plane of size 2
    solution = synthetic(plane(15), light, 20.0, grid=16)
    problem = problem_of(solution)
    found = fit_mixed(problem, 1, 20.0, light_kind="positional", iterations=100)
    assert np.linalg.norm(found.pos[0, :3] - light[0, :3]) < 0.01 * problem.size
    assert error_of(problem, found) < 1e-3


@pytest.mark.parametrize("scale", [0.0, 1e-8, 1e8])
def test_radiance_from_zero_to_1e8(scale):
    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(9), light, 40.0, grid=10, scale=scale)
    model = fit(solution, FitOptions(model="lights", lights=2, iterations=30))
    o = model.objects[0]
    for a in (o.emitted, o.specular, o.light_pos, o.light_rgb, o.shininess):
        assert np.isfinite(a).all()
    if scale == 0.0:
        assert (o.emitted == 0).all() and (o.specular == 0).all() and o.info["error"]["relative_rms"] == 0.0
    else:
        assert o.info["error"]["relative_rms"] < 0.05


@pytest.mark.parametrize("exponent", [1.0, 1e2, 1e4])
def test_exponents_from_1_to_1e4(exponent):
    light = np.array([[0.2, 0.1, 1.5, 1.0]])
    solution = synthetic(sphere(2), light, exponent, grid=24 if exponent > 100 else 10)
    problem = problem_of(solution)
    found = fit_mixed(problem, 1, exponent, light_kind="auto", iterations=40)
    for a in (found.pos, found.specular, found.emitted, found.shininess):
        assert np.isfinite(a).all()
    diffuse_only = relative_error(problem.data, np.broadcast_to(found.emitted[:, None], problem.data.radiance.shape))
    assert error_of(problem, found) < diffuse_only["relative_rms"]
    if exponent > 1:
        assert error_of(problem, found) < 0.05
    # (at n = 1 the lobe is as wide as the hemisphere: no highlight locates the light,
    # which is then seeded distant and stays so; the fit is stable, not exact)


def test_useless_and_duplicate_lights_are_not_kept():
    # one true light; asked for four, the fitter must not keep four copies of it or empty lights
    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(11), light, 40.0, grid=12)
    problem = problem_of(solution)
    found = fit_mixed(problem, 4, 40.0, light_kind="auto", iterations=40)
    assert error_of(problem, found) < 1e-3
    assert found.n_lights <= 4
    from fitting.mixed import degenerate_lights

    assert degenerate_lights(problem, found) == []


def test_auto_light_count_says_when_the_target_is_missed():
    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(9), light, 40.0, grid=10, rng=np.random.default_rng(2))
    noisy = solution.objects[0]
    rng = np.random.default_rng(3)
    radiance = noisy.radiance * (1 + 0.3 * rng.random(noisy.radiance.shape)).astype(np.float32)
    obj = ObjectSolution(name="thing", positions=noisy.positions, normals=noisy.normals, tangents=noisy.tangents,
                         faces=noisy.faces, directions=noisy.directions, radiance=radiance, material=MATERIAL)
    model = fit(Solution(objects=(obj,), settings={}, stats={}, scene="x"),
                FitOptions(model="lights", lights="auto", target=1e-4, max_lights=6, iterations=20))
    o = model.objects[0]
    assert "target 0.0001 not reached" in o.info["chosen_by"]
    assert o.n_lights < 6  # it stopped when a light no longer paid


def test_fit_writes_version_2_with_kinds(tmp_path):
    from fitting import load_fit

    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(9), light, 40.0, grid=10)
    model = fit(solution, FitOptions(model="lights", lights=1, iterations=40))
    model.save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz").objects[0]
    assert back.light_pos.shape == (1, 4) and back.per_light and back.specular.shape == (81, 1, 3)
    assert back.info["kinds"] == ["positional"] and back.floats_per_vertex == 6
    shared = fit(solution, FitOptions(model="lights", lights=1, iterations=40, coefficients="shared")).objects[0]
    assert shared.specular.shape == (81, 3) and not shared.per_light


def test_refine_never_makes_a_fit_worse():
    light = np.array([[0.3, -0.2, 1.5, 1.0]])
    solution = synthetic(plane(9), light, 40.0, grid=10)
    problem = problem_of(solution)
    start = evaluate(problem, np.array([[0.0, 0.0, 1.0, 0.0]]), np.ones((1, 3)), np.array([40.0]))
    refined = refine(problem, start, max_iterations=10)
    assert isinstance(refined, LightsFit) and refined.sq_error <= start.sq_error
    assert isinstance(refined.lights(), Lights)


def test_an_emitter_of_fewer_triangles_than_its_lights_gets_one_light_on_each():
    # a glossy plane lit by a point light that stands on a lamp of two triangles: a mirror
    # ray from the highlight hits the lamp, whose area gets SPREAD point lights, but it
    # has only two triangles (two centroids): one light each, the arrays agreeing
    light = np.array([0.0, 0.0, 1.5])
    solution = synthetic(plane(9), [np.append(light, 1.0)], 60.0)
    lamp = ObjectSolution(
        name="lamp", positions=(light + np.array([[-0.2, -0.2, 0], [0.2, -0.2, 0], [0.2, 0.2, 0], [-0.2, 0.2, 0]])).astype(np.float32),
        normals=np.tile(np.float32([0, 0, -1]), (4, 1)), tangents=np.tile(np.float32([1, 0, 0]), (4, 1)),
        faces=np.array([[0, 2, 1], [0, 3, 2]], np.int32), directions=np.float32([[0, 0, 1]]),
        radiance=np.full((4, 1, 3), 5.0, np.float32), material={**MATERIAL, "emission": [5.0, 5.0, 5.0]},
    )
    problem = problem_of(Solution(objects=(solution.objects[0], lamp), settings={}, stats={}, scene="synthetic"))
    assert problem.scene.emissive.tolist() == [False, True]
    found = fit_mixed(problem, 4, 60.0, light_kind="positional", iterations=20)
    assert 1 <= found.n_lights <= 4
    assert len(found.pos) == len(found.rgb) == len(found.shininess) == found.specular.shape[1]
    assert error_of(problem, found) < 0.1
