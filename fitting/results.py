"""The typed results that pass between the steps of a fit: a set of lights, a fit.

Both are frozen: a step that changes a result makes a new one (``dataclasses.replace``,
``LightSet.extended``). Arrays are float64 on the way in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lobes import Lights

__all__ = ["FitResult", "LightSet"]


@dataclass(frozen=True, eq=False)
class LightSet:
    """K directional virtual lights.

    light_dirs : (K, 3) float64 unit vectors towards each light (world)
    light_rgb  : (K, 3) float64 each light's colour
    shininess  : (K,) float64 each light's exponent (all equal in the paper's model)
    """

    light_dirs: np.ndarray
    light_rgb: np.ndarray
    shininess: np.ndarray

    def __post_init__(self):
        dirs = np.asarray(self.light_dirs, np.float64).reshape(-1, 3)
        rgb = np.asarray(self.light_rgb, np.float64).reshape(-1, 3)
        shininess = np.asarray(self.shininess, np.float64).reshape(-1)
        if not len(dirs) == len(rgb) == len(shininess):
            raise ValueError(
                f"LightSet: {len(dirs)} directions, {len(rgb)} colours and {len(shininess)} exponents; "
                "expected one of each per light"
            )
        object.__setattr__(self, "light_dirs", dirs)
        object.__setattr__(self, "light_rgb", rgb)
        object.__setattr__(self, "shininess", shininess)

    @classmethod
    def empty(cls) -> LightSet:
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))

    @property
    def n_lights(self) -> int:
        return len(self.light_dirs)

    def __len__(self) -> int:
        return self.n_lights

    def extended(self, light_dirs, light_rgb, shininess) -> LightSet:
        """These lights followed by more: (k, 3), (k, 3), (k,) or one light's (3,), (3,), number."""
        count = np.size(light_dirs) // 3
        more = LightSet(light_dirs, light_rgb, np.broadcast_to(np.asarray(shininess, np.float64), (count,)))
        return LightSet(
            np.vstack([self.light_dirs, more.light_dirs]),
            np.vstack([self.light_rgb, more.light_rgb]),
            np.concatenate([self.shininess, more.shininess]),
        )

    def kernel_arrays(self) -> Lights:
        """The lights as the numba kernels of ``fitting.lobes`` take them."""
        return Lights(
            np.ascontiguousarray(self.light_dirs),
            np.ascontiguousarray(self.light_rgb),
            np.ascontiguousarray(self.shininess),
        )


@dataclass(frozen=True, eq=False)
class FitResult:
    """One object's fit: lights and per-vertex coefficients.

    lights      : the ``LightSet``
    emitted     : (V, 3) float64 per-vertex emitted colour
    specular    : (V, 3) float64 per-vertex specular coefficient
    sq_error    : the weighted squared error the fit minimised (sum w (L - model)^2)
    search      : the exponent search, ((exponent, sq_error), ...) in evaluation order
    iterations  : L-BFGS iterations of the refinement (None: not refined)
    evaluations : objective evaluations of the refinement (None: not refined)
    """

    lights: LightSet
    emitted: np.ndarray
    specular: np.ndarray
    sq_error: float = 0.0
    search: tuple[tuple[float, float], ...] = ()
    iterations: int | None = None
    evaluations: int | None = None

    @property
    def light_dirs(self) -> np.ndarray:
        return self.lights.light_dirs

    @property
    def light_rgb(self) -> np.ndarray:
        return self.lights.light_rgb

    @property
    def shininess(self) -> np.ndarray:
        return self.lights.shininess

    @property
    def n_lights(self) -> int:
        return self.lights.n_lights
