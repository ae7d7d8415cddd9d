"""The paper's fitting algorithm (Walter et al. 1997, section 3.2), exactly.

For one non-diffuse object:

    repeat (golden-section search over the exponent, on a log scale)
        choose a shininess value
        repeat K times
            subtract the effects of the existing lights from the data
            find the maximum difference over all vertices and directions
            add a directional light that puts a highlight there: the mirror of that
                direction about that vertex's normal (so the half vector is the normal)
            set the light intensities to match the data at their maxima
                (specular coefficient 1 meanwhile)
        for each vertex: emitted and specular by (non-negative) least squares
    until the search is done; keep the exponent with the least squared error
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.optimize import nnls

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)

from .lobes import one_light
from .model import directional
from .results import Lights, LightsFit

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
# a vertex's highlight may exceed its brightest sample this many times (a true peak can
# fall between samples or at grazing views outside the grid; an unbounded one is absurd)
CAP_FACTOR = 8.0


def mirror(normal, view):
    """The light direction whose half vector with ``view`` is ``normal``."""
    light = 2.0 * np.dot(normal, view) * normal - view
    return light / np.linalg.norm(light)


def greedy_lights(data, shininess, n_lights):
    """Up to ``n_lights`` lights for one exponent, as the paper places them.

    Returns (``Lights``, directional, lobe values (K, V, D) of its lights); fewer than
    ``n_lights`` lights when the data have nothing left above the lights' sum.
    """
    radiance = data.radiance
    score_data = radiance.sum(axis=2)
    score = score_data.copy()
    values = np.empty((n_lights,) + score.shape)
    dirs, peaks = [], []
    rgb = np.zeros((0, 3))
    for k in range(n_lights):
        v, d = np.unravel_index(np.argmax(score), score.shape)
        if not score[v, d] > 0:
            break
        dirs.append(mirror(data.normals[v], data.views[v, d]))
        one_light(data.normals, data.views, dirs[-1], float(shininess), values[k])
        peaks.append((v, d))
        # intensities that reproduce the data at every light's maximum
        pv, pd = np.array(peaks).T
        at_peaks = values[: k + 1, pv, pd].T  # [peak i, light j]
        target = radiance[pv, pd]
        rgb = np.stack([nnls(at_peaks, target[:, c])[0] for c in range(3)], axis=1)
        score = score_data - np.tensordot(rgb.sum(axis=1), values[: k + 1], axes=1)
    lights = Lights.of(directional(dirs), rgb, np.full(len(dirs), float(shininess)))
    return lights, values[: len(dirs)]


def vertex_coefficients(data, basis, loss_weights=None, lights=None):
    """Per-vertex, per-channel non-negative least squares for emitted e and specular s.

    Minimises sum_d w (L - e - s B)^2 for each vertex and channel, B = ``basis`` (V, D, 3)
    (the lights' sum with specular 1), w = the sample weights (times ``loss_weights``
    (V, D, 3) if given), subject to e >= 0 and 0 <= s <= cap. The cap keeps a vertex
    from showing, in any direction, a highlight brighter than ``CAP_FACTOR`` times the
    brightest radiance it has: s * (the lights' peak over the hemisphere) <=
    CAP_FACTOR max_d L, the peak taken over the samples and, given ``lights`` (the
    directional ``Lights`` behind ``basis``), over every view. Without it a lobe too sharp to
    touch any sample direction would be scaled up without bound to reach the data at
    one sample, and blaze between samples. Returns (emitted (V, 3), specular (V, 3),
    weighted squared error).
    """
    if loss_weights is None:
        loss_weights = np.ones((1, 1, 1))
    s1, sb, sbb, sl, slb, sll = _sums(data.radiance, basis, data.weights, np.ascontiguousarray(loss_weights, np.float64))
    peak = basis.max(axis=1)  # (V, 3)
    if lights is not None and len(lights.pos):
        dirs, rgb, exponents = lights.pos[:, :3], lights.rgb, lights.shininess
        # over all views of the hemisphere a light's lobe peaks at 1 if the light is above
        # the horizon, else at the grazing view opposite it: half-vector angle (theta - 90) / 2
        theta = np.arccos(np.clip(data.normals @ dirs.T, -1.0, 1.0))  # (V, K)
        lobe_peak = np.cos(np.maximum(theta - np.pi / 2, 0.0) / 2) ** exponents
        peak = np.maximum(peak, np.max(lobe_peak[:, :, None] * rgb[None], axis=1))
    brightest = data.radiance.max(axis=1)
    with np.errstate(over="ignore"):
        cap = np.where(peak > 0, np.minimum(CAP_FACTOR * brightest / np.where(peak > 0, peak, 1.0), 1e200), 0.0)

    def sq_error(e, s):
        # sum w (L - e - s B)^2 expanded in the sums above
        return sll - 2 * e * sl - 2 * s * slb + e * e * s1 + 2 * e * s * sb + s * s * sbb

    tiny = 1e-300
    det = s1 * sbb - sb * sb
    ok = det > 1e-12 * np.maximum(s1 * sbb, tiny)
    safe = np.where(ok, det, 1.0)
    candidates = [
        # the free optimum, if it is inside the box
        (np.where(ok, (sbb * sl - sb * slb) / safe, -1.0), np.where(ok, (s1 * slb - sb * sl) / safe, -1.0)),
        # each edge of the box: the one-variable optimum, clipped to the edge
        (np.maximum(sl / np.maximum(s1, tiny), 0.0), np.zeros_like(sl)),  # s = 0
        (np.zeros_like(sl), np.clip(slb / np.maximum(sbb, tiny), 0.0, cap)),  # e = 0
        (np.maximum((sl - cap * sb) / np.maximum(s1, tiny), 0.0), cap),  # s = cap
    ]
    best_e, best_s = candidates[1]
    best = sq_error(best_e, best_s)
    # a candidate on an astronomically large cap overflows to inf or NaN: it never wins
    with np.errstate(over="ignore", invalid="ignore"):
        for e, s in candidates[0:1] + candidates[2:]:
            feasible = (e >= 0) & (s >= 0) & (s <= cap)
            e, s = np.where(feasible, e, 0.0), np.where(feasible, s, 0.0)
            err = np.where(feasible, sq_error(e, s), np.inf)
            better = err < best
            best_e = np.where(better, e, best_e)
            best_s = np.where(better, s, best_s)
            best = np.where(better, err, best)
    return best_e, best_s, float(np.maximum(best, 0.0).sum())


@numba.njit(cache=True, nogil=True, parallel=True)
def _sums(L, B, weights, loss_weights):
    """Per (vertex, channel) sums of w, wB, wB^2, wL, wLB, wL^2 over directions; the
    weight is weights[v, d] times loss_weights broadcast from (1, 1, 1) or (V, D, 3)."""
    n_v, n_d = weights.shape
    out = np.zeros((6, n_v, 3))
    full = loss_weights.shape[0] > 1
    for v in numba.prange(n_v):
        for d in range(n_d):
            for c in range(3):
                w = weights[v, d] * (loss_weights[v, d, c] if full else loss_weights[0, 0, 0])
                b, y = B[v, d, c], L[v, d, c]
                out[0, v, c] += w
                out[1, v, c] += w * b
                out[2, v, c] += w * b * b
                out[3, v, c] += w * y
                out[4, v, c] += w * y * b
                out[5, v, c] += w * y * y
    return out[0], out[1], out[2], out[3], out[4], out[5]


def fit_exponent(data, shininess, n_lights, loss_weights=None):
    """The paper's inner loop for one exponent: lights, then vertex coefficients.

    Returns a ``LightsFit`` (directional lights, ``shininess`` repeated for each, shared
    coefficients).
    """
    lights, values = greedy_lights(data, shininess, n_lights)
    basis = np.tensordot(values, lights.rgb, axes=([0], [0])) if len(lights.pos) else np.zeros_like(data.radiance)
    emitted, specular, err = vertex_coefficients(data, basis, loss_weights, lights)
    return LightsFit(*lights, emitted=emitted, specular=specular, sq_error=err)


def golden_section(f, lo, hi, tolerance):
    """Minimise f on [lo, hi] by golden-section search; returns (x, f(x), evaluations)."""
    a, b = lo, hi
    c = b - GOLDEN * (b - a)
    d = a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    evaluations = [(c, fc), (d, fd)]
    while b - a > tolerance:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = f(c)
            evaluations.append((c, fc))
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = f(d)
            evaluations.append((d, fd))
    x, fx = min(evaluations, key=lambda e: e[1])
    return x, fx, evaluations


def fit_paper(data, n_lights=8, *, exponent_bounds=(1.0, 1e4), log_tolerance=0.05, loss_weights=None):
    """The paper's fit of one object: ``fit_exponent``'s ``LightsFit`` for the exponent
    of the least error that the golden-section search over log p found."""
    lo, hi = (math.log(b) for b in exponent_bounds)
    cache = {}

    def error_at(log_p):
        result = fit_exponent(data, math.exp(log_p), n_lights, loss_weights)
        cache[log_p] = result
        return result.sq_error

    if hi - lo <= log_tolerance:
        best = 0.5 * (lo + hi)
        error_at(best)
    else:
        best, _, _ = golden_section(error_at, lo, hi, log_tolerance)
    return cache[best]
