"""The fitter against synthetic solutions generated from a known model."""

import numpy as np
import pytest
import trimesh

from fitting import FitOptions, fit, load_fit, shade
from fitting.data import fit_data, relative_error
from fitting.lights import fit_lights, problem_for, reconstruct
from fitting.mixed import SceneGeometry
from fitting.model import directional, shade_arrays
from fitting.paper import fit_paper, vertex_coefficients
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.scene import geometry

MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 50.0, "emission": [0.0, 0.0, 0.0]}


def dome(subdivisions=2):
    """The upper half of an icosphere: curved, so one light lights vertices differently."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    keep = s.vertices[s.faces].mean(axis=1)[:, 2] > -0.2
    positions, faces = geometry.compact(np.asarray(s.vertices), np.asarray(s.faces)[keep])
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    return positions, faces, normals


def synthetic(rng, lights=3, shininess=40.0, grid=12, noise=0.0, scale=1.0, subdivisions=2, light_dirs=None):
    """A one-object solution whose radiance is exactly a virtual-light model."""
    positions, faces, normals = dome(subdivisions)
    tangents = geometry.tangents(normals)
    if light_dirs is None:
        light_dirs = rng.normal(size=(lights, 3))
        light_dirs[:, 2] = np.abs(light_dirs[:, 2]) + 0.5
    light_dirs = light_dirs / np.linalg.norm(light_dirs, axis=1, keepdims=True)
    light_rgb = rng.uniform(0.5, 2.0, (len(light_dirs), 3))
    emitted = rng.uniform(0.0, 0.3, (len(positions), 3))
    specular = rng.uniform(0.2, 1.0, (len(positions), 3))
    local = directions.grid_directions(grid)
    bitangents = np.cross(normals, tangents)
    views = local[None, :, :1] * tangents[:, None] + local[None, :, 1:2] * bitangents[:, None] + local[None, :, 2:] * normals[:, None]
    lights = (directional(light_dirs), light_rgb, np.full(len(light_dirs), shininess))
    radiance = shade_arrays(emitted[:, None], specular[:, None], normals[:, None], positions[:, None], lights, views)
    radiance = radiance * (1 + noise * rng.normal(size=radiance.shape))
    radiance = np.maximum(radiance, 0) * scale
    obj = ObjectSolution(
        name="dome", positions=positions.astype(np.float32), normals=normals.astype(np.float32),
        tangents=tangents.astype(np.float32), faces=faces.astype(np.int32), directions=local.astype(np.float32),
        radiance=radiance.astype(np.float32), material=MATERIAL,
    )
    truth = {"light_dirs": light_dirs, "light_rgb": light_rgb, "shininess": shininess, "emitted": emitted, "specular": specular}
    return Solution(objects=(obj,), settings={}, stats={}, scene="synthetic"), truth


def colours(data, result):
    """The model of a shared-coefficient ``LightsFit`` at the data's samples."""
    lights = (result.pos, result.rgb, result.shininess)
    return shade_arrays(result.emitted[:, None], result.specular[:, None], data.normals[:, None],
                        data.positions[:, None], lights, data.views)


def lights_of(solution, options, k, previous=None):
    """A refined fit (``results.LightsFit``) of the solution's one object with k lights."""
    obj = solution.objects[0]
    problem = problem_for(fit_data(obj), options, SceneGeometry.of_solution(solution))
    return problem, fit_lights(problem, k, options, 4 * obj.material["exponent"] + 1, previous=previous)


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.dot(a, b), -1, 1)))


def matched_angles(found, truth):
    """For every true light, the angle to the nearest fitted light (degrees)."""
    return np.array([min(angle_deg(f, t) for f in found) for t in truth])


def test_single_light_found_by_the_paper_heuristic_alone(rng):
    solution, truth = synthetic(rng, lights=1, shininess=80.0, grid=16)
    data = fit_data(solution.objects[0])
    result = fit_paper(data, 1)
    # the brightest sample sits on a grid direction: the light is within about a grid cell
    assert matched_angles(result.pos[:, :3], truth["light_dirs"]).max() < 6.0
    assert relative_error(data, colours(data, result))["relative_rms"] < 0.2


@pytest.mark.slow  # ~15 s of CPU: six refined fits with warm starts
def test_adding_a_light_never_increases_the_error(rng):
    solution, _ = synthetic(rng, lights=4, shininess=25.0)
    options = FitOptions(model="lights", lights=1, method="refined", iterations=60)
    errors, previous = [], None
    for k in range(1, 7):
        problem, previous = lights_of(solution, options, k, previous)
        errors.append(relative_error(problem.data, reconstruct(problem, previous))["relative_rms"])
    assert all(b <= a * (1 + 1e-9) for a, b in zip(errors, errors[1:])), errors
    assert errors[3] < 0.01 * errors[0]  # four true lights: four fitted ones suffice


