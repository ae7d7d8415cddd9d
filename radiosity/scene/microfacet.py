"""Mitsuba 3's rough materials in numpy, and the modified-Phong lobe that stands in for each.

Reference BRDFs (written from Walter et al. 2007, "Microfacet models for refraction
through rough surfaces", and Mitsuba 3's documentation of ``roughplastic``,
``roughconductor``, ``plastic`` and ``conductor`` for the parameters and defaults):

    f_s(wi, wo) = F(wi.h) D(h) G1(wi, h) G1(wo, h) / (4 cos(theta_i) cos(theta_o)),
    h = normalize(wi + wo),

with D the GGX or Beckmann normal distribution of roughness ``alpha`` (isotropic),
G1 Smith's masking (exact for both: GGX's closed form, Beckmann's with erf), F the
exact unpolarised Fresnel reflectance (dielectric of relative index eta for plastic,
conductor of complex index eta + i k for metals). ``roughplastic`` adds Mitsuba's
diffuse substrate under the rough dielectric interface:

    f_d(wi, wo) = kd' / pi * t(cos theta_i) t(cos theta_o) / eta^2,
    kd' = kd / (1 - R_int)   (kd / (1 - kd R_int) with ``nonlinear``),

t(mu) = the rough interface's transmittance at mu (Walter's single-scattering BTDF
integrated: (1 - F(wi.m)) G1(wt, m) over the visible normals m, wt refracted; not 1 - R,
which would count the light the masking loses), R_int = the interface's hemispherical
albedo seen from inside (relative index 1/eta), both tabulated on 64 cosines as Mitsuba
3 does (t interpolated linearly, R_int = 2 mean(R(mu) mu) over the table). ``plastic`` is the same with a smooth interface: t = 1 - F, R_int the exact
hemispherical Fresnel albedo 2 int F(mu, 1/eta) mu dmu (Mitsuba uses a polynomial fit
of it). Defaults as Mitsuba's: int_ior 1.49 (polypropylene), ext_ior 1.000277 (air),
diffuse_reflectance 0.5, specular_reflectance 1, alpha 0.1, distribution beckmann;
conductors ``material="none"`` (eta 0, k 1: a perfect mirror) or a named metal from
``METALS`` (RGB eta, k as Mitsuba 3's ``scalar_rgb`` variant uses them, read from
Mitsuba itself by ``benchmarks/mitsuba_materials.py`` into ``data/mitsuba_metals.json``).

Conventions as in ``radiosity.scene.material_kernels``: local frame (z the normal), wi and wo
unit vectors pointing away from the surface, arrays of shape (..., 3), BRDF values
without the cosine (Mitsuba's ``eval`` returns f cos(theta_o)).

The mapping, ``phong_lobe_for(kind, distribution, alpha, **params)``, gives the
modified-Phong (kd, ks, n) of ``radiosity.scene.material_kernels`` by this rule:

- n(alpha) = ``phong_exponent(distribution, alpha)`` = c / alpha^2 + d + e alpha^2
  (``RULE``), 0 from its first root on (alpha about 0.74 for GGX, 0.61 for Beckmann:
  lobes broader than Phong's broadest, the cosine). Measured by
  ``benchmarks/bench_material_mapping.py --parts rule``: per alpha (13 values in
  [0.01, 1]) and incidence (0 to 85 degrees), the exponent whose lobe (f cos, the
  radiance a viewer sees from a small light moving about the mirror direction) has the
  same half-maximum solid angle as the microfacet lobe's (F = 1); their log mean over
  incidence weighted by sin(2 theta), the density of a highlight's incidence when light
  and viewer are independent uniform directions; then n alpha^2 fitted by c + d alpha^2
  + e alpha^4 in relative least squares (within 0.5 % where n alpha^2 > 0.05). GGX: c =
  1.368, d = -3.261, e = 1.384; Beckmann: c = 0.818, d = -3.014, e = 2.183. The single n
  is a compromise: the microfacet lobe narrows across the plane of incidence as the
  incidence grows (for small alpha n alpha^2 = 0.80 at normal incidence, 1.18 at 45,
  1.67 at 60, 3.2 at 75 degrees for GGX; 0.49, 0.70, 1.0, 1.9 for Beckmann), so the
  mapped lobe is about 25 % narrower (radius) than the microfacet one at normal incidence,
  7 % at 45 degrees, and wider beyond 55. The user's guess 2/alpha^2 - 2 is 1.5 (GGX)
  to 2.4 (Beckmann) times the rule at small alpha: too sharp except at grazing
  incidence; the glTF loader's (2/alpha^2 - 2)/4 is 2.7 (GGX) and 1.6 (Beckmann) times
  too broad (glTF's roughness is GGX's).
- Fresnel (the rule for every microfacet material): the lobe gets Schlick's term
  (``radiosity.physics.materials``) with F0 the exact reflectance at normal incidence
  (``normal_reflectance``: the dielectric's for plastics, the conductor's per channel
  for metals); ks, the lobe's scale, is the least-squares fit of its specular albedo ks
  (F0 S_n + (1 - F0) Q_n)(theta) to the microfacet term's (times specular_reflectance)
  over incidence, weighted by sin 2 theta as the exponent is, at most what keeps that
  albedo <= 1 (``fresnel_ks_limit``); kd is the fit of kd b(theta) to the diffuse
  term's albedo (plastic; 0 for conductors), at most ``fresnel_kd_limit``. ks comes out
  above 1 (2.4 to 2.8 for the plastics, 1.0 to 1.4 for the metals): the Phong lobe's
  albedo falls as about cos theta where the microfacet lobe's does not, and the fit
  makes up part of it. The price: an oblique highlight comes out too bright on the
  plastics at 30 degrees and too dim at 60 (no single ks makes a lobe whose albedo falls
  as the cosine right at both); ``bench_material_mapping.py --parts sphere`` measures the
  power ratio Phong / reference per material and incidence.
- Without Fresnel (``fresnel=False``, kept for comparison): ks the fit of a constant ks
  S_n(theta), kd of a constant, both scaled down if kd + ks would exceed 1; matching at
  normal incidence only leaves oblique highlights dim. ``benchmarks/validate_mitsuba.py``
  measures how near Mitsuba 3's converged images the rule in use comes (RESULTS.md).
- smooth ``plastic`` and ``conductor``: n = MAX_EXPONENT (the nearest to a mirror the
  material model holds), ks fitted as above.

What the rule cannot hold (measured by ``bench_material_mapping.py --parts fresnel``):
the Phong lobe's albedo falls towards grazing as about cos theta, so even with Fresnel
a plastic's specular albedo at 80 degrees is 0.12-0.20 where the microfacet one is
0.2-0.39, and a metal's 0.18-0.22
where the microfacet one is 0.6-0.83 (the metals gain little: their F is nearly flat);
the microfacet lobe's off-specular peak and its anisotropy at oblique incidence; GGX's
long tail, which carries energy the Phong lobe puts nearer the peak (a smooth aluminium
plate reflecting what lies far from its mirror direction); Schlick's curve misses
aluminium's dip before grazing (0.13).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

import numpy as np
from scipy.special import erf

from radiosity.files.errors import InputError
from radiosity.physics.materials import (
    MAX_EXPONENT,
    fresnel_dielectric,
    fresnel_kd_limit,
    fresnel_ks_limit,
    schlick_albedo,
    schlick_diffuse,
    specular_albedo,
)

__all__ = [
    "DISTRIBUTIONS",
    "KINDS",
    "METALS",
    "RULE",
    "RoughConductor",
    "RoughPlastic",
    "directional_albedo",
    "fresnel_conductor",
    "fresnel_dielectric",
    "fresnel_schlick",
    "lobe_width",
    "masking",
    "ndf",
    "normal_reflectance",
    "phong_exponent",
    "phong_lobe_for",
    "reference_brdf",
]

DISTRIBUTIONS = ("ggx", "beckmann")
KINDS = ("roughplastic", "roughconductor", "plastic", "conductor")

POLYPROPYLENE = 1.49  # Mitsuba's default int_ior
AIR = 1.000277  # Mitsuba's default ext_ior

RULE = {"ggx": (1.368, -3.261, 1.384), "beckmann": (0.818, -3.014, 2.183)}
"""n(alpha) = c / alpha^2 + d + e alpha^2 per distribution: (c, d, e), see the module's docstring."""

