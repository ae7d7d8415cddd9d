"""An object's virtual lights: how many, fitted how (the paper's section 3.2 or
variable projection), from where the exponent starts, and their coefficients on every
vertex once they are found. ``fitting.glossy`` calls these for every model with
lights, the model "lights" (the paper's) included.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import blocks, loss, mixed, paper
from .data import ErrorSums, fit_data, relative_error
from .options import PAYS

__all__ = ["PAYS", "LightFitter", "auto_lights", "fit_lights", "lights_on_every_vertex", "problem_for", "reconstruct",
           "start_exponent"]


def reconstruct(problem, result):
    """The model's colours (V, D, 3) at the data's samples; ``result`` a ``results.LightsFit``."""
    return mixed.model_colours(problem, result.lights(), result.emitted, result.specular)


def start_exponent(obj, options):
    """Where the refinement's exponent starts: the Blinn-Phong exponent that matches the
    material's modified-Phong lobe about the mirror direction (about 4 n: the half vector
    turns half as far as the view), within the bounds."""
    n = float(obj.material_record.exponent)
    guess = 4.0 * n + 1.0 if n > 0 else 100.0
    return float(np.clip(guess, *options.exponent_bounds))


def problem_for(data, options, scene):
    lw = loss.loss_weights(data, options.loss_for("lights"))
    per_light = options.coefficients == "per-light" and options.method != "paper"
    return mixed.Problem.make(data, lw, per_light, scene, options.exponent_bounds)


def fit_lights(problem, n_lights, options, exponent, previous=None, log=None):
    """One object's fit (a ``results.LightsFit``) with at most ``n_lights`` lights."""
    if options.method == "paper":
        lw = loss.loss_weights(problem.data, options.loss_for("lights"))
        return paper.fit_paper(problem.data, n_lights, exponent_bounds=options.exponent_bounds, loss_weights=lw)
    return mixed.fit_mixed(
        problem, n_lights, exponent, light_kind=options.light_kind, per_light_exponents=options.method == "per-light",
        iterations=options.iterations, previous=previous, log=log,
    )


def auto_lights(problem, options, exponent, log=None):
    """The fewest lights (up to ``max_lights``) reaching the target: lights are added
    one by one (each fit continues the one before, so the error only falls), and the
    search stops when the target is reached, or when a light no longer pays (lowers
    the relative error by less than ``PAYS`` of it), or at ``max_lights``."""
    data = problem.data
    empty = mixed.no_lights(problem)
    fit, last = None, relative_error(data, np.broadcast_to(empty.emitted[:, None, :], data.radiance.shape))["relative_rms"]
    why = None
    for k in range(1, options.max_lights + 1):
        trial = fit_lights(problem, k, options, exponent, previous=fit, log=log)
        error = relative_error(data, reconstruct(problem, trial))["relative_rms"]
        if fit is not None and error > last * (1 - PAYS):
            why = (f"auto: target {options.target:g} not reached; a light more lowered the error by less than "
                   f"{PAYS:.0%} ({last:.4g} -> {error:.4g}), so {fit.n_lights} lights")
            break
        fit, last = trial, error
        if error <= options.target:
            why = f"auto: fewest lights reaching {options.target:g}"
            break
        if fit.n_lights < k:  # nothing left to explain
            break
    if why is None:
        why = f"auto: target {options.target:g} not reached by {fit.n_lights} lights (--max-lights {options.max_lights})"
    return fit, why


def lights_on_every_vertex(obj, result, options, scene, area):
    """(the ``results.LightsFit`` ``result``, its lights held and its per-vertex coefficients
    solved on every vertex of ``obj``, a block at a time; its ``relative_error``; that of
    its emitted colour alone; its perceptual error)."""
    v, d = obj.num_vertices, len(obj.directions)
    mean = blocks.object_mean(obj.radiance, area, options.block_samples)
    lights = result.lights()
    emitted = np.empty((v, 3))
    specular = np.empty((v, result.n_lights, 3) if result.per_light else (v, 3))
    model, diffuse, sq_error = ErrorSums(mean), ErrorSums(mean), 0.0
    for sl in blocks.vertex_blocks(v, d, options.block_samples):
        data = fit_data(obj, sl, area)
        lw = loss.loss_weights(data, options.loss_for("lights"), mean)
        problem = mixed.Problem.make(data, lw, result.per_light, scene, options.exponent_bounds)
        emitted[sl], specular[sl], err = mixed.coefficients(problem, lights)
        sq_error += err
        model.add(data, mixed.model_colours(problem, lights, emitted[sl], specular[sl]), sl.start)
        diffuse.add(data, np.broadcast_to(emitted[sl, None, :], data.radiance.shape), sl.start)
    return (replace(result, emitted=emitted, specular=specular, sq_error=sq_error), model.relative(), diffuse.relative(),
            model.perceptual())


class LightFitter:
    """The lights of one glossy object's models, as ``fitting.glossy`` asks for them:
    ``options`` say how many and fitted how, ``scene`` (a ``mixed.SceneGeometry``) where
    positional lights are seeded, ``log(fit)`` shows progress (or None). ``chosen_by``
    gathers how each full fit beside a probe chose its count."""

    def __init__(self, options, scene, log=None):
        self.options, self.scene, self.log = options, scene, log
        self.chosen_by = []

    def problem(self, data, loss_weights):
        """The ``mixed.Problem`` of ``data`` with these loss weights (``problem_for``'s)."""
        options = self.options
        per_light = options.coefficients == "per-light" and options.method != "paper"
        return mixed.Problem.make(data, loss_weights, per_light, self.scene, options.exponent_bounds)

    def asked(self, data, loss_weights, start):
        """(problem, ``results.LightsFit``, how its count was chosen) of the model "lights"
        asked for (``--model lights``, the paper's method): --lights of them, or "auto"."""
        options = self.options
        problem = self.problem(data, loss_weights)
        if options.lights == "auto":
            found, why = auto_lights(problem, options, start, self.log)
            return problem, found, why
        return problem, fit_lights(problem, options.lights, options, start, log=self.log), f"--lights {options.lights}"

    def __call__(self, data, loss_weights, start, count=None, previous=None, alone=False):
        """A ``results.LightsFit`` of ``data``: ``count`` given, a quick fit of that many
        lights (the first light's polish, as many iterations: whether lights pay);
        ``previous``, a fit of fewer to continue from; ``alone``, the lights of the model
        "lights" (--lights of them) as "auto" weighs it; else the lights beside a probe
        (--probe-lights of them, or "auto")."""
        options = self.options
        problem = self.problem(data, loss_weights)
        quick = replace(options, iterations=min(options.iterations, mixed.FIRST_POLISH_ITERATIONS))
        if alone:
            opts = options if count is None else quick
            if options.lights == "auto":
                return auto_lights(problem, opts, start, self.log)[0]
            return fit_lights(problem, options.lights, opts, start, previous=previous, log=self.log)
        if count is not None:
            return fit_lights(problem, count, quick, start, previous=previous, log=self.log)
        if options.probe_lights == "auto":
            found, why = auto_lights(problem, options, start, self.log)
            self.chosen_by.append(why)
            return found
        self.chosen_by.append(f"{options.probe_lights} lights")
        return fit_lights(problem, options.probe_lights, options, start, previous=previous, log=self.log)
