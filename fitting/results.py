"""The two records a fit passes between its steps: a set of lights and one object's fit.

``Lights`` is the one type for a set of virtual lights, of either kind, as every step
and every kernel of the fit takes them (the paper's directional lights are the case
w = 0). ``LightsFit`` is the lights with the per-vertex coefficients fitted to them. Both
are immutable: a step that changes a fit makes a new one (``dataclasses.replace``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["Lights", "LightsFit"]


class Lights(NamedTuple):
    """K lights of either kind (C-contiguous float64, as the numba kernels of
    ``fitting.lobes`` take them).

    pos       : (K, 4) (x, y, z, w): w = 0 directional (xyz a unit vector towards the
                light), w = 1 a point light at xyz
    rgb       : (K, 3) each light's colour (ones where the coefficients are per light)
    shininess : (K,) exponent per light
    """

    pos: np.ndarray
    rgb: np.ndarray
    shininess: np.ndarray

    @classmethod
    def of(cls, pos, rgb, shininess) -> Lights:
        """The lights of these arrays, made C-contiguous float64 of shapes (K, 4), (K, 3), (K,)."""
        return cls(np.ascontiguousarray(pos, np.float64).reshape(-1, 4),
                   np.ascontiguousarray(rgb, np.float64).reshape(-1, 3),
                   np.ascontiguousarray(shininess, np.float64).reshape(-1))

    @classmethod
    def none(cls) -> Lights:
        """No lights (a diffuse, glass or mirror object's)."""
        return cls(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0))


@dataclass(frozen=True, eq=False)
class LightsFit:
    """One object's fit: its lights and the per-vertex coefficients fitted to them.

    pos (K, 4), rgb (K, 3), shininess (K,): the lights (``lights()`` gives them as a ``Lights``)
    emitted (V, 3); specular (V, 3) shared or (V, K, 3) per light
    sq_error: the weighted squared error; iterations, evaluations: of the last refinement
    """

    pos: np.ndarray
    rgb: np.ndarray
    shininess: np.ndarray
    emitted: np.ndarray
    specular: np.ndarray
    sq_error: float
    iterations: int = 0
    evaluations: int = 0

    @property
    def n_lights(self):
        return len(self.pos)

    @property
    def per_light(self):
        return self.specular.ndim == 3

    def lights(self) -> Lights:
        return Lights.of(self.pos, self.rgb, self.shininess)
