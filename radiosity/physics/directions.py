"""The equal-area hemisphere grid on which glossy objects store outgoing radiance.

The solution file's convention (docs/formats.md):

    Diffuse objects have D = 1 with direction (0, 0, 1). Glossy objects use the n x n
    equal-area hemisphere grid (D = n * n): for cell (i, j), i the column and j the row,
    d = j * n + i, take the square point a = 2 (i + 0.5) / n - 1, b = 2 (j + 0.5) / n - 1,
    map it to the unit disk with the Shirley-Chiu concentric map (|a| > |b|: r = a,
    phi = pi/4 * b/a; else r = b, phi = pi/2 - pi/4 * a/b), and lift to the hemisphere
    with equal area: w = (r cos phi * s, r sin phi * s, 1 - r^2) with s = sqrt(2 - r^2).
    The value stored is the radiance at the cell-centre direction.

Directions are unit vectors in the local frame (x tangent, y bitangent, z normal).
Note that r may be negative: |a| > |b| with a < 0 is the left wedge of the disk and
|b| >= |a| with b < 0 the bottom one. The diagonals |a| = |b| take the second branch,
and a = b = 0 (the centre cell of an odd grid) is the pole (0, 0, 1).

Both maps preserve area up to a constant (square of area 4 -> disk of area pi ->
hemisphere of solid angle 2 pi), so every cell subtends exactly 2 pi / n^2 sr.

Contents:

- ``grid_directions(n)``: the (n*n, 3) cell-centre directions, ``DIFFUSE_DIRECTIONS``.
- ``square_to_hemisphere(a, b)`` and its exact inverse ``hemisphere_to_square(w)``
  (vectorised numpy), and the scalar numba kernels ``square_to_hemisphere_nb``,
  ``hemisphere_to_square_nb`` for hot loops.
- ``grid_lookup_weights(w, n)``: the four cells and bilinear weights (in the square)
  with which to read a value stored on the grid in any direction.
- ``grid_size(exponent, quality)``: the grid n a Phong lobe of that exponent needs.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.policies.presets import PRESETS

__all__ = [
    "DIFFUSE_DIRECTIONS",
    "GRID_MAX",
    "GRID_MIN",
    "QUALITY_FACTORS",
    "grid_directions",
    "grid_lookup_weights",
    "grid_size",
    "hemisphere_to_square",
    "hemisphere_to_square_nb",
    "square_boundary_nb",
    "square_to_hemisphere",
    "square_to_hemisphere_nb",
]

DIFFUSE_DIRECTIONS = np.array([[0.0, 0.0, 1.0]])
"""The single direction of a diffuse object (D = 1), shape (1, 3) float64."""

QUALITY_FACTORS = {quality: p.grid_factor for quality, p in PRESETS.items()}
"""c in n = ceil(c * sqrt(exponent + 1)), per quality preset (``presets.Preset.grid_factor``)."""

GRID_MIN = 8
GRID_MAX = 64

_QUARTER_PI = 0.25 * math.pi
_HALF_PI = 0.5 * math.pi
_FOUR_OVER_PI = 4.0 / math.pi


def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"grid size n must be an integer >= 1, got {n!r}")
    return int(n)


# ---------------------------------------------------------------------------
# numpy
# ---------------------------------------------------------------------------


def square_to_hemisphere(a, b) -> np.ndarray:
    """Map square points (a, b) in [-1, 1]^2 to unit directions with z >= 0.

    ``a`` and ``b`` are array-likes that broadcast together to a shape S; returns
    float64 of shape S + (3,). Concentric map to the disk, then the equal-area lift,
    exactly as the contract says (module docstring); (0, 0) maps to (0, 0, 1).
    """
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    first = np.abs(a) > np.abs(b)
    # Safe denominators: a != 0 wherever `first` holds; b == 0 outside it only at the centre.
    safe_a = np.where(first, a, 1.0)
    safe_b = np.where(first | (b == 0.0), 1.0, b)
    r = np.where(first, a, b)
    phi = np.where(first, _QUARTER_PI * (b / safe_a), _HALF_PI - _QUARTER_PI * (a / safe_b))
    r2 = r * r
    rs = r * np.sqrt(2.0 - r2)
    return np.stack((rs * np.cos(phi), rs * np.sin(phi), 1.0 - r2), axis=-1)


def hemisphere_to_square(w) -> tuple[np.ndarray, np.ndarray]:
    """The exact inverse of ``square_to_hemisphere``: directions to square points.

    ``w`` is array-like of shape S + (3,); returns (a, b), two float64 arrays of shape
    S with values in [-1, 1]. ``w`` is normalised first (a zero vector counts as
    (0, 0, 1)); z is clamped into [0, 1], so directions below the horizon map to the
    rim of the square at their azimuth. The disk radius is sqrt(1 - z), computed as
    |(x, y)| / sqrt(1 + z) near the pole, where 1 - z would lose digits.
    """
    w = np.asarray(w, dtype=np.float64)
    if w.shape[-1:] != (3,):
        raise ValueError(f"directions must have shape (..., 3), got {w.shape}")
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    norm = np.sqrt(x * x + y * y + z * z)
    ok = norm > 0.0
    safe = np.where(ok, norm, 1.0)
    x, y, z = x / safe, y / safe, np.where(ok, z / safe, 1.0)
    z = np.clip(z, 0.0, 1.0)
    radius = np.where(z > 0.5, np.hypot(x, y) / np.sqrt(1.0 + z), np.sqrt(1.0 - z))
    t = np.arctan2(y, x) * _FOUR_OVER_PI  # the azimuth in units of pi/4, in [-4, 4]
    right = np.abs(t) < 1.0
    top = (t >= 1.0) & (t <= 3.0)
    bottom = (t <= -1.0) & (t >= -3.0)
    # left: |t| > 3, where the forward map had r = a < 0 and phi = t * pi/4 -+ pi
    a_rest = np.where(bottom, radius * (2.0 + t), -radius)
    a = np.where(right, radius, np.where(top, radius * (2.0 - t), a_rest))
    left_b = np.where(t > 0.0, radius * (4.0 - t), -radius * (4.0 + t))
    b = np.where(right, radius * t, np.where(top, radius, np.where(bottom, -radius, left_b)))
    return np.clip(a, -1.0, 1.0), np.clip(b, -1.0, 1.0)


def grid_directions(n: int) -> np.ndarray:
    """The cell-centre directions of the n x n grid, (n*n, 3) float64, row d = j*n + i.

    Raises ValueError unless n is an integer >= 1. n = 1 gives ``DIFFUSE_DIRECTIONS``.
    """
    n = _check_n(n)
    centres = 2.0 * (np.arange(n) + 0.5) / n - 1.0
    b, a = np.meshgrid(centres, centres, indexing="ij")  # [j, i]: row j, column i
    return square_to_hemisphere(a, b).reshape(n * n, 3)


def grid_lookup_weights(w, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid cells and weights that interpolate a grid-stored value in direction w.

    Bilinear interpolation in the square (a, b) between cell centres: with
    (a, b) = hemisphere_to_square(w), the continuous cell coordinates are
    x = (a + 1) / 2 * n - 0.5 and y = (b + 1) / 2 * n - 0.5; i0 = floor(x),
    fx = x - i0, likewise j0, fy. Indices are clamped into [0, n - 1], so beyond the
    outermost centres the value extends flat (an index may then appear twice, with
    its weight split; summing ``weight * value[idx]`` is still right).

    ``w``: array-like S + (3,) local directions (z >= 0; see ``hemisphere_to_square``
    for other input). Returns ``idx`` int64 S + (4,), the rows d = j*n + i, and
    ``weight`` float64 S + (4,), non-negative and summing to 1, in the order
    (i0, j0), (i0 + 1, j0), (i0, j0 + 1), (i0 + 1, j0 + 1). At a cell centre the weight
    of that cell is 1 (to rounding, about 1e-15).
    """
    n = _check_n(n)
    a, b = hemisphere_to_square(w)
    half_n = 0.5 * n
    x = (a + 1.0) * half_n - 0.5
    y = (b + 1.0) * half_n - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    i0 = np.clip(x0.astype(np.int64), 0, n - 1)
    j0 = np.clip(y0.astype(np.int64), 0, n - 1)
    i1 = np.clip(x0.astype(np.int64) + 1, 0, n - 1)
    j1 = np.clip(y0.astype(np.int64) + 1, 0, n - 1)
    idx = np.stack((j0 * n + i0, j0 * n + i1, j1 * n + i0, j1 * n + i1), axis=-1)
    gx, gy = 1.0 - fx, 1.0 - fy
    weight = np.stack((gx * gy, fx * gy, gx * fy, fx * fy), axis=-1)
    return idx, weight


