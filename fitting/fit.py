"""The fitting stage: ``fit(solution, options) -> FittedModel`` (Contract 2).

Per object: diffuse objects keep their radiance as the emitted colour and get no
lights; glossy objects get the paper's fit (``paper``), optionally refined by variable
projection with one exponent or one per light (``refine``), with K lights given or
chosen as the smallest K whose error reaches a target.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from radiosity.formats.errors import InputError

from . import paper, refine
from .data import fit_data, relative_error
from .model import FittedModel, FittedObject, shade_arrays
from .results import FitResult, LightSet

METHODS = ("paper", "refined", "per-light")
TRIAL_ITERATIONS = 15  # refinement of each start before the best one is refined further
POLISH_ITERATIONS = 8  # refinement after each light the least-squares greedy start adds


@dataclass(frozen=True)
class FitOptions:
    """lights          : K per glossy object, or "auto" (smallest K reaching ``target``)
    target          : relative RMS error target of "auto"
    max_lights      : the cap of "auto"
    method          : "paper" (section 3.2 exactly), "refined" (then variable projection,
                      one exponent), "per-light" (refined with an exponent per light)
    loss            : "linear" or "relative" (see ``refine.loss_weights``)
    exponent_bounds : the exponent search's range
    iterations      : L-BFGS iterations of the refinement
    """

    lights: int | str = 8
    target: float = 0.1
    max_lights: int = 16
    method: str = "refined"
    loss: str = "linear"
    exponent_bounds: tuple[float, float] = (1.0, 1e4)
    iterations: int = 100

    def check(self):
        if self.lights != "auto" and not (isinstance(self.lights, int) and 0 <= self.lights <= 64):
            raise InputError(f"--lights must be a whole number from 0 to 64 or 'auto', got {self.lights!r}")
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r}; choose one of {', '.join(METHODS)}")
        if self.loss not in refine.LOSSES:
            raise InputError(f"unknown loss {self.loss!r}; choose one of {', '.join(refine.LOSSES)}")
        lo, hi = self.exponent_bounds
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi <= 1e6):
            raise InputError(f"exponent bounds must satisfy 0 < low <= high <= 1e6, got {lo:g} {hi:g}")
        if not 0 < self.target < 10:
            raise InputError(f"--target must be a relative error between 0 and 10, got {self.target:g}")
        if not (isinstance(self.max_lights, int) and 1 <= self.max_lights <= 64):
            raise InputError(f"--max-lights must be a whole number from 1 to 64, got {self.max_lights!r}")
        if not (isinstance(self.iterations, int) and self.iterations >= 0):
            raise InputError(f"--iterations must be a whole number >= 0, got {self.iterations!r}")
        return self


def reconstruct(data, result):
    """The model's colours (V, D, 3) at the data's samples; ``result`` a ``FitResult``."""
    return shade_arrays(
        result.emitted[:, None], result.specular[:, None], data.normals[:, None],
        result.light_dirs, result.light_rgb, result.shininess, data.views,
    )


def fit_lights(data, n_lights, options, previous=None):
    """One object's fit (a ``FitResult``) with ``n_lights`` lights by ``options.method``.

    The refined methods start from the paper's fit and from ``paper.greedy_least_squares``
    at the paper's exponent, each light polished by a short refinement before the next.
    With ``previous`` (a refined ``FitResult`` with fewer lights) they also try that fit
    plus the paper's next light at zero intensity, a model with ``n_lights`` lights
    whose error is the previous one, and keep the better of the two: the error then
    never grows when a light is added.
    """
    lw = refine.loss_weights(data, options.loss)
    result = paper.fit_paper(data, n_lights, exponent_bounds=options.exponent_bounds, loss_weights=lw)
    if options.method == "paper" or not result.n_lights:
        return result
    starts = [result.lights]
    kw = dict(per_light_exponents=options.method == "per-light", exponent_bounds=options.exponent_bounds, loss=options.loss)
    alternative = paper.greedy_least_squares(
        data, result.shininess[0], n_lights, lw,
        polish=lambda lights: refine.refine(data, lights, max_iterations=POLISH_ITERATIONS, **kw),
    )
    if alternative.n_lights:
        starts.append(alternative)
    if previous is not None and 0 < previous.n_lights < result.n_lights:
        extra = result.n_lights - previous.n_lights
        starts.append(previous.lights.extended(
            result.light_dirs[-extra:], np.zeros((extra, 3)), np.full(extra, previous.shininess[-1]),
        ))
    # a short refinement of every start, then the best one to the end
    trials = [refine.refine(data, start, max_iterations=min(options.iterations, TRIAL_ITERATIONS), **kw) for start in starts]
    best = min(trials, key=lambda r: r.sq_error)
    if options.iterations > TRIAL_ITERATIONS:
        best = refine.refine(data, best, max_iterations=options.iterations - TRIAL_ITERATIONS, **kw)
    return replace(best, search=result.search)


def _json_number(value):
    """A float for the file's meta, None where it is not finite (strict JSON)."""
    value = float(value)
    return value if math.isfinite(value) else None


