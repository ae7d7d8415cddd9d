"""Tests for fitting.baselines: diffuse, dominant direction and SH L1 / L2 per vertex.

Known answers: data in the span of the SH basis are reproduced to 1e-9, a constant
plus one Phong lobe centred on a grid direction is recovered by the dominant
direction (its exponent from the search set, its direction exactly), the diffuse
baseline is the weighted mean; the errors are ordered on glossy data; zeros, D = 1,
few directions and huge / tiny scales behave.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fitting.baselines import (
    DEFAULT_EXPONENTS,
    Approximation,
    all_baselines,
    diffuse_only,
    dominant_direction,
    sh_basis,
    spherical_harmonics,
)
from fitting.data import FitData, fit_data, relative_error
from radiosity.files.solution import ObjectSolution
from radiosity.physics.directions import DIFFUSE_DIRECTIONS, grid_directions

MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 50, "emission": [0, 0, 0]}


def make_object(radiance, n_grid, seed=0, side=4):
    """A side x side vertex grid (jittered, so vertex areas differ) in a tilted plane."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(float(side)), np.arange(float(side)))
    positions = np.stack([u.ravel(), v.ravel(), np.zeros(side * side)], axis=1)
    positions[:, :2] += rng.uniform(-0.3, 0.3, (side * side, 2))
    faces = []
    for r in range(side - 1):
        for c in range(side - 1):
            k = side * r + c
            faces += [[k, k + 1, k + side + 1], [k, k + side + 1, k + side]]
    n_v = side * side
    directions = DIFFUSE_DIRECTIONS if n_grid == 1 else grid_directions(n_grid)
    return ObjectSolution(
        name="thing",
        positions=positions,
        normals=np.tile([0.0, 0.0, 1.0], (n_v, 1)),
        tangents=np.tile([1.0, 0.0, 0.0], (n_v, 1)),
        faces=np.array(faces),
        directions=directions,
        radiance=np.asarray(radiance).reshape(n_v, len(directions), 3),
        material=MATERIAL,
    )


def exact_data(obj, radiance):
    """fit_data(obj) with the float64 radiance (the object stores float32)."""
    return replace(fit_data(obj), radiance=np.asarray(radiance, np.float64))


def phong(dirs, centres, exponent):
    """(V, D) max(0, dot(d, centre_v))^exponent."""
    return np.maximum(np.einsum("vk,dk->vd", centres, dirs), 0.0) ** exponent


def random_hemisphere(rng, count, min_z=0.3):
    out = []
    while len(out) < count:
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        if w[2] >= min_z:
            out.append(w)
    return np.array(out)


def glossy(rng, n_grid, exponent=20.0, side=4):
    """Constant + an off-grid Phong lobe per vertex, random RGB: (obj, data, centres)."""
    n_v = side * side
    dirs = grid_directions(n_grid)
    centres = random_hemisphere(rng, n_v)
    base = rng.uniform(0.05, 0.3, (n_v, 1, 3))
    intensity = rng.uniform(0.5, 2.0, (n_v, 1, 3))
    radiance = base + intensity * phong(dirs, centres, exponent)[:, :, None]
    obj = make_object(radiance, n_grid, side=side)
    return obj, exact_data(obj, radiance), centres


def rel_max(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


# ---------------------------------------------------------------------------
# spherical harmonics
# ---------------------------------------------------------------------------


def test_sh_basis_is_the_standard_real_basis():
    w = np.array([[0.36, 0.48, 0.8]])
    x, y, z = w[0]
    expected = [
        0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1), 1.092548 * x * z,
        0.546274 * (x * x - y * y),
    ]
    np.testing.assert_allclose(sh_basis(w, 2)[0], expected, rtol=2e-6)
    np.testing.assert_allclose(sh_basis(w, 1)[0], expected[:4], rtol=2e-6)
    # orthonormal on the sphere: integrate with a fine Fibonacci sphere
    m = 20000
    k = np.arange(m) + 0.5
    zz = 1 - 2 * k / m
    phi = math.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - zz * zz)
    sphere = np.stack([r * np.cos(phi), r * np.sin(phi), zz], axis=1)
    y_all = sh_basis(sphere, 2)
    gram = y_all.T @ y_all * (4 * math.pi / m)
    np.testing.assert_allclose(gram, np.eye(9), atol=2e-3)


def non_negative_in_span(basis, coeffs):
    """(coeffs, basis @ coeffs) with each (vertex, channel)'s constant term raised just
    enough that the radiance is non-negative (a solution refuses negative radiance); the
    data stay in the span of the basis."""
    radiance = basis @ coeffs
    coeffs = coeffs.copy()
    coeffs[:, 0, :] += np.maximum(-radiance.min(axis=1), 0.0) / basis[0, 0]
    return coeffs, np.maximum(basis @ coeffs, 0.0)


