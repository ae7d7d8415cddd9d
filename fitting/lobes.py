"""The one Blinn-Phong lobe of the shading formula, its gradient, and the kernels that evaluate them.

For a unit normal n, a unit direction w towards the eye and a unit direction l towards
a directional light, with h = l + w the (unnormalised) half vector:

    lobe(n, h, p) = max(0, n . h / |h|)^p        (0 where |h| = 0: the light opposite the eye)

Cut-off (the one policy, applied by every caller): with c = n . h / |h|, the lobe is
set to 0 when c <= 0 or when (1 - c) p > ``NEGLIGIBLE`` = 30. Because log c <= c - 1,
the second case implies p log c < -30, so c^p < e^-30 ~ 9.4e-14: only terms below
1e-13 of the lobe's peak (1) are dropped, and the pow is not evaluated for them (most
(vertex, direction, light) triples of a sharp lobe). The gradient is 0 wherever the
lobe is.

Gradient (``lobe_gradient``), with value = c^p:

    d value / d l       = p c^(p-1) (n - c h / |h|) / |h|      (h = l + w, so dh/dl = I)
    d value / d log p   = value log(c) p

Contents:

- scalar numba functions ``lobe(n, h, p)`` and ``lobe_gradient(n, h, p)`` (n, h are
  3-tuples of floats), the one definition of the formula;
- ``lobe_vectorised``: the same as a numpy ufunc, ``(nx, ny, nz, hx, hy, hz, p)``,
  broadcasting, for the numpy reference ``fitting.model.shade_arrays``;
- the kernels of the fit: ``one_light`` (one light's lobe, where the paper's fit places
  its lights) and, below, the kernels that take a set of lights (a ``fitting.results.Lights``).

numba's on-disk cache (``cache=True``) of every kernel of the project is keyed on all the
source files of its package and of the packages it may import (radiosity/jit_cache.py),
so an edit here recompiles every cached kernel that inlines ``lobe``, wherever it lives.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)

__all__ = [
    "NEGLIGIBLE",
    "lobe",
    "lobe_gradient",
    "lobe_vectorised",
    "one_light",
]

NEGLIGIBLE = 30.0  # lobe set to 0 where (1 - c) p > NEGLIGIBLE: then c^p < e^-30 ~ 9.4e-14


@numba.njit(cache=True, nogil=True)
def _half_cosine(n, h):
    """(c, |h|): the cosine between n and h, 0 where |h| = 0."""
    length = math.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
    if length > 0.0:
        return (n[0] * h[0] + n[1] * h[1] + n[2] * h[2]) / length, length
    return 0.0, 0.0


@numba.njit(cache=True, nogil=True)
def _power(c, p):
    """max(0, c)^p with the cut-off of the module docstring."""
    if c <= 0.0 or (1.0 - c) * p > NEGLIGIBLE:
        return 0.0
    return c**p


@numba.njit(cache=True, nogil=True)
def lobe(n, h, p):
    """max(0, n . h / |h|)^p with the cut-off; n, h 3-tuples (h = l + w), p >= 0."""
    c, _ = _half_cosine(n, h)
    return _power(c, p)


@numba.njit(cache=True, nogil=True)
def lobe_gradient(n, h, p):
    """(value, (d/dl_x, d/dl_y, d/dl_z), d/d log p) of ``lobe(n, h, p)``, h = l + w."""
    c, length = _half_cosine(n, h)
    value = _power(c, p)
    if value <= 0.0:
        return 0.0, (0.0, 0.0, 0.0), 0.0
    scale = p * value / c / length  # p c^(p-1) / |h|
    dl = (
        scale * (n[0] - c * h[0] / length),
        scale * (n[1] - c * h[1] / length),
        scale * (n[2] - c * h[2] / length),
    )
    return value, dl, value * math.log(c) * p


@numba.vectorize(cache=True)
def lobe_vectorised(nx, ny, nz, hx, hy, hz, p):
    """``lobe((nx, ny, nz), (hx, hy, hz), p)`` as a broadcasting numpy ufunc (float64)."""
    return lobe((nx, ny, nz), (hx, hy, hz), p)


@numba.njit(cache=True, nogil=True, parallel=True)
def one_light(normals, views, light, shininess, out):
    """out[v, d] = lobe(n_v, light + views[v, d], shininess).

    normals (V, 3), views (V, D, 3) unit towards the eye, light (3,) unit, out (V, D).
    Returns out.
    """
    lx, ly, lz = light[0], light[1], light[2]
    for v in numba.prange(views.shape[0]):
        n = (normals[v, 0], normals[v, 1], normals[v, 2])
        for d in range(views.shape[1]):
            out[v, d] = lobe(n, (views[v, d, 0] + lx, views[v, d, 1] + ly, views[v, d, 2] + lz), shininess)
    return out


# ---------------------------------------------------------------------------------------
# Lights of either kind (fit.npz version 2, a ``fitting.results.Lights``) and shared or
# per-light coefficients: the kernels of every fit. A light is pos[k] = (x, y, z, w): w = 0 a unit direction towards
# a distant light, w = 1 a point light; at a vertex x the light vector is
# l = normalize(xyz - w x) (no distance attenuation).


class Samples(NamedTuple):
    """The data a fit is measured against (float64).

    positions    : (V, 3) vertex positions (world)
    radiance     : (V, D, 3) the data L
    weights      : (V, D) sample weights (area x solid angle)
    loss_weights : (V, D, 3) loss weights, or (1, 1, 1) ones for the linear loss
    """

    positions: np.ndarray
    radiance: np.ndarray
    weights: np.ndarray
    loss_weights: np.ndarray


@numba.njit(cache=True, nogil=True)
def light_vector(pos, k, x, y, z):
    """(lx, ly, lz, distance) of light k seen from (x, y, z): unit; distance 1 for a
    directional light, 0 (and a zero vector) for a point light at the point itself."""
    w = pos[k, 3]
    lx, ly, lz = pos[k, 0] - w * x, pos[k, 1] - w * y, pos[k, 2] - w * z
    length = math.sqrt(lx * lx + ly * ly + lz * lz)
    if length <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    return lx / length, ly / length, lz / length, length if w != 0.0 else 1.0


@numba.njit(cache=True, nogil=True)
def vertex_lights(pos, positions, v):
    """(K, 4): every light's ``light_vector`` seen from vertex v."""
    n_k = pos.shape[0]
    ls = np.empty((n_k, 4))
    for k in range(n_k):
        ls[k, 0], ls[k, 1], ls[k, 2], ls[k, 3] = light_vector(pos, k, positions[v, 0], positions[v, 1], positions[v, 2])
    return ls


