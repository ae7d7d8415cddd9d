"""A fitted reflection probe per glossy object: the broad reflections of its surroundings.

The model's probe term (fit.npz version 3, docs/formats.md) at a surface point x with
unit normal n seen from the unit direction w:

    r    = 2 (n . w) n - w                      the mirror direction
    x'   = x clamped into the proxy box [lo, hi]
    t    = the distance along r at which x' + t r leaves the box
    u    = normalize(x' + t r - c)              seen from the probe's centre c
    term = s(x) * S(n . w) * P(u)               s per vertex (RGB), P the probe's texels

and S the material's specular albedo (``radiosity.physics.materials.specular_albedo``),
linear in a table of ``ALBEDO_POINTS`` values at n . w = 0, 1/32, ..., 1 (clamped to
[0, 1]): a Phong lobe about a mirror direction near the horizon loses what falls below
it, so what a glossy surface reflects falls with the view's angle like the cosine. The
probe holds what the surroundings send, S how much of it the view sees; without S the
teapot's fit error was 0.092 (relative RMS), with it 0.073, the satin block's 0.021 and
0.007 (draft, 32 x 32 texels).

Parallax-corrected ("box-projected") look-ups: a reflection of a wall is found where the
wall is, not where an infinitely far environment would put it. P is an octahedral map
of M x M texels (``encode``): the sphere of directions folded onto a square, texel
centres at ((i + 0.5) / M, (j + 0.5) / M), bilinear between the four texels around a
point, with the octahedron's own continuity across the square's border (``texels``):
texel (-1, j) is (0, M - 1 - j), (M, j) is (M - 1, M - 1 - j), and likewise in j, x
wrapped first. The same four texels and weights in the fitter, ``fitting.model`` and
every display (``display/shaders/probe.glsl``): seamless by construction, identical everywhere.

Fitting (``fitting.glossy.fit_probe_part``): the probe enters the per-vertex least squares as one more
column (its look-up), P is linear given the per-vertex weights, and the weights are
linear given P: alternating least squares, P on its sparse normal equations with a
small smoothness term (texels no sample sees take their neighbours' values: finite and
smooth), the per-vertex coefficients (emitted, probe weight, light coefficients) by
the bounded non-negative solver (``fitting.nnls``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.materials import specular_albedo

from .nnls import solve_many

__all__ = ["Probe", "albedo_table", "box_directions", "decode", "encode", "look_up", "probe_values", "solve_texels", "texels"]

SMOOTHNESS = 1e-3  # the smoothness term's weight, relative to the mean of the data term's diagonal
INSET = 1e-6  # points are kept this fraction of the box's size inside it
ALTERNATIONS = 6
ALBEDO_POINTS = 33


@dataclass(frozen=True, eq=False)
class Probe:
    """One object's probe.

    texels : (M, M, 3) float32, the octahedral map P (>= 0)
    centre : (3,) float64, c; box : (2, 3) float64, the proxy's (lo, hi) corners
    albedo : (ALBEDO_POINTS,) float64, S at n . w = 0, 1 / (ALBEDO_POINTS - 1), ..., 1
    """

    texels: np.ndarray
    centre: np.ndarray
    box: np.ndarray
    albedo: np.ndarray

    @property
    def size(self):
        return self.texels.shape[0]

    def to_meta(self):
        return {"size": int(self.size), "centre": [float(v) for v in self.centre],
                "box": [[float(v) for v in row] for row in self.box], "albedo": [float(v) for v in self.albedo]}


def albedo_table(exponent):
    """(ALBEDO_POINTS,) the specular albedo S of a modified-Phong lobe of ``exponent`` at
    n . w = 0, 1 / (ALBEDO_POINTS - 1), ..., 1."""
    return specular_albedo(float(exponent), np.linspace(0.0, 1.0, ALBEDO_POINTS))


def albedo_factor(albedo, normals, views):
    """S(n . w) (...,) by linear interpolation in the table ``albedo``."""
    mu = np.clip(np.sum(np.asarray(normals, np.float64) * np.asarray(views, np.float64), axis=-1), 0.0, 1.0)
    x = mu * (len(albedo) - 1)
    i = np.minimum(np.floor(x).astype(np.int64), len(albedo) - 2)
    f = x - i
    a = np.asarray(albedo, np.float64)
    return (1.0 - f) * a[i] + f * a[i + 1]


def encode(u):
    """Octahedral coordinates (..., 2) in [0, 1]^2 of unit directions u (..., 3)."""
    u = np.asarray(u, np.float64)
    s = np.abs(u).sum(axis=-1, keepdims=True)
    p = u[..., :2] / np.where(s > 0, s, 1.0)
    sign = np.where(p >= 0, 1.0, -1.0)
    folded = (1.0 - np.abs(p[..., ::-1])) * sign
    p = np.where(u[..., 2:3] < 0, folded, p)
    return 0.5 * (p + 1.0)


def decode(uv):
    """Unit directions (..., 3) of octahedral coordinates uv (..., 2)."""
    p = 2.0 * np.asarray(uv, np.float64) - 1.0
    z = 1.0 - np.abs(p).sum(axis=-1)
    sign = np.where(p >= 0, 1.0, -1.0)
    xy = np.where((z < 0)[..., None], (1.0 - np.abs(p[..., ::-1])) * sign, p)
    v = np.concatenate([xy, z[..., None]], axis=-1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _wrap(i, j, m):
    """Texel (i, j) folded back into [0, m)^2 by the octahedron's continuity (i first)."""
    j = np.where(i < 0, m - 1 - j, np.where(i >= m, m - 1 - j, j))
    i = np.clip(i, 0, m - 1)
    i = np.where(j < 0, m - 1 - i, np.where(j >= m, m - 1 - i, i))
    j = np.clip(j, 0, m - 1)
    return i, j


