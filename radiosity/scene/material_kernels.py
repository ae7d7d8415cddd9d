"""Materials: Lambert plus the modified Phong BRDF of Lafortune & Willems (1994).

A material with diffuse reflectance ``kd``, specular reflectance ``ks`` (RGB) and
Phong exponent ``n`` reflects with

    f(wi, wo) = kd / pi + ks (n + 2) / (2 pi) * max(0, dot(reflect(wi), wo))^n

when wi.z > 0 and wo.z > 0, and f = 0 otherwise. The lobe max(0, c)^n is 0 for
c <= 0 also when n = 0. f is reciprocal and, for kd + ks <= 1 in every channel,
energy conserving: the directional albedo is kd + ks at normal incidence and the
specular part falls towards grazing incidence (see ``albedo``).

A material with a Fresnel term (``Material.fresnel``: Schlick's F0 per channel; the
rule and its reasons in ``radiosity.physics.materials``) reflects with

    f(wi, wo) = kd / pi * (21/20) b(wi.z) b(wo.z) + ks F(wi.h) (n + 2) / (2 pi) cos^n(alpha),
    F(c) = F0 + (1 - F0)(1 - c)^5, b(c) = 1 - (1 - c)^5, h = normalize(wi + wo),

reciprocal, and energy conserving when ``Material`` accepts it. Materials without
Fresnel run the same operations as before (the same bits).

Conventions: directions are unit vectors in the local shading frame (x tangent,
y bitangent, z normal), wi and wo both pointing away from the surface, and
reflect(w) = (-w.x, -w.y, w.z).

Contents:

- ``Material``: an immutable, validated description, as scene files give it.
- ``pack_materials``: a float64 table, one row per material, with the column
  indices ``KD``, ``KS``, ``EXPONENT``, ``EMISSION``, ``P_SPECULAR``, ``F0``,
  ``HAS_FRESNEL`` and ``NCOL``.
- numba kernels on one row ``mat`` of that table and plain floats:
  ``brdf_eval``, ``brdf_pdf``, ``brdf_sample`` and the basis helper ``onb``.
- ``eval_brdf``, ``pdf``, ``sample``: the kernels vectorised over arrays.
- ``albedo``: the exact directional albedo, by deterministic quadrature.

Importance sampling: ``brdf_sample`` picks the specular lobe with probability
``P_SPECULAR`` = mean(ks) / (mean(kd) + mean(ks)), otherwise the diffuse lobe (with
Fresnel the probability follows the two parts' albedos at wo, ``p_specular``). The
diffuse lobe is cosine-weighted over the upper hemisphere; the specular lobe has
density (n + 1) / (2 pi) * max(0, cos alpha)^n over the whole sphere, alpha being
the angle to the mirror direction reflect(wo). Some specular samples therefore lie
below the horizon (wi.z <= 0); they are returned as they are, with the mixture
density, and the caller treats them as absorbed (zero weight).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.materials import (
    FRESNEL_NORMALISATION,
    MAX_EXPONENT,
    Material,
    schlick_albedo,
    schlick_diffuse,
    specular_albedo,
)
from radiosity.scene.columns import (
    EMISSION,
    EXPONENT,
    F0,
    GLASS_TRANSMITTANCE,
    HAS_FRESNEL,
    KD,
    KIND,
    KIND_DIELECTRIC,
    KIND_PHONG,
    KIND_ROUGH_CONDUCTOR,
    KIND_ROUGH_DIELECTRIC,
    KIND_ROUGH_PLASTIC,
    KIND_THIN_DIELECTRIC,
    KS,
    MF_ALPHA,
    MF_BECKMANN,
    MF_DIFFUSE_NORM,
    MF_DISTRIBUTION,
    MF_ETA,
    MF_GGX,
    MF_K,
    MF_SPECULAR,
    MF_SPECULAR_WEIGHT,
    MF_TABLE,
    MF_TABLE_SIZE,
    NCOL,
    P_SPECULAR,
)
from radiosity.scene.microfacet_kernels import (
    mf_deposit_weight,
    mf_diffuse_exitance,
    mf_eval,
    mf_pdf,
    mf_sample,
    mf_specular_eval,
    mf_specular_pdf,
    mf_specular_sample,
)

__all__ = [
    "EMISSION",
    "EXPONENT",
    "F0",
    "HAS_FRESNEL",
    "KD",
    "KIND",
    "KS",
    "MAX_EXPONENT",
    "NCOL",
    "P_SPECULAR",
    "Material",
    "albedo",
    "albedo_table",
    "brdf_eval",
    "brdf_pdf",
    "brdf_sample",
    "eval_brdf",
    "deposit_weight",
    "diffuse_exitance",
    "diffuse_exitances",
    "diffuse_reflectance",
    "fresnel_diffuse",
    "half_cosine",
    "onb",
    "p_specular",
    "pack_materials",
    "schlick",
    "phong_lobe",
    "specular_eval",
    "specular_pdf",
    "specular_sample",
    "pdf",
    "sample",
]

P_SPECULAR_MIN = 0.05  # with Fresnel, the least probability of the specular lobe (ks > 0)


def pack_materials(materials: Sequence[Material], microfacet_models: bool = True) -> np.ndarray:
    """Pack materials into a table for the numba kernels.

    Returns a C-contiguous float64 array of shape (M, NCOL); row i describes
    ``materials[i]`` with the column layout of ``radiosity.scene.columns``: ``KD``,
    ``KS``, ``EXPONENT``, ``EMISSION``, ``P_SPECULAR``, ``F0``, ``HAS_FRESNEL`` (the
    Phong model, or a microfacet material's Phong stand-in), ``KIND`` and the microfacet
    columns. P_SPECULAR = mean(ks) / (mean(kd) + mean(ks)), 0 if both are 0; F0 and
    HAS_FRESNEL are 0 without Fresnel. A material with a ``microfacet`` model gets its
    kind and columns (``_pack_microfacet``) unless ``microfacet_models`` is False: then
    every row is its Phong model (what the solver's gather and closed-form highlights
    evaluate).
    """
    table = np.zeros((len(materials), NCOL), dtype=np.float64)
    for row, m in zip(table, materials):
        row[KD : KD + 3] = m.diffuse
        row[KS : KS + 3] = m.specular
        row[EXPONENT] = m.exponent
        row[EMISSION : EMISSION + 3] = m.emission
        kd, ks = sum(m.diffuse) / 3.0, sum(m.specular) / 3.0
        row[P_SPECULAR] = ks / (kd + ks) if kd + ks > 0.0 else 0.0
        if m.fresnel is not None:
            row[F0 : F0 + 3] = m.fresnel
            row[HAS_FRESNEL] = 1.0
        if m.microfacet is not None and microfacet_models:
            _pack_microfacet(row, m.microfacet)
        if m.glass is not None:
            _pack_glass(row, m.glass)
    return table


def _pack_glass(row: np.ndarray, glass) -> None:
    """Write a ``Glass`` model's kind and columns into ``row`` (its Phong part is zero)."""
    row[KIND] = {"dielectric": KIND_DIELECTRIC, "thindielectric": KIND_THIN_DIELECTRIC,
                 "roughdielectric": KIND_ROUGH_DIELECTRIC}[glass.kind]
    row[MF_DISTRIBUTION] = MF_GGX if glass.distribution == "ggx" else MF_BECKMANN
    row[MF_ALPHA] = glass.alpha
    row[MF_ETA : MF_ETA + 3] = glass.eta
    row[MF_SPECULAR : MF_SPECULAR + 3] = glass.specular_reflectance
    row[GLASS_TRANSMITTANCE : GLASS_TRANSMITTANCE + 3] = glass.specular_transmittance


def _pack_microfacet(row: np.ndarray, model) -> None:
    """Write a ``Microfacet`` model's kind and columns into ``row`` (its Phong stand-in
    stays in the first columns, KD replaced by the substrate's; ``_microfacet_columns``)."""
    kd, has_fresnel, tail = _microfacet_columns(model)
    row[KD : KD + 3] = kd
    row[HAS_FRESNEL] = has_fresnel
    row[P_SPECULAR] = 0.0
    row[KIND:] = tail


@lru_cache(maxsize=256)
def _microfacet_columns(model) -> tuple[np.ndarray, float, np.ndarray]:
    """(KD (3,), HAS_FRESNEL, the columns from KIND on) of a ``Microfacet`` model,
    remembered per model (the solver packs an object's material for every gather block):
    the transmittance table and R_int of a plastic from the oracle (``microfacet.RoughPlastic``),
    KD = kd' / (eta^2 N), N = 1 / (2 int t mu dmu); a conductor has no diffuse part."""
    row = np.zeros(NCOL)
    row[MF_DISTRIBUTION] = MF_GGX if model.distribution == "ggx" else MF_BECKMANN
    row[MF_ALPHA] = model.alpha
    row[MF_ETA : MF_ETA + 3] = model.eta
    row[MF_K : MF_K + 3] = model.k
    row[MF_SPECULAR : MF_SPECULAR + 3] = model.specular_reflectance
    if model.kind == "roughconductor":
        row[KIND] = KIND_ROUGH_CONDUCTOR
        return np.zeros(3), 0.0, row[KIND:]
    row[KIND] = KIND_ROUGH_PLASTIC
    brdf = microfacet_reference(model)
    table = brdf.transmittance(np.linspace(0.0, 1.0, MF_TABLE_SIZE))
    row[MF_TABLE : MF_TABLE + MF_TABLE_SIZE] = table
    mu, w = np.polynomial.legendre.leggauss(64)
    mu = 0.5 * (mu + 1.0)
    norm = 1.0 / (np.sum(w * mu * np.interp(mu, np.linspace(0.0, 1.0, MF_TABLE_SIZE), table)))
    row[MF_DIFFUSE_NORM] = norm
    s, d = float(np.mean(model.specular_reflectance)), float(np.mean(model.diffuse_reflectance))
    row[MF_SPECULAR_WEIGHT] = s / (s + d) if s + d > 0.0 else 0.0
    return brdf.substrate / (model.eta[0] ** 2 * norm), 1.0, row[KIND:]


def microfacet_reference(model):
    """The numpy oracle (``radiosity.scene.microfacet``) of a ``Microfacet`` model."""
    from radiosity.scene import microfacet  # scipy's: imported where a microfacet material is
    if model.kind == "roughconductor":
        return microfacet.RoughConductor(model.distribution, model.alpha, np.asarray(model.eta), np.asarray(model.k),
                                         np.asarray(model.specular_reflectance))
    return microfacet.RoughPlastic(model.distribution, model.alpha, model.eta[0], np.asarray(model.diffuse_reflectance),
                                   np.asarray(model.specular_reflectance), model.nonlinear)


_INV_PI = 1.0 / math.pi
_INV_2PI = 0.5 / math.pi
_DIFFUSE_NORM = FRESNEL_NORMALISATION / math.pi


@numba.njit(cache=True, fastmath=False)
def schlick(mat, cos_h):
    """Schlick's F per channel at cos_h (clamped to [0, 1]) for the material row ``mat``."""
    x = 1.0 - min(max(cos_h, 0.0), 1.0)
    x2 = x * x
    x5 = x2 * x2 * x
    return (
        mat[F0] + (1.0 - mat[F0]) * x5,
        mat[F0 + 1] + (1.0 - mat[F0 + 1]) * x5,
        mat[F0 + 2] + (1.0 - mat[F0 + 2]) * x5,
    )


@numba.njit(cache=True, fastmath=False)
def half_cosine(dot_wi_wo):
    """wi.h for unit wi, wo with wi.wo = dot_wi_wo: sqrt((1 + wi.wo) / 2)."""
    return math.sqrt(max(0.5 * (1.0 + dot_wi_wo), 0.0))


@numba.njit(cache=True, fastmath=False)
def fresnel_diffuse(cos_theta):
    """b(c) = 1 - (1 - c)^5 (c clamped to [0, 1]): the Fresnel diffuse part's factor."""
    x = 1.0 - min(max(cos_theta, 0.0), 1.0)
    x2 = x * x
    return 1.0 - x2 * x2 * x


@numba.njit(cache=True, fastmath=False)
def deposit_weight(mat, cos_in):
    """What a photon arriving at cos_in to the shading normal adds to the density
    estimate of a surface of material row ``mat``, per unit power: 1 without Fresnel;
    with it (21/20) b(cos_in), so the estimate E' = (21/20) int b(cos_i) L cos_i dwi is
    what the Fresnel diffuse part reflects, L_d(wo) = kd / pi * b(wo.z) * E' (E' = E
    for uniform light)."""
    if mat[KIND] != KIND_PHONG:
        return mf_deposit_weight(mat, cos_in)
    if mat[HAS_FRESNEL] <= 0.0:
        return 1.0
    return FRESNEL_NORMALISATION * fresnel_diffuse(cos_in)


@numba.njit(cache=True, fastmath=False)
def diffuse_exitance(mat, cos_out):
    """The factor of kd / pi * E' (``deposit_weight``) in the diffuse radiance leaving at
    cos_out: 1 without Fresnel, b(cos_out) with it."""
    if mat[KIND] != KIND_PHONG:
        return mf_diffuse_exitance(mat, cos_out)
    if mat[HAS_FRESNEL] <= 0.0:
        return 1.0
    return fresnel_diffuse(cos_out)


@numba.njit(cache=True, fastmath=False)
def p_specular(mat, woz):
    """Probability that ``brdf_sample`` picks the specular lobe for wo.z = woz.

    Without Fresnel mat[P_SPECULAR]; with it the specular part's share of the two
    albedos' channel means at wo, s / (d + s), s = mean(ks) F(woz) with mean F0, d =
    mean(kd) b(woz), at least ``P_SPECULAR_MIN`` if ks > 0 (the gather's forced lobe
    samples, u1 = 0, need it positive; 0 if both are 0): most samples go where the
    light goes, the specular lobe near grazing."""
    if mat[HAS_FRESNEL] <= 0.0:
        return mat[P_SPECULAR]
    kd = (mat[KD] + mat[KD + 1] + mat[KD + 2]) / 3.0
    ks = (mat[KS] + mat[KS + 1] + mat[KS + 2]) / 3.0
    f0 = (mat[F0] + mat[F0 + 1] + mat[F0 + 2]) / 3.0
    b = fresnel_diffuse(woz)
    s = ks * (f0 + (1.0 - f0) * (1.0 - b))
    d = kd * b
    if ks <= 0.0:
        return 0.0
    return max(s / (d + s), P_SPECULAR_MIN)


@numba.njit(cache=True, fastmath=False)
def onb(nx, ny, nz):
    """Tangent t and bitangent b completing the unit vector n to an orthonormal basis.

    Branchless construction of Duff et al. (2017), "Building an orthonormal basis,
    revisited"; (t, b, n) is right-handed. Returns (tx, ty, tz, bx, by, bz).
    """
    sign = math.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    return 1.0 + sign * nx * nx * a, sign * b, -sign * nx, b, sign + ny * ny * a, -ny


@numba.njit(cache=True, fastmath=False)
def phong_lobe(cos_alpha, exponent):
    """max(0, cos_alpha)^exponent, with cos_alpha clamped to 1 and 0 for cos_alpha <= 0."""
    if cos_alpha <= 0.0:
        return 0.0
    return min(cos_alpha, 1.0) ** exponent


@numba.njit(cache=True, fastmath=False)
def _mixture_pdf(mat, cos_alpha, wiz, p_spec):
    """Sampling density of a direction with wi.z = wiz at angle alpha from reflect(wo),
    p_spec the probability of the specular lobe."""
    n = mat[EXPONENT]
    diffuse = max(0.0, wiz) * _INV_PI
    specular = (n + 1.0) * _INV_2PI * phong_lobe(cos_alpha, n)
    return (1.0 - p_spec) * diffuse + p_spec * specular


@numba.njit(cache=True, fastmath=False, inline="always")
def brdf_eval(mat, wix, wiy, wiz, wox, woy, woz):
    """BRDF value f(wi, wo) as an (r, g, b) tuple; 0 unless wi.z > 0 and wo.z > 0.

    ``mat`` is one row (float64, length NCOL) of ``pack_materials``; wi and wo are
    unit vectors in the shading frame, both pointing away from the surface.
    """
    if wiz <= 0.0 or woz <= 0.0:
        return 0.0, 0.0, 0.0
    if mat[KIND] != KIND_PHONG:
        return mf_eval(mat, wix, wiy, wiz, wox, woy, woz)
    n = mat[EXPONENT]
    cos_alpha = wiz * woz - wix * wox - wiy * woy
    specular = (n + 2.0) * _INV_2PI * phong_lobe(cos_alpha, n)
    if mat[HAS_FRESNEL] > 0.0:
        f0, f1, f2 = schlick(mat, half_cosine(wix * wox + wiy * woy + wiz * woz))
        diffuse = _DIFFUSE_NORM * fresnel_diffuse(wiz) * fresnel_diffuse(woz)
        return (
            mat[KD] * diffuse + mat[KS] * f0 * specular,
            mat[KD + 1] * diffuse + mat[KS + 1] * f1 * specular,
            mat[KD + 2] * diffuse + mat[KS + 2] * f2 * specular,
        )
    return (
        mat[KD] * _INV_PI + mat[KS] * specular,
        mat[KD + 1] * _INV_PI + mat[KS + 1] * specular,
        mat[KD + 2] * _INV_PI + mat[KS + 2] * specular,
    )


@numba.njit(cache=True, fastmath=False, inline="always")
def brdf_pdf(mat, wox, woy, woz, wix, wiy, wiz):
    """Density, per unit solid angle over the whole sphere, of ``brdf_sample``'s wi for this wo.

    (1 - ps) * max(0, wi.z) / pi + ps * (n + 1) / (2 pi) * max(0, cos alpha)^n, with
    ps = ``p_specular(mat, wo.z)`` and alpha the angle between wi and reflect(wo). It integrates
    to 1 over the sphere; if ps > 0 it is also positive below the horizon within 90
    degrees of the mirror direction.
    """
    if mat[KIND] != KIND_PHONG:
        return mf_pdf(mat, wox, woy, woz, wix, wiy, wiz)
    cos_alpha = wiz * woz - wix * wox - wiy * woy
    return _mixture_pdf(mat, cos_alpha, wiz, p_specular(mat, woz))


@numba.njit(cache=True, fastmath=False, inline="always")
def _phong_lobe_direction(mat, wox, woy, woz, u2, phi):
    """A direction of the Phong lobe about reflect(wo): cos alpha = (1 - u2)^(1/(n+1)) at
    azimuth phi. Returns (wix, wiy, wiz, cos alpha), cos alpha the sampled one."""
    rx, ry, rz = -wox, -woy, woz
    tx, ty, tz, bx, by, bz = onb(rx, ry, rz)
    # log(cos alpha); sin^2 alpha = 1 - cos^2 alpha without cancellation for huge n.
    log_cos = math.log(1.0 - u2) / (mat[EXPONENT] + 1.0)
    cos_alpha = math.exp(log_cos)
    sin_alpha = math.sqrt(-math.expm1(2.0 * log_cos))
    sx = sin_alpha * math.cos(phi)
    sy = sin_alpha * math.sin(phi)
    return sx * tx + sy * bx + cos_alpha * rx, sx * ty + sy * by + cos_alpha * ry, sx * tz + sy * bz + cos_alpha * rz, cos_alpha


@numba.njit(cache=True, fastmath=False, inline="always")
def brdf_sample(mat, wox, woy, woz, u1, u2, u3):
    """Sample wi for the outgoing direction wo from uniform numbers u1, u2, u3 in [0, 1).

    u1 < ``p_specular(mat, wo.z)`` picks the specular lobe, otherwise the diffuse lobe;
    (u2, u3) place the direction in the lobe: cos alpha = (1 - u2)^(1/(n+1)) about
    reflect(wo) for the specular lobe (u2 = 0 gives the mirror direction; 1 - u2 is
    never 0 for u2 < 1, and u2 = 1 still gives a finite direction), and the
    cosine-weighted hemisphere for the diffuse lobe. Returns (wix, wiy, wiz, pdf),
    pdf being the mixture density of ``brdf_pdf`` at wi, evaluated with the sampled
    cos alpha rather than one recomputed from the rounded wi. Specular samples may
    lie below the horizon (wiz <= 0); the caller must treat those as absorbed.
    """
    if mat[KIND] != KIND_PHONG:
        return mf_sample(mat, wox, woy, woz, u1, u2, u3)
    phi = 2.0 * math.pi * u3
    p_spec = p_specular(mat, woz)
    if u1 < p_spec:
        wix, wiy, wiz, cos_alpha = _phong_lobe_direction(mat, wox, woy, woz, u2, phi)
        return wix, wiy, wiz, _mixture_pdf(mat, cos_alpha, wiz, p_spec)
    radius = math.sqrt(u2)
    wix = radius * math.cos(phi)
    wiy = radius * math.sin(phi)
    wiz = math.sqrt(1.0 - u2)
    cos_alpha = wiz * woz - wix * wox - wiy * woy
    return wix, wiy, wiz, _mixture_pdf(mat, cos_alpha, wiz, p_spec)


@numba.njit(cache=True, fastmath=False)
def _eval_rows(mat, wi, wo, out):
    for k in range(wi.shape[0]):
        r, g, b = brdf_eval(mat, wi[k, 0], wi[k, 1], wi[k, 2], wo[k, 0], wo[k, 1], wo[k, 2])
        out[k, 0] = r
        out[k, 1] = g
        out[k, 2] = b


@numba.njit(cache=True, fastmath=False)
def _pdf_rows(mat, wo, wi, out):
    for k in range(wi.shape[0]):
        out[k] = brdf_pdf(mat, wo[k, 0], wo[k, 1], wo[k, 2], wi[k, 0], wi[k, 1], wi[k, 2])


@numba.njit(cache=True, fastmath=False)
def _sample_rows(mat, wo, u, wi, density):
    for k in range(u.shape[0]):
        x, y, z, p = brdf_sample(mat, wo[k, 0], wo[k, 1], wo[k, 2], u[k, 0], u[k, 1], u[k, 2])
        wi[k, 0] = x
        wi[k, 1] = y
        wi[k, 2] = z
        density[k] = p


def _rows_of_three(*arrays) -> list[np.ndarray]:
    """Arrays of shape (3,) or (N, 3), broadcast together to C-contiguous float64 (N, 3)."""
    rows = [np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in arrays]
    for a in rows:
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"expected shape (3,) or (N, 3), got {a.shape}")
    shape = np.broadcast_shapes(*(a.shape for a in rows))
    return [np.ascontiguousarray(np.broadcast_to(a, shape)) for a in rows]


