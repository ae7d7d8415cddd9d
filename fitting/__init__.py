"""The fitting stage: virtual lights fitted to a solution (fit.npz, docs/formats.md).

    fit(solution, FitOptions(...)) -> FittedModel     fit.npz via FittedModel.save, load_fit
    shade(model, name, world_dirs)                    the one reference of the shading formula
    LightSet, FitResult                               what the steps of a fit pass between them

Modules: ``fit`` (orchestration), ``glossy`` (a glossy object part by part and
``--model auto``), ``mixed`` (virtual lights by variable projection), ``probe``, ``paper``
(section 3.2), ``lobes`` (the one Blinn-Phong lobe, its gradient and the kernels),
``loss``, ``model`` (fit.npz and ``shade``), ``results``, ``data``, ``baselines``,
``cli``; docs/layout.md has the whole map.
"""


from .fit import FitOptions, fit
from .model import FittedModel, FittedObject, load_fit, shade, shade_arrays
from .results import FitResult, LightSet

__all__ = [
    "FitOptions",
    "FitResult",
    "FittedModel",
    "FittedObject",
    "LightSet",
    "fit",
    "load_fit",
    "shade",
    "shade_arrays",
]
