"""One fit pipeline: every glossy model, the paper's lights alone included, goes through
``fitting.glossy.fit_components`` and leaves one record of what was fitted (the same
keys whatever the model); the model "lights" found on every k-th vertex and solved on
all is the lights' own projection, as the paper solves it."""

from dataclasses import replace

import numpy as np
import pytest
from test_glossy import MATERIAL, plane, solution_of

from fitting import FitOptions
from fitting.fit import fit_object
from fitting.glossy import fit_components
from fitting.lights import LightFitter, start_exponent
from fitting.mixed import SceneGeometry
from fitting.results import Lights

OPTIONS = FitOptions(probe_sizes=(8,), probe_lights=2, lights=2, iterations=10)
RECORD = {"model", "method", "loss", "chosen_by", "coefficients", "kinds", "shininess", "error", "floats", "tried",
          "time_s"}
ERRORS = {"relative_rms", "perceptual", "diffuse_only_relative_rms"}


def _highlighted():
    """A glossy plane with a highlight (a lobe about a direction) on a diffuse base."""
    positions, faces, normals = plane(9)
    towards = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])

    def radiance(views, normals, positions):
        r = 2 * np.sum(views * normals[:, None], axis=2, keepdims=True) * normals[:, None] - views
        lobe = np.maximum(np.sum(r * towards, axis=2, keepdims=True), 0.0) ** 30
        return 0.2 + 3.0 * lobe * np.array([1.0, 0.9, 0.8])

    solution = solution_of(positions, faces, normals, radiance)
    obj = replace(solution.objects[0], material=dict(MATERIAL))
    return replace(solution, objects=(obj,)), obj


@pytest.mark.parametrize("options", [replace(OPTIONS, model="lights"), replace(OPTIONS, method="paper"),
                                     replace(OPTIONS, model="probe"), replace(OPTIONS, model="probe+lights"),
                                     replace(OPTIONS, model="emitters"), OPTIONS])
def test_every_model_leaves_one_record(options):
    solution, obj = _highlighted()
    fitted = fit_object(obj, options, SceneGeometry.of_solution(solution), None, solution, np.array([[-2.0] * 3, [2.0] * 3]))
    assert RECORD <= set(fitted.info), sorted(RECORD - set(fitted.info))
    assert ERRORS <= set(fitted.info["error"])
    assert fitted.info["model"] == (options.glossy_model if options.model != "auto" else fitted.info["model"])
    assert all(np.isfinite(fitted.info["error"][k]) for k in ERRORS)
    if options.glossy_model == "lights":
        assert fitted.info["method"] == options.method and fitted.info["chosen_by"] == "--lights 2"
        assert fitted.n_lights == 2 and {"worst_vertex", "worst_vertex_index"} <= set(fitted.info["error"])


def test_the_paper_s_lights_go_through_the_glossy_pipeline_without_the_solution():
    """The model "lights" needs no emitters: fit_components fits it (it raised before),
    and fit_object fits it without the solution."""
    solution, obj = _highlighted()
    scene = SceneGeometry.of_solution(solution)
    options = replace(OPTIONS, method="paper")
    c = fit_components(obj, None, 0, options, scene, None, start_exponent(obj, options), LightFitter(options, scene))
    assert c.model == "lights" and isinstance(c.lights, Lights) and len(c.lights.pos) == 2
    assert np.all(c.lights.pos[:, 3] == 0)  # the paper's lights are directional
    alone = fit_object(obj, options, scene)
    assert np.array_equal(alone.emitted, np.asarray(c.emitted, np.float32))
    assert np.array_equal(alone.light_pos, np.asarray(c.lights.pos, np.float32))


def test_the_lights_found_on_a_subset_are_solved_on_every_vertex():
    """Found on every k-th vertex, the lights' coefficients are then solved on all: the
    error is measured on every vertex, and the record says on which the lights were found."""
    solution, obj = _highlighted()
    scene = SceneGeometry.of_solution(solution)
    whole = fit_object(obj, replace(OPTIONS, model="lights"), scene)
    sub = fit_object(obj, replace(OPTIONS, model="lights", search_samples=20 * len(obj.directions)), scene)
    assert "found on every" in sub.info["chosen_by"] and "found on every" not in whole.info["chosen_by"]
    assert sub.emitted.shape == whole.emitted.shape == (obj.num_vertices, 3)
    assert sub.info["error"]["relative_rms"] < 2 * whole.info["error"]["relative_rms"] + 0.05


@pytest.mark.parametrize("method", ["paper", "refined", "per-light"])
def test_every_method_gives_one_type_for_its_lights(method):
    """The paper's fit, the refined fit and per-light exponents all return a
    ``LightsFit`` whose lights are a ``Lights``; the paper's are directional (w = 0),
    share one exponent, and carry their colour with shared coefficients."""
    from fitting.data import fit_data
    from fitting.lights import fit_lights, problem_for
    from fitting.results import LightsFit

    solution, obj = _highlighted()
    options = replace(OPTIONS, model="lights", method=method, coefficients="shared")
    problem = problem_for(fit_data(obj), options, SceneGeometry.of_solution(solution))
    found = fit_lights(problem, 2, options, start_exponent(obj, options))
    assert isinstance(found, LightsFit) and isinstance(found.lights(), Lights)
    lights = found.lights()
    assert lights.pos.shape == (found.n_lights, 4) and lights.rgb.shape == (found.n_lights, 3)
    assert lights.pos.flags.c_contiguous and lights.pos.dtype == np.float64
    assert found.emitted.shape == (obj.num_vertices, 3) and found.specular.shape == (obj.num_vertices, 3)
    if method == "paper":
        assert found.n_lights >= 1 and np.all(lights.pos[:, 3] == 0.0)
        assert np.allclose(np.linalg.norm(lights.pos[:, :3], axis=1), 1.0)
        assert np.all(lights.shininess == lights.shininess[0])