def eval_brdf(material: Material, wi, wo) -> np.ndarray:
    """f(wi, wo) for arrays of directions.

    wi, wo: float arrays of shape (N, 3) or (3,) (broadcast), unit vectors in the
    shading frame. Returns float64 (N, 3), RGB.
    """
    wi, wo = _rows_of_three(wi, wo)
    out = np.empty((wi.shape[0], 3), dtype=np.float64)
    _eval_rows(pack_materials([material])[0], wi, wo, out)
    return out


def pdf(material: Material, wo, wi) -> np.ndarray:
    """``brdf_pdf`` for arrays: density of sampling wi given wo.

    wo, wi: float arrays of shape (N, 3) or (3,) (broadcast). Returns float64 (N,).
    """
    wo, wi = _rows_of_three(wo, wi)
    out = np.empty(wi.shape[0], dtype=np.float64)
    _pdf_rows(pack_materials([material])[0], wo, wi, out)
    return out


def sample(material: Material, wo, u) -> tuple[np.ndarray, np.ndarray]:
    """``brdf_sample`` for arrays.

    wo: float (N, 3) or (3,), unit vectors; u: float (N, 3), uniform in [0, 1).
    Returns (wi, pdf): float64 (N, 3) and (N,). Rows with wi[:, 2] <= 0 are
    samples below the horizon, to be treated as absorbed.
    """
    wo, u = _rows_of_three(wo, u)
    wi = np.empty_like(u)
    density = np.empty(u.shape[0], dtype=np.float64)
    _sample_rows(pack_materials([material])[0], wo, u, wi, density)
    return wi, density