def test_adding_a_light_never_increases_the_error_small(rng):
    """The fast cousin of the test above: a coarser dome, three lights, short refinements."""
    solution, _ = synthetic(rng, lights=3, shininess=25.0, grid=8, subdivisions=1)
    options = FitOptions(model="lights", lights=1, method="refined", iterations=20)
    errors, previous = [], None
    for k in range(1, 4):
        problem, previous = lights_of(solution, options, k, previous)
        errors.append(relative_error(problem.data, reconstruct(problem, previous))["relative_rms"])
    assert all(b <= a * (1 + 1e-9) for a, b in zip(errors, errors[1:])), errors
    assert errors[2] < 0.1 * errors[0]


def test_zero_data_gives_zeros(rng):
    solution, _ = synthetic(rng, scale=0.0)
    model = fit(solution, FitOptions(model="lights", lights=4))
    o = model.objects[0]
    for a in (o.emitted, o.specular, o.light_rgb, o.light_pos):
        assert np.isfinite(a).all()
    assert (o.emitted == 0).all() and (o.specular == 0).all()
    assert o.info["error"]["relative_rms"] == 0.0


@pytest.mark.parametrize("scale", [1e8, 1e-8])
def test_scaled_data_scale_the_coefficients(rng, scale):
    base_solution, _ = synthetic(np.random.default_rng(3))
    scaled_solution, _ = synthetic(np.random.default_rng(3), scale=scale)
    options = FitOptions(model="lights", lights=3, method="paper")
    a, b = fit(base_solution, options).objects[0], fit(scaled_solution, options).objects[0]
    assert np.allclose(b.shininess, a.shininess, rtol=1e-4)
    assert np.allclose(b.light_pos, a.light_pos, atol=1e-4)
    model_a = a.emitted.astype(float), a.specular[:, None] * a.light_rgb[None]
    model_b = b.emitted.astype(float), b.specular[:, None] * b.light_rgb[None]
    assert np.allclose(model_b[0], model_a[0] * scale, rtol=1e-3, atol=1e-6 * scale)
    assert np.allclose(model_b[1], model_a[1] * scale, rtol=1e-3, atol=1e-6 * scale)
    assert b.info["error"]["relative_rms"] == pytest.approx(a.info["error"]["relative_rms"], rel=1e-3)


@pytest.mark.parametrize("bounds", [(1.0, 1.0), (1e4, 1e4)])
def test_exponents_at_the_bounds_stay_finite(rng, bounds):
    solution, _ = synthetic(rng, shininess=50.0)
    for method in ("paper", "refined", "per-light"):
        o = fit(solution, FitOptions(model="lights", lights=3, method=method, exponent_bounds=bounds, iterations=20)).objects[0]
        for a in (o.emitted, o.specular, o.light_rgb, o.light_pos, o.shininess):
            assert np.isfinite(a).all()
        assert np.allclose(o.shininess, bounds[0])


def test_a_single_vertex(rng):
    solution, _ = synthetic(rng, subdivisions=0)
    obj = solution.objects[0]
    one = ObjectSolution(
        name="one", positions=obj.positions[:3], normals=obj.normals[:3], tangents=obj.tangents[:3],
        faces=np.array([[0, 1, 2]], np.int32), directions=obj.directions, radiance=obj.radiance[:3], material=MATERIAL,
    )
    o = fit(Solution(objects=(one,), settings={}, stats={}, scene="x"), FitOptions(model="lights", lights=2)).objects[0]
    assert np.isfinite(o.emitted).all() and o.info["error"]["relative_rms"] < 0.5


def test_directions_only_near_grazing(rng):
    solution, truth = synthetic(rng, lights=2, shininess=20.0,
                                light_dirs=np.array([[1.0, 0.0, 0.05], [0.0, -1.0, 0.08]]))
    o = fit(solution, FitOptions(model="lights", lights=2)).objects[0]
    assert np.isfinite(o.light_pos).all()
    assert o.info["error"]["relative_rms"] < 0.05


def test_noisy_data_stay_stable(rng):
    clean, truth = synthetic(np.random.default_rng(5), lights=2, shininess=30.0)
    noisy, _ = synthetic(np.random.default_rng(5), lights=2, shininess=30.0, noise=0.05)
    a = fit(clean, FitOptions(model="lights", lights=2)).objects[0]
    b = fit(noisy, FitOptions(model="lights", lights=2)).objects[0]
    assert (b.light_pos[:, 3] == 0).all()
    assert matched_angles(b.light_pos[:, :3], truth["light_dirs"]).max() < 3.0
    assert b.shininess[0] == pytest.approx(a.shininess[0], rel=0.15)
    assert b.info["error"]["relative_rms"] < 0.08  # about the noise itself


