"""The fitting stage: virtual lights fitted to a solution (fit.npz, docs/formats.md).

    fit(solution, FitOptions(...)) -> FittedModel     fit.npz via FittedModel.save, load_fit
    shade(model, name, world_dirs)                    the one reference of the shading formula
    Lights, LightsFit                                 a set of lights; one object's fit of them

Modules: ``fit`` (orchestration), ``options`` (``FitOptions`` and the words of the
flags), ``glossy`` (a glossy object part by part and ``--model auto``: every model, the
paper's included), ``lights`` (how many virtual lights, fitted how), ``mixed``
(virtual lights by variable projection), ``probe``, ``paper`` (section 3.2), ``lobes``
(the one Blinn-Phong lobe, its gradient and the kernels), ``loss``, ``model`` (fit.npz
and ``shade``), ``results``, ``data``, ``baselines``, ``cli``; docs/layout.md has the
whole map.

Each public name is imported from its module the first time it is asked for, so that
importing the package (as the ``vlights`` command does to build its parser) loads
neither scipy nor numba.
"""

import importlib

_HOMES = {
    "FitOptions": "options",
    "fit": "fit",
    "FittedModel": "model",
    "FittedObject": "model",
    "load_fit": "model",
    "shade": "model",
    "shade_arrays": "model",
    "Lights": "results",
    "LightsFit": "results",
}

__all__ = sorted(_HOMES)


def __getattr__(name):
    if name not in _HOMES:
        raise AttributeError(f"module 'fitting' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"fitting.{_HOMES[name]}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_HOMES))
