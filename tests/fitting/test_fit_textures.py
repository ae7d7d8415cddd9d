"""A textured object through the fit: its diffuse term (irradiance per vertex, texture
per pixel) is carried from the solution to fit.npz (version 4) unchanged, the fit
approximates the rest of its radiance, and the shading adds kd * texture(uv) / pi * E."""

import json

import numpy as np
import pytest

from fitting import FitOptions, fit, load_fit
from radiosity.files.errors import InputError
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.textures import TexturedDiffuse, lookup
from radiosity.scene import builtins

KD = (0.8, 0.6, 0.4)


def textured_solution(rng, glossy):
    positions, faces = builtins.mesh("sphere", subdivisions=1)
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    tangents = np.cross(normals, [0.3, 0.5, 0.8])
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    n = len(positions)
    texture = rng.uniform(0, 1, (3, 5, 3)).astype(np.float32)
    textured = TexturedDiffuse(uvs=positions[:, :2] / 2 + 0.5, irradiance=rng.uniform(1, 2, (n, 3)), texture=texture, kd=KD)
    if glossy:
        from radiosity.physics.directions import grid_directions

        dirs = grid_directions(4)
        radiance = 0.1 + np.broadcast_to(dirs[None, :, 2:3] ** 8, (n, 16, 3)) * rng.uniform(0.5, 1, (n, 1, 3))
        material = {"diffuse": list(KD), "specular": [0.15, 0.15, 0.15], "exponent": 10.0, "emission": [0, 0, 0]}
    else:
        dirs = np.array([[0.0, 0.0, 1.0]])
        radiance = np.full((n, 1, 3), 0.25)  # its emission
        material = {"diffuse": list(KD), "specular": [0, 0, 0], "exponent": 0.0, "emission": [0.25, 0.25, 0.25]}
    obj = ObjectSolution(name="ball", positions=positions, normals=normals, tangents=tangents, faces=faces,
                         directions=dirs, radiance=radiance, material=material, textured=textured)
    return Solution(objects=(obj,), scene="test")


@pytest.mark.parametrize("glossy", [False, True], ids=["diffuse", "glossy"])
def test_the_texture_goes_through_the_fit_file(rng, tmp_path, glossy):
    solution = textured_solution(rng, glossy)
    model = fit(solution, FitOptions.for_quality("draft"))
    assert model.version == 4
    model.save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    t, t0 = back.object("ball").textured, solution.object("ball").textured
    assert np.array_equal(t.texture, t0.texture) and np.array_equal(t.uvs, t0.uvs)
    assert np.array_equal(t.irradiance, t0.irradiance) and t.kd == t0.kd
    # the shading at the vertices: the fitted rest plus kd * texture(uv) / pi * E
    obj = back.object("ball")
    w = obj.normals.astype(np.float64)
    expected = np.asarray(KD) / np.pi * lookup(t0.texture, t0.uvs) * t0.irradiance
    without = obj.shade(w, parts=()) - obj.emitted  # parts=() leaves emitted + the textured term
    assert np.allclose(without, expected, rtol=1e-5, atol=1e-7)
    if not glossy:
        assert np.allclose(obj.emitted, 0.25, atol=1e-3)  # the fit approximates the radiance it was given


def test_an_untextured_fit_is_version_3(rng, tmp_path):
    solution = textured_solution(rng, False)
    plain = Solution(objects=(ObjectSolution(**{**vars(solution.object("ball")), "textured": None}),))
    model = fit(plain, FitOptions.for_quality("draft"))
    assert model.version == 3
    model.save(tmp_path / "fit.npz")
    with np.load(tmp_path / "fit.npz") as z:
        assert json.loads(str(z["meta"]))["version"] == 3


def test_a_half_textured_object_is_refused(rng, tmp_path):
    fit(textured_solution(rng, False), FitOptions.for_quality("draft")).save(tmp_path / "fit.npz")
    with np.load(tmp_path / "fit.npz") as z:
        content = {k: z[k] for k in z.files}
    del content["ball/irradiance"]
    np.savez(tmp_path / "bad.npz", **content)
    with pytest.raises(InputError, match="ball/irradiance"):
        load_fit(tmp_path / "bad.npz")


def test_objects_fitted_in_workers_share_the_texture_the_parent_holds(rng, tmp_path):
    """Two glossy objects with one texture, fitted in two worker processes: each comes
    back with its textured term read in the parent, the one shared array (a worker's
    copy would be a copy each), and the model is the one fitted here."""
    from dataclasses import replace

    from radiosity.files.solution import SolutionFile

    ball = textured_solution(rng, True).objects[0]
    solution = Solution(objects=(ball, replace(ball, name="ball2", positions=ball.positions + 3.0)), scene="test")
    solution.save(tmp_path / "solution.npz")
    options = FitOptions.for_quality("draft")
    from fitting.fit import planned_workers

    with SolutionFile(tmp_path / "solution.npz") as source:
        assert planned_workers(source, 2) == 2
        apart = fit(source, options, workers=2)
        here = fit(source, options, workers=1)
    a, b = apart.object("ball").textured, apart.object("ball2").textured
    assert a.texture is b.texture
    for name in ("ball", "ball2"):
        x, y = apart.object(name), here.object(name)
        assert np.array_equal(x.textured.texture, y.textured.texture) and np.array_equal(x.textured.uvs, y.textured.uvs)
        assert np.array_equal(x.emitted, y.emitted) and np.array_equal(x.specular, y.specular)
