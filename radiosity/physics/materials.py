"""The material record of a scene and of solution.npz's ``meta.materials``: Lambert plus
modified Phong (``kd``, ``ks``, ``n``), an optional Fresnel term and an emitted radiance,
validated on construction. The BRDF's kernels that use it live in
``radiosity.scene.material_kernels``.

Without Fresnel (``fresnel`` None, the files' key absent) the BRDF is

    f(wi, wo) = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha),

energy conserving for kd + ks <= 1. With Fresnel (``fresnel`` = Schlick's F0 per
channel, the files' key ``"fresnel": [r, g, b]``) the specular lobe is weighted by
Schlick's reflectance at the half vector and the diffuse part loses what the interface
reflects, both ways:

    f(wi, wo) = kd / pi * (21/20) b(cos_i) b(cos_o) + ks F(wi.h) (n + 2) / (2 pi) cos^n(alpha),
    F(c) = F0 + (1 - F0) (1 - c)^5,   b(c) = 1 - (1 - c)^5 = (1 - F(c)) / (1 - F0),

h = normalize(wi + wo). Both parts are symmetric in wi and wo (reciprocal). 21/20
normalises the diffuse part so its directional albedo is kd b(cos theta): kd at normal
incidence, 0 at grazing (2 int_0^1 b(mu) mu dmu = 20/21). ``ks`` is the interface's
scale (Mitsuba's ``specular_reflectance``, 1 for physics); the specular albedo is
ks (F0 S_n(theta) + (1 - F0) Q_n(theta)), S the lobe's albedo without Fresnel
(``specular_albedo``) and Q the same with the weight (1 - wi.h)^5
(``schlick_albedo``). Energy: a Fresnel material must satisfy, per channel and at every
incidence, kd b(cos theta) + ks (F0 S + (1 - F0) Q) <= 1 (``fresnel_kd_limit`` gives the
largest kd, ``fresnel_ks_limit`` the largest ks; the check is made on 129 incidences, to
1e-4); kd + ks <= 1 is not asked of it, and ks may exceed 1 (a fitted lobe's scale).

Why this form (measured by ``benchmarks/bench_material_mapping.py --parts fresnel``,
rows "fresnel_form" and "fresnel_rule"): Schlick's curve is within 0.036 of the exact
dielectric's for eta 1.49 (the plastics) and within 0.03 of Mitsuba's Cu, Ag and Au, 0.13
of its Al (the dip before grazing), so one RGB triple serves dielectrics, metals and
glTF alike at no cost in the kernels (6 columns and complex arithmetic for an exact
conductor would buy back less than the Phong lobe's own loss towards grazing: its
albedo falls as about cos theta, 5 to 6 times below a microfacet lobe's at 80 degrees).
Mitsuba's rough plastics' diffuse part has the (1 - F(cos_i))(1 - F(cos_o)) shape this
one has: its albedo's misfit over incidence falls from 0.07-0.11 (constant kd) to
0.01-0.06 in four plastics of five (0.061 to 0.068 in the fifth, GGX alpha 0.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from radiosity.files.errors import InputError

__all__ = [
    "FRESNEL_NORMALISATION",
    "MAX_EXPONENT",
    "MICROFACET_DISTRIBUTIONS",
    "MIRROR_EXPONENT",
    "GLASS_KINDS",
    "MICROFACET_KINDS",
    "Glass",
    "Material",
    "Microfacet",
    "NEAR_MIRROR_ALPHA",
    "fresnel_dielectric",
    "fresnel_kd_limit",
    "fresnel_ks_limit",
    "near_base",
    "schlick_albedo",
    "schlick_diffuse",
    "specular_albedo",
]

MAX_EXPONENT = 1e6
"""Largest Phong exponent a material may have."""

MIRROR_EXPONENT = 1e5
"""A material with no diffuse part and a Phong exponent this high or higher is a mirror
(a smooth conductor's stand-in): the displays draw what it reflects (``display.mirror``)."""

FLOAT32_MAX = 3.4028234663852886e38

NEAR_MIRROR_ALPHA = 0.03
"""A flat microfacet object at most this rough is a near mirror (a polished floor): the
displays may draw what it reflects from the scene in its plane (``display.mirror``), over
its own part (``near_base``)."""

NEAR_BASE_COSINE = 0.3  # a plastic's substrate is read from its grid's directions at least this far from grazing
"""Largest value a float32 array (the solver's and the files') can hold."""

_ENERGY_TOLERANCE = 1e-6
_FRESNEL_TOLERANCE = 1e-4  # the Fresnel energy check is made on a grid of incidences
_CHANNELS = ("red", "green", "blue")

FRESNEL_NORMALISATION = 21.0 / 20.0
"""The Fresnel diffuse part's factor: 1 / (2 int_0^1 (1 - (1 - mu)^5) mu dmu)."""


MICROFACET_KINDS = ("roughplastic", "roughconductor")
"""The microfacet models a material may name (Mitsuba 3's, with its parameters)."""
MICROFACET_DISTRIBUTIONS = ("ggx", "beckmann")
MIN_ALPHA = 1e-4
"""The smallest microfacet roughness a material may have (sharper lobes are mirrors)."""
MAX_ALPHA = 4.0
"""The largest microfacet roughness a material may have."""


@dataclass(frozen=True)
class Microfacet:
    """A microfacet model (Walter et al. 2007, as Mitsuba 3 defines it), validated on
    construction. The kernels evaluate it in ``radiosity.scene.microfacet_kernels``, the
    numpy oracle in ``radiosity.scene.microfacet``.

    Attributes:
        kind: ``"roughplastic"`` (a rough dielectric interface over a Lambertian
            substrate) or ``"roughconductor"``.
        distribution: ``"ggx"`` or ``"beckmann"`` (isotropic).
        alpha: the roughness, in [``MIN_ALPHA``, ``MAX_ALPHA``].
        eta: a plastic's relative index of refraction (interior over exterior, the same
            in each channel, positive and not 1); a conductor's real index per channel (>= 0).
        k: a conductor's absorption per channel (>= 0; eta + i k not 0); zeros for a plastic.
        specular_reflectance: the interface's scale per channel (>= 0; 1 for physics).
        diffuse_reflectance: a plastic's substrate reflectance in [0, 1] (zeros for a
            conductor); with a texture, the texture's brightest texel.
        nonlinear: a plastic's ``nonlinear`` flag (Mitsuba's: kd' = kd / (1 - kd R_int)).
    """

    kind: str
    distribution: str
    alpha: float
    eta: tuple[float, float, float]
    k: tuple[float, float, float] = (0.0, 0.0, 0.0)
    specular_reflectance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    diffuse_reflectance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nonlinear: bool = False

    def __post_init__(self) -> None:
        if self.kind not in MICROFACET_KINDS:
            raise ValueError(f"microfacet kind {self.kind!r}: expected one of {', '.join(MICROFACET_KINDS)}")
        if self.distribution not in MICROFACET_DISTRIBUTIONS:
            raise ValueError(f"microfacet distribution {self.distribution!r}: expected one of "
                             f"{', '.join(MICROFACET_DISTRIBUTIONS)}")
        try:
            alpha = float(self.alpha)
        except (TypeError, ValueError):
            raise ValueError(f"microfacet alpha must be a number, got {self.alpha!r}") from None
        if not (MIN_ALPHA <= alpha <= MAX_ALPHA):
            raise ValueError(f"microfacet alpha = {alpha:g} is outside [{MIN_ALPHA:g}, {MAX_ALPHA:g}]")
        object.__setattr__(self, "alpha", alpha)
        for field, upper in (("eta", FLOAT32_MAX), ("k", FLOAT32_MAX), ("specular_reflectance", FLOAT32_MAX),
                             ("diffuse_reflectance", 1.0)):
            object.__setattr__(self, field, _triple(f"microfacet {field}", getattr(self, field), upper))
        object.__setattr__(self, "nonlinear", bool(self.nonlinear))
        if self.kind == "roughplastic":
            if len(set(self.eta)) != 1 or not self.eta[0] > 0.0 or self.eta[0] == 1.0:
                raise ValueError(f"a rough plastic's eta must be one positive index other than 1, got {self.eta}")
            if any(self.k):
                raise ValueError("a rough plastic has no absorption k")
        else:
            if any(e == 0.0 and k == 0.0 for e, k in zip(self.eta, self.k)):
                raise ValueError("a conductor's index eta + i k must not be 0 in any channel")
            if any(self.diffuse_reflectance):
                raise ValueError("a conductor has no diffuse_reflectance")

    def to_dict(self) -> dict:
        """The model as plain JSON-ready values."""
        return {"kind": self.kind, "distribution": self.distribution, "alpha": self.alpha,
                "eta": list(self.eta), "k": list(self.k), "specular_reflectance": list(self.specular_reflectance),
                "diffuse_reflectance": list(self.diffuse_reflectance), "nonlinear": self.nonlinear}

    @classmethod
    def from_dict(cls, entry) -> Microfacet:
        """The model of a ``to_dict`` entry; raises ValueError naming what is wrong."""
        if not isinstance(entry, dict):
            raise ValueError(f"microfacet must be an object, got {type(entry).__name__}")
        known = {"kind", "distribution", "alpha", "eta", "k", "specular_reflectance", "diffuse_reflectance",
                 "nonlinear"}
        unknown = sorted(set(entry) - known)
        if unknown:
            raise ValueError(f"microfacet has unknown key(s) {', '.join(map(repr, unknown))}")
        missing = [key for key in ("kind", "distribution", "alpha", "eta") if key not in entry]
        if missing:
            raise ValueError(f"microfacet has no {', '.join(map(repr, missing))}")
        if not isinstance(entry.get("nonlinear", False), bool):
            raise ValueError("microfacet 'nonlinear' must be true or false")
        return cls(**entry)


GLASS_KINDS = ("dielectric", "thindielectric", "roughdielectric")
"""The glass models a material may name (Mitsuba 3's, with its parameters)."""


@dataclass(frozen=True)
class Glass:
    """A dielectric interface that reflects and transmits (Mitsuba 3's models), validated
    on construction. The kernels evaluate it in ``radiosity.scene.glass_kernels``, the numpy
    oracle in ``radiosity.scene.glass``.

    Attributes:
        kind: ``"dielectric"`` (a smooth interface between the outside and the inside of a
            closed shape, its normals pointing out), ``"thindielectric"`` (a thin smooth
            sheet: light passes straight through, the reflections between its two faces
            summed) or ``"roughdielectric"`` (a microfacet interface, Walter et al. 2007).
        eta: the relative index of refraction, inside over outside (positive, not 1).
        distribution: ``"ggx"`` or ``"beckmann"`` (a rough dielectric's; kept for the others).
        alpha: a rough dielectric's roughness in [``MIN_ALPHA``, ``MAX_ALPHA``]; 0 for the
            smooth kinds.
        specular_reflectance, specular_transmittance: the scales of the reflected and the
            transmitted light per channel (in [0, 1]; 1 for physics).
    """

    kind: str
    eta: float
    distribution: str = "beckmann"
    alpha: float = 0.0
    specular_reflectance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    specular_transmittance: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        if self.kind not in GLASS_KINDS:
            raise ValueError(f"glass kind {self.kind!r}: expected one of {', '.join(GLASS_KINDS)}")
        if self.distribution not in MICROFACET_DISTRIBUTIONS:
            raise ValueError(f"glass distribution {self.distribution!r}: expected one of "
                             f"{', '.join(MICROFACET_DISTRIBUTIONS)}")
        for field in ("eta", "alpha"):
            try:
                object.__setattr__(self, field, float(getattr(self, field)))
            except (TypeError, ValueError):
                raise ValueError(f"glass {field} must be a number, got {getattr(self, field)!r}") from None
        if not (math.isfinite(self.eta) and 0.0 < self.eta <= 1e3 and self.eta != 1.0):
            raise ValueError(f"glass eta = {self.eta:g} must be a positive index of refraction other than 1 "
                             "(at most 1000)")
        if self.kind == "roughdielectric":
            if not (MIN_ALPHA <= self.alpha <= MAX_ALPHA):
                raise ValueError(f"glass alpha = {self.alpha:g} is outside [{MIN_ALPHA:g}, {MAX_ALPHA:g}]")
        elif self.alpha != 0.0:
            raise ValueError(f"a smooth glass ({self.kind}) has alpha 0, got {self.alpha:g}")
        for field in ("specular_reflectance", "specular_transmittance"):
            object.__setattr__(self, field, _triple(f"glass {field}", getattr(self, field), 1.0))

    def to_dict(self) -> dict:
        """The model as plain JSON-ready values."""
        return {"kind": self.kind, "eta": self.eta, "distribution": self.distribution, "alpha": self.alpha,
                "specular_reflectance": list(self.specular_reflectance),
                "specular_transmittance": list(self.specular_transmittance)}

    @classmethod
    def from_dict(cls, entry) -> Glass:
        """The model of a ``to_dict`` entry; raises ValueError naming what is wrong."""
        if not isinstance(entry, dict):
            raise ValueError(f"glass must be an object, got {type(entry).__name__}")
        known = {"kind", "eta", "distribution", "alpha", "specular_reflectance", "specular_transmittance"}
        unknown = sorted(set(entry) - known)
        if unknown:
            raise ValueError(f"glass has unknown key(s) {', '.join(map(repr, unknown))}")
        missing = [key for key in ("kind", "eta") if key not in entry]
        if missing:
            raise ValueError(f"glass has no {', '.join(map(repr, missing))}")
        return cls(**entry)


def _triple(field: str, value, upper: float) -> tuple[float, float, float]:
    """Three finite numbers in [0, upper]; raises ValueError naming ``field``."""
    try:
        rgb = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{field} must be 3 numbers (red, green, blue), got {value!r}") from None
    if len(rgb) != 3:
        raise ValueError(f"{field} must be 3 numbers (red, green, blue), got {len(rgb)}")
    for channel, v in zip(_CHANNELS, rgb):
        if not math.isfinite(v) or v < 0.0 or v > upper:
            raise ValueError(f"{field} {channel} = {v!r} is not in [0, {upper:g}]")
    return rgb


@dataclass(frozen=True)
class Material:
    """A Lambert + modified Phong material; validated on construction.

    Attributes:
        name: how the scene calls it; used in error messages.
        diffuse: kd, RGB reflectance in [0, 1].
        specular: ks, RGB reflectance in [0, 1], with kd + ks <= 1 per channel (with
            Fresnel: the interface's scale, >= 0, bounded by the energy check).
        exponent: Phong exponent n, in [0, ``MAX_EXPONENT``].
        emission: emitted radiance, RGB, >= 0 (not bounded by 1).
        fresnel: None (no Fresnel term), or Schlick's F0, RGB in [0, 1]: the specular
            lobe is weighted by F(wi.h) and the diffuse part by the light the interface
            lets through (see the module's docstring); needs a positive ks.
        microfacet: None (the material is the Phong model above), or the ``Microfacet``
            model the path tracer evaluates; the Phong fields then hold its stand-in
            (``radiosity.scene.microfacet.phong_lobe_for``), which the stages that draw
            Phong lobes use.
        glass: None, or the ``Glass`` interface the transport traces through (reflecting
            and transmitting); such a material has no Phong part (kd = ks = 0), reflects
            nothing the per-vertex stages store, and no microfacet model.

    All numbers are stored as python floats. Raises ``InputError`` naming the
    material and the problem if a value is missing, not finite, out of range, or if
    the material reflects more than it receives: kd + ks > 1 in a channel without
    Fresnel, kd above ``fresnel_kd_limit`` with it.
    """

    name: str
    diffuse: tuple[float, float, float]
    specular: tuple[float, float, float] = (0.0, 0.0, 0.0)
    exponent: float = 0.0
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fresnel: tuple[float, float, float] | None = None
    microfacet: Microfacet | None = None
    glass: Glass | None = None

    def __post_init__(self) -> None:
        if self.glass is not None and not isinstance(self.glass, Glass):
            try:
                object.__setattr__(self, "glass", Glass.from_dict(self.glass))
            except (TypeError, ValueError) as exc:
                raise self._error(str(exc)) from None
        if self.microfacet is not None and not isinstance(self.microfacet, Microfacet):
            try:
                object.__setattr__(self, "microfacet", Microfacet.from_dict(self.microfacet))
            except (TypeError, ValueError) as exc:
                raise self._error(str(exc)) from None
        ks_upper = 1.0 if self.fresnel is None else FLOAT32_MAX  # with Fresnel: the energy check bounds it
        for field, upper in (("diffuse", 1.0), ("specular", ks_upper), ("emission", FLOAT32_MAX)):
            object.__setattr__(self, field, self._rgb(field, upper))
        object.__setattr__(self, "exponent", self._exponent())
        if self.glass is not None and (self.is_reflective or self.microfacet is not None or self.fresnel is not None):
            raise self._error("a glass material has no diffuse, specular, fresnel or microfacet part")
        if self.fresnel is not None:
            object.__setattr__(self, "fresnel", self._rgb("fresnel", 1.0))
            self._check_fresnel_energy()
            return
        for channel, kd, ks in zip(_CHANNELS, self.diffuse, self.specular):
            if kd + ks > 1.0 + _ENERGY_TOLERANCE:
                raise self._error(
                    f"diffuse + specular = {kd + ks:.6g} in the {channel} channel is above 1, "
                    "so the material would reflect more light than it receives"
                )

    def _check_fresnel_energy(self) -> None:
        if not self.is_glossy:
            raise self._error("fresnel needs a positive specular (the interface's reflectance scale)")
        limit = fresnel_kd_limit(self.specular, self.fresnel, self.exponent)
        for channel, kd, top in zip(_CHANNELS, self.diffuse, limit):
            if top < 0.0:
                raise self._error(
                    f"specular with fresnel reflects more than 1 at some incidence in the {channel} channel"
                )
            if kd > top + _FRESNEL_TOLERANCE:
                raise self._error(
                    f"diffuse {channel} = {kd:.6g} is above {top:.6g}, the most this specular and fresnel "
                    "leave at some incidence, so the material would reflect more light than it receives"
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
    def is_mirror(self) -> bool:
        """True for a perfect mirror: glossy, no diffuse part, exponent >= MIRROR_EXPONENT, no
        microfacet model of its own (a smooth conductor's stand-in)."""
        return (self.is_glossy and not any(self.diffuse) and self.exponent >= MIRROR_EXPONENT
                and self.microfacet is None)

    @property
    def has_grid(self) -> bool:
        """True if the solver gathers the material's directional radiance into a grid: glossy
        and not a perfect mirror (a mirror's appearance is what it reflects, drawn by the
        displays; it stores its diffuse part, none)."""
        return self.is_glossy and not self.is_mirror

    @property
    def is_glass(self) -> bool:
        """True if the material is a glass interface (``glass``)."""
        return self.glass is not None

    @property
    def is_reflective(self) -> bool:
        """True if the material reflects any light (diffusely or glossily)."""
        return self.is_glossy or any(v > 0.0 for v in self.diffuse)

    def to_dict(self) -> dict:
        """The material as plain JSON-ready values (the name is the caller's key); the key
        ``fresnel`` only if the material has one, so files without Fresnel stay as they were;
        likewise ``microfacet`` and ``glass``."""
        out = {
            "diffuse": list(self.diffuse),
            "specular": list(self.specular),
            "exponent": self.exponent,
            "emission": list(self.emission),
        }
        if self.fresnel is not None:
            out["fresnel"] = list(self.fresnel)
        if self.microfacet is not None:
            out["microfacet"] = self.microfacet.to_dict()
        if self.glass is not None:
            out["glass"] = self.glass.to_dict()
        return out


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


# --- Fresnel (Schlick) ---------------------------------------------------------------

_PHI_X, _PHI_W = np.polynomial.legendre.leggauss(24)


def _schlick_albedo_rows(exponent: float, cos_theta: np.ndarray, power: float = 5.0) -> np.ndarray:
    """Q_n(theta) for each cos_theta (see ``schlick_albedo``), float64 (N,); ``power`` 0
    gives S_n(theta) (the tests' check of the rule).

    In the lobe's frame (alpha from the mirror direction, phi about it, phi = 0 towards
    the normal): wi.z = A + B cos phi and wi.wo = cos alpha cos 2 theta + sin alpha sin
    2 theta cos phi. With s = cos^(n+1) alpha the lobe's measure is (n + 2) / ((n + 1) 2
    pi) ds dphi. The s integral is split at the kink s_k = sin^(n+1) theta (below it
    part of the circle about the mirror direction is under the horizon, phi0 =
    arccos(-A/B) < pi), each part mapped onto ``_kink_rule``'s nodes (s = s_k (1 - w^2)
    below, s = s_k + (1 - s_k)(1 - w^2) above), and the phi integral over [0, phi0] is
    a 24-point Gauss-Legendre rule (the integrand is smooth there).
    """
    n = exponent
    out = np.empty(len(cos_theta))
    one_minus_w2 = np.exp(_LOG_ONE_MINUS_W2)
    for i, c in enumerate(cos_theta):
        c = float(min(max(c, 0.0), 1.0))
        s_theta = math.sqrt(max(0.0, 1.0 - c * c))
        s_k = s_theta ** (n + 1.0)
        total = 0.0
        for lo, span, u in ((0.0, s_k, one_minus_w2), (s_k, 1.0 - s_k, one_minus_w2)):
            if span <= 0.0:
                continue
            s = lo + span * u
            s = np.where(lo > 0.0, np.minimum(s, 1.0), s)
            log_s = np.log(np.maximum(s, 1e-300))
            cos_a = np.exp(log_s / (n + 1.0))
            sin_a = np.sqrt(-np.expm1(2.0 * log_s / (n + 1.0)))
            a = cos_a * c
            b = sin_a * s_theta
            with np.errstate(divide="ignore", invalid="ignore"):
                phi0 = np.where(b > a, np.arccos(np.clip(-a / np.where(b > 0, b, 1.0), -1.0, 1.0)), math.pi)
            phi = 0.5 * phi0[:, None] * (_PHI_X[None, :] + 1.0)
            cos_phi = np.cos(phi)
            wiz = np.maximum(a[:, None] + b[:, None] * cos_phi, 0.0)
            dot = cos_a[:, None] * (2.0 * c * c - 1.0) + (sin_a * 2.0 * s_theta * c)[:, None] * cos_phi
            cos_h = np.sqrt(np.clip(0.5 * (1.0 + dot), 0.0, 1.0))
            inner = 0.5 * phi0 * ((_PHI_W[None, :] * (1.0 - cos_h) ** power * wiz).sum(axis=1))
            total += span * float(_W_WEIGHTS @ inner)
        out[i] = (n + 2.0) / ((n + 1.0) * math.pi) * total
    return out


def schlick_albedo(exponent: float, cos_theta) -> np.ndarray:
    """Q_n(theta) = int (1 - wi.h)^5 (n + 2) / (2 pi) max(0, cos alpha)^n cos(theta_i) dwi
    over the upper hemisphere, for wo at each cos_theta; float64 (N,).

    With Schlick's F the specular albedo of the normalised lobe (ks = 1) is F0 S + (1 -
    F0) Q. Deterministic quadrature (``_schlick_albedo_rows``); it gives
    ``specular_albedo`` to 1e-7 when the weight is left out (tests check), and Q is 0 at
    normal incidence only in the limit n -> infinity.
    """
    cos_theta = np.atleast_1d(np.asarray(cos_theta, dtype=np.float64))
    return _schlick_albedo_rows(float(exponent), cos_theta)


def schlick_diffuse(cos_theta):
    """b(c) = 1 - (1 - c)^5: the Fresnel diffuse part's directional albedo over kd, float64."""
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    return 1.0 - (1.0 - c) ** 5


_CHECK_COSINES = np.linspace(0.0, 1.0, 129)
_LIMIT_MARGIN = 1e-3  # the limits take Q this much larger: its peak may fall between the grid's points
# (S peaks at normal incidence, on the grid)


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric interface, exact (Walter 2007, eq. 22).

    cos_i: cosine of the incident angle (its absolute value is used); eta: the relative
    index (transmitted side over incident side). Total internal reflection gives 1.
    Arrays broadcast; float64.
    """
    c = np.abs(np.asarray(cos_i, dtype=np.float64))
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(g2 > 0.0, np.nan_to_num(f, nan=1.0), 1.0)


def near_base(microfacet, directions, reduce):
    """(its own part per vertex, eta) of a near mirror's radiance grid (V, D, 3) at local
    ``directions`` (D, 3), reduced over directions by ``reduce`` (``reduce(function)`` ->
    (V, 3), the function taking a chunk of vertices' grids (v, D, 3) to (v, 3): chunked by
    the caller). For a plastic (``microfacet``: a ``Microfacet`` or its dict) the substrate
    D, which leaves the interface as 1 - F(n . w, eta): its grid holds D (1 - F) plus the
    interface's reflection, which only adds, so D is the least of radiance / (1 - F) over
    the directions at least ``NEAR_BASE_COSINE`` from grazing, and a display draws D (1 - F)
    at the pixel's view. (The least radiance itself would be the substrate at a grazing
    view, where 1 - F is small: veach_mi's plates drew almost black.) For a conductor (no
    substrate) the least radiance, eta 0."""
    model = microfacet if isinstance(microfacet, Microfacet) else Microfacet.from_dict(microfacet)
    if model.kind not in ("plastic", "roughplastic"):
        return reduce(lambda chunk: np.min(chunk, axis=1)), 0.0
    eta = float(model.eta[0])
    cos = np.asarray(directions, np.float64)[:, 2]
    ok = cos >= NEAR_BASE_COSINE
    scale = 1.0 / (1.0 - fresnel_dielectric(cos[ok], eta))
    return reduce(lambda chunk: np.min(chunk[:, ok] * scale[None, :, None], axis=1)), eta


@lru_cache(maxsize=256)
def _albedo_curves(exponent: float) -> tuple[np.ndarray, np.ndarray]:
    """(S, Q) on ``_CHECK_COSINES``, remembered per exponent."""
    return specular_albedo(exponent, _CHECK_COSINES), schlick_albedo(exponent, _CHECK_COSINES)


def fresnel_ks_limit(f0, exponent: float) -> np.ndarray:
    """The largest ks (3,) per channel whose specular albedo ks (F0 S + (1 - F0) Q) is <= 1
    at every incidence (kd = 0), Q taken 1e-3 larger on the check's grid so that it
    stays <= 1 between the grid's points too (tests sample 401). float64 (3,)."""
    s, q = _albedo_curves(float(exponent))
    f0 = np.asarray(f0, dtype=np.float64)[:, None]
    return 1.0 / np.maximum((f0 * s + (1.0 - f0) * q * (1.0 + _LIMIT_MARGIN)).max(axis=1), 1e-300)


def fresnel_kd_limit(ks, f0, exponent: float) -> np.ndarray:
    """The largest kd (3,) per channel such that kd b(cos theta) + ks (F0 S + (1 - F0) Q)
    <= 1 at every incidence of a 129-point grid in cos theta, Q taken 1e-3 larger as in
    ``fresnel_ks_limit`` (the specular albedo at
    grazing must itself be <= 1: a negative limit says it is not). float64 (3,)."""
    s, q = _albedo_curves(float(exponent))
    ks = np.asarray(ks, dtype=np.float64)[:, None]
    f0 = np.asarray(f0, dtype=np.float64)[:, None]
    specular = ks * (f0 * s + (1.0 - f0) * q * (1.0 + _LIMIT_MARGIN))  # (3, A)
    b = schlick_diffuse(_CHECK_COSINES)
    with np.errstate(divide="ignore"):
        room = np.where(b > 0.0, (1.0 - specular) / np.where(b > 0.0, b, 1.0), np.inf)
    limit = room.min(axis=1)
    worst = specular.max(axis=1)
    return np.where(worst > 1.0 + _FRESNEL_TOLERANCE, -1.0, np.maximum(limit, 0.0))