_TABLE_SIZE = 64  # Mitsuba's MTS_ROUGH_TRANSMITTANCE_RES
_METALS_FILE = Path(__file__).resolve().parent / "data" / "mitsuba_metals.json"


def _load_metals() -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]:
    data = json.loads(_METALS_FILE.read_text())
    return {name: (tuple(v["eta"]), tuple(v["k"])) for name, v in data["metals"].items()}


METALS = _load_metals()
"""Named conductors: name -> (RGB eta, RGB k), Mitsuba 3's presets as ``scalar_rgb`` uses
them (``none`` is eta 0, k 1: every wavelength reflected)."""


# --- Fresnel -----------------------------------------------------------------------


def fresnel_conductor(cos_i, eta, k):
    """Unpolarised Fresnel reflectance of a conductor of complex index eta + i k, exact.

    The s and p amplitudes of the complex Fresnel equations, averaged in power. eta = 0,
    k = 1 (Mitsuba's ``none``) gives 1 at every angle. Arrays broadcast; float64.
    """
    c = np.clip(np.abs(np.asarray(cos_i, dtype=np.float64)), 0.0, 1.0)
    n = np.asarray(eta, dtype=np.float64) + 1j * np.asarray(k, dtype=np.float64)
    cos_t = np.sqrt(1.0 - (1.0 - c * c) / (n * n) + 0j)
    rs = (c - n * cos_t) / (c + n * cos_t)
    rp = (n * c - cos_t) / (n * c + cos_t)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def fresnel_schlick(cos_i, r0):
    """Schlick's approximation r0 + (1 - r0)(1 - cos_i)^5."""
    c = np.abs(np.asarray(cos_i, dtype=np.float64))
    return r0 + (1.0 - r0) * (1.0 - c) ** 5


