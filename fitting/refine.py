"""Beyond the paper: non-linear refinement of the virtual lights by variable projection.

The paper stops at its heuristic and notes that "further optimization could then be
done using these values as the initial guess". Here the light directions, the light
intensities and the exponents (one for the object, or one per light) are optimised
jointly by L-BFGS-B from the paper's fit. The per-vertex coefficients (emitted and
specular, non-negative) are linear given the lights, so they are solved in closed
form inside the objective (variable projection, Golub and Pereyra 1973):

    F(lights) = min_{e, s >= 0} sum_{v, d, c} w (L - e - s B(lights))^2

and the gradient of this reduced objective is the partial gradient at the optimal
(e, s), computed analytically in one pass over the data.

The weights w are the sample weights (area x solid angle) times an optional loss
weight: "linear" (1) or "relative" (1 / (eps + L)^2, so an error counts relative to
the radiance it is in, as a viewer's eye, adapted to brightness, sees it; eps is a
small fraction of the mean radiance so black regions do not dominate).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.optimize import minimize

from .paper import vertex_coefficients

LOSSES = ("linear", "relative")
RELATIVE_FLOOR = 0.05  # eps of the relative loss, as a fraction of the mean radiance
# a lobe c^p is skipped when (1 - c) p exceeds this: then p log c < -30 and c^p < 1e-13
NEGLIGIBLE = 30.0


def loss_weights(data, loss):
    """(V, D, 3) loss weights, or None for the linear loss."""
    if loss == "linear":
        return None
    if loss == "relative":
        mean = float(np.sum(data.weights[:, :, None] * data.radiance) / 3.0)
        eps = RELATIVE_FLOOR * mean if mean > 0 else 1.0
        return 1.0 / (eps + data.radiance) ** 2
    raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")


@numba.njit(cache=True, nogil=True, parallel=True)
def _basis(normals, views, dirs, rgb, shininess, out):
    """out[v, d, c] = sum_k rgb[k, c] * max(0, n_v . normalize(l_k + w_vd))^p_k."""
    n_v, n_d = views.shape[0], views.shape[1]
    for v in numba.prange(n_v):
        for d in range(n_d):
            b0, b1, b2 = 0.0, 0.0, 0.0
            for k in range(dirs.shape[0]):
                hx = views[v, d, 0] + dirs[k, 0]
                hy = views[v, d, 1] + dirs[k, 1]
                hz = views[v, d, 2] + dirs[k, 2]
                length = math.sqrt(hx * hx + hy * hy + hz * hz)
                if length <= 0.0:
                    continue
                c = (normals[v, 0] * hx + normals[v, 1] * hy + normals[v, 2] * hz) / length
                if c <= 0.0 or (1.0 - c) * shininess[k] > NEGLIGIBLE:
                    continue
                lobe = c ** shininess[k]
                b0 += rgb[k, 0] * lobe
                b1 += rgb[k, 1] * lobe
                b2 += rgb[k, 2] * lobe
            out[v, d, 0], out[v, d, 1], out[v, d, 2] = b0, b1, b2


@numba.njit(cache=True, nogil=True, parallel=True)
def _loss_and_gradient(normals, views, dirs, rgb, shininess, radiance, emitted, specular, weights, lw, partial):
    """Weighted squared residual at fixed (emitted, specular), and its gradient.

    partial[v, k] receives vertex v's contribution to light k's gradient:
    [d/d rgb (3), d/d log p (1), d/d light direction (3)]. Returns the loss.
    """
    n_v, n_d, n_k = views.shape[0], views.shape[1], dirs.shape[0]
    full = lw.shape[0] > 1
    losses = np.zeros(n_v)
    for v in numba.prange(n_v):
        nx, ny, nz = normals[v, 0], normals[v, 1], normals[v, 2]
        lobes = np.empty(n_k)
        cosines = np.empty(n_k)
        halves = np.empty((n_k, 4))
        for d in range(n_d):
            b0, b1, b2 = 0.0, 0.0, 0.0
            for k in range(n_k):
                hx = views[v, d, 0] + dirs[k, 0]
                hy = views[v, d, 1] + dirs[k, 1]
                hz = views[v, d, 2] + dirs[k, 2]
                length = math.sqrt(hx * hx + hy * hy + hz * hz)
                c = (nx * hx + ny * hy + nz * hz) / length if length > 0.0 else 0.0
                lobe = c ** shininess[k] if c > 0.0 and (1.0 - c) * shininess[k] <= NEGLIGIBLE else 0.0
                lobes[k], cosines[k] = lobe, c
                halves[k, 0], halves[k, 1], halves[k, 2], halves[k, 3] = hx, hy, hz, length
                b0 += rgb[k, 0] * lobe
                b1 += rgb[k, 1] * lobe
                b2 += rgb[k, 2] * lobe
            coef = np.empty(3)
            for c_ in range(3):
                b = b0 if c_ == 0 else (b1 if c_ == 1 else b2)
                w = weights[v, d] * (lw[v, d, c_] if full else 1.0)
                r = radiance[v, d, c_] - emitted[v, c_] - specular[v, c_] * b
                losses[v] += w * r * r
                coef[c_] = -2.0 * w * r * specular[v, c_]  # d loss / d B[v, d, c]
            for k in range(n_k):
                lobe = lobes[k]
                if lobe <= 0.0:
                    continue
                common = coef[0] * rgb[k, 0] + coef[1] * rgb[k, 1] + coef[2] * rgb[k, 2]
                partial[v, k, 0] += coef[0] * lobe
                partial[v, k, 1] += coef[1] * lobe
                partial[v, k, 2] += coef[2] * lobe
                p = shininess[k]
                c = cosines[k]
                partial[v, k, 3] += common * lobe * math.log(c) * p  # d/d log p
                # d lobe / d h = p c^(p-1) (n - c h/|h|) / |h|; h = w + l
                hx, hy, hz, length = halves[k, 0], halves[k, 1], halves[k, 2], halves[k, 3]
                scale = common * p * lobe / c / length
                partial[v, k, 4] += scale * (nx - c * hx / length)
                partial[v, k, 5] += scale * (ny - c * hy / length)
                partial[v, k, 6] += scale * (nz - c * hz / length)
    return losses.sum()


def basis(data, dirs, rgb, shininess):
    out = np.empty_like(data.radiance)
    _basis(data.normals, data.views, np.ascontiguousarray(dirs, np.float64), np.ascontiguousarray(rgb, np.float64),
           np.ascontiguousarray(shininess, np.float64), out)
    return out


def refine(data, start, per_light_exponents=False, exponent_bounds=(1.0, 1e4), loss="linear", max_iterations=200):
    """Refine a fit (dict with light_dirs, light_rgb, shininess) by variable projection.

    Returns a dict like ``paper.fit_exponent``'s (light_dirs, light_rgb, shininess,
    emitted, specular, sq_error) plus "iterations" and "evaluations".
    """
    dirs0 = np.asarray(start["light_dirs"], np.float64).reshape(-1, 3)
    n_k = len(dirs0)
    lw = loss_weights(data, loss)
    lw_array = np.ones((1, 1, 1)) if lw is None else np.ascontiguousarray(lw)
    if n_k == 0:
        e, s, err = vertex_coefficients(data, np.zeros_like(data.radiance), lw)
        return {**_pack(dirs0, np.zeros((0, 3)), np.zeros(0), e, s, err), "iterations": 0, "evaluations": 0}

    scale = float(np.max(np.asarray(start["light_rgb"]))) or 1.0
    log_lo, log_hi = math.log(exponent_bounds[0]), math.log(exponent_bounds[1])
    n_p = n_k if per_light_exponents else 1
    p0 = np.log(np.clip(np.asarray(start["shininess"], np.float64), *exponent_bounds))
    p0 = p0 if per_light_exponents else p0[:1]
    x0 = np.concatenate([dirs0.ravel(), np.asarray(start["light_rgb"], np.float64).ravel() / scale, p0])
    bounds = [(None, None)] * (3 * n_k) + [(0.0, None)] * (3 * n_k) + [(log_lo, log_hi)] * n_p
    state = {"evaluations": 0}

    def unpack(x):
        raw = x[: 3 * n_k].reshape(n_k, 3)
        norm = np.linalg.norm(raw, axis=1, keepdims=True)
        dirs = raw / np.where(norm > 0, norm, 1.0)
        rgb = x[3 * n_k: 6 * n_k].reshape(n_k, 3) * scale
        shininess = np.exp(np.broadcast_to(x[6 * n_k:], (n_k,)))
        return raw, norm, dirs, rgb, np.ascontiguousarray(shininess)

    def objective(x):
        state["evaluations"] += 1
        raw, norm, dirs, rgb, shininess = unpack(x)
        e, s, _ = vertex_coefficients(data, basis(data, dirs, rgb, shininess), lw, (dirs, rgb, shininess))
        partial = np.zeros((data.n_vertices, n_k, 7))
        loss_value = _loss_and_gradient(
            data.normals, data.views, dirs, rgb, shininess, data.radiance, e, s, data.weights, lw_array, partial,
        )
        g = partial.sum(axis=0)
        g_dir = g[:, 4:7]
        # through the normalisation l = raw / |raw|: project out the radial part
        g_dir = (g_dir - np.sum(g_dir * dirs, axis=1, keepdims=True) * dirs) / np.where(norm > 0, norm, 1.0)
        g_logp = g[:, 3] if per_light_exponents else np.array([g[:, 3].sum()])
        grad = np.concatenate([g_dir.ravel(), (g[:, 0:3] * scale).ravel(), g_logp])
        return loss_value, grad

    result = minimize(
        objective, x0, jac=True, method="L-BFGS-B", bounds=bounds,
        options={"maxiter": max_iterations, "ftol": 1e-12, "gtol": 1e-12},
    )
    x = result.x if result.fun <= objective(x0)[0] else x0
    _, _, dirs, rgb, shininess = unpack(x)
    e, s, err = vertex_coefficients(data, basis(data, dirs, rgb, shininess), lw, (dirs, rgb, shininess))
    return {**_pack(dirs, rgb, shininess, e, s, err), "iterations": int(result.nit), "evaluations": state["evaluations"]}


def _pack(dirs, rgb, shininess, emitted, specular, err):
    return {
        "light_dirs": dirs, "light_rgb": rgb, "shininess": np.asarray(shininess, np.float64),
        "emitted": emitted, "specular": specular, "sq_error": err,
    }