@pytest.mark.parametrize("order", [1, 2])
def test_sh_reproduces_data_in_its_span(rng, order):
    n_grid, n_v = 8, 16
    k = (order + 1) ** 2
    coeffs, radiance = non_negative_in_span(sh_basis(grid_directions(n_grid), order), rng.normal(size=(n_v, k, 3)))
    obj = make_object(radiance, n_grid)
    data = exact_data(obj, radiance)
    approx = spherical_harmonics(obj, data, order)
    assert approx.name == f"sh_l{order}"
    assert approx.floats_per_vertex == 3 * k
    assert approx.reconstruction.shape == radiance.shape
    assert approx.reconstruction.dtype == np.float64
    assert rel_max(approx.reconstruction, radiance) < 1e-9
    assert rel_max(approx.params["coefficients"], coeffs) < 1e-9
    assert relative_error(data, approx.reconstruction)["relative_rms"] < 1e-9


def test_sh_l1_cannot_reproduce_l2_data(rng):
    """The exactness above is not automatic: L2 content is beyond L1."""
    n_grid, n_v = 8, 16
    _, radiance = non_negative_in_span(sh_basis(grid_directions(n_grid), 2), rng.normal(size=(n_v, 9, 3)))
    obj = make_object(radiance, n_grid)
    data = exact_data(obj, radiance)
    assert relative_error(data, spherical_harmonics(obj, data, 1).reconstruction)["relative_rms"] > 0.1


def test_sh_with_direction_dependent_weights_matches_per_vertex_lstsq(rng):
    """The general path (weights varying across directions) is the weighted LS per vertex."""
    n_grid, n_v = 6, 16
    obj, data, _ = glossy(rng, n_grid)
    weights = rng.uniform(0.0, 1.0, data.weights.shape)
    weights[3] = 0.0  # a vertex of no weight counts as uniform
    weights /= weights.sum()
    data_w = replace(data, weights=weights)
    dirs = grid_directions(n_grid)
    for order in (1, 2):
        approx = spherical_harmonics(obj, data_w, order)
        basis = sh_basis(dirs, order)
        for v in range(n_v):
            w = weights[v] if weights[v].sum() > 0 else np.ones(len(dirs))
            root = np.sqrt(w)[:, None]
            c, *_ = np.linalg.lstsq(root * basis, root * data.radiance[v], rcond=None)
            np.testing.assert_allclose(approx.reconstruction[v], basis @ c, rtol=1e-9, atol=1e-12)
    # weights equal for every vertex up to a factor, but not across directions:
    # the shared pseudo-inverse must carry the direction weights
    profile = rng.uniform(0.0, 1.0, len(dirs))
    profile[:5] = 0.0
    shared = np.outer(rng.uniform(0.5, 2.0, n_v), profile)
    approx = spherical_harmonics(obj, replace(data, weights=shared), 2)
    basis = sh_basis(dirs, 2)
    root = np.sqrt(profile)[:, None]
    for v in range(n_v):
        c, *_ = np.linalg.lstsq(root * basis, root * data.radiance[v], rcond=None)
        np.testing.assert_allclose(approx.reconstruction[v], basis @ c, rtol=1e-9, atol=1e-12)
    # data in the span are still exact under any positive weights
    coeffs = rng.normal(size=(n_v, 9, 3))
    radiance = sh_basis(dirs, 2) @ coeffs
    data_span = replace(data_w, radiance=radiance, weights=weights + 1e-3)
    assert rel_max(spherical_harmonics(obj, data_span, 2).reconstruction, radiance) < 1e-9


@pytest.mark.parametrize("order", [0, 3, 1.0, True, "2"])
def test_sh_order_must_be_1_or_2(rng, order):
    obj, data, _ = glossy(rng, 4)
    with pytest.raises(ValueError, match="order"):
        spherical_harmonics(obj, data, order)


def test_errors_are_ordered_on_glossy_data(rng):
    obj, data, _ = glossy(rng, 12, exponent=20.0)
    err = {a.name: relative_error(data, a.reconstruction)["relative_rms"] for a in all_baselines(obj, data)}
    assert err["sh_l2"] < err["sh_l1"] < err["diffuse"]
    # the dominant direction has the lobe's shape: far better than the diffuse constant
    assert err["dominant_direction"] < 0.5 * err["diffuse"]
    assert all(np.isfinite(list(err.values())))


# ---------------------------------------------------------------------------
# dominant direction
# ---------------------------------------------------------------------------


