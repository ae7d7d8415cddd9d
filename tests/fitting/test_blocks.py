"""A glossy object fitted in bounded memory (``fitting.blocks``): its model searched for
on every k-th vertex, its per-vertex coefficients solved on every vertex a block at a
time. Known answers: lights found on a subset are the object's lights; the blocks change
no coefficient; the working set does not grow with the object beyond its radiance."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_glossy import plane, solution_of

from fitting import FitOptions
from fitting.blocks import search_slice, vertex_blocks
from fitting.fit import fit_object
from fitting.model import directional, shade_arrays

TRUE_DIRS = np.array([[0.6, 0.2, 0.77], [-0.5, -0.4, 0.77]]) / np.linalg.norm([0.6, 0.2, 0.77])
TRUE_DIRS /= np.linalg.norm(TRUE_DIRS, axis=1, keepdims=True)
TRUE_SHININESS = 60.0


def two_lights(views, normals, positions):
    """Exactly two distant Blinn-Phong lights over an emitted colour; each vertex's
    coefficients vary smoothly over the plane (as a solution's do)."""
    x, y = positions[:, None, 0:1], positions[:, None, 1:2]
    emitted = 0.1 + 0.05 * np.cos(x + 2 * y) * np.ones((1, 1, 3))
    specular = np.stack([1.5 + 0.5 * np.sin(x - y) * np.ones((1, 1, 3)), 2.0 + 0.5 * np.cos(2 * x) * np.ones((1, 1, 3))],
                        axis=2)
    lights = (directional(TRUE_DIRS), np.ones((2, 3)), np.full(2, TRUE_SHININESS))
    return shade_arrays(emitted, specular, normals[:, None], positions[:, None], lights, views)


def fit_one(solution, options):
    obj = solution.objects[0]
    return fit_object(obj, options, None, None, solution, np.array([[-2.0, -2.0, -1.0], [2.0, 2.0, 2.0]]))


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def matched(found):
    """The found lights' directions in the order of TRUE_DIRS."""
    dirs = found.light_pos[:, :3].astype(np.float64)
    order = [int(np.argmin(angle_deg(dirs, t))) for t in TRUE_DIRS]
    return dirs[order], found.shininess[order]


@pytest.fixture(scope="module")
def lit_plane():
    positions, faces, normals = plane(n=25)  # 625 vertices x 144 directions: 90,000 samples
    return solution_of(positions, faces, normals, two_lights, grid=12)


LIGHTS = FitOptions(model="lights", lights=2, light_kind="directional", iterations=40)


def test_the_search_s_subset_finds_the_object_s_lights(lit_plane):
    samples = lit_plane.objects[0].num_vertices * 144
    whole = fit_one(lit_plane, replace(LIGHTS, search_samples=samples))
    subset = fit_one(lit_plane, replace(LIGHTS, search_samples=samples // 8))  # every 8th vertex
    assert "found on every 8-th vertex" in subset.info["chosen_by"]
    for found in (whole, subset):
        dirs, shininess = matched(found)
        assert np.all(angle_deg(dirs, TRUE_DIRS) < 0.5), dirs
        np.testing.assert_allclose(shininess, TRUE_SHININESS, rtol=0.03)
        assert found.info["error"]["relative_rms"] < 0.01, found.info
    # the same lights within 0.25 degree and 2 % of the exponent; errors alike
    assert np.all(angle_deg(matched(whole)[0], matched(subset)[0]) < 0.25)
    np.testing.assert_allclose(matched(whole)[1], matched(subset)[1], rtol=0.02)
    assert subset.info["error"]["relative_rms"] < whole.info["error"]["relative_rms"] + 0.005


@pytest.mark.parametrize("model", ["lights", "probe+lights", "auto"])
def test_blocks_change_no_coefficient(lit_plane, model):
    """The per-vertex pass two vertices a block or everything at once: the same bits."""
    options = replace(LIGHTS, model=model, probe_sizes=(8,), probe_lights=2, iterations=10, search_samples=20_000)
    one = fit_one(lit_plane, replace(options, block_samples=1))
    every = fit_one(lit_plane, replace(options, block_samples=10**9))
    for key in ("emitted", "specular", "light_pos", "shininess"):
        np.testing.assert_array_equal(getattr(one, key), getattr(every, key), err_msg=key)
    if one.probe is not None:
        np.testing.assert_array_equal(one.probe_weight, every.probe_weight)
        np.testing.assert_array_equal(one.probe.texels, every.probe.texels)
    for key, value in one.info["error"].items():
        assert value == pytest.approx(every.info["error"][key], rel=1e-9, abs=1e-12), key


def test_a_fit_is_the_same_run_twice(lit_plane):
    options = replace(LIGHTS, model="auto", probe_sizes=(8,), probe_lights=2, iterations=10, search_samples=20_000)
    a, b = fit_one(lit_plane, options), fit_one(lit_plane, options)
    for key in ("emitted", "specular", "light_pos", "shininess", "probe_weight"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)


def test_slices():
    assert search_slice(1000, 100, 10**6) == slice(0, 1000, 1)
    assert search_slice(1000, 100, 25_000) == slice(0, 1000, 4)
    blocks = vertex_blocks(1000, 100, 30_000)
    assert [b.stop - b.start for b in blocks] == [300, 300, 300, 100]
    # at least two vertices a block (the kernels read one vertex's loss weights as none)
    assert [b.stop - b.start for b in vertex_blocks(5, 10_000, 100)] == [2, 3]
    assert [b.stop - b.start for b in vertex_blocks(901, 100, 30_000)] == [300, 300, 301]
    assert search_slice(5, 10_000, 1) == slice(0, 5, 2)


MEASURE = textwrap.dedent("""
    import json, sys, tracemalloc
    import numpy as np
    from fitting import FitOptions
    from fitting.fit import fit_object
    sys.path.insert(0, sys.argv[3])
    from test_glossy import plane, solution_of
    from test_blocks import two_lights

    n, search = int(sys.argv[1]), int(sys.argv[2])
    options = FitOptions(model="probe", probe_size=8, loss="linear", search_samples=search, block_samples=search)
    box = np.array([[-2.0, -2.0, -1.0], [2.0, 2.0, 2.0]])

    def solution(n):
        positions, faces, normals = plane(n=n)
        return solution_of(positions, faces, normals, two_lights, grid=12)

    warm = solution(12)  # every kernel compiled before anything is measured
    fit_object(warm.objects[0], options, None, None, warm, box)
    big = solution(n)
    tracemalloc.start()  # numpy's allocations are traced: every array of the fit
    held, _ = tracemalloc.get_traced_memory()
    fitted = fit_object(big.objects[0], options, None, None, big, box)
    _, peak = tracemalloc.get_traced_memory()
    print(json.dumps({"samples": big.objects[0].radiance.shape[0] * 144, "radiance": big.objects[0].radiance.nbytes,
                      "grew": peak - held, "error": fitted.info["error"]["relative_rms"]}))
""")


def measure(n, search):
    out = subprocess.run([sys.executable, "-c", MEASURE, str(n), str(search), str(Path(__file__).parent)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_large_object_s_working_set_is_the_block_budget_not_its_samples():
    """Objects of 0.7 and 2.9 million samples, the search and the blocks at 2^16
    samples: the arrays the fit allocates (tracemalloc's peak, in a process of its
    own) stay within the budget's working set, and four times the samples add only
    what grows with the vertices (the model), where arrays of every sample would be
    gigabytes (1.2 kB a sample before)."""
    small, large = measure(71, 2**16), measure(141, 2**16)
    assert large["samples"] > 2.8e6 and large["samples"] > 3.9 * small["samples"]
    assert large["error"] < 0.7  # an 8 x 8 probe draws two sharp lights' glow: the test is of memory
    assert large["grew"] < 2**16 * 1_200 + 1_000 * large["samples"] / 144, large
    assert large["grew"] - small["grew"] < 1_000 * (large["samples"] - small["samples"]) / 144, (small, large)