def albedo(material: Material, cos_theta, microfacet_models: bool = True) -> np.ndarray:
    """Directional albedo rho(wo) = int f(wi, wo) cos(theta_i) dwi over the upper hemisphere.

    cos_theta: wo.z, a float or float array of shape (N,), in [0, 1] (at 0 the
    grazing limit). Deterministic quadrature, accurate to ~1e-12. Returns float64
    RGB, shape (3,) for a scalar, (N, 3) for an array: kd + ks * S(theta), where
    S = 1 at normal incidence and falls towards grazing incidence; with Fresnel
    kd b(theta) + ks (F0 S + (1 - F0) Q) (``radiosity.physics.materials``). A material
    with a microfacet model (and ``microfacet_models``): the oracle's albedo
    (``microfacet.directional_albedo``, quadrature over microfacet normals, to ~1e-4).
    """
    cos_theta = np.asarray(cos_theta, dtype=np.float64)
    if cos_theta.ndim > 1:
        raise ValueError(f"cos_theta must be a scalar or of shape (N,), got {cos_theta.shape}")
    if not np.all((cos_theta >= 0.0) & (cos_theta <= 1.0)):
        raise ValueError("cos_theta must be in [0, 1]")
    if material.microfacet is not None and microfacet_models:
        from radiosity.scene.microfacet import directional_albedo

        rho = directional_albedo(microfacet_reference(material.microfacet), np.atleast_1d(cos_theta))
        return rho[0] if cos_theta.ndim == 0 else rho
    specular = specular_albedo(material.exponent, np.atleast_1d(cos_theta))
    if material.fresnel is not None:
        f0 = np.asarray(material.fresnel)
        q = schlick_albedo(material.exponent, np.atleast_1d(cos_theta))
        diffuse = schlick_diffuse(np.atleast_1d(cos_theta))[:, None] * np.asarray(material.diffuse)
        rho = diffuse + (f0 * specular[:, None] + (1.0 - f0) * q[:, None]) * np.asarray(material.specular)
        return rho[0] if cos_theta.ndim == 0 else rho
    rho = np.asarray(material.diffuse) + specular[:, None] * np.asarray(material.specular)
    return rho[0] if cos_theta.ndim == 0 else rho