def grid_size(exponent: float, quality: str) -> int:
    """The grid n (D = n * n directions) that a glossy object of this Phong exponent needs.

    n = clamp(ceil(c * sqrt(exponent + 1)), 8, 64), c from ``QUALITY_FACTORS``
    (draft 1.5, medium 2.5, high 4.0).

    Why sqrt: the Phong lobe cos(alpha)^e ~ exp(-e alpha^2 / 2) has an angular width
    (standard deviation) of about 1 / sqrt(e) radians, while the n x n equal-area grid
    gives each cell 2 pi / n^2 sr, i.e. a spacing of about sqrt(2 pi) / n radians. Keeping
    a fixed number of cells across the lobe therefore needs n proportional to sqrt(e);
    c sets how many (spacing ~ sqrt(2 pi) / c lobe widths: 1.7 for draft, 1.0 for
    medium, 0.63 for high). The + 1 keeps a finite answer at e = 0; the clamp keeps
    broad lobes from getting a uselessly coarse grid and sharp ones from an enormous
    one (64^2 = 4096 directions per vertex).

    Raises ValueError for an unknown quality or a negative or non-finite exponent.
    """
    try:
        c = QUALITY_FACTORS[quality]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown quality {quality!r}; expected one of {', '.join(QUALITY_FACTORS)}"
        ) from None
    e = float(exponent)
    if not math.isfinite(e) or e < 0.0:
        raise ValueError(f"Phong exponent must be a finite number >= 0, got {exponent!r}")
    return int(min(max(math.ceil(c * math.sqrt(e + 1.0)), GRID_MIN), GRID_MAX))