def test_dominant_direction_recovers_a_lobe_on_a_grid_direction(rng):
    n_grid, n_v, exponent = 12, 16, 100.0
    assert exponent in DEFAULT_EXPONENTS
    dirs = grid_directions(n_grid)
    candidates = np.flatnonzero(dirs[:, 2] > 0.2)
    centres = dirs[rng.choice(candidates, n_v)]
    base = rng.uniform(0.0, 0.3, (n_v, 1, 3))
    base[0] = 0.0  # a pure lobe
    intensity = rng.uniform(0.2, 3.0, (n_v, 1, 3))
    intensity[1, 0, 2] = 0.0  # a channel with no lobe
    radiance = base + intensity * phong(dirs, centres, exponent)[:, :, None]
    obj = make_object(radiance, n_grid)
    data = fit_data(obj)  # float32-rounded data: the error floor is ~1e-7
    approx = dominant_direction(obj, data)
    assert approx.name == "dominant_direction" and approx.floats_per_vertex == 8
    assert approx.params["exponent"] == exponent
    assert relative_error(data, approx.reconstruction)["relative_rms"] < 1e-6
    assert relative_error(data, approx.reconstruction)["worst_vertex"] < 1e-6
    np.testing.assert_allclose(approx.params["directions"], centres, atol=1e-9)
    np.testing.assert_allclose(approx.params["base"], base[:, 0], atol=1e-6)
    np.testing.assert_allclose(approx.params["intensity"], intensity[:, 0], rtol=1e-5, atol=1e-6)
    assert np.all(approx.params["base"] >= 0) and np.all(approx.params["intensity"] >= 0)
    # other exponents of the search are clearly worse
    errors = approx.params["relative_rms"]
    assert all(e > 1e-3 for p, e in errors.items() if p != exponent)


def test_dominant_direction_off_grid_lobe_within_a_cell(rng):
    n_grid = 16
    obj, data, centres = glossy(rng, n_grid, exponent=100.0)
    approx = dominant_direction(obj, data)
    spacing = math.sqrt(2 * math.pi / n_grid**2)
    found = approx.params["directions"]
    angle = np.arccos(np.clip(np.sum(found * centres, axis=1), -1, 1))
    assert np.all(angle < spacing), (angle / spacing).round(2)
    assert np.allclose(np.linalg.norm(found, axis=1), 1.0)
    # the (a, b) stored are these directions
    from radiosity.physics.directions import square_to_hemisphere

    a, b = approx.params["square"].T
    np.testing.assert_allclose(square_to_hemisphere(a, b), found, atol=1e-12)
    # the centroid refinement matters: the nearest grid cell alone is off by up to
    # ~0.7 spacing (mean ~0.37) with a relative error ~0.16 on data like these
    assert angle.mean() < 0.2 * spacing and angle.max() < 0.4 * spacing
    assert relative_error(data, approx.reconstruction)["relative_rms"] < 0.08


def test_dominant_direction_honours_given_exponents(rng):
    obj, data, _ = glossy(rng, 8, exponent=20.0)
    approx = dominant_direction(obj, data, exponents=[7.0])
    assert approx.params["exponent"] == 7.0 and list(approx.params["relative_rms"]) == [7.0]
    for bad in ([], [0.0], [-1.0], [math.inf], [math.nan], "x"):
        with pytest.raises(ValueError, match="exponents"):
            dominant_direction(obj, data, exponents=bad)


def test_dominant_direction_nnls_boundaries(rng):
    """A dip below a constant cannot be a negative lobe: the best is then a constant."""
    n_grid, n_v = 8, 16
    dirs = grid_directions(n_grid)
    centres = dirs[rng.integers(0, len(dirs), n_v)]
    radiance = 1.0 - 0.5 * phong(dirs, centres, 10.0)[:, :, None] * np.ones(3)
    obj = make_object(radiance, n_grid)
    data = exact_data(obj, radiance)
    approx = dominant_direction(obj, data, exponents=[10.0])
    assert np.all(approx.params["intensity"] >= 0) and np.all(approx.params["base"] >= 0)
    # never worse than the best non-negative constant, which is the weighted mean here
    mean = diffuse_only(obj, data).reconstruction
    assert relative_error(data, approx.reconstruction)["relative_rms"] <= relative_error(data, mean)["relative_rms"] + 1e-12
    # all-negative data: the non-negative fit is zero
    neg = replace(data, radiance=-np.abs(data.radiance))
    assert np.all(dominant_direction(obj, neg).reconstruction == 0.0)


# ---------------------------------------------------------------------------
# diffuse only
# ---------------------------------------------------------------------------


