"""The material record of a scene and of Contract 1's ``meta.materials``: Lambert plus
modified Phong (``kd``, ``ks``, ``n``) and an emitted radiance, validated on
construction. The BRDF's kernels that use it live in ``radiosity.scene.materials``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from radiosity.formats.errors import InputError

__all__ = ["MAX_EXPONENT", "Material"]

MAX_EXPONENT = 1e6
"""Largest Phong exponent a material may have."""

FLOAT32_MAX = 3.4028234663852886e38
"""Largest value a float32 array (the solver's and the files') can hold."""

_ENERGY_TOLERANCE = 1e-6
_CHANNELS = ("red", "green", "blue")


@dataclass(frozen=True)
class Material:
    """A Lambert + modified Phong material; validated on construction.

    Attributes:
        name: how the scene calls it; used in error messages.
        diffuse: kd, RGB reflectance in [0, 1].
        specular: ks, RGB reflectance in [0, 1], with kd + ks <= 1 per channel.
        exponent: Phong exponent n, in [0, ``MAX_EXPONENT``].
        emission: emitted radiance, RGB, >= 0 (not bounded by 1).

    All numbers are stored as python floats. Raises ``InputError`` naming the
    material and the problem if a value is missing, not finite, out of range, or if
    kd + ks > 1 in a channel.
    """

    name: str
    diffuse: tuple[float, float, float]
    specular: tuple[float, float, float] = (0.0, 0.0, 0.0)
    exponent: float = 0.0
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for field, upper in (("diffuse", 1.0), ("specular", 1.0), ("emission", FLOAT32_MAX)):
            object.__setattr__(self, field, self._rgb(field, upper))
        object.__setattr__(self, "exponent", self._exponent())
        for channel, kd, ks in zip(_CHANNELS, self.diffuse, self.specular):
            if kd + ks > 1.0 + _ENERGY_TOLERANCE:
                raise self._error(
                    f"diffuse + specular = {kd + ks:.6g} in the {channel} channel is above 1, "
                    "so the material would reflect more light than it receives"
                )

    def _error(self, problem: str) -> InputError:
        return InputError(f"material {self.name!r}: {problem}")

    def _rgb(self, field: str, upper: float) -> tuple[float, float, float]:
        value = getattr(self, field)
        try:
            rgb = tuple(float(v) for v in value)
        except (TypeError, ValueError):
            raise self._error(
                f"{field} must be 3 numbers (red, green, blue), got {value!r}"
            ) from None
        if len(rgb) != 3:
            raise self._error(f"{field} must be 3 numbers (red, green, blue), got {len(rgb)}")
        for channel, v in zip(_CHANNELS, rgb):
            if not math.isfinite(v):
                raise self._error(f"{field} {channel} is {v}, not a finite number")
            if v < 0.0:
                raise self._error(f"{field} {channel} = {v:g} is negative")
            if v > upper:
                raise self._error(f"{field} {channel} = {v:g} is above {upper:g}")
        return rgb

    def _exponent(self) -> float:
        try:
            n = float(self.exponent)
        except (TypeError, ValueError):
            raise self._error(f"exponent must be a number, got {self.exponent!r}") from None
        if not math.isfinite(n):
            raise self._error(f"exponent is {n}, not a finite number")
        if n < 0.0:
            raise self._error(f"exponent = {n:g} is negative")
        if n > MAX_EXPONENT:
            raise self._error(f"exponent = {n:g} is above the maximum {MAX_EXPONENT:g}")
        return n

    @property
    def is_glossy(self) -> bool:
        """True if some specular channel is positive."""
        return any(v > 0.0 for v in self.specular)

    @property
    def is_emitter(self) -> bool:
        """True if some emission channel is positive."""
        return any(v > 0.0 for v in self.emission)

    @property
    def is_reflective(self) -> bool:
        """True if the material reflects any light (diffusely or glossily)."""
        return self.is_glossy or any(v > 0.0 for v in self.diffuse)

    def to_dict(self) -> dict:
        """The material as plain JSON-ready values (the name is the caller's key)."""
        return {
            "diffuse": list(self.diffuse),
            "specular": list(self.specular),
            "exponent": self.exponent,
            "emission": list(self.emission),
        }