# ---------------------------------------------------------------------------
# numba: the same maps on scalars, for per-sample loops
# ---------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def square_to_hemisphere_nb(a, b):
    """Scalar ``square_to_hemisphere``: floats a, b in [-1, 1] -> (x, y, z)."""
    if abs(a) > abs(b):
        r = a
        phi = _QUARTER_PI * (b / a)
    elif b != 0.0:
        r = b
        phi = _HALF_PI - _QUARTER_PI * (a / b)
    else:
        return 0.0, 0.0, 1.0
    r2 = r * r
    rs = r * math.sqrt(2.0 - r2)
    return rs * math.cos(phi), rs * math.sin(phi), 1.0 - r2


@numba.njit(cache=True, nogil=True)
def hemisphere_to_square_nb(x, y, z):
    """Scalar ``hemisphere_to_square``: direction floats (x, y, z) -> (a, b) in [-1, 1]."""
    norm = math.sqrt(x * x + y * y + z * z)
    if norm > 0.0:
        x /= norm
        y /= norm
        z /= norm
    else:
        x, y, z = 0.0, 0.0, 1.0
    z = min(max(z, 0.0), 1.0)
    if z > 0.5:
        radius = math.hypot(x, y) / math.sqrt(1.0 + z)
    else:
        radius = math.sqrt(1.0 - z)
    sa, sb = square_boundary_nb(math.atan2(y, x) * _FOUR_OVER_PI)
    a, b = radius * sa, radius * sb
    return min(max(a, -1.0), 1.0), min(max(b, -1.0), 1.0)


@numba.njit(cache=True, nogil=True, inline="always")
def square_boundary_nb(t):
    """The point of the unit square's boundary at t = 4 / pi times an azimuth, t in
    [-4, 4]: where ``hemisphere_to_square`` puts that azimuth at radius 1 (the corners
    at odd t, linear between them)."""
    if abs(t) < 1.0:
        return 1.0, t
    if t >= 1.0 and t <= 3.0:
        return 2.0 - t, 1.0
    if t <= -1.0 and t >= -3.0:
        return 2.0 + t, -1.0
    if t > 0.0:
        return -1.0, 4.0 - t
    return -1.0, -(4.0 + t)