@numba.njit(cache=True, nogil=True, parallel=True)
def mixed_light_sum(normals, views, lights, samples, coefficients, out):
    """out[v, d, c] = sum_k coefficients[v, k or 0, c] * rgb[k, c] * lobe(n_v, l_k(x_v) + w_vd, p_k).

    coefficients (V, K, 3) per light or (V, 1, 3) shared (ones: the lights' plain sum).
    Returns out (V, D, 3)."""
    pos, rgb, shininess = lights.pos, lights.rgb, lights.shininess
    positions = samples.positions
    n_k = pos.shape[0]
    shared = coefficients.shape[1] == 1
    for v in numba.prange(views.shape[0]):
        n = (normals[v, 0], normals[v, 1], normals[v, 2])
        ls = vertex_lights(pos, positions, v)
        for d in range(views.shape[1]):
            b0, b1, b2 = 0.0, 0.0, 0.0
            for k in range(n_k):
                if ls[k, 3] <= 0.0:
                    continue
                value = lobe(n, (views[v, d, 0] + ls[k, 0], views[v, d, 1] + ls[k, 1], views[v, d, 2] + ls[k, 2]),
                             shininess[k])
                if value > 0.0:
                    j = 0 if shared else k
                    b0 += coefficients[v, j, 0] * rgb[k, 0] * value
                    b1 += coefficients[v, j, 1] * rgb[k, 1] * value
                    b2 += coefficients[v, j, 2] * rgb[k, 2] * value
            out[v, d, 0], out[v, d, 1], out[v, d, 2] = b0, b1, b2
    return out