def test_diffuse_only_is_the_weighted_mean(rng):
    obj, data, _ = glossy(rng, 8)
    approx = diffuse_only(obj, data)
    mean = data.radiance.mean(axis=1)  # fit_data's weights are constant per vertex
    assert approx.name == "diffuse" and approx.floats_per_vertex == 3
    np.testing.assert_allclose(approx.reconstruction, np.broadcast_to(mean[:, None], data.radiance.shape), rtol=1e-12)
    weights = rng.uniform(0.0, 1.0, data.weights.shape)
    weighted = replace(data, weights=weights)
    expected = np.einsum("vd,vdc->vc", weights, data.radiance) / weights.sum(axis=1)[:, None]
    np.testing.assert_allclose(diffuse_only(obj, weighted).params["base"], expected, rtol=1e-12)
    np.testing.assert_allclose(diffuse_only(obj, weighted).reconstruction[:, 5], expected, rtol=1e-12)


# ---------------------------------------------------------------------------
# all baselines, extremes
# ---------------------------------------------------------------------------


def test_all_baselines_order_and_storage(rng):
    obj, data, _ = glossy(rng, 8)
    approxes = all_baselines(obj, data)
    assert [a.name for a in approxes] == ["diffuse", "dominant_direction", "sh_l1", "sh_l2"]
    assert [a.floats_per_vertex for a in approxes] == [3, 8, 12, 27]
    for a in approxes:
        assert isinstance(a, Approximation)
        assert a.reconstruction.shape == data.radiance.shape
        assert np.isfinite(a.reconstruction).all()


@pytest.mark.parametrize("n_grid", [1, 8])
def test_zeros_give_zeros(n_grid):
    side = 3
    obj = make_object(np.zeros((side * side, n_grid * n_grid, 3)), n_grid, side=side)
    data = fit_data(obj)
    for a in all_baselines(obj, data):
        assert np.all(a.reconstruction == 0.0), a.name
        for key, value in a.params.items():
            if isinstance(value, np.ndarray):
                assert np.isfinite(value).all(), (a.name, key)
        assert relative_error(data, a.reconstruction)["relative_rms"] == 0.0


@pytest.mark.parametrize("scale", [1e8, 1e-8])
def test_reconstructions_scale_linearly(rng, scale):
    obj, data, _ = glossy(rng, 8)
    scaled = replace(data, radiance=data.radiance * scale)
    for a, b in zip(all_baselines(obj, data), all_baselines(obj, scaled)):
        assert np.isfinite(b.reconstruction).all()
        assert rel_max(b.reconstruction / scale, a.reconstruction) < 1e-9, a.name
    da, db = dominant_direction(obj, data), dominant_direction(obj, scaled)
    assert da.params["exponent"] == db.params["exponent"]
    np.testing.assert_allclose(db.params["directions"], da.params["directions"], atol=1e-12)


def test_diffuse_object_with_one_direction(rng):
    """D = 1: every baseline reproduces the data (SH with fewer samples than coefficients)."""
    radiance = rng.uniform(0.0, 5.0, (16, 1, 3))
    obj = make_object(radiance, 1)
    data = exact_data(obj, radiance)
    for a in all_baselines(obj, data):
        assert a.reconstruction.shape == (16, 1, 3)
        assert np.isfinite(a.reconstruction).all()
        assert rel_max(a.reconstruction, radiance) < 1e-12, a.name


def test_sh_l2_with_fewer_directions_than_coefficients(rng):
    """n = 2 (D = 4 < 9): the minimum-norm fit still reproduces the samples."""
    obj, data, _ = glossy(rng, 2)
    approx = spherical_harmonics(obj, data, 2)
    assert np.isfinite(approx.params["coefficients"]).all()
    assert rel_max(approx.reconstruction, data.radiance) < 1e-9


@pytest.mark.parametrize("n_grid, order", [(2, 1), (3, 2)])
def test_sh_rank_deficient_grids_give_the_minimum_norm_fit(rng, n_grid, order):
    """On the 2 x 2 grid 1 and z coincide (L1 has rank 3); on 3 x 3, L2 has rank 6 of 9.

    The fit is then the least-squares fit of least coefficient norm: bounded, not a
    blow-up from inverting a zero singular value.
    """
    obj, data, _ = glossy(rng, n_grid)
    approx = spherical_harmonics(obj, data, order)
    basis = sh_basis(grid_directions(n_grid), order)
    scale = np.abs(data.radiance).max()
    for v in range(data.n_vertices):
        c, *_ = np.linalg.lstsq(basis, data.radiance[v], rcond=1e-10)
        np.testing.assert_allclose(approx.params["coefficients"][v], c, rtol=1e-8, atol=1e-10 * scale)
    assert np.abs(approx.params["coefficients"]).max() < 20 * scale


def test_shape_mismatch_is_refused(rng):
    obj, data, _ = glossy(rng, 4)
    wrong = FitData(
        radiance=data.radiance[:, :9], views=data.views[:, :9], normals=data.normals, weights=data.weights[:, :9]
    )
    for fn in (diffuse_only, dominant_direction, lambda o, d: spherical_harmonics(o, d, 2)):
        with pytest.raises(ValueError, match="radiance"):
            fn(obj, wrong)
