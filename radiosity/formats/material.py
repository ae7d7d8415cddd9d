"""The material record of a scene and of Contract 1's ``meta.materials``: Lambert plus
modified Phong (``kd``, ``ks``, ``n``) and an emitted radiance, validated on
construction. The BRDF's kernels that use it live in ``radiosity.scene.materials``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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


def _kink_rule(points: int, ratio: float, panels: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature for int_0^1 g(w) 2w dw, g analytic inside (0, 1): (log(1 - w^2), weights).

    Each half of [0, 1] is cut into panels shrinking geometrically (by ``ratio``)
    towards its end, each panel with ``points`` Gauss-Legendre points; this
    converges exponentially for integrands that are singular at w = 1 like
    (1 - w)^p and nearly singular at w = 0. The nodes are returned as
    log(1 - w^2), computed without rounding near either end; the weights include
    the 2w Jacobian.
    """
    x, w = np.polynomial.legendre.leggauss(points)
    edges = 0.5 * np.concatenate(([0.0], ratio ** np.arange(panels, -1, -1, dtype=np.float64)))
    half = 0.5 * np.diff(edges)[:, None]
    t = (edges[:-1, None] + half * (1.0 + x)).ravel()  # distance from the end, in (0, 1/2)
    t_weights = (half * w).ravel()
    log_one_minus_w2 = np.concatenate((np.log1p(-t * t), np.log(t * (2.0 - t))))
    weights = np.concatenate((2.0 * t * t_weights, 2.0 * (1.0 - t) * t_weights))
    return log_one_minus_w2, weights


# Quadrature for the clipped part of the specular albedo (see specular_albedo):
# absolute error below 1e-12 for exponents 0 to MAX_EXPONENT, at all angles.
_LOG_ONE_MINUS_W2, _W_WEIGHTS = _kink_rule(points=16, ratio=0.25, panels=24)


def specular_albedo(exponent: float, cos_theta: np.ndarray) -> np.ndarray:
    """Directional albedo of the normalised lobe (ks = 1) for wo at cos_theta, float64 (N,).

    S = (n+2)/(2 pi) * int cos^n(alpha) Phi(alpha) sin(alpha) dalpha over [0, pi/2],
    where Phi = int max(0, A + B cos phi) dphi, A = cos alpha cos theta and
    B = sin alpha sin theta. With s = cos^(n+1) alpha the alpha integral is
    1/(n+1) * int_0^1 Phi ds. Above the kink s_k = sin^(n+1) theta (A >= B: the
    whole circle about the mirror direction is above the horizon) Phi = 2 pi A and
    the integral is closed form: S_above = cos theta (1 - sin^(n+2) theta). Below
    it Phi = 2 (A phi0 + B sin phi0), phi0 = arccos(-A/B); the substitution
    s = s_k (1 - w^2) removes the square-root behaviour at the kink (w = 0), and
    ``_kink_rule`` handles the s^(1/(n+1)) singularity at s = 0 (w = 1).
    """
    n = exponent
    c = cos_theta[:, None]
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    # e = 1 - (1 - w^2)^(2/(n+1)), so cos^2 alpha = sin^2 theta (1 - e) and
    # sin^2 alpha = cos^2 theta + sin^2 theta e, both without cancellation.
    e = -np.expm1(2.0 / (n + 1.0) * _LOG_ONE_MINUS_W2)
    a = c * np.sqrt(1.0 - e)  # A / sin theta
    b = np.sqrt(c * c + s * s * e)  # B / sin theta; > 0 at every node since e > 0
    phi0 = np.arccos(np.clip(-a / b, -1.0, 0.0))
    clipped = (_W_WEIGHTS * (a * phi0 + b * np.sin(phi0))).sum(axis=1)
    sin_pow = s[:, 0] ** (n + 2.0)
    return cos_theta * (1.0 - sin_pow) + sin_pow * (n + 2.0) / ((n + 1.0) * math.pi) * clipped


def srgb_to_linear(c):
    """sRGB-encoded values in [0, 1] as linear ones (the IEC 61966-2-1 curve), float64."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