@numba.njit(cache=True, nogil=True, parallel=True)
def normal_equations(normals, views, lights, samples, per_light, G, h, yy):
    """Each vertex's least-squares problem for its coefficients, per channel c:
    unknowns [emitted, coefficient of light 1, ..., light K] (``per_light``) or
    [emitted, shared specular] with design rows [1, lobe_1, ..., lobe_K] or
    [1, sum_k rgb[k, c] lobe_k]. Writes the normal equations G (V, 3, n, n), h (V, 3, n)
    and the weighted data energy yy (V, 3) (sum w L^2).

    Per light with the linear loss the rows do not depend on the channel, so G is
    accumulated once and copied; only the lobes that are not zero (a sharp lobe's are
    mostly zero) enter the outer products."""
    pos, rgb, shininess = lights.pos, lights.rgb, lights.shininess
    positions, radiance, weights, lw = samples.positions, samples.radiance, samples.weights, samples.loss_weights
    n_k = pos.shape[0]
    n = G.shape[2]
    full = lw.shape[0] > 1
    same = per_light and not full
    for v in numba.prange(views.shape[0]):
        nv = (normals[v, 0], normals[v, 1], normals[v, 2])
        ls = vertex_lights(pos, positions, v)
        values = np.empty(n_k)
        row = np.empty(n)
        nz = np.empty(n, np.int64)
        for c in range(3):
            for i in range(n):
                h[v, c, i] = 0.0
                for j in range(n):
                    G[v, c, i, j] = 0.0
            yy[v, c] = 0.0
        for d in range(views.shape[1]):
            for k in range(n_k):
                values[k] = 0.0 if ls[k, 3] <= 0.0 else lobe(
                    nv, (views[v, d, 0] + ls[k, 0], views[v, d, 1] + ls[k, 1], views[v, d, 2] + ls[k, 2]), shininess[k])
            if same:
                # one row for the three channels: G once, h per channel
                wt = weights[v, d]
                if wt == 0.0:
                    continue
                row[0] = 1.0
                nz[0] = 0
                m = 1
                for k in range(n_k):
                    row[1 + k] = values[k]
                    if values[k] != 0.0:
                        nz[m] = 1 + k
                        m += 1
                for c in range(3):
                    y = radiance[v, d, c]
                    yy[v, c] += wt * y * y
                    for a in range(m):
                        h[v, c, nz[a]] += wt * row[nz[a]] * y
                for a in range(m):
                    ri = wt * row[nz[a]]
                    for b in range(a + 1):
                        G[v, 0, nz[a], nz[b]] += ri * row[nz[b]]
                continue
            for c in range(3):
                wt = weights[v, d] * (lw[v, d, c] if full else 1.0)
                if wt == 0.0:
                    continue
                row[0] = 1.0
                nz[0] = 0
                m = 1
                if per_light:
                    for k in range(n_k):
                        row[1 + k] = values[k]
                        if values[k] != 0.0:
                            nz[m] = 1 + k
                            m += 1
                else:
                    s = 0.0
                    for k in range(n_k):
                        s += rgb[k, c] * values[k]
                    row[1] = s
                    if s != 0.0:
                        nz[m] = 1
                        m += 1
                y = radiance[v, d, c]
                yy[v, c] += wt * y * y
                for a in range(m):
                    h[v, c, nz[a]] += wt * row[nz[a]] * y
                for a in range(m):
                    ri = wt * row[nz[a]]
                    for b in range(a + 1):
                        G[v, c, nz[a], nz[b]] += ri * row[nz[b]]
        for c in range(3):
            if same and c > 0:
                for i in range(n):
                    for j in range(n):
                        G[v, c, i, j] = G[v, 0, i, j]
                continue
            # nz is increasing, so entries went to the lower triangle; mirror them
            for i in range(n):
                for j in range(i):
                    G[v, c, j, i] = G[v, c, i, j]


@numba.njit(cache=True, nogil=True)
def ordered_sum(values):
    """sum(values) added in order, one thread: inside a parallel kernel numba makes
    ``values.sum()`` a parallel reduction whose bits depend on the number of threads
    (and a fit's on the number of worker processes, ``fit(workers=...)``)."""
    total = 0.0
    for i in range(values.shape[0]):
        total += values[i]
    return total