def test_coefficients_are_never_negative(rng):
    # data that a least-squares fit would answer with negative coefficients: a dip
    solution, _ = synthetic(rng, lights=2)
    obj = solution.objects[0]
    flipped = ObjectSolution(
        name="dip", positions=obj.positions, normals=obj.normals, tangents=obj.tangents, faces=obj.faces,
        directions=obj.directions, radiance=(obj.radiance.max() - obj.radiance).astype(np.float32), material=MATERIAL,
    )
    for method in ("paper", "refined"):
        o = fit(Solution(objects=(flipped,), settings={}, stats={}, scene="x"), FitOptions(model="lights", lights=3, method=method)).objects[0]
        assert (o.emitted >= 0).all() and (o.specular >= 0).all() and (o.light_rgb >= 0).all()


def test_vertex_coefficients_closed_form_matches_nnls(rng):
    from scipy.optimize import nnls

    solution, _ = synthetic(rng)
    data = fit_data(solution.objects[0])
    basis = rng.uniform(0, 2, data.radiance.shape)
    target = data.radiance - 0.5 * basis  # pushes some optima to the bounds
    data_shifted = type(data)(radiance=target, views=data.views, normals=data.normals, weights=data.weights, positions=data.positions)
    e, s, _ = vertex_coefficients(data_shifted, basis)
    for v in range(0, data.n_vertices, 7):
        for c in range(3):
            w = np.sqrt(data.weights[v])
            a = np.stack([w, w * basis[v, :, c]], axis=1)
            ref, _ = nnls(a, w * target[v, :, c])
            got = np.array([e[v, c], s[v, c]])
            assert np.sum((a @ got - w * target[v, :, c]) ** 2) <= np.sum((a @ ref - w * target[v, :, c]) ** 2) * (1 + 1e-9) + 1e-15


@pytest.mark.slow  # ~10 s of CPU: a bisection over K of refined fits
def test_auto_lights_reaches_the_target_with_fewest_lights(rng):
    solution, _ = synthetic(rng, lights=3, shininess=40.0)
    model = fit(solution, FitOptions(model="lights", lights="auto", target=0.01, max_lights=8, method="refined"))
    o = model.objects[0]
    assert o.info["error"]["relative_rms"] <= 0.01
    assert 1 <= o.n_lights <= 3 and o.info["chosen_by"].startswith("auto")


def test_auto_lights_small(rng):
    """The fast cousin of the test above: a coarser dome, short refinements; three true
    lights, so K = 1, 2, 4 bracket the answer and bisection finds 3."""
    solution, _ = synthetic(rng, lights=3, shininess=30.0, grid=8, subdivisions=1)
    model = fit(solution, FitOptions(model="lights", lights="auto", target=0.02, max_lights=4, method="refined", iterations=20))
    o = model.objects[0]
    assert o.info["error"]["relative_rms"] <= 0.02
    assert o.n_lights == 3 and o.info["chosen_by"].startswith("auto: fewest")


def test_relative_loss_lowers_the_relative_error_of_dim_regions(rng):
    solution, _ = synthetic(rng, lights=5, shininess=60.0, noise=0.02)
    data = fit_data(solution.objects[0])
    problem_lin, lin = lights_of(solution, FitOptions(model="lights", lights=2, loss="linear", coefficients="shared"), 2)
    problem_rel, rel = lights_of(solution, FitOptions(model="lights", lights=2, loss="relative", coefficients="shared"), 2)

    def relative_to_radiance(result):
        r = reconstruct(problem_lin, result)
        return np.sqrt(np.sum(data.weights[:, :, None] * ((r - data.radiance) / (data.radiance + 1e-3)) ** 2))

    assert relative_to_radiance(rel) < relative_to_radiance(lin)


def test_fit_file_round_trip_and_shade(rng, tmp_path):
    solution, truth = synthetic(rng, lights=2)
    model = fit(solution, FitOptions(model="lights", lights=2))
    path = tmp_path / "fit.npz"
    model.save(path)
    loaded = load_fit(path)
    with np.load(path, allow_pickle=False) as npz:
        keys = set(npz.files)
    assert keys == {"meta"} | {f"dome/{k}" for k in ("positions", "normals", "faces", "emitted", "specular", "light_pos", "light_rgb", "shininess")}
    o, back = model.object("dome"), loaded.object("dome")
    assert np.array_equal(o.light_pos, back.light_pos) and back.info["error"] == pytest.approx(o.info["error"])
    # shade() reproduces the data the model was fitted to
    data = fit_data(solution.objects[0])
    colours = shade(loaded, "dome", data.views)
    # (float32 storage moves an error of ~1e-7 by ~1e-7)
    assert relative_error(data, colours)["relative_rms"] == pytest.approx(o.info["error"]["relative_rms"], abs=1e-5)