@numba.njit(cache=True, nogil=True, inline="always")
def textured_row(mat, rgb, row):
    """The material row ``mat`` with its diffuse colour multiplied by a texture's
    ``rgb`` (3-tuple), written into ``row`` (NCOL,) and returned; the probability of
    sampling the specular lobe follows the textured colour (``pack_materials``'s rule).
    """
    for c in range(NCOL if mat[KIND] != KIND_PHONG else KIND + 1):  # a Phong row's other columns are unread
        row[c] = mat[c]
    for c in range(3):
        row[KD + c] = mat[KD + c] * rgb[c]
    kd = (row[KD] + row[KD + 1] + row[KD + 2]) / 3.0
    ks = (row[KS] + row[KS + 1] + row[KS + 2]) / 3.0
    row[P_SPECULAR] = ks / (kd + ks) if kd + ks > 0.0 else 0.0
    return row


# --- the specular part alone (the gather's glossy hits and grids) ----------------------


@numba.njit(cache=True, nogil=True)
def specular_eval(mat, wix, wiy, wiz, wox, woy, woz):
    """The specular part of f(wi, wo) per channel (the diffuse part left out): ks F (n +
    2) / (2 pi) cos^n(alpha) for the Phong kind, the interface's lobe for a microfacet
    kind; 0 unless wi.z > 0 and wo.z > 0."""
    if mat[KIND] != KIND_PHONG:
        return mf_specular_eval(mat, wix, wiy, wiz, wox, woy, woz)
    if wiz <= 0.0 or woz <= 0.0:
        return 0.0, 0.0, 0.0
    n = mat[EXPONENT]
    lobe = (n + 2.0) * _INV_2PI * phong_lobe(wiz * woz - wix * wox - wiy * woy, n)
    f0, f1, f2 = 1.0, 1.0, 1.0
    if mat[HAS_FRESNEL] > 0.0:
        f0, f1, f2 = schlick(mat, half_cosine(wix * wox + wiy * woy + wiz * woz))
    return mat[KS] * f0 * lobe, mat[KS + 1] * f1 * lobe, mat[KS + 2] * f2 * lobe