@numba.njit(cache=True, nogil=True, parallel=True)
def mixed_loss_and_gradient(normals, views, lights, samples, emitted, coefficients, partial):
    """sum_{v,d,c} w (L - e - sum_k S[v, k or 0, c] rgb[k, c] lobe_k)^2 at fixed
    coefficients, and its gradient with respect to the lights.

    ``partial`` (V, K, 7), zeroed by the caller, receives vertex v's part of light k's
    gradient: [d/d rgb (3), d/d log p, d/d xyz (3)], where d/d xyz is with respect to
    the unit vector l for a directional light (the caller projects it through its own
    parametrisation) and with respect to the position for a point light (l = (P - x) /
    |P - x|: d/dP = (I - l l^T) / |P - x| d/dl). Returns the loss."""
    pos, rgb, shininess = lights.pos, lights.rgb, lights.shininess
    positions, radiance, weights, lw = samples.positions, samples.radiance, samples.weights, samples.loss_weights
    n_v, n_d, n_k = views.shape[0], views.shape[1], pos.shape[0]
    full = lw.shape[0] > 1
    shared = coefficients.shape[1] == 1
    losses = np.zeros(n_v)
    for v in numba.prange(n_v):
        nv = (normals[v, 0], normals[v, 1], normals[v, 2])
        ls = vertex_lights(pos, positions, v)
        values = np.empty(n_k)
        grads = np.empty((n_k, 4))
        dl = np.zeros((n_k, 3))
        coef = np.empty(3)
        for d in range(n_d):
            b0, b1, b2 = 0.0, 0.0, 0.0
            for k in range(n_k):
                if ls[k, 3] <= 0.0:
                    values[k] = 0.0
                    continue
                hv = (views[v, d, 0] + ls[k, 0], views[v, d, 1] + ls[k, 1], views[v, d, 2] + ls[k, 2])
                value, g, dlogp = lobe_gradient(nv, hv, shininess[k])
                values[k] = value
                grads[k, 0], grads[k, 1], grads[k, 2], grads[k, 3] = g[0], g[1], g[2], dlogp
                if value > 0.0:
                    j = 0 if shared else k
                    b0 += coefficients[v, j, 0] * rgb[k, 0] * value
                    b1 += coefficients[v, j, 1] * rgb[k, 1] * value
                    b2 += coefficients[v, j, 2] * rgb[k, 2] * value
            for c in range(3):
                b = b0 if c == 0 else (b1 if c == 1 else b2)
                wt = weights[v, d] * (lw[v, d, c] if full else 1.0)
                r = radiance[v, d, c] - emitted[v, c] - b
                losses[v] += wt * r * r
                coef[c] = -2.0 * wt * r  # d loss / d model[v, d, c]
            for k in range(n_k):
                value = values[k]
                if value <= 0.0:
                    continue
                j = 0 if shared else k
                s0 = coef[0] * coefficients[v, j, 0]
                s1 = coef[1] * coefficients[v, j, 1]
                s2 = coef[2] * coefficients[v, j, 2]
                common = s0 * rgb[k, 0] + s1 * rgb[k, 1] + s2 * rgb[k, 2]  # d loss / d lobe_k
                partial[v, k, 0] += s0 * value
                partial[v, k, 1] += s1 * value
                partial[v, k, 2] += s2 * value
                partial[v, k, 3] += common * grads[k, 3]
                dl[k, 0] += common * grads[k, 0]
                dl[k, 1] += common * grads[k, 1]
                dl[k, 2] += common * grads[k, 2]
        for k in range(n_k):
            if ls[k, 3] <= 0.0:
                continue
            gx, gy, gz = dl[k, 0], dl[k, 1], dl[k, 2]
            if pos[k, 3] != 0.0:
                # through l = (P - x) / |P - x|
                radial = gx * ls[k, 0] + gy * ls[k, 1] + gz * ls[k, 2]
                inv = 1.0 / ls[k, 3]
                gx, gy, gz = (gx - radial * ls[k, 0]) * inv, (gy - radial * ls[k, 1]) * inv, (gz - radial * ls[k, 2]) * inv
            partial[v, k, 4] += gx
            partial[v, k, 5] += gy
            partial[v, k, 6] += gz
    return ordered_sum(losses)  # in vertex order: the same bits whatever the thread count
