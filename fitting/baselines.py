"""Baseline per-vertex approximations of a solution's outgoing radiance.

The benchmark compares the virtual lights with simpler per-vertex encodings of the
same radiance L[v, d, c] (V vertices, D local grid directions, RGB) at a given
storage per vertex:

- ``diffuse_only``: one RGB constant per vertex (3 floats), the weighted mean.
- ``dominant_direction``: an RGB constant plus one Phong-like lobe
  ``max(0, dot(w, dir_v))^p`` with an RGB intensity about a per-vertex direction
  (2 floats: the direction's equal-area square coordinates (a, b)), 8 floats; the
  exponent p is one per object, chosen by a search over a short log grid.
- ``spherical_harmonics``: real spherical harmonics of order 1 (4 x 3 = 12 floats)
  or 2 (9 x 3 = 27 floats), fitted by weighted least squares.
- ``all_baselines``: the four above, in that order.

Every function takes the ``radiosity.files.solution.ObjectSolution`` (for its local
directions, which are the same for every vertex) and the object's
``fitting.data.FitData``; the values approximated are ``data.radiance`` (float64;
``fit_data(obj)`` makes it ``obj.radiance``) and the fit weights are
``data.weights``. Each vertex is fitted on its own, with its row of weights
normalised to sum to 1 (a row summing to 0 counts as uniform), so the per-vertex
fits minimise exactly the per-vertex numerator of ``fitting.data.relative_error``.
The reconstructions are on the same (V, D, 3) samples as ``data.radiance``, so
``relative_error(data, approximation.reconstruction)`` measures them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from radiosity.physics.directions import (
    grid_directions,
    hemisphere_to_square,
    square_to_hemisphere,
)

__all__ = [
    "Approximation",
    "DEFAULT_EXPONENTS",
    "SH_BASIS",
    "all_baselines",
    "diffuse_only",
    "dominant_direction",
    "sh_basis",
    "spherical_harmonics",
]

DEFAULT_EXPONENTS = tuple(float(10.0 ** (k / 2.0)) for k in range(9))
"""The exponents ``dominant_direction`` tries by default: 1, 3.16, 10, ..., 1e4
(half-decade steps; the whole decades are exact: 1.0, 10.0, 100.0, 1000.0, 10000.0)."""

SH_BASIS = (
    "real spherical harmonics in the local frame (x tangent, y bitangent, z normal), "
    "orthonormal on the sphere, no Condon-Shortley phase, ordered (l, m) with m = -l..l: "
    "Y00 = 0.282095; Y1-1, Y10, Y11 = 0.488603 (y, z, x); "
    "Y2-2, Y2-1, Y21 = 1.092548 (xy, yz, xz), Y20 = 0.315392 (3z^2 - 1), "
    "Y22 = 0.546274 (x^2 - y^2)"
)

_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709, picks the lobe's direction
_RCOND = 1e-10  # pseudo-inverse cut-off relative to the largest singular value
_CHUNK_SAMPLES = 1 << 20  # vertices per chunk x D, bounds temporary memory
_NEIGHBOUR_CELLS = 1.5  # radius of the centroid refinement, in grid spacings

# Real SH normalisations: sqrt((2l+1)/(4 pi) (l-|m|)!/(l+|m|)!) times 1 or sqrt(2)
_C00 = 0.5 * math.sqrt(1.0 / math.pi)
_C1 = math.sqrt(3.0 / (4.0 * math.pi))
_C2 = 0.5 * math.sqrt(15.0 / math.pi)
_C20 = 0.25 * math.sqrt(5.0 / math.pi)
_C22 = 0.25 * math.sqrt(15.0 / math.pi)


@dataclass(frozen=True, eq=False)
class Approximation:
    """A per-vertex approximation of an object's radiance.

    name: "diffuse", "dominant_direction", "sh_l1" or "sh_l2".
    floats_per_vertex: the storage it needs per vertex (3, 8, 12, 27).
    reconstruction: (V, D, 3) float64, the approximation on the data's samples.
    params: small metadata and the fitted per-vertex parameters (see each function).
    """

    name: str
    floats_per_vertex: int
    reconstruction: np.ndarray
    params: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------
# shared input handling
# ---------------------------------------------------------------------------


def _local_directions(obj) -> np.ndarray:
    """(D, 3) float64 local directions: the exact float64 grid if obj's (float32) match it."""
    raw = np.asarray(obj.directions, np.float64)
    if raw.ndim != 2 or raw.shape[1] != 3 or raw.shape[0] < 1:
        raise ValueError(f"obj.directions has shape {raw.shape}, expected (D, 3) with D >= 1")
    n = math.isqrt(raw.shape[0])
    if n * n == raw.shape[0]:
        grid = grid_directions(n)
        if np.abs(raw - grid).max() <= 1e-5:
            return grid
    length = np.linalg.norm(raw, axis=1, keepdims=True)
    if not np.all(length > 0) or not np.isfinite(raw).all():
        raise ValueError("obj.directions must be finite non-zero vectors")
    return raw / length