# --- The microfacet distribution ---------------------------------------------------


def _check_distribution(distribution: str, alpha: float) -> None:
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"microfacet distribution {distribution!r}: expected one of {', '.join(DISTRIBUTIONS)}")
    if not (math.isfinite(alpha) and alpha > 0.0):
        raise InputError(f"microfacet roughness alpha = {alpha!r}: expected a positive number")


def ndf(distribution: str, alpha: float, cos_h):
    """D(h) for a microfacet normal at cos_h to the normal; 0 for cos_h <= 0.

    GGX: alpha^2 / (pi cos^4 (alpha^2 + tan^2)^2); Beckmann: exp(-tan^2 / alpha^2) /
    (pi alpha^2 cos^4). Normalised: int D(h) cos(theta_h) dh = 1 over the hemisphere.
    """
    c = np.asarray(cos_h, dtype=np.float64)
    c2 = np.maximum(c * c, 1e-300)
    tan2 = np.maximum(1.0 - c2, 0.0) / c2
    a2 = alpha * alpha
    if distribution == "ggx":
        d = a2 / (math.pi * (a2 * c2 + (1.0 - c2)) ** 2)
    else:
        d = np.exp(-tan2 / a2) / (math.pi * a2 * c2 * c2)
    return np.where(c > 0.0, d, 0.0)


def masking(distribution: str, alpha: float, cos_v, cos_vh):
    """Smith's G1(v, h): cos_v = v.n, cos_vh = v.h; 0 where v sees the microfacet's back.

    GGX: 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_v)) (Walter eq. 34); Beckmann:
    2 / (1 + erf(a) + exp(-a^2) / (a sqrt(pi))), a = 1 / (alpha tan theta_v) (eq. 25,
    exact where Mitsuba uses a rational fit within 0.35 %).
    """
    cv = np.asarray(cos_v, dtype=np.float64)
    c2 = np.clip(cv * cv, 1e-300, 1.0)
    tan2 = (1.0 - c2) / c2
    if distribution == "ggx":
        g = 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * tan2))
    else:
        with np.errstate(divide="ignore"):
            a = 1.0 / (alpha * np.sqrt(tan2))
        a_safe = np.minimum(a, 30.0)
        g = np.where(a > 30.0, 1.0, 2.0 / (1.0 + erf(a_safe) + np.exp(-a_safe * a_safe) / (a_safe * math.sqrt(math.pi))))
    ok = (np.asarray(cos_vh) * cv) > 0.0
    return np.where(ok, g, 0.0)


def _half_vector(wi, wo):
    h = wi + wo
    norm = np.linalg.norm(h, axis=-1, keepdims=True)
    return h / np.maximum(norm, 1e-300)


