"""The fitting stage: virtual lights fitted to a solution (Contract 2).

    fit(solution, FitOptions(...)) -> FittedModel     fit.npz via FittedModel.save
    shade(model, name, world_dirs)                    the one reference of the shading formula
"""

from .fit import FitOptions, fit
from .model import FittedModel, FittedObject, load_fit, shade, shade_arrays

__all__ = ["FitOptions", "FittedModel", "FittedObject", "fit", "load_fit", "shade", "shade_arrays"]
