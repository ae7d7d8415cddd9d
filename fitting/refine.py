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
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .lobes import Residual, light_sum, loss_and_gradient
from .paper import vertex_coefficients
from .results import FitResult, LightSet

LOSSES = ("linear", "relative")
RELATIVE_FLOOR = 0.05  # eps of the relative loss, as a fraction of the mean radiance


def loss_weights(data, loss):
    """(V, D, 3) loss weights, or None for the linear loss."""
    if loss == "linear":
        return None
    if loss == "relative":
        mean = float(np.sum(data.weights[:, :, None] * data.radiance) / 3.0)
        eps = RELATIVE_FLOOR * mean if mean > 0 else 1.0
        return 1.0 / (eps + data.radiance) ** 2
    raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")


def basis(data, lights):
    """(V, D, 3) sum_k light_rgb[k] * lobe_k at the data's samples (specular 1)."""
    return light_sum(data.normals, data.views, lights.kernel_arrays(), np.empty_like(data.radiance))


@dataclass(frozen=True, eq=False)
class Parameters:
    """How the refinement's parameter vector x maps to lights.

    x = [raw directions (3K), colours / ``scale`` (3K), log exponents (1 or K)]; a
    direction is its raw vector normalised.
    """

    n_lights: int
    per_light_exponents: bool
    scale: float

    def pack(self, lights):
        log_p = np.log(lights.shininess)
        log_p = log_p if self.per_light_exponents else log_p[:1]
        return np.concatenate([lights.light_dirs.ravel(), lights.light_rgb.ravel() / self.scale, log_p])

    def unpack(self, x):
        """(``LightSet``, the raw directions' lengths (K, 1))."""
        n_k = self.n_lights
        raw = x[: 3 * n_k].reshape(n_k, 3)
        norm = np.linalg.norm(raw, axis=1, keepdims=True)
        dirs = raw / np.where(norm > 0, norm, 1.0)
        rgb = x[3 * n_k: 6 * n_k].reshape(n_k, 3) * self.scale
        shininess = np.exp(np.broadcast_to(x[6 * n_k:], (n_k,)))
        return LightSet(dirs, rgb, shininess), norm

    def bounds(self, exponent_bounds):
        n_k = self.n_lights
        log_lo, log_hi = math.log(exponent_bounds[0]), math.log(exponent_bounds[1])
        n_p = n_k if self.per_light_exponents else 1
        return [(None, None)] * (3 * n_k) + [(0.0, None)] * (3 * n_k) + [(log_lo, log_hi)] * n_p


def objective(data, lw, params, x):
    """The reduced objective F at parameters ``x`` and its gradient with respect to x.

    ``lw`` the loss weights (None: linear), ``params`` the ``Parameters`` of x. The
    per-vertex coefficients are solved for first (``vertex_coefficients``); the
    gradient is the partial one at those coefficients (variable projection).
    """
    lights, norm = params.unpack(x)
    e, s, _ = vertex_coefficients(data, basis(data, lights), lw, lights)
    lw_array = np.ones((1, 1, 1)) if lw is None else np.ascontiguousarray(lw, np.float64)
    residual = Residual(data.radiance, data.weights, lw_array, e, s)
    partial = np.zeros((data.n_vertices, lights.n_lights, 7))
    loss_value = loss_and_gradient(data.normals, data.views, lights.kernel_arrays(), residual, partial)
    g = partial.sum(axis=0)
    g_dir = g[:, 4:7]
    dirs = lights.light_dirs
    # through the normalisation l = raw / |raw|: project out the radial part
    g_dir = (g_dir - np.sum(g_dir * dirs, axis=1, keepdims=True) * dirs) / np.where(norm > 0, norm, 1.0)
    g_logp = g[:, 3] if params.per_light_exponents else np.array([g[:, 3].sum()])
    grad = np.concatenate([g_dir.ravel(), (g[:, 0:3] * params.scale).ravel(), g_logp])
    return loss_value, grad


def refine(data, start, *, per_light_exponents=False, exponent_bounds=(1.0, 1e4), loss="linear", max_iterations=200):
    """Refine lights by variable projection; ``start`` a ``LightSet`` or ``FitResult``.

    Returns a ``FitResult`` (its ``iterations`` and ``evaluations`` those of L-BFGS-B).
    """
    start = start.lights if isinstance(start, FitResult) else start
    lw = loss_weights(data, loss)
    if start.n_lights == 0:
        e, s, err = vertex_coefficients(data, np.zeros_like(data.radiance), lw)
        return FitResult(lights=LightSet.empty(), emitted=e, specular=s, sq_error=err, iterations=0, evaluations=0)

    params = Parameters(start.n_lights, per_light_exponents, float(np.max(start.light_rgb)) or 1.0)
    clipped = LightSet(start.light_dirs, start.light_rgb, np.clip(start.shininess, *exponent_bounds))
    x0 = params.pack(clipped)
    evaluations = 0

    def counted(x):
        nonlocal evaluations
        evaluations += 1
        return objective(data, lw, params, x)

    result = minimize(
        counted, x0, jac=True, method="L-BFGS-B", bounds=params.bounds(exponent_bounds),
        options={"maxiter": max_iterations, "ftol": 1e-12, "gtol": 1e-12},
    )
    x = result.x if result.fun <= counted(x0)[0] else x0
    lights, _ = params.unpack(x)
    e, s, err = vertex_coefficients(data, basis(data, lights), lw, lights)
    return FitResult(
        lights=lights, emitted=e, specular=s, sq_error=err, iterations=int(result.nit), evaluations=evaluations,
    )