def _specular(distribution, alpha, wi, wo, fresnel):
    """F D G1 G1 / (4 cos_i cos_o), without the reflectance factor; (...) float64."""
    h = _half_vector(wi, wo)
    ci, co = wi[..., 2], wo[..., 2]
    cih = np.sum(wi * h, axis=-1)
    coh = np.sum(wo * h, axis=-1)
    g = masking(distribution, alpha, ci, cih) * masking(distribution, alpha, co, coh)
    d = ndf(distribution, alpha, h[..., 2])
    ok = (ci > 0.0) & (co > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        value = d * g / (4.0 * ci * co)
    return np.where(ok, value, 0.0)[..., None] * fresnel(np.where(ok, cih, 1.0))


# --- Quadrature over microfacet normals ----------------------------------------------


@cache
def _unit_rule(points: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(points)
    return 0.5 * (x + 1.0), 0.5 * w


def _sample_normals(distribution: str, alpha: float, u_points: int, phi_points: int):
    """Microfacet normals on a (u, phi) product rule where D(h) cos(theta_h) dh = du dphi / 2pi.

    tan^2 theta_h = alpha^2 x with x = u / (1 - u) (GGX) or -log(1 - u) (Beckmann): the
    inverse of the projected distribution's cumulative, so the quadrature follows the
    lobe whatever alpha. Returns (h (U*P, 3), weight (U*P,)) with sum(weight) = 1.
    """
    u, wu = _unit_rule(u_points)
    # panels refined towards u = 1, where the tails live
    edges = 1.0 - np.geomspace(1.0, 1e-9, 10)
    edges[0] = 0.0
    nodes = (edges[:-1, None] + np.diff(edges)[:, None] * u[None, :]).ravel()
    weights = (np.diff(edges)[:, None] * wu[None, :]).ravel()
    x = nodes / (1.0 - nodes) if distribution == "ggx" else -np.log1p(-nodes)
    tan_t = alpha * np.sqrt(x)
    cos_t = 1.0 / np.sqrt(1.0 + tan_t * tan_t)
    sin_t = tan_t * cos_t
    phi = (np.arange(phi_points) + 0.5) * (2.0 * math.pi / phi_points)
    h = np.stack(
        [
            (sin_t[:, None] * np.cos(phi)[None, :]).ravel(),
            (sin_t[:, None] * np.sin(phi)[None, :]).ravel(),
            np.repeat(cos_t, phi_points),
        ],
        axis=-1,
    )
    w = np.repeat(weights / phi_points, phi_points)
    return h, w


def _interface_albedo(distribution, alpha, cos_i, fresnel, points=24):
    """int f_s(wi, wo) cos(theta_o) dwo for wi at each cos_i: (len(cos_i), C) float64.

    In microfacet normals: dwo = 4 (wo.h) dh, so the integrand is F G1 G1 (wi.h) /
    (cos_i cos_h) against D cos_h dh (``_sample_normals``).
    """
    h, w = _sample_normals(distribution, alpha, points, 4 * points)
    out = []
    for c in np.atleast_1d(np.asarray(cos_i, dtype=np.float64)):
        c = min(max(c, 1e-6), 1.0)
        wi = np.array([math.sqrt(1.0 - c * c), 0.0, c])
        cih = h @ wi
        wo = 2.0 * cih[:, None] * h - wi
        g = masking(distribution, alpha, c, cih) * masking(distribution, alpha, wo[:, 2], np.sum(wo * h, axis=-1))
        g = np.where(wo[:, 2] > 0.0, g, 0.0)
        f = fresnel(np.maximum(cih, 0.0))
        weight = w * g * np.maximum(cih, 0.0) / (c * h[:, 2])
        out.append(weight @ f)
    return np.array(out)


# --- The reference BRDFs -------------------------------------------------------------


def _rgb(value, name: str) -> np.ndarray:
    v = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v < 0.0):
        raise InputError(f"{name} = {value!r}: expected one or three non-negative numbers")
    return v


@dataclass(frozen=True)
class RoughConductor:
    """Mitsuba 3's ``roughconductor`` (``conductor`` when ``alpha`` is None): complex index
    eta + i k per RGB channel, ``specular_reflectance`` a factor (1 for physics)."""

    distribution: str
    alpha: float | None
    eta: np.ndarray
    k: np.ndarray
    specular_reflectance: np.ndarray

    def fresnel(self, cos_i):
        """F per channel, (..., 3)."""
        c = np.asarray(cos_i, dtype=np.float64)[..., None]
        return self.specular_reflectance * fresnel_conductor(c, self.eta, self.k)

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo), (..., 3) float64; a smooth conductor's is a delta: 0 here."""
        wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
        if self.alpha is None:
            return np.zeros(np.broadcast_shapes(wi.shape, wo.shape))
        return _specular(self.distribution, self.alpha, wi, wo, self.fresnel)

    def albedo(self, cos_i) -> tuple[np.ndarray, np.ndarray]:
        """Directional albedo (specular (N, 3), diffuse (N, 3)) for wi at each cos_i."""
        cos_i = np.atleast_1d(np.asarray(cos_i, dtype=np.float64))
        if self.alpha is None:
            specular = self.fresnel(cos_i)
        else:
            specular = _interface_albedo(self.distribution, self.alpha, cos_i, self.fresnel)
        return specular, np.zeros_like(specular)


