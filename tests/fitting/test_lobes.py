"""The one lobe: shade against numbers worked out by hand, the kernels against shade, the
cut-off, and the refinement's gradient against central differences."""

import math

import numpy as np
import pytest
from test_fit import synthetic

from fitting import FittedModel, FittedObject, Lights, shade
from fitting.data import fit_data
from fitting.lobes import NEGLIGIBLE, Samples, lobe, lobe_gradient, mixed_light_sum, one_light
from fitting.model import directional, shade_arrays

UP = [0.0, 0.0, 1.0]


def one_vertex_model(emitted, specular, light_dirs, light_rgb, shininess, normal=UP):
    """A model of one triangle whose three vertices share the same values."""
    obj = FittedObject(
        name="tri", positions=np.eye(3), normals=np.tile(normal, (3, 1)), faces=np.array([[0, 1, 2]]),
        emitted=np.tile(emitted, (3, 1)), specular=np.tile(specular, (3, 1)),
        light_pos=directional(np.reshape(light_dirs, (-1, 3))), light_rgb=np.reshape(light_rgb, (-1, 3)),
        shininess=np.reshape(shininess, -1),
    )
    return FittedModel(objects=(obj,))


def shade_one(model, w):
    """shade() of the three (identical) vertices seen from ``w``; checks they agree."""
    colours = shade(model, "tri", np.tile(w, (3, 1)))
    assert np.array_equal(colours[0], colours[1]) and np.array_equal(colours[0], colours[2])
    return colours[0]


def test_shade_by_hand():
    # light, eye and normal all along z: h = (0, 0, 2), cos = 1, lobe = 1 whatever the exponent
    model = one_vertex_model([0.1, 0.2, 0.3], [0.5, 0.5, 0.5], UP, [1.0, 2.0, 3.0], 10.0)
    assert shade_one(model, UP) == pytest.approx([0.6, 1.2, 1.8], rel=1e-15)
    # eye at w = (0.6, 0, 0.8), light along z: h = (0.6, 0, 1.8), cos = 1.8 / sqrt(3.6) = 3 / sqrt(10),
    # cos^2 = 0.9, so with exponent 4 the lobe is 0.81
    model = one_vertex_model([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], UP, [1.0, 1.0, 1.0], 4.0)
    assert shade_one(model, [0.6, 0.0, 0.8]) == pytest.approx([0.81, 0.81, 0.81], rel=1e-14)
    # two lights from the same eye: along z (exponent 2: 0.9, red) and the mirror of the eye
    # about the normal, (-0.6, 0, 0.8) (h along n: 1, green): e + s (0.9, 1, 0) with s = 2
    model = one_vertex_model(
        [0.1, 0.1, 0.1], [2.0, 2.0, 2.0], [UP, [-0.6, 0.0, 0.8]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [2.0, 50.0],
    )
    assert shade_one(model, [0.6, 0.0, 0.8]) == pytest.approx([1.9, 2.1, 0.1], rel=1e-14)


def test_shade_gives_no_light_opposite_the_eye_behind_or_below_the_cut_off():
    emitted = [0.25, 0.5, 0.75]
    # the light exactly opposite the eye: h = 0
    model = one_vertex_model(emitted, [1.0, 1.0, 1.0], [-0.6, 0.0, -0.8], [5.0, 5.0, 5.0], 1.0)
    assert np.array_equal(shade_one(model, [0.6, 0.0, 0.8]), emitted)
    # the half vector below the surface: h = (1, 0, -1), cos < 0
    model = one_vertex_model(emitted, [1.0, 1.0, 1.0], [0.0, 0.0, -1.0], [5.0, 5.0, 5.0], 1.0)
    assert np.array_equal(shade_one(model, [1.0, 0.0, 0.0]), emitted)
    # cos = 3 / sqrt(10): (1 - cos) p = 25.7 at p = 500 is kept (0.9^250 = 3.6e-12) ...
    model = one_vertex_model([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], UP, [1.0, 1.0, 1.0], 500.0)
    assert shade_one(model, [0.6, 0.0, 0.8]) == pytest.approx([0.9**250] * 3, rel=1e-12)
    # ... and 51 at p = 1000 is cut (0.9^500 = 1.3e-23, below e^-30 of the peak)
    model = one_vertex_model([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], UP, [1.0, 1.0, 1.0], 1000.0)
    assert np.array_equal(shade_one(model, [0.6, 0.0, 0.8]), [0.0, 0.0, 0.0])


def test_the_cut_off_drops_only_terms_below_1e_13(rng):
    cosines = rng.uniform(0.0, 1.0, 20000)
    exponents = np.exp(rng.uniform(0.0, math.log(1e4), 20000))
    for c, p in zip(cosines, exponents):
        h = (math.sqrt(1 - c * c), 0.0, c)
        value = lobe((0.0, 0.0, 1.0), h, p)
        exact = c**p
        if (1 - c) * p > NEGLIGIBLE:
            assert value == 0.0 and exact < 1e-13
        else:
            assert value == pytest.approx(exact, rel=1e-12, abs=1e-300)


def test_the_kernels_and_shade_are_the_same_lobe(rng):
    solution, _ = synthetic(rng, lights=3, shininess=60.0, grid=8)
    data = fit_data(solution.objects[0])
    dirs = rng.normal(size=(3, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lights = Lights.of(directional(dirs), rng.uniform(0.5, 2.0, (3, 3)), [3.0, 60.0, 900.0])
    zero, one = np.zeros((data.n_vertices, 1, 3)), np.ones((data.n_vertices, 1, 3))
    expected = shade_arrays(zero, one, data.normals[:, None], data.positions[:, None], lights, data.views)
    samples = Samples(np.ascontiguousarray(data.positions, np.float64), data.radiance, data.weights, np.ones((1, 1, 1)))
    got = mixed_light_sum(data.normals, data.views, lights, samples, one, np.empty_like(data.radiance))
    # shade renormalises the light vector (a point light's needs it): p = 900 magnifies that last bit
    assert np.allclose(got, expected, rtol=1e-11, atol=0)
    single = one_light(data.normals, data.views, dirs[1], 60.0, np.empty(data.radiance.shape[:2]))
    expected = shade_arrays(zero, one, data.normals[:, None], data.positions[:, None],
                            (directional(dirs[1:2]), [[1.0, 1.0, 1.0]], [60.0]), data.views)
    assert np.allclose(single, expected[..., 0], rtol=1e-11, atol=0)


def test_lobe_gradient_against_central_differences(rng):
    for _ in range(200):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        w, light = rng.normal(size=3), rng.normal(size=3)
        w, light = w / np.linalg.norm(w), light / np.linalg.norm(light)
        p = float(np.exp(rng.uniform(0, 5)))
        value, dl, dlogp = lobe_gradient(tuple(n), tuple(w + light), p)
        assert value == lobe(tuple(n), tuple(w + light), p)
        if value < 1e-8:
            continue
        step = 1e-6
        for i in range(3):
            e = np.zeros(3)
            e[i] = step
            fd = (lobe(tuple(n), tuple(w + light + e), p) - lobe(tuple(n), tuple(w + light - e), p)) / (2 * step)
            assert dl[i] == pytest.approx(fd, rel=1e-5, abs=1e-7 * p)
        fd = (lobe(tuple(n), tuple(w + light), p * math.exp(step)) - lobe(tuple(n), tuple(w + light), p * math.exp(-step)))
        assert dlogp == pytest.approx(fd / (2 * step), rel=1e-5, abs=1e-9)