@numba.njit(cache=True, nogil=True)
def specular_pdf(mat, wox, woy, woz, wix, wiy, wiz):
    """Density of ``specular_sample``'s wi for wo over the whole sphere."""
    if mat[KIND] != KIND_PHONG:
        return mf_specular_pdf(mat, wox, woy, woz, wix, wiy, wiz)
    n = mat[EXPONENT]
    return (n + 1.0) * _INV_2PI * phong_lobe(wiz * woz - wix * wox - wiy * woy, n)


@numba.njit(cache=True, nogil=True)
def specular_sample(mat, wox, woy, woz, u2, u3):
    """wi drawn from the specular part alone with uniform numbers (u2, u3): (wix, wiy, wiz,
    pdf), pdf ``specular_pdf``'s; wi may lie below the horizon (absorbed by the caller)."""
    if mat[KIND] != KIND_PHONG:
        return mf_specular_sample(mat, wox, woy, woz, u2, u3)
    wix, wiy, wiz, cos_alpha = _phong_lobe_direction(mat, wox, woy, woz, u2, 2.0 * math.pi * u3)
    n = mat[EXPONENT]
    return wix, wiy, wiz, (n + 1.0) * _INV_2PI * phong_lobe(cos_alpha, n)


def diffuse_reflectance(material: Material) -> np.ndarray:
    """The kd (3,) float64 that multiplies E' / pi in the material's diffuse radiance (the
    photons' estimate E', ``deposit_weight``): ``material.diffuse`` for the Phong kind, a
    rough plastic's packed KD (its substrate's, ``_pack_microfacet``), 0 for a conductor."""
    return pack_materials([material])[0, KD : KD + 3].copy()