@dataclass(frozen=True)
class RoughPlastic:
    """Mitsuba 3's ``roughplastic`` (``plastic`` when ``alpha`` is None): a rough dielectric
    interface of relative index ``eta`` over a Lambertian substrate of reflectance
    ``diffuse_reflectance``; ``nonlinear`` as Mitsuba's flag."""

    distribution: str
    alpha: float | None
    eta: float
    diffuse_reflectance: np.ndarray
    specular_reflectance: np.ndarray
    nonlinear: bool = False

    def fresnel(self, cos_i):
        """The interface's F times specular_reflectance, (..., 3)."""
        f = fresnel_dielectric(cos_i, self.eta)
        return np.asarray(f)[..., None] * self.specular_reflectance

    @property
    def _tables(self) -> tuple[np.ndarray, float]:
        return _transmittance_tables(self.distribution, self.alpha, self.eta)

    def transmittance(self, cos_i) -> np.ndarray:
        """t(mu): the interface's transmittance from outside, as Mitsuba's table; float64."""
        c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
        if self.alpha is None:
            return 1.0 - fresnel_dielectric(c, self.eta)
        table, _ = self._tables
        return np.interp(c, np.linspace(0.0, 1.0, _TABLE_SIZE), table)

    @property
    def substrate(self) -> np.ndarray:
        """kd' = kd / (1 - R_int), or kd / (1 - kd R_int) if nonlinear; (3,)."""
        if self.alpha is None:
            r_int = _smooth_internal_reflectance(self.eta)
        else:
            r_int = self._tables[1]
        kd = self.diffuse_reflectance
        return kd / (1.0 - (kd * r_int if self.nonlinear else r_int))

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo), (..., 3) float64 (the smooth interface's delta left out)."""
        wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
        ci, co = wi[..., 2], wo[..., 2]
        ok = (ci > 0.0) & (co > 0.0)
        diffuse = np.where(ok, self.transmittance(ci) * self.transmittance(co) / (math.pi * self.eta**2), 0.0)
        value = diffuse[..., None] * self.substrate
        if self.alpha is not None:
            value = value + _specular(self.distribution, self.alpha, wi, wo, self.fresnel)
        return value

    def albedo(self, cos_i) -> tuple[np.ndarray, np.ndarray]:
        """Directional albedo (specular (N, 3), diffuse (N, 3)) for wi at each cos_i."""
        cos_i = np.atleast_1d(np.asarray(cos_i, dtype=np.float64))
        if self.alpha is None:
            specular = self.fresnel(cos_i)
        else:
            specular = _interface_albedo(self.distribution, self.alpha, cos_i, self.fresnel)
        mu, w = _unit_rule(64)
        mean_t = 2.0 * np.sum(w * mu * self.transmittance(mu))
        diffuse = (self.transmittance(cos_i) * mean_t / self.eta**2)[:, None] * self.substrate
        return specular, diffuse


@cache
def _transmittance_tables(distribution: str, alpha: float, eta: float) -> tuple[np.ndarray, float]:
    """Mitsuba's tables on 64 cosines i/63 (the first 1e-6): t = the rough interface's
    transmittance into the substrate (``_interface_transmittance``), and R_int =
    2 mean(R(mu, 1/eta) mu), R the interface's albedo seen from inside."""
    mu = np.maximum(np.linspace(0.0, 1.0, _TABLE_SIZE), 1e-6)
    external = _interface_transmittance(distribution, alpha, mu, eta)
    inside = _interface_albedo(distribution, alpha, mu, lambda c: fresnel_dielectric(c, 1.0 / eta)[..., None], points=32)
    internal = 2.0 * float(np.mean(inside[:, 0] * mu))
    return external, internal


def _interface_transmittance(distribution, alpha, cos_i, eta, points=32):
    """Fraction of light at each cos_i refracted through the rough interface (single
    scattering): over visible normals m, (1 - F(wi.m)) G1(wt, m), wt the refracted
    direction; (len(cos_i),) float64."""
    h, w = _sample_normals(distribution, alpha, points, 4 * points)
    out = []
    for c in np.atleast_1d(np.asarray(cos_i, dtype=np.float64)):
        c = min(max(c, 1e-6), 1.0)
        wi = np.array([math.sqrt(1.0 - c * c), 0.0, c])
        cih = h @ wi
        inv = 1.0 / eta
        cos_t2 = 1.0 - inv * inv * (1.0 - cih * cih)
        cos_t = np.sqrt(np.maximum(cos_t2, 0.0))
        wt = -inv * wi + (inv * cih - cos_t)[:, None] * h
        g = masking(distribution, alpha, c, cih) * masking(distribution, alpha, wt[:, 2], np.sum(wt * h, axis=-1))
        g = np.where((wt[:, 2] < 0.0) & (cos_t2 > 0.0) & (cih > 0.0), g, 0.0)
        t = 1.0 - fresnel_dielectric(np.maximum(cih, 0.0), eta)
        out.append(np.sum(w * g * t * np.maximum(cih, 0.0) / (c * h[:, 2])))
    return np.array(out)


@cache
def _smooth_internal_reflectance(eta: float) -> float:
    mu, w = _unit_rule(256)
    return float(2.0 * np.sum(w * mu * fresnel_dielectric(mu, 1.0 / eta)))


def reference_brdf(kind: str, distribution: str = "beckmann", alpha: float = 0.1, **params):
    """The reference of one of Mitsuba's ``KINDS`` with its parameters.

    params (Mitsuba's names): ``int_ior``, ``ext_ior``, ``diffuse_reflectance``,
    ``specular_reflectance``, ``nonlinear`` (plastics); ``material`` (a name in
    ``METALS``), or ``eta`` and ``k``, and ``specular_reflectance`` (conductors).
    ``distribution`` and ``alpha`` are ignored by the smooth kinds. Raises InputError
    naming the problem.
    """
    smooth = kind in ("plastic", "conductor")
    if kind not in KINDS:
        raise InputError(f"bsdf {kind!r}: expected one of {', '.join(KINDS)}")
    if not smooth:
        _check_distribution(distribution, alpha)
        alpha = float(alpha)
    allowed = (
        {"int_ior", "ext_ior", "diffuse_reflectance", "specular_reflectance", "nonlinear"}
        if kind.endswith("plastic")
        else {"material", "eta", "k", "specular_reflectance"}
    )
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise InputError(f"bsdf {kind!r}: unknown parameter(s) {', '.join(unknown)}")
    specular = _rgb(params.get("specular_reflectance", 1.0), "specular_reflectance")
    if kind.endswith("plastic"):
        int_ior = float(params.get("int_ior", POLYPROPYLENE))
        ext_ior = float(params.get("ext_ior", AIR))
        if not (int_ior > 0.0 and ext_ior > 0.0 and int_ior != ext_ior):
            raise InputError(f"bsdf {kind!r}: int_ior {int_ior:g} and ext_ior {ext_ior:g} must be positive and differ")
        diffuse = _rgb(params.get("diffuse_reflectance", 0.5), "diffuse_reflectance")
        return RoughPlastic(
            distribution, None if smooth else alpha, int_ior / ext_ior, diffuse, specular, bool(params.get("nonlinear", False))
        )
    if "eta" in params or "k" in params:
        if "material" in params:
            raise InputError(f"bsdf {kind!r}: give either material or (eta, k), not both")
        eta, k = _rgb(params.get("eta", 0.0), "eta"), _rgb(params.get("k", 1.0), "k")
    else:
        name = params.get("material", "none")
        if name not in METALS:
            raise InputError(f"bsdf {kind!r}: unknown material {name!r} (Mitsuba's presets: {', '.join(sorted(METALS))})")
        eta, k = (np.array(v, dtype=np.float64) for v in METALS[name])
    return RoughConductor(distribution, None if smooth else alpha, eta, k, specular)


def directional_albedo(brdf, cos_i) -> np.ndarray:
    """Total directional albedo of a reference BRDF for wi at each cos_i, (N, 3)."""
    specular, diffuse = brdf.albedo(cos_i)
    return specular + diffuse


# --- Lobe shapes -----------------------------------------------------------------------


def _rotated(theta_i: float, delta, phi):
    """Directions at angle delta from the mirror direction of wi = (sin theta_i, 0, cos theta_i),
    phi measured from the plane of incidence (phi = 0 towards the normal)."""
    m = np.array([-math.sin(theta_i), 0.0, math.cos(theta_i)])  # mirror direction
    e1 = np.array([math.cos(theta_i), 0.0, math.sin(theta_i)])  # in plane, towards the normal's side
    e2 = np.array([0.0, 1.0, 0.0])
    sd, cd = np.sin(delta), np.cos(delta)
    return (
        cd[..., None] * m
        + (sd * np.cos(phi))[..., None] * e1
        + (sd * np.sin(phi))[..., None] * e2
    )


def lobe_width(lobe, theta_i: float, extent: float, samples: int = 400) -> dict:
    """Shape of a lobe about the mirror direction of wv = (sin theta_i, 0, cos theta_i).

    lobe: a function of directions w (..., 3) -> (...): for the radiance a viewer at wv
    sees from a small light moving over w, f(w, wv) cos(theta_w) (reciprocity makes
    wv the light and w the viewer equally); extent: the largest angle from the mirror
    direction looked at (radians), on a polar grid of ``samples`` x 256 directions.
    Returns the peak's offset from the mirror direction in the plane of incidence
    (radians, > 0 towards the horizon), the peak value, ``solid_angle`` of the region
    at or above half the peak and ``radius`` = sqrt(solid_angle / pi) (the half width
    at half maximum of an equivalent round lobe), and the in-plane and across-plane half
    widths at half maximum through the peak (radians).
    """
    delta = (np.arange(samples) + 0.5) * (extent / samples)
    phi = (np.arange(256) + 0.5) * (2.0 * math.pi / 256)
    dd, pp = np.meshgrid(delta, phi, indexing="ij")
    wo = _rotated(theta_i, dd, pp)
    value = np.where(wo[..., 2] > 0.0, lobe(wo), 0.0)
    peak_index = np.unravel_index(np.argmax(value), value.shape)
    peak = float(value[peak_index])
    # offset in plane: phi near 0 is towards the normal, near pi towards the horizon
    offset = float(dd[peak_index] * -np.cos(pp[peak_index]))
    cell = (extent / samples) * (2.0 * math.pi / 256) * np.sin(dd)
    solid_angle = float(np.sum(np.where(value >= 0.5 * peak, cell, 0.0)))
    # half widths along the plane of incidence and across it, through the peak
    line = np.linspace(-extent, extent, 4 * samples + 1)
    d_in = np.abs(line + offset)
    in_plane = _rotated(theta_i, d_in, np.where(line + offset > 0.0, math.pi, 0.0))
    peak_dir = _rotated(theta_i, np.array(abs(offset)), np.array(math.pi if offset > 0 else 0.0))
    across = np.cos(line)[:, None] * peak_dir + np.sin(line)[:, None] * np.array([0.0, 1.0, 0.0])
    widths = {}
    for name, dirs in (("in_plane", in_plane), ("across", across)):
        v = np.where(dirs[:, 2] > 0.0, lobe(dirs), 0.0)
        above = line[v >= 0.5 * peak]
        widths[name] = float(above.max() - above.min()) / 2.0 if above.size else 0.0
    return {
        "offset": offset,
        "peak": peak,
        "solid_angle": solid_angle,
        "radius": math.sqrt(solid_angle / math.pi),
        "hwhm_in_plane": widths["in_plane"],
        "hwhm_across": widths["across"],
    }


# --- The mapping -------------------------------------------------------------------------


def phong_exponent(distribution: str, alpha: float) -> float:
    """The rule's Phong exponent c / alpha^2 + d + e alpha^2 (``RULE``), 0 from the first
    alpha where it reaches 0 on, at most MAX_EXPONENT."""
    _check_distribution(distribution, alpha)
    c, d, e = RULE[distribution]
    x = alpha * alpha
    first_root = (-d - math.sqrt(d * d - 4.0 * c * e)) / (2.0 * e)  # in x = alpha^2; both constants' roots real
    if x >= first_root:
        return 0.0
    return float(min(max(c / x + d + e * x, 0.0), MAX_EXPONENT))


def phong_lobe_for(
    kind: str, distribution: str = "beckmann", alpha: float = 0.1, *, measure: bool = False, fresnel: bool = True,
    **params,
):
    """The modified-Phong (kd, ks, n) standing in for a Mitsuba material, by the module's rule.

    kind: one of ``KINDS``; distribution, alpha: the microfacet roughness (ignored by
    the smooth kinds); params: Mitsuba's parameters (see ``reference_brdf``);
    fresnel: True (the rule): give the lobe a Fresnel term (Schlick's F0 = the exact
    reflectance at normal incidence: the dielectric's for plastics, the conductor's per
    channel), ks and kd fitted with it (``_fresnel_albedos_over_incidence``), ks at most
    what keeps the specular albedo <= 1 (``fresnel_ks_limit``), kd at most
    ``fresnel_kd_limit``; "physical": the same with ks <= 1 (Mitsuba's
    specular_reflectance); False: the constant-ks rule of before. The last two are kept
    for the benchmark's comparison.
    Returns (kd (3,), ks (3,), exponent, report): report holds the rule, ``fresnel`` (F0
    as a list, or None), the reference's albedo (specular, diffuse) at incidence 0, 60
    and 80 degrees against the Phong lobe's, and with ``measure`` the half-maximum
    radius of both lobes at 0, 30, 45 and 60 degrees (radians; ``lobe_width``).
    """
    brdf = reference_brdf(kind, distribution, alpha, **params)
    angles = np.radians([0.0, 60.0, 80.0])
    specular, diffuse = brdf.albedo(np.cos(angles))
    smooth = brdf.alpha is None
    exponent = float(MAX_EXPONENT) if smooth else phong_exponent(distribution, alpha)
    f0 = None
    if fresnel:
        f0 = normal_reflectance(brdf)
        ks, kd = _fresnel_albedos_over_incidence(brdf, exponent, f0)
        ks = np.minimum(ks, 1.0 if fresnel == "physical" else fresnel_ks_limit(f0, exponent))
        limit = fresnel_kd_limit(ks, f0, exponent)
        scale = np.where(kd > limit, limit / np.maximum(kd, 1e-300), 1.0)
        kd = kd * scale
        phong_specular = ks * (f0 * specular_albedo(exponent, np.cos(angles))[:, None]
                               + (1.0 - f0) * schlick_albedo(exponent, np.cos(angles))[:, None])
        phong_diffuse = schlick_diffuse(np.cos(angles))[:, None] * kd
    else:
        ks, kd = _albedos_over_incidence(brdf, exponent)
        total = kd + ks
        scale = np.where(total > 1.0, 1.0 / np.maximum(total, 1e-300), 1.0)
        kd, ks = kd * scale, ks * scale
        phong_specular = specular_albedo(exponent, np.cos(angles))[:, None] * ks
        phong_diffuse = np.broadcast_to(kd, (3, 3))

    report = {
        "kind": kind,
        "distribution": None if smooth else distribution,
        "alpha": None if smooth else float(alpha),
        "rule": "n = MAX_EXPONENT (smooth)" if smooth else "n = {} / alpha^2 + ({}) + {} alpha^2".format(*RULE[distribution]),
        "incidence_deg": [0.0, 60.0, 80.0],
        "reference_specular_albedo": specular.tolist(),
        "reference_diffuse_albedo": diffuse.tolist(),
        "fresnel": None if f0 is None else f0.tolist(),
        "phong_specular_albedo": phong_specular.tolist(),
        "phong_diffuse_albedo": phong_diffuse.tolist(),
        "energy_scaled": bool(np.any(scale < 1.0)),
    }
    if measure and not smooth:
        report["hwhm_deg"] = {}
        for deg in (0.0, 30.0, 45.0, 60.0):
            ref, phong = _lobe_radii(brdf, exponent, math.radians(deg))
            report["hwhm_deg"][f"{deg:g}"] = {"reference": math.degrees(ref), "phong": math.degrees(phong)}
    return kd, ks, exponent, report


def phong_lobe(kind: str, distribution: str = "beckmann", alpha: float = 0.1, **params):
    """(kd, ks, n, fresnel) of ``phong_lobe_for``, as tuples (fresnel: F0, or None),
    remembered per distinct material:
    a scene's many shapes of one material pay for its quadratures once (a few tenths
    of a second each)."""

    def hashable(value):
        return tuple(float(v) for v in np.ravel(value)) if np.ndim(value) else value

    return _lobe(kind, distribution, float(alpha), tuple(sorted((k, hashable(v)) for k, v in params.items())))


@lru_cache(maxsize=1024)
def _lobe(kind, distribution, alpha, params):
    kd, ks, exponent, report = phong_lobe_for(kind, distribution, alpha, **dict(params))
    f0 = report["fresnel"]
    return tuple(map(float, kd)), tuple(map(float, ks)), exponent, None if f0 is None else tuple(map(float, f0))


ALBEDO_NODES = 48  # incidence angles of the albedo fit (Gauss-Legendre in theta)


def _albedos_over_incidence(brdf, exponent):
    """(ks, kd) whose Phong albedos, ks S_n(theta) and kd, are closest in least squares
    to the reference's specular and diffuse albedos over incidence theta, weighted by
    sin(2 theta) (the density of a highlight's incidence when light and viewer are
    independent uniform directions, as for the exponent): the Phong lobe's albedo falls
    towards grazing roughly as cos theta while a microfacet lobe's stays and Fresnel
    rises, so matching at normal incidence alone leaves every oblique highlight dim."""
    x, w = np.polynomial.legendre.leggauss(ALBEDO_NODES)
    theta = (x + 1.0) * np.pi / 4.0  # (0, pi/2)
    weight = w * np.sin(2.0 * theta)
    specular, diffuse = brdf.albedo(np.cos(theta))  # (N, 3) each
    phong = specular_albedo(exponent, np.cos(theta))  # (N,), ks = 1
    ks = (weight * phong) @ specular / float(weight @ phong**2)
    kd = weight @ diffuse / float(weight.sum())
    return ks, kd


def normal_reflectance(brdf) -> np.ndarray:
    """Schlick's F0 (3,) for a reference: its interface's exact reflectance at normal
    incidence (without ``specular_reflectance``, which the fitted ks carries)."""
    if isinstance(brdf, RoughPlastic):
        return np.full(3, float(fresnel_dielectric(1.0, brdf.eta)))
    return np.asarray(fresnel_conductor(1.0, brdf.eta, brdf.k), dtype=np.float64).reshape(3)


def _fresnel_albedos_over_incidence(brdf, exponent, f0):
    """(ks, kd) of the Fresnel lobe by the same weighted least squares as
    ``_albedos_over_incidence``: ks (F0 S + (1 - F0) Q) against the reference's specular
    albedo per channel, kd b(cos theta) against its diffuse albedo."""
    x, w = np.polynomial.legendre.leggauss(ALBEDO_NODES)
    theta = (x + 1.0) * np.pi / 4.0
    weight = w * np.sin(2.0 * theta)
    cos = np.cos(theta)
    specular, diffuse = brdf.albedo(cos)  # (N, 3) each
    shape = f0[None, :] * specular_albedo(exponent, cos)[:, None] + (1.0 - f0[None, :]) * schlick_albedo(exponent, cos)[:, None]
    ks = (weight[:, None] * shape * specular).sum(axis=0) / np.maximum((weight[:, None] * shape**2).sum(axis=0), 1e-300)
    b = schlick_diffuse(cos)
    kd = (weight * b) @ diffuse / float(weight @ b**2)
    return ks, kd


def _no_fresnel(cos):
    return np.ones(np.shape(cos) + (1,))


def _lobe_radii(brdf, exponent: float, theta_i: float) -> tuple[float, float]:
    """Half-maximum radius of the reference's specular lobe and the Phong lobe's (radians)."""
    wi = np.array([math.sin(theta_i), 0.0, math.cos(theta_i)])
    guess = max(math.acos(0.5 ** (1.0 / max(exponent, 1e-3))), 1e-4) if exponent > 0 else math.pi / 2
    extent = min(math.pi, 4.0 * guess)

    def reference(w):
        unit = _specular(brdf.distribution, brdf.alpha, np.broadcast_to(wi, w.shape), w, _no_fresnel)
        return unit[..., 0] * w[..., 2]

    def phong(w):
        m = np.array([-wi[0], -wi[1], wi[2]])
        return np.maximum(w @ m, 0.0) ** exponent * w[..., 2]

    return lobe_width(reference, theta_i, extent)["radius"], lobe_width(phong, theta_i, extent)["radius"]