def _inputs(obj, data):
    """(directions (D,3), radiance (V,D,3), normalised weights (V,D), vertex weights (V,))."""
    dirs = _local_directions(obj)
    radiance = np.asarray(data.radiance, np.float64)
    if radiance.ndim != 3 or radiance.shape[2] != 3 or radiance.shape[1] != dirs.shape[0]:
        raise ValueError(
            f"data.radiance has shape {radiance.shape}, expected (V, D, 3) with "
            f"D = {dirs.shape[0]} (the object's directions)"
        )
    if not np.isfinite(radiance).all():
        raise ValueError("data.radiance has NaN or infinite values")
    weights = np.asarray(data.weights, np.float64)
    if weights.shape != radiance.shape[:2]:
        raise ValueError(f"data.weights has shape {weights.shape}, expected {radiance.shape[:2]}")
    if not np.isfinite(weights).all() or (weights < 0).any():
        raise ValueError("data.weights must be finite and non-negative")
    vertex = weights.sum(axis=1)
    safe = np.where(vertex > 0, vertex, 1.0)
    unit = np.where(vertex[:, None] > 0, weights / safe[:, None], 1.0 / weights.shape[1])
    return dirs, radiance, unit, vertex


def _chunks(n_vertices: int, n_directions: int):
    step = max(1, _CHUNK_SAMPLES // max(1, n_directions))
    for start in range(0, n_vertices, step):
        yield slice(start, min(start + step, n_vertices))


def _shared_row(unit: np.ndarray):
    """The common weight row if every vertex has the same normalised weights, else None."""
    if unit.shape[0] == 0:
        return np.full(unit.shape[1], 1.0 / unit.shape[1])
    first = unit[0]
    if np.abs(unit - first).max() <= 1e-12 * first.max():
        return first
    return None


# ---------------------------------------------------------------------------
# diffuse only
# ---------------------------------------------------------------------------


def diffuse_only(obj, data) -> Approximation:
    """One RGB constant per vertex (3 floats): the weighted mean over the directions.

    params: {"base": (V, 3) float64}.
    """
    _, radiance, unit, _ = _inputs(obj, data)
    base = np.einsum("vd,vdc->vc", unit, radiance)
    recon = np.ascontiguousarray(np.broadcast_to(base[:, None, :], radiance.shape))
    return Approximation("diffuse", 3, recon, {"base": base})


# ---------------------------------------------------------------------------
# spherical harmonics
# ---------------------------------------------------------------------------


def sh_basis(directions, order: int) -> np.ndarray:
    """(D, (order + 1)^2) float64: the real SH basis ``SH_BASIS`` at unit directions (D, 3)."""
    order = _check_order(order)
    w = np.asarray(directions, np.float64)
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    cols = [np.full_like(x, _C00), _C1 * y, _C1 * z, _C1 * x]
    if order == 2:
        cols += [
            _C2 * x * y,
            _C2 * y * z,
            _C20 * (3.0 * z * z - 1.0),
            _C2 * x * z,
            _C22 * (x * x - y * y),
        ]
    return np.stack(cols, axis=1)


def _check_order(order) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order not in (1, 2):
        raise ValueError(f"spherical harmonics order must be 1 or 2, got {order!r}")
    return int(order)


def spherical_harmonics(obj, data, order: int) -> Approximation:
    """Per-vertex real spherical harmonics of order 1 (12 floats) or 2 (27 floats).

    Basis: ``SH_BASIS`` (the usual orthonormal real SH, Y00 = 0.282095,
    Y1m = 0.488603 (y, z, x), ...; no Condon-Shortley phase), evaluated at the local
    directions, which are the same for every vertex. Per vertex and channel the
    coefficients minimise sum_d w[v, d] (sum_k c_k Y_k(d) - L[v, d])^2 with
    w = data.weights normalised per vertex. When every vertex has the same normalised
    weights (always for ``fit_data``, whose weights are constant across directions)
    one weighted pseudo-inverse serves all vertices; otherwise each vertex gets its own.
    Pseudo-inverses cut singular values below 1e-10 of the largest, so with fewer
    directions than coefficients (a diffuse object, D = 1) the fit is the minimum-norm
    solution and still reproduces the data.

    Raises ValueError unless order is 1 or 2.
    params: {"order", "basis": SH_BASIS, "coefficients": (V, K, 3) float64}.
    """
    order = _check_order(order)
    dirs, radiance, unit, _ = _inputs(obj, data)
    basis = sh_basis(dirs, order)  # (D, K)
    n_v, n_d = radiance.shape[:2]
    coeffs = np.empty((n_v, basis.shape[1], 3))
    shared = _shared_row(unit)
    if shared is not None:
        root = np.sqrt(shared)
        solve = np.linalg.pinv(root[:, None] * basis, rcond=_RCOND) * root[None, :]  # (K, D)
        for s in _chunks(n_v, n_d):
            coeffs[s] = np.matmul(solve, radiance[s])
    else:
        for s in _chunks(n_v, n_d * basis.shape[1]):
            root = np.sqrt(unit[s])[:, :, None]  # (c, D, 1)
            solve = np.linalg.pinv(root * basis[None], rcond=_RCOND)  # (c, K, D)
            coeffs[s] = np.matmul(solve, root * radiance[s])
    recon = np.matmul(basis, coeffs)  # (V, D, 3)
    return Approximation(
        f"sh_l{order}",
        3 * basis.shape[1],
        recon,
        {"order": order, "basis": SH_BASIS, "coefficients": coeffs},
    )


# ---------------------------------------------------------------------------
# single dominant direction
# ---------------------------------------------------------------------------


def _check_exponents(exponents) -> tuple[float, ...]:
    if exponents is None:
        return DEFAULT_EXPONENTS
    try:
        values = tuple(float(e) for e in np.atleast_1d(np.asarray(exponents, np.float64)))
    except (TypeError, ValueError):
        raise ValueError(f"exponents must be positive finite numbers, got {exponents!r}") from None
    if not values or not all(math.isfinite(e) and e > 0 for e in values):
        raise ValueError(f"exponents must be a non-empty list of positive finite numbers, got {exponents!r}")
    return values


def _candidate_directions(dirs, radiance):
    """Per vertex: the grid direction of maximum luminance and its local refinement.

    The refinement is the centroid of the directions within 1.5 grid spacings of the
    maximum, weighted by luminance minus the vertex's minimum luminance (a constant
    base does not pull it). Both are returned as (V, 3) unit vectors after the round
    trip through the 2-float square coordinates (a, b) they are stored as.
    """
    n_d = dirs.shape[0]
    lum = radiance @ _LUMINANCE  # (V, D)
    peak = np.argmax(lum, axis=1)
    grid = dirs[peak]
    spacing = math.sqrt(2.0 * math.pi / n_d)
    near = dirs @ dirs.T >= math.cos(min(math.pi, _NEIGHBOUR_CELLS * spacing))  # (D, D)
    excess = (lum - lum.min(axis=1, keepdims=True)) * near[peak]
    centroid = excess @ dirs
    length = np.linalg.norm(centroid, axis=1, keepdims=True)
    ok = (length[:, 0] > 0) & np.isfinite(length[:, 0])
    refined = np.where(ok[:, None], centroid / np.where(ok, length[:, 0], 1.0)[:, None], grid)
    return _round_trip(grid), _round_trip(refined)


def _round_trip(w):
    """Unit directions as stored: through (a, b) and back (z >= 0 assumed)."""
    a, b = hemisphere_to_square(w)
    return square_to_hemisphere(a, b)


def _fit_lobe(unit, unit_l, size, b_l, lobe):
    """Non-negative base and intensity per vertex and channel for L ~ base + I * lobe.

    unit (c, D) weights summing to 1, unit_l (c, 3, D) = unit * L (channels first),
    size (c,) = sum_d unit |L|^2, b_l (c, 3) = sum_d unit L, lobe (c, D) in [0, 1].
    The two-unknown NNLS is solved exactly: the KKT point is the unconstrained
    solution if both are >= 0, else base only, lobe only or nothing; the feasible one
    of least objective wins. Returns base (c, 3), intensity (c, 3) and the residual
    (c,) = sum_d unit |base + I lobe - L|^2 (from the moments, clamped at 0: it is
    exact to rounding of the order of 1e-16 size, enough to compare fits).
    """
    uf = unit * lobe
    s_f = uf.sum(axis=1)[:, None]  # (c, 1); the sum of unit is 1
    s_ff = np.einsum("vd,vd->v", uf, lobe)[:, None]
    b_fl = np.matmul(unit_l, lobe[:, :, None])[:, :, 0]  # (c, 3)

    det = s_ff - s_f * s_f
    regular = det > 1e-12 * s_ff
    safe_det = np.where(regular, det, 1.0)
    free_base = (s_ff * b_l - s_f * b_fl) / safe_det
    free_int = (b_fl - s_f * b_l) / safe_det
    free_ok = regular & (free_base >= 0) & (free_int >= 0)

    only_base = np.maximum(b_l, 0.0)
    has_lobe = s_ff > 0
    only_int = np.where(has_lobe, np.maximum(b_fl, 0.0) / np.where(has_lobe, s_ff, 1.0), 0.0)

    zero = np.zeros_like(b_l)
    yes = np.ones_like(free_ok)
    # candidates in order of preference on ties: base only, unconstrained, lobe only, zero
    bases = np.stack([only_base, np.where(free_ok, free_base, 0.0), zero, zero])
    ints = np.stack([zero, np.where(free_ok, free_int, 0.0), only_int, zero])
    objective = (
        bases * bases + 2.0 * bases * ints * s_f + ints * ints * s_ff
        - 2.0 * (bases * b_l + ints * b_fl)
    )
    objective = np.where(np.stack([yes, free_ok, yes, yes]), objective, np.inf)
    pick = np.argmin(objective, axis=0)[None]
    base = np.take_along_axis(bases, pick, axis=0)[0]
    intensity = np.take_along_axis(ints, pick, axis=0)[0]
    residual = np.maximum(size + np.take_along_axis(objective, pick, axis=0)[0].sum(axis=1), 0.0)
    return base, intensity, residual


def dominant_direction(obj, data, exponents=None) -> Approximation:
    """A constant plus one Phong-like lobe per vertex (8 floats per vertex).

    Model: L[v, d] ~ base[v] + intensity[v] * max(0, dot(w_d, dir[v]))^p, with RGB
    base and intensity >= 0, a per-vertex unit direction dir[v] stored as its 2
    equal-area square coordinates (a, b) (``radiosity.physics.directions``), and one exponent
    p per object: the one of ``exponents`` (default ``DEFAULT_EXPONENTS``, 1 to 1e4
    on a half-decade grid) with the least total weighted squared error.

    Per vertex, two directions are tried: the grid direction of maximum luminance and
    the luminance-weighted centroid of its neighbourhood (luminance minus the vertex's
    minimum); for each, base and intensity are the exact two-unknown non-negative least
    squares per channel; the direction with the smaller weighted error is kept.

    Raises ValueError for an empty list or a non-positive / non-finite exponent.
    params: {"exponent", "exponents", "relative_rms": {p: error for every p tried},
    "directions": (V, 3) local unit vectors, "square": (V, 2) their (a, b),
    "base": (V, 3), "intensity": (V, 3)}.
    """
    exps = _check_exponents(exponents)
    dirs, radiance, unit, vertex = _inputs(obj, data)
    n_v, n_d = radiance.shape[:2]
    n_e = len(exps)

    candidates = _candidate_directions(dirs, radiance)
    # per exponent, per vertex: the chosen candidate, base, intensity, residual
    which = np.zeros((n_e, n_v), np.int64)
    bases = np.empty((n_e, n_v, 3))
    ints = np.empty((n_e, n_v, 3))
    residuals = np.empty((n_e, n_v))
    size = np.einsum("vd,vd->v", unit, np.einsum("vdc,vdc->vd", radiance, radiance))
    with np.errstate(divide="ignore"):
        for s in _chunks(n_v, n_d):
            u = unit[s]
            unit_l = np.ascontiguousarray(np.moveaxis(radiance[s], 2, 1)) * u[:, None, :]
            b_l = unit_l.sum(axis=2)
            # log of the clamped cosine (-inf behind): lobe = exp(p log cos)
            log_cos = [np.log(np.maximum(cand[s] @ dirs.T, 0.0)) for cand in candidates]
            for e, p in enumerate(exps):
                for k, lc in enumerate(log_cos):
                    base, intensity, residual = _fit_lobe(u, unit_l, size[s], b_l, np.exp(p * lc))
                    if k == 0:
                        bases[e, s], ints[e, s], residuals[e, s] = base, intensity, residual
                        continue
                    better = residual < residuals[e, s]
                    idx = np.flatnonzero(better) + s.start
                    which[e, idx] = k
                    bases[e, idx], ints[e, idx] = base[better], intensity[better]
                    residuals[e, idx] = residual[better]

    totals = residuals @ vertex  # (n_e,) area-weighted, as relative_error's numerator
    best = int(np.argmin(totals))  # first of equals: the smallest exponent listed first
    p = exps[best]
    stack = np.stack(candidates)  # (n_cand, V, 3)
    out_dir = stack[which[best], np.arange(n_v)]
    out_base, out_int = bases[best], ints[best]
    lobe = np.maximum(np.einsum("vk,dk->vd", out_dir, dirs), 0.0) ** p
    recon = out_base[:, None, :] + out_int[:, None, :] * lobe[:, :, None]
    total_size = float(np.dot(vertex, size))
    errors = {
        q: (math.sqrt(float(t) / total_size) if total_size > 0 else 0.0) for q, t in zip(exps, totals)
    }
    a, b = hemisphere_to_square(out_dir)
    return Approximation(
        "dominant_direction",
        8,
        recon,
        {
            "exponent": p,
            "exponents": exps,
            "relative_rms": errors,
            "directions": out_dir,
            "square": np.stack([a, b], axis=1),
            "base": out_base,
            "intensity": out_int,
        },
    )


# ---------------------------------------------------------------------------


def all_baselines(obj, data) -> list[Approximation]:
    """[diffuse_only, dominant_direction, SH order 1, SH order 2] (3, 8, 12, 27 floats)."""
    return [
        diffuse_only(obj, data),
        dominant_direction(obj, data),
        spherical_harmonics(obj, data, 1),
        spherical_harmonics(obj, data, 2),
    ]