@numba.njit(cache=True, nogil=True)
def _exitances(mat, cos_out, out):
    for k in range(cos_out.shape[0]):
        out[k] = diffuse_exitance(mat, cos_out[k])


def diffuse_exitances(material: Material, cos_out) -> np.ndarray:
    """``diffuse_exitance`` at each of ``cos_out`` (N,), float64: 1 for the Phong kind,
    1 - (1 - c)^5 with Fresnel, a rough plastic's t(c)."""
    cos_out = np.asarray(cos_out, dtype=np.float64)
    if material.microfacet is None:
        if material.fresnel is None:
            return np.ones(len(cos_out))
        return 1.0 - (1.0 - np.clip(cos_out, 0.0, 1.0)) ** 5
    out = np.empty(len(cos_out))
    _exitances(pack_materials([material])[0], np.ascontiguousarray(cos_out), out)
    return out


@lru_cache(maxsize=64)
def _microfacet_albedos(model, size: int) -> np.ndarray:
    from radiosity.scene.microfacet import directional_albedo

    return directional_albedo(microfacet_reference(model), np.linspace(0.0, 1.0, size))


def albedo_table(material: Material, size: int, microfacet_models: bool = True) -> np.ndarray:
    """The directional albedo (size, 3) at cos theta = k / (size - 1), what the photons
    tally absorption with: ``albedo`` at every node, a microfacet model's remembered per
    model (the shapes of a scene that share a bsdf share it; its quadrature takes about
    half a second)."""
    if material.microfacet is None or not microfacet_models:
        return albedo(material, np.linspace(0.0, 1.0, size), microfacet_models)
    return _microfacet_albedos(material.microfacet, size).copy()