def fit_object(obj, options):
    """FittedObject for one ``ObjectSolution``."""
    t0 = time.perf_counter()
    data = fit_data(obj)
    if obj.is_diffuse:
        emitted = data.radiance[:, 0, :]
        result = FitResult(lights=LightSet.empty(), emitted=emitted, specular=np.zeros_like(emitted))
        chosen_by = "diffuse: no lights"
    elif options.lights == "auto":
        result, chosen_by = _auto_lights(data, options)
    else:
        result = fit_lights(data, options.lights, options)
        chosen_by = f"--lights {options.lights}"
    error = relative_error(data, reconstruct(data, result))
    diffuse_part = relative_error(data, np.broadcast_to(result.emitted[:, None, :], data.radiance.shape))
    info = {
        "method": "diffuse" if obj.is_diffuse else options.method,
        "loss": options.loss,
        "chosen_by": chosen_by,
        "shininess": [round(float(p), 4) for p in result.shininess],
        "error": {
            "relative_rms": _json_number(error["relative_rms"]),
            "worst_vertex": _json_number(error["worst_vertex"]),
            "worst_vertex_index": error["worst_vertex_index"],
            "diffuse_only_relative_rms": _json_number(diffuse_part["relative_rms"]),
            "diffuse_only_worst_vertex": _json_number(diffuse_part["worst_vertex"]),
        },
        "time_s": round(time.perf_counter() - t0, 4),
    }
    if result.iterations is not None:
        info["iterations"] = result.iterations
    return FittedObject(
        name=obj.name,
        positions=np.asarray(obj.positions, np.float32),
        normals=np.asarray(obj.normals, np.float32),
        faces=np.asarray(obj.faces, np.int32),
        emitted=np.asarray(result.emitted, np.float32),
        specular=np.asarray(result.specular, np.float32),
        light_dirs=np.asarray(result.light_dirs, np.float32).reshape(-1, 3),
        light_rgb=np.asarray(result.light_rgb, np.float32).reshape(-1, 3),
        shininess=np.asarray(result.shininess, np.float32).reshape(-1),
        info=info,
    )


def _auto_lights(data, options):
    """The smallest K <= max_lights whose fit reaches the target, by the chosen method:
    K = 1, 2, 4, ... brackets it, bisection finds it; every fit is warm-started from
    the fit with fewer lights below it, so the error only falls as K grows."""
    fits = {}

    def fit_k(k, below):
        fits[k] = fit_lights(data, k, options, previous=fits.get(below))
        return relative_error(data, reconstruct(data, fits[k]))["relative_rms"]

    low, k = 0, 1
    while fit_k(k, low) > options.target and k < options.max_lights:
        low, k = k, min(2 * k, options.max_lights)
    high = k
    while high - low > 1:
        mid = (low + high) // 2
        if fit_k(mid, low) <= options.target:
            high = mid
        else:
            low = mid
    result = fits[high]
    reached = relative_error(data, reconstruct(data, result))["relative_rms"] <= options.target
    why = f"auto: smallest K reaching {options.target:g}" if reached else f"auto: target {options.target:g} not reached by {options.max_lights} lights"
    return result, why


def fit(solution, options=FitOptions(), progress=False):
    """The fitted model of every object of ``solution``."""
    options.check()
    objects = []
    items = solution.objects
    if progress:
        from tqdm import tqdm

        items = tqdm(items, desc="fit", unit="object", disable=None, dynamic_ncols=True)
    for obj in items:
        objects.append(fit_object(obj, options))
    return FittedModel(
        objects=tuple(objects),
        source=str(solution.scene),
        model="virtual lights: emitted + Blinn-Phong directional lights (Walter et al. 1997)",
        settings={
            "lights": options.lights, "target": options.target, "max_lights": options.max_lights,
            "method": options.method, "loss": options.loss,
            "exponent_bounds": list(options.exponent_bounds), "iterations": options.iterations,
        },
        camera=solution.camera,
    )
