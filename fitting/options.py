"""What a fit does: ``FitOptions`` (every knob of ``vlights fit``, checked) and the
words its flags take. Light to import: the ``fit`` command builds its parser from here
without loading the fitter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from radiosity.files.errors import InputError
from radiosity.policies.presets import DEFAULT_QUALITY, QUALITIES, preset

from .blocks import BLOCK_SAMPLES

__all__ = ["COEFFICIENTS", "LIGHT_KINDS", "LOSSES", "METHODS", "MODELS", "MODEL_TARGET", "PARTS", "FitOptions", "quality_of"]

METHODS = ("paper", "refined", "per-light")
GLOSSY_MODELS = ("diffuse", "emitters", "probe", "probe+lights", "lights")  # a glossy object's models (``fitting.glossy``)
MODELS = ("auto", *GLOSSY_MODELS)
LIGHT_KINDS = ("auto", "directional", "positional")  # a virtual light's kind (``fitting.mixed``)
COEFFICIENTS = ("shared", "per-light")  # the lights' specular coefficients: one per vertex, or one per light
LOSSES = ("linear", "relative")  # the loss weights (``fitting.loss``)
PARTS = ("lights", "probe", "emitters")  # the parts of a model a display may switch off (``--off``)
PAYS = 0.02  # --lights auto: a light that lowers the relative error by less than this (relative) no longer pays
MODEL_TARGET = 0.03  # "auto"'s perceptual error target (``data.perceptual_error``)


_DEFAULT = preset(DEFAULT_QUALITY)  # FitOptions() is what ``vlights fit`` does at the default quality


@dataclass(frozen=True)
class FitOptions:
    """What a fit does; ``FitOptions()`` is ``FitOptions.for_quality(DEFAULT_QUALITY)``,
    what ``vlights fit`` does with no flag on a solution that records no quality.

    lights          : K per glossy object, or "auto" (smallest K reaching ``target``)
    target          : relative RMS error target of "auto"
    max_lights      : the cap of "auto"
    method          : "paper" (section 3.2 exactly: directional lights, shared
                      coefficients), "refined" (variable projection, one exponent),
                      "per-light" (refined with an exponent per light)
    light_kind      : "auto" (each light directional or positional as the data
                      require), "directional", "positional" (refined methods)
    coefficients    : "per-light" (a specular coefficient per light at each vertex) or
                      "shared" (one per vertex, the paper's model) (refined methods)
    loss            : "linear", "relative" (see ``loss.loss_weights``), or "auto": with
                      model "auto" both, the one with the lower perceptual error kept
                      (``glossy.AUTO_LOSSES``); otherwise relative for the models with a
                      probe (the teapot's reflections won in pictures: glossy FLIP against
                      the truth 0.171 / 0.172 / 0.162 in three views, linear 0.185 / 0.187 /
                      0.179), linear for virtual lights alone
    exponent_bounds : the exponent search's range
    iterations      : L-BFGS iterations of the refinement
    model           : what a glossy object's model is made of (``fitting.glossy``):
                      "auto" (the cheapest reaching ``target``), "diffuse", "emitters",
                      "probe", "probe+lights", or "lights" (virtual lights alone on the
                      whole radiance; "paper" always is)
    probe_size      : the probe's M (M x M texels), or "auto": the sizes ``probe_sizes``
                      tried (the quality preset's), each fitted, the cheapest within reach
                      of the best kept
    probe_lights    : lights beside a probe (the model "probe+lights"), or "auto"
    model_target    : the error target of --model auto (``data.perceptual_error``)
    search_samples  : a glossy object's model is searched for (the comparison of models,
                      the probe's texels, the lights' placement and refinement) on every
                      k-th vertex, at most this many samples (vertex x direction), and its
                      per-vertex coefficients then solved on every vertex (``fitting.blocks``)
    block_samples   : the samples of a block of vertices in that last pass (memory only:
                      the same model whatever it is)
    """

    lights: int | str = _DEFAULT.fit_lights
    target: float = 0.1
    max_lights: int = 16
    method: str = "refined"
    light_kind: str = "auto"
    coefficients: str = "per-light"
    loss: str = "auto"
    exponent_bounds: tuple[float, float] = (1.0, 1e4)
    iterations: int = _DEFAULT.fit_iterations
    model: str = "auto"
    probe_size: int | str = "auto"
    probe_sizes: tuple[int, ...] = tuple(_DEFAULT.probe_sizes)
    probe_lights: int | str = _DEFAULT.probe_lights
    model_target: float = MODEL_TARGET
    search_samples: int = _DEFAULT.fit_search_samples
    block_samples: int = BLOCK_SAMPLES

    @classmethod
    def for_quality(cls, quality):
        """The options ``vlights fit`` uses at ``quality`` (a preset name) with no other
        flag: the preset's lights, iterations, probe sizes and probe lights."""
        knobs = preset(quality)
        return cls(lights=knobs.fit_lights, iterations=knobs.fit_iterations, probe_sizes=tuple(knobs.probe_sizes),
                   probe_lights=knobs.probe_lights, search_samples=knobs.fit_search_samples).check()

    def check(self):
        for lights in (self.lights, self.probe_lights):
            if lights != "auto" and not (isinstance(lights, int) and 0 <= lights <= 64):
                raise InputError(f"--lights must be a whole number from 0 to 64 or 'auto', got {lights!r}")
        if not 0 < self.model_target < 10:
            raise InputError(f"--model-target must be an error between 0 and 10, got {self.model_target:g}")
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r}; choose one of {', '.join(METHODS)}")
        if self.light_kind not in LIGHT_KINDS:
            raise InputError(f"unknown light kind {self.light_kind!r}; choose one of {', '.join(LIGHT_KINDS)}")
        if self.coefficients not in COEFFICIENTS:
            raise InputError(f"unknown coefficients {self.coefficients!r}; choose one of {', '.join(COEFFICIENTS)}")
        if self.loss not in (*LOSSES, "auto"):
            raise InputError(f"unknown loss {self.loss!r}; choose one of auto, {', '.join(LOSSES)}")
        lo, hi = self.exponent_bounds
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi <= 1e6):
            raise InputError(f"exponent bounds must satisfy 0 < low <= high <= 1e6, got {lo:g} {hi:g}")
        if not 0 < self.target < 10:
            raise InputError(f"--target must be a relative error between 0 and 10, got {self.target:g}")
        if not (isinstance(self.max_lights, int) and 1 <= self.max_lights <= 64):
            raise InputError(f"--max-lights must be a whole number from 1 to 64, got {self.max_lights!r}")
        if not (isinstance(self.iterations, int) and self.iterations >= 0):
            raise InputError(f"--iterations must be a whole number >= 0, got {self.iterations!r}")
        for name, value in (("--search-samples", self.search_samples), ("--block-samples", self.block_samples)):
            if not (isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= 2**40):
                raise InputError(f"{name} must be a whole number of samples from 1, got {value!r}")
        if self.model not in MODELS:
            raise InputError(f"unknown model {self.model!r}; choose one of {', '.join(MODELS)}")
        if self.probe_size != "auto" and not (
            isinstance(self.probe_size, int) and not isinstance(self.probe_size, bool) and 2 <= self.probe_size <= 128
        ):
            raise InputError(f"--probe-size must be 'auto' or a whole number from 2 to 128, got {self.probe_size!r}")
        return self

    def loss_for(self, model):
        """The loss a ``model`` ("lights" or one with a probe) is fitted with."""
        if self.loss != "auto":
            return self.loss
        return "linear" if model == "lights" else "relative"

    @property
    def glossy_model(self):
        """The model glossy objects get: the paper's method is always lights alone."""
        return "lights" if self.method == "paper" else self.model


def quality_of(solution):
    """(quality, how it was chosen) of a fit of ``solution`` given none: the quality its
    solve recorded (``settings["quality"]``) if it is one we know, else the default."""
    recorded = solution.settings.get("quality")
    if isinstance(recorded, str) and recorded in QUALITIES:
        return recorded, "the solution's quality"
    return DEFAULT_QUALITY, "default"
