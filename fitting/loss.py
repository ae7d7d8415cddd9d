"""The fitters' loss weights: "linear" (every sample's error counts as it is) or
"relative" (1 / (eps + L)^2, so an error counts relative to the radiance it is in, as
a viewer's eye, adapted to brightness, sees it; eps is a small fraction of the mean
radiance so black regions do not dominate). Both multiply the sample weights (area x
solid angle).
"""

from __future__ import annotations

import numpy as np

from .options import LOSSES

RELATIVE_FLOOR = 0.05  # eps of the relative loss, as a fraction of the mean radiance


def loss_weights(data, loss, mean=None):
    """(V, D, 3) loss weights, or None for the linear loss; ``mean``: the object's mean
    radiance (sum w L / 3) where ``data`` is a block of it (default: of ``data``)."""
    if loss == "linear":
        return None
    if loss == "relative":
        if mean is None:
            mean = float(np.sum(data.weights[:, :, None] * data.radiance) / 3.0)
        eps = RELATIVE_FLOOR * mean if mean > 0 else 1.0
        return 1.0 / (eps + data.radiance) ** 2
    raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")
