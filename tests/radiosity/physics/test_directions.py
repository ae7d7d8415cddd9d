"""Tests for radiosity.physics.directions: the contract's equal-area hemisphere grid, the maps
between the square and the hemisphere (numpy and numba), bilinear grid lookup, and the
grid size rule.

Equal area is checked by a chi-square test of uniform hemisphere directions binned
into grid cells through ``hemisphere_to_square``; a companion test shows the same test
rejects a map that is not equal-area.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from radiosity.physics.directions import (
    DIFFUSE_DIRECTIONS,
    GRID_MAX,
    GRID_MIN,
    QUALITY_FACTORS,
    grid_directions,
    grid_lookup_weights,
    grid_size,
    hemisphere_to_square,
    hemisphere_to_square_nb,
    square_to_hemisphere,
    square_to_hemisphere_nb,
)

SEED = 1997  # Walter et al.


def centres(n: int) -> np.ndarray:
    """Square coordinates of the cell centres along one axis, from the contract."""
    return 2.0 * (np.arange(n) + 0.5) / n - 1.0


def special_square_points() -> tuple[np.ndarray, np.ndarray]:
    """Diagonals |a| = |b|, axes, corners, edges, the centre and points near it."""
    t = np.linspace(-1.0, 1.0, 41)
    zero = np.zeros_like(t)
    ones = np.ones_like(t)
    tiny = np.array([1e-300, 1e-12, 1e-9, -1e-9, 1e-6, 0.0])
    a = np.concatenate([t, t, t, zero, ones, -ones, t, t, tiny, tiny[::-1], [0.0]])
    b = np.concatenate([t, -t, zero, t, t, t, ones, -ones, tiny[::-1], -tiny, [0.0]])
    return a, b


def all_square_points(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    a, b = special_square_points()
    ra, rb = rng.uniform(-1.0, 1.0, (2, 20_000))
    return np.concatenate([a, ra]), np.concatenate([b, rb])


# ---------------------------------------------------------------------------
# grid_directions
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 16, 64])
def test_grid_directions_are_n_squared_unit_vectors_above_the_horizon(n):
    d = grid_directions(n)
    assert d.shape == (n * n, 3) and d.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-15)
    assert (d[:, 2] > 0.0).all()
    assert len(np.unique(np.round(d, 12), axis=0)) == n * n


def test_first_cell_of_the_2x2_grid_by_hand():
    # Cell (i, j) = (0, 0): a = b = 2 * 0.5 / 2 - 1 = -0.5. |a| > |b| is false, so
    # r = b = -0.5 and phi = pi/2 - pi/4 * a/b = pi/4; s = sqrt(2 - r^2).
    a = b = -0.5
    r, phi = b, math.pi / 2 - math.pi / 4 * a / b
    s = math.sqrt(2.0 - r * r)
    expected = [r * math.cos(phi) * s, r * math.sin(phi) * s, 1.0 - r * r]
    np.testing.assert_allclose(grid_directions(2)[0], expected, rtol=0, atol=1e-15)
    # Pointing away from +x and +y: the lower-left cell of the square.
    assert expected[0] < 0 and expected[1] < 0 and expected[2] == 0.75


def test_grid_order_is_row_major_with_i_the_column():
    n = 3
    d = grid_directions(n)
    c = centres(n)
    for j in range(n):
        for i in range(n):
            np.testing.assert_allclose(d[j * n + i], square_to_hemisphere(c[i], c[j]), atol=1e-15)
    # Increasing i (d = 0 -> 1) changes a, the x-ish coordinate: x grows, y stays
    # negative; increasing j (d = 0 -> 3) changes b: y grows.
    assert d[1, 0] > d[0, 0] + 0.3 and d[1, 1] < 0
    assert d[3, 1] > d[0, 1] + 0.3 and d[3, 0] < 0
    # Along every row x increases with i; along every column y increases with j.
    grid = d.reshape(n, n, 3)
    assert (np.diff(grid[:, :, 0], axis=1) > 0).all()
    assert (np.diff(grid[:, :, 1], axis=0) > 0).all()


def test_odd_grid_centre_cell_is_the_normal_and_n1_is_the_diffuse_direction():
    for n in (1, 3, 5, 15):
        np.testing.assert_array_equal(grid_directions(n)[(n * n) // 2], [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(grid_directions(1), DIFFUSE_DIRECTIONS)
    assert DIFFUSE_DIRECTIONS.shape == (1, 3)


def test_grid_cells_map_back_to_their_centres():
    for n in (2, 5, 8):
        a, b = hemisphere_to_square(grid_directions(n))
        c = centres(n)
        np.testing.assert_allclose(a, np.tile(c, n), rtol=0, atol=1e-12)
        np.testing.assert_allclose(b, np.repeat(c, n), rtol=0, atol=1e-12)


@pytest.mark.parametrize("bad", [0, -1, 2.0, 2.5, True, "4", None])
def test_grid_n_must_be_a_positive_integer(bad):
    with pytest.raises(ValueError):
        grid_directions(bad)
    with pytest.raises(ValueError):
        grid_lookup_weights(np.array([0.0, 0.0, 1.0]), bad)


def test_numpy_integer_grid_size_is_accepted():
    np.testing.assert_array_equal(grid_directions(np.int64(4)), grid_directions(4))


# ---------------------------------------------------------------------------
# Equal area: chi-square of uniform directions over the cells
# ---------------------------------------------------------------------------

CHI2_SAMPLES = 2_000_000
CHI2_GRIDS = (4, 7, 16)
CHI2_LEVEL = 1.0 - (1.0 - 0.01) ** (1.0 / len(CHI2_GRIDS))  # family-wise 1% (Sidak)


@pytest.fixture(scope="module")
def uniform_hemisphere_squares():
    """2e6 uniform directions on the hemisphere, their (a, b), and their radii."""
    rng = np.random.default_rng(SEED)
    z = rng.random(CHI2_SAMPLES)  # uniform z on [0, 1) is uniform solid angle
    phi = rng.uniform(-math.pi, math.pi, CHI2_SAMPLES)
    rho = np.sqrt(1.0 - z * z)
    w = np.stack((rho * np.cos(phi), rho * np.sin(phi), z), axis=-1)
    a, b = hemisphere_to_square(w)
    return a, b, z


def cell_p_value(a: np.ndarray, b: np.ndarray, n: int) -> float:
    """Chi-square p-value of the cell counts of (a, b) against equal probabilities."""
    i = np.clip(np.floor((a + 1.0) * 0.5 * n).astype(np.int64), 0, n - 1)
    j = np.clip(np.floor((b + 1.0) * 0.5 * n).astype(np.int64), 0, n - 1)
    counts = np.bincount(j * n + i, minlength=n * n)
    expected = len(a) / (n * n)
    statistic = float(((counts - expected) ** 2 / expected).sum())
    return float(stats.chi2.sf(statistic, n * n - 1))


@pytest.mark.parametrize("n", CHI2_GRIDS)
def test_every_cell_has_solid_angle_2pi_over_n_squared(uniform_hemisphere_squares, n):
    a, b, _ = uniform_hemisphere_squares
    assert cell_p_value(a, b, n) > CHI2_LEVEL


def test_the_chi_square_test_rejects_a_map_that_is_not_equal_area(uniform_hemisphere_squares):
    # Same concentric map, but the disk radius sin(theta) (orthographic projection)
    # instead of the equal-area sqrt(1 - cos(theta)).
    a, b, z = uniform_hemisphere_squares
    true_r = np.sqrt(1.0 - z)
    scale = np.sqrt(1.0 - z * z) / np.where(true_r > 0, true_r, 1.0)
    assert cell_p_value(np.clip(a * scale, -1, 1), np.clip(b * scale, -1, 1), 7) < 1e-12


# ---------------------------------------------------------------------------
# square_to_hemisphere <-> hemisphere_to_square, numpy and numba
# ---------------------------------------------------------------------------


def test_square_to_hemisphere_gives_unit_vectors_above_the_horizon():
    a, b = all_square_points(np.random.default_rng(SEED))
    w = square_to_hemisphere(a, b)
    assert w.shape == a.shape + (3,)
    np.testing.assert_allclose(np.linalg.norm(w, axis=-1), 1.0, rtol=0, atol=1e-15)
    assert (w[:, 2] >= 0.0).all()
    np.testing.assert_array_equal(square_to_hemisphere(0.0, 0.0), [0.0, 0.0, 1.0])


def test_square_to_hemisphere_wedges_follow_the_sign_conventions():
    # Left wedge (|a| > |b|, a < 0, so r = a < 0): points to -x.
    np.testing.assert_allclose(square_to_hemisphere(-1.0, 0.0), [-1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(square_to_hemisphere(1.0, 0.0), [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(square_to_hemisphere(0.0, 1.0), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(square_to_hemisphere(0.0, -1.0), [0.0, -1.0, 0.0], atol=1e-15)
    h = math.sqrt(0.5)
    np.testing.assert_allclose(square_to_hemisphere(1.0, -1.0), [h, -h, 0.0], atol=1e-15)
    np.testing.assert_allclose(square_to_hemisphere(-1.0, 1.0), [-h, h, 0.0], atol=1e-15)
    # Quadrants: sign(x) = sign(a), sign(y) = sign(b) away from the axes.
    rng = np.random.default_rng(SEED)
    a, b = rng.uniform(-1.0, 1.0, (2, 1000))
    w = square_to_hemisphere(a, b)
    assert (np.sign(w[:, 0]) == np.sign(a)).all() and (np.sign(w[:, 1]) == np.sign(b)).all()


def test_square_round_trip_is_exact():
    a, b = all_square_points(np.random.default_rng(SEED))
    a2, b2 = hemisphere_to_square(square_to_hemisphere(a, b))
    np.testing.assert_allclose(a2, a, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b2, b, rtol=0, atol=1e-12)


def test_hemisphere_round_trip_is_exact():
    rng = np.random.default_rng(SEED)
    w = rng.normal(size=(20_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:, 2] = np.abs(w[:, 2])
    w = np.concatenate([w, [[0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]])
    back = square_to_hemisphere(*hemisphere_to_square(w))
    np.testing.assert_allclose(back, w, rtol=0, atol=1e-12)


def test_hemisphere_to_square_input_conventions():
    # Below the horizon: the rim of the square, at the direction's azimuth.
    below = np.array([[1.0, 1.0, -0.5], [-0.3, 0.2, -1e-9], [0.0, -1.0, -0.1]])
    a, b = hemisphere_to_square(below)
    np.testing.assert_allclose(np.maximum(np.abs(a), np.abs(b)), 1.0, atol=1e-15)
    np.testing.assert_allclose(np.arctan2(b, a)[[0, 2]], [math.pi / 4, -math.pi / 2], atol=1e-15)
    # Non-unit vectors count as their direction; the zero vector as the normal.
    w = np.array([[0.3, -0.2, 0.5]])
    scaled = np.array(hemisphere_to_square(7.0 * w))
    unit = np.array(hemisphere_to_square(w / np.linalg.norm(w)))
    np.testing.assert_allclose(scaled, unit, rtol=0, atol=1e-15)
    assert hemisphere_to_square(np.zeros(3)) == (0.0, 0.0)
    # Shapes broadcast: S + (3,) -> S.
    a, b = hemisphere_to_square(np.ones((2, 5, 3)))
    assert a.shape == b.shape == (2, 5)
    with pytest.raises(ValueError):
        hemisphere_to_square(np.ones((4, 2)))


def test_numba_maps_agree_with_numpy():
    a, b = all_square_points(np.random.default_rng(SEED))
    a, b = a[:3000], b[:3000]
    w = square_to_hemisphere(a, b)
    w_nb = np.array([square_to_hemisphere_nb(x, y) for x, y in zip(a, b)])
    np.testing.assert_allclose(w_nb, w, rtol=0, atol=1e-14)
    extra = np.array([[1.0, 1.0, -0.5], [0.0, 0.0, 0.0], [3.0, -4.0, 12.0], [0.0, 0.0, 2.0]])
    ws = np.concatenate([w, extra])
    ab = np.stack(hemisphere_to_square(ws), axis=-1)
    ab_nb = np.array([hemisphere_to_square_nb(*v) for v in ws])
    np.testing.assert_allclose(ab_nb, ab, rtol=0, atol=1e-14)
    np.testing.assert_allclose(ab_nb[: len(a)], np.stack([a, b], axis=-1), rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# grid_lookup_weights
# ---------------------------------------------------------------------------


def interpolate(values: np.ndarray, w: np.ndarray, n: int) -> np.ndarray:
    idx, weight = grid_lookup_weights(w, n)
    return (values[idx] * weight).sum(axis=-1)


def linear_on_grid(n: int, coef=(0.7, -1.3, 2.1)) -> np.ndarray:
    """f(a, b) = c0 + c1 a + c2 b at each cell centre, in the order d = j*n + i."""
    c = centres(n)
    return coef[0] + coef[1] * np.tile(c, n) + coef[2] * np.repeat(c, n)


@pytest.mark.parametrize("n", [1, 2, 5, 8, 33])
def test_lookup_at_a_cell_centre_returns_that_cell(n):
    idx, weight = grid_lookup_weights(grid_directions(n), n)
    assert idx.shape == weight.shape == (n * n, 4)
    assert idx.dtype == np.int64 and weight.dtype == np.float64
    own = np.where(idx == np.arange(n * n)[:, None], weight, 0.0).sum(axis=1)
    np.testing.assert_allclose(own, 1.0, rtol=0, atol=1e-12)


def test_lookup_interpolates_a_linear_function_exactly_in_the_interior():
    n = 6
    c = centres(n)
    rng = np.random.default_rng(SEED)
    a, b = rng.uniform(c[0], c[-1], (2, 5000))
    values = linear_on_grid(n)
    got = interpolate(values, square_to_hemisphere(a, b), n)
    np.testing.assert_allclose(got, 0.7 - 1.3 * a + 2.1 * b, rtol=0, atol=1e-12)


def test_lookup_weights_are_a_partition_of_unity_on_the_grid():
    n = 7
    rng = np.random.default_rng(SEED)
    w = rng.normal(size=(10_000, 3))  # includes directions below the horizon
    idx, weight = grid_lookup_weights(w, n)
    assert (weight >= 0.0).all()
    np.testing.assert_allclose(weight.sum(axis=-1), 1.0, rtol=0, atol=1e-14)
    assert idx.min() >= 0 and idx.max() < n * n
    idx, weight = grid_lookup_weights(w.reshape(100, 100, 3), n)
    assert idx.shape == weight.shape == (100, 100, 4)


def test_lookup_extends_flat_beyond_the_outer_cell_centres():
    n = 5
    c = centres(n)
    values = linear_on_grid(n)
    rng = np.random.default_rng(SEED)
    b = rng.uniform(c[0], c[-1], 200)
    for a_edge, a_clamped in ((-1.0, c[0]), (1.0, c[-1])):
        a = np.linspace(a_edge, a_clamped, 200)  # between the rim and the outer centres
        got = interpolate(values, square_to_hemisphere(a, b), n)
        np.testing.assert_allclose(got, 0.7 - 1.3 * a_clamped + 2.1 * b, rtol=0, atol=1e-12)
    # Corners of the square: the corner cell alone.
    corners = square_to_hemisphere([-1.0, 1.0, -1.0, 1.0], [-1.0, -1.0, 1.0, 1.0])
    got = interpolate(values, corners, n)
    np.testing.assert_allclose(got, values[[0, n - 1, n * n - n, n * n - 1]], rtol=0, atol=1e-12)
    # A 1 x 1 grid is constant.
    idx, weight = grid_lookup_weights(corners, 1)
    assert (idx == 0).all()
    np.testing.assert_allclose(weight.sum(axis=-1), 1.0, atol=1e-15)


# ---------------------------------------------------------------------------
# grid_size
# ---------------------------------------------------------------------------

EXPONENTS = np.concatenate([np.linspace(0, 50, 501), np.geomspace(50, 1e6, 200)])


def test_grid_size_is_monotone_in_exponent_and_quality():
    sizes = {q: [grid_size(e, q) for e in EXPONENTS] for q in QUALITY_FACTORS}
    for q, ns in sizes.items():
        assert all(isinstance(n, int) for n in ns)
        assert (np.diff(ns) >= 0).all(), q
    assert (np.array(sizes["draft"]) <= sizes["medium"]).all()
    assert (np.array(sizes["medium"]) <= sizes["high"]).all()
    assert sizes["draft"][-1] == sizes["high"][-1] == GRID_MAX


def test_grid_size_bounds_and_values():
    for q in QUALITY_FACTORS:
        assert grid_size(0, q) == GRID_MIN == 8
        assert grid_size(1e6, q) == GRID_MAX == 64
        assert all(GRID_MIN <= grid_size(e, q) <= GRID_MAX for e in EXPONENTS)
    assert grid_size(60, "medium") == math.ceil(2.5 * math.sqrt(61)) == 20
    assert grid_size(120, "high") == math.ceil(4.0 * math.sqrt(121)) == 44
    assert grid_size(8, "draft") == 8  # ceil(1.5 * 3) = 5, raised to the minimum


@pytest.mark.parametrize("quality", ["ultra", "", None, "Draft"])
def test_grid_size_rejects_unknown_quality(quality):
    with pytest.raises(ValueError, match="quality"):
        grid_size(10, quality)


@pytest.mark.parametrize("exponent", [-1.0, math.nan, math.inf])
def test_grid_size_rejects_bad_exponents(exponent):
    with pytest.raises(ValueError, match="exponent"):
        grid_size(exponent, "medium")