def texels(u, m, cells=False):
    """The bilinear look-up of unit directions u (..., 3) in an m x m map: (indices (..., 4)
    int64 as j * m + i, weights (..., 4) float64 summing to 1); with ``cells`` also each
    look-up's footprint, (j0 + 1) (m + 1) + i0 + 1 for its lower corner (i0, j0)."""
    f = encode(u) * m - 0.5
    f0 = np.floor(f)
    fx, fy = (f - f0)[..., 0], (f - f0)[..., 1]
    i0, j0 = f0[..., 0].astype(np.int64), f0[..., 1].astype(np.int64)
    i0, j0 = np.clip(i0, -1, m - 1), np.clip(j0, -1, m - 1)  # u on the square's far edge (rounding)
    idx, wts = [], []
    for di, dj, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        i, j = _wrap(i0 + di, j0 + dj, m)
        idx.append(j * m + i)
        wts.append(w)
    out = np.stack(idx, axis=-1), np.stack(wts, axis=-1)
    return (*out, (j0 + 1) * (m + 1) + i0 + 1) if cells else out


def box_directions(positions, views, normals, centre, box):
    """u (..., 3): the directions from the probe's centre to where each mirror ray leaves
    the box (positions, normals (..., 3); views (..., 3) unit towards the eye)."""
    lo, hi = np.asarray(box[0], np.float64), np.asarray(box[1], np.float64)
    inset = INSET * np.linalg.norm(hi - lo)
    x = np.clip(np.asarray(positions, np.float64), lo + inset, hi - inset)
    n = np.asarray(normals, np.float64)
    w = np.asarray(views, np.float64)
    r = 2.0 * np.sum(n * w, axis=-1, keepdims=True) * n - w
    r = r / np.maximum(np.linalg.norm(r, axis=-1, keepdims=True), 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(r > 0, hi, lo)
        t_axis = np.where(r != 0, (bound - x) / r, np.inf)
    t = np.min(t_axis, axis=-1, keepdims=True)
    t = np.where(np.isfinite(t), np.maximum(t, 0.0), 0.0)
    d = x + t * r - np.asarray(centre, np.float64)
    length = np.linalg.norm(d, axis=-1, keepdims=True)
    return np.where(length > 0, d / np.where(length > 0, length, 1.0), r)


def look_up(texel_values, u):
    """P(u) (..., 3) float64: the bilinear look-up of (M, M, 3) texels in directions u."""
    t = np.asarray(texel_values, np.float64)
    m = t.shape[0]
    idx, w = texels(u, m)
    flat = t.reshape(m * m, 3)
    return np.einsum("...k,...kc->...c", w, flat[idx])


def probe_values(probe, positions, views, normals):
    """S(n . w) P(u) (..., 3) at surface points seen from ``views`` (the probe term without s)."""
    u = box_directions(positions, views, normals, probe.centre, probe.box)
    return albedo_factor(probe.albedo, normals, views)[..., None] * look_up(probe.texels, u)


def _laplacian(m):
    """(m^2, m^2) sparse graph Laplacian of the texel grid with the octahedral wrap."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    i, j = i.ravel(), j.ravel()
    rows, cols = [], []
    for di, dj in ((1, 0), (0, 1)):
        a = j * m + i
        ii, jj = _wrap(i + di, j + dj, m)
        b = jj * m + ii
        keep = a != b
        rows += [a[keep], b[keep]]
        cols += [b[keep], a[keep]]
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    adjacency = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(m * m, m * m)).tocsr()
    adjacency.data[:] = 1.0
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return scipy.sparse.diags(degree) - adjacency


_PATTERNS = {}


def _pattern(m):
    """The normal equations' sparsity of an m x m map: (CSR indptr, indices, and for each
    bilinear footprint (``texels``'s cells, (m + 1)^2) the positions (cells, 16) of its 16
    texel pairs in the CSR data), border wrap included; cached per m."""
    if m not in _PATTERNS:
        i0, j0 = np.meshgrid(np.arange(-1, m), np.arange(-1, m), indexing="xy")
        i0, j0 = i0.ravel(), j0.ravel()
        corners = [_wrap(i0 + di, j0 + dj, m) for di, dj in ((0, 0), (1, 0), (0, 1), (1, 1))]
        ids = [j * m + i for i, j in corners]
        a = np.stack([x for x in ids for _ in ids], axis=1)  # (cells, 16)
        b = np.stack([y for _ in ids for y in ids], axis=1)
        keys = np.unique(a * (m * m) + b)
        rows, cols = keys // (m * m), keys % (m * m)
        indptr = np.searchsorted(rows, np.arange(m * m + 1)).astype(np.int64)
        positions = np.searchsorted(keys, a * (m * m) + b).astype(np.int64)
        _PATTERNS[m] = (indptr, cols.astype(np.int64), positions)
    return _PATTERNS[m]


@numba.njit(cache=True, nogil=True, parallel=True)
def _accumulate(lookups, samples, positions, out):
    """The normal equations of ``solve_texels`` into out = (CSR data (nnz, 3), rhs (n, 3)),
    a channel per thread; lookups = (idx, wts, cells), samples = (weight, target, scale)."""
    idx, wts, cells = lookups
    weight, target, scale = samples
    data, rhs = out
    for c in numba.prange(3):
        for s in range(idx.shape[0]):
            w = weight[s, c]
            if w == 0.0:
                continue
            sc = scale[s, c]
            ws2 = w * sc * sc
            wt = w * sc * target[s, c]
            cell = cells[s]
            for k in range(4):
                wa = wts[s, k]
                rhs[idx[s, k], c] += wt * wa
                for q in range(4):
                    data[positions[cell, 4 * k + q], c] += ws2 * wa * wts[s, q]


def solve_texels(idx, wts, cells, weight, target, scale, m):
    """P (m, m, 3) >= 0 minimising sum weight (target - scale * sum_k wts_k P[idx_k])^2
    per channel, plus the smoothness term.

    idx, wts, cells : the look-ups of S samples (``texels(..., cells=True)``); weight :
    (S,) or (S, 3); target, scale : (S, 3)."""
    n = m * m
    weight = np.ascontiguousarray(np.broadcast_to(np.asarray(weight, np.float64).reshape(len(idx), -1), (len(idx), 3)))
    indptr, indices, positions = _pattern(m)
    data = np.zeros((len(indices), 3))
    rhs = np.zeros((n, 3))
    lookups = (
        np.ascontiguousarray(idx, np.int64),
        np.ascontiguousarray(wts, np.float64),
        np.ascontiguousarray(cells, np.int64),
    )
    samples = (weight, np.ascontiguousarray(target, np.float64), np.ascontiguousarray(scale, np.float64))
    _accumulate(lookups, samples, positions, (data, rhs))
    lap = _laplacian(m)
    out = np.zeros((n, 3))
    for c in range(3):
        A = scipy.sparse.csr_matrix((data[:, c], indices, indptr), shape=(n, n))
        diag = A.diagonal()
        level = diag[diag > 0].mean() if (diag > 0).any() else 1.0
        A = A + SMOOTHNESS * level * lap + scipy.sparse.identity(n) * (1e-9 * level)
        out[:, c] = np.maximum(scipy.sparse.linalg.spsolve(A.tocsc(), rhs[:, c]), 0.0)
    return out.reshape(m, m, 3)


@numba.njit(cache=True, nogil=True, parallel=True)
def _vertex_equations(columns, target, weights, lw, G, h, yy):
    """Per vertex and channel, the normal equations of target ~ columns @ x:
    columns (V, D, n, 3) (the design per channel), target (V, D, 3), weights (V, D),
    lw (V, D, 3) or (1, 1, 1) loss weights; G (V, 3, n, n), h (V, 3, n), yy (V, 3)."""
    n = columns.shape[2]
    full = lw.shape[0] > 1
    for v in numba.prange(columns.shape[0]):
        for c in range(3):
            for a in range(n):
                h[v, c, a] = 0.0
                for b in range(n):
                    G[v, c, a, b] = 0.0
            yy[v, c] = 0.0
        for d in range(columns.shape[1]):
            for c in range(3):
                w = weights[v, d] * (lw[v, d, c] if full else 1.0)
                if w == 0.0:
                    continue
                y = target[v, d, c]
                yy[v, c] += w * y * y
                for a in range(n):
                    xa = columns[v, d, a, c]
                    if xa == 0.0:
                        continue
                    h[v, c, a] += w * xa * y
                    for b in range(a, n):
                        G[v, c, a, b] += w * xa * columns[v, d, b, c]
        for c in range(3):
            for a in range(n):
                for b in range(a):
                    G[v, c, a, b] = G[v, c, b, a]


def vertex_coefficients(columns, target, weights, loss_weights, cap):
    """x (V, 3, n) >= 0 (and <= cap (V, 3, n)) per vertex and channel minimising
    sum_d w (target - columns @ x)^2; and the weighted squared error (V, 3)."""
    v, _, n, _ = columns.shape
    G = np.empty((v, 3, n, n))
    h = np.empty((v, 3, n))
    yy = np.empty((v, 3))
    lw = np.ones((1, 1, 1)) if loss_weights is None else np.ascontiguousarray(loss_weights, np.float64)
    _vertex_equations(np.ascontiguousarray(columns, np.float64), np.ascontiguousarray(target, np.float64),
                      np.ascontiguousarray(weights, np.float64), lw, G, h, yy)
    # columns of very different sizes (the constant 1 and a probe's radiance of 1e8): solve
    # for x scaled by each column's norm, so that the solver's relative ridge treats all alike
    diag = np.einsum("vcii->vci", G)
    d = np.where(diag > 0, 1.0 / np.sqrt(np.where(diag > 0, diag, 1.0)), 1.0)
    scaled = G * d[..., :, None] * d[..., None, :]
    xs = solve_many(scaled.reshape(-1, n, n), (h * d).reshape(-1, n),
                    (np.asarray(cap, np.float64) / d).reshape(-1, n), np.zeros((v * 3, n))).reshape(v, 3, n)
    x = xs * d
    err = yy - 2 * np.einsum("vci,vci->vc", h, x) + np.einsum("vci,vcij,vcj->vc", x, G, x)
    return x, np.maximum(err, 0.0)
