"""numba kernels of the microfacet kinds: Mitsuba 3's ``roughplastic`` and
``roughconductor``, GGX or Beckmann, isotropic, on one row of the packed material table
(``radiosity.scene.columns``).

The physics is that of the numpy oracle ``radiosity.scene.microfacet`` (Walter et al.
2007; Mitsuba 3's documentation for the parameters): the interface's lobe

    f_s(wi, wo) = s F(wi.h) D(h) G1(wi, h) G1(wo, h) / (4 cos_i cos_o),

s = ``specular_reflectance``, F the exact Fresnel reflectance (a dielectric of relative
index eta for plastics, a conductor of complex index eta + i k per channel for metals),
G1 Smith's masking (exact for both distributions; Mitsuba's Beckmann G1 is a rational fit
within 0.35 % of it); a plastic adds its substrate

    f_d(wi, wo) = kd' / (pi eta^2) t(cos_i) t(cos_o),

t the rough interface's transmittance, tabulated on ``MF_TABLE_SIZE`` cosines and
interpolated linearly, as Mitsuba does. The row stores KD = kd' / (eta^2 N), N = 1 / (2
int t(mu) mu dmu) in ``MF_DIFFUSE_NORM``, so that the photons' density estimate E' =
N int t(cos_i) L cos_i dwi (``deposit_weight``) is the irradiance E for uniform light
and the diffuse radiance is KD / pi * t(cos_o) * E' (``diffuse_exitance``), as for the
Phong kind with Fresnel.

Sampling: the interface's lobe by its distribution of visible normals (Heitz 2018 for
GGX; for Beckmann the visible slopes of Jakob 2014, the x slope found by a bracketed
Newton iteration in erf's domain), wi the reflection of wo about the sampled normal, so
f_s cos_i / pdf_s = s F G1(wi, h): one masking term, no D. The plastic picks the
interface with Mitsuba's probability (1 - t(cos_o)) w / ((1 - t(cos_o)) w + t(cos_o)
(1 - w)), w = mean(s) / (mean(s) + mean(kd)), at least ``P_MIN`` either way where both
parts reflect; otherwise the cosine-weighted hemisphere.

Conventions as in ``radiosity.scene.material_kernels``: the local shading frame (z the normal),
wi and wo unit vectors pointing away from the surface, values without the cosine.
"""

from __future__ import annotations

import cmath
import math

import numba

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.scene.columns import (
    KD,
    KIND,
    KIND_ROUGH_PLASTIC,
    MF_ALPHA,
    MF_DIFFUSE_NORM,
    MF_DISTRIBUTION,
    MF_ETA,
    MF_GGX,
    MF_K,
    MF_SPECULAR,
    MF_SPECULAR_WEIGHT,
    MF_TABLE,
    MF_TABLE_SIZE,
)

__all__ = [
    "P_MIN",
    "erfinv",
    "fresnel_conductor",
    "fresnel_dielectric",
    "interface_fresnel",
    "mf_deposit_weight",
    "mf_diffuse_exitance",
    "mf_eval",
    "mf_pdf",
    "mf_sample",
    "mf_specular_eval",
    "mf_specular_pdf",
    "mf_specular_sample",
    "ndf",
    "smith_g1",
    "transmittance",
    "visible_normal",
]

P_MIN = 0.05  # the least probability of either part of a rough plastic that has both
_INV_PI = 1.0 / math.pi
_INV_SQRT_PI = 1.0 / math.sqrt(math.pi)
_ONE_MINUS = 1.0 - 2.0**-52  # the largest |z| erfinv is asked for


@numba.njit(cache=True, nogil=True)
def ndf(distribution, alpha, cos_h):
    """D(h) of the isotropic distribution (``MF_GGX`` or ``MF_BECKMANN``) at cos_h = h.z;
    0 for cos_h <= 0. Normalised: int D(h) cos(theta_h) dh = 1."""
    if cos_h <= 0.0:
        return 0.0
    c2 = min(cos_h * cos_h, 1.0)
    s2 = 1.0 - c2
    a2 = alpha * alpha
    if distribution == MF_GGX:
        t = a2 * c2 + s2
        return a2 * _INV_PI / (t * t)
    return math.exp(-s2 / (c2 * a2)) * _INV_PI / (a2 * c2 * c2)


@numba.njit(cache=True, nogil=True)
def smith_g1(distribution, alpha, cos_v, cos_vh):
    """Smith's G1(v, h) for v at cos_v = v.z to the normal, cos_vh = v.h: 0 where v sees
    the microfacet's back (cos_v cos_vh <= 0). GGX: 2 / (1 + sqrt(1 + alpha^2 tan^2));
    Beckmann: 2 / (1 + erf(a) + exp(-a^2) / (a sqrt pi)), a = 1 / (alpha tan), 1 beyond a = 30."""
    if cos_v * cos_vh <= 0.0:
        return 0.0
    c2 = min(cos_v * cos_v, 1.0)
    s2 = 1.0 - c2
    if s2 <= 0.0:
        return 1.0
    if distribution == MF_GGX:
        return 2.0 / (1.0 + math.sqrt(1.0 + alpha * alpha * s2 / c2))
    a = math.sqrt(c2 / s2) / alpha
    if a > 30.0:
        return 1.0
    return 2.0 / (1.0 + math.erf(a) + math.exp(-a * a) * _INV_SQRT_PI / a)


@numba.njit(cache=True, nogil=True)
def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric of relative index eta at |cos_i|;
    1 under total internal reflection (Walter et al. 2007, eq. 22)."""
    c = min(abs(cos_i), 1.0)
    g2 = eta * eta - 1.0 + c * c
    if g2 <= 0.0:
        return 1.0
    g = math.sqrt(g2)
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return 0.5 * a * a * (1.0 + b * b)


@numba.njit(cache=True, nogil=True)
def fresnel_conductor(cos_i, eta, k):
    """Unpolarised Fresnel reflectance of a conductor of complex index eta + i k at
    |cos_i|: the complex s and p amplitudes, averaged in power (eta + i k != 0)."""
    c = min(abs(cos_i), 1.0)
    n = complex(eta, k)
    cos_t = cmath.sqrt(1.0 - (1.0 - c * c) / (n * n))
    rs = (c - n * cos_t) / (c + n * cos_t)
    rp = (n * c - cos_t) / (n * c + cos_t)
    return 0.5 * (rs.real * rs.real + rs.imag * rs.imag + rp.real * rp.real + rp.imag * rp.imag)


@numba.njit(cache=True, nogil=True)
def erfinv(z):
    """The inverse of erf on (-1, 1), to about 1e-15 (Giles 2010's approximation, then two
    Newton steps on math.erf); |z| is clamped to just below 1."""
    z = min(max(z, -_ONE_MINUS), _ONE_MINUS)
    w = -math.log((1.0 - z) * (1.0 + z))
    if w < 5.0:
        w -= 2.5
        p = 2.81022636e-08
        p = 3.43273939e-07 + p * w
        p = -3.5233877e-06 + p * w
        p = -4.39150654e-06 + p * w
        p = 0.00021858087 + p * w
        p = -0.00125372503 + p * w
        p = -0.00417768164 + p * w
        p = 0.246640727 + p * w
        p = 1.50140941 + p * w
    else:
        w = math.sqrt(w) - 3.0
        p = -0.000200214257
        p = 0.000100950558 + p * w
        p = 0.00134934322 + p * w
        p = -0.00367342844 + p * w
        p = 0.00573950773 + p * w
        p = -0.0076224613 + p * w
        p = 0.00943887047 + p * w
        p = 1.00167406 + p * w
        p = 2.83297682 + p * w
    x = p * z
    for _ in range(2):
        slope = 2.0 * _INV_SQRT_PI * math.exp(-x * x)
        if slope <= 0.0:
            break
        x -= (math.erf(x) - z) / slope
    return x


@numba.njit(cache=True, nogil=True)
def _beckmann_visible_slopes(cos_t, u1, u2):
    """Slopes (x, y) of a visible normal of the unit-roughness Beckmann distribution for a
    view at cos_t in the x-z plane (Jakob 2014): y ~ N(0, 1/2); x from the cumulative
    C(x) = 1 + erf(x) + tan/sqrt(pi) exp(-x^2), x < cot, solved for C = u1 C(cot) in z = erf(x)
    (C is increasing in z: dC/dz = 1 - x tan > 0) by Newton steps kept inside a bracket."""
    y = erfinv(2.0 * u2 - 1.0)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    if sin_t < 1e-12:
        return erfinv(2.0 * u1 - 1.0), y
    tan_t = sin_t / cos_t
    cot_t = cos_t / sin_t
    top = math.erf(cot_t)
    target = u1 * (1.0 + top + tan_t * _INV_SQRT_PI * math.exp(-cot_t * cot_t))
    lo, hi = -1.0, top
    z = 0.5 * (lo + hi)
    for _ in range(60):
        x = erfinv(z)
        value = 1.0 + z + tan_t * _INV_SQRT_PI * math.exp(-x * x) - target
        if value > 0.0:
            hi = z
        else:
            lo = z
        step = value / max(1.0 - x * tan_t, 1e-12)
        nz = z - step
        if not (lo < nz < hi):
            nz = 0.5 * (lo + hi)
        if abs(nz - z) < 1e-14:
            z = nz
            break
        z = nz
    return erfinv(z), y


@numba.njit(cache=True, nogil=True)
def visible_normal(distribution, alpha, wx, wy, wz, u1, u2):
    """A microfacet normal m drawn with density G1(w, m) max(0, w.m) D(m) / w.z for a view
    w (w.z > 0) from uniform numbers u1, u2: Heitz 2018 for GGX (the hemisphere of the
    stretched view), Jakob 2014's visible slopes for Beckmann. Returns (mx, my, mz)."""
    sx, sy, sz = alpha * wx, alpha * wy, wz
    inv = 1.0 / math.sqrt(sx * sx + sy * sy + sz * sz)
    sx, sy, sz = sx * inv, sy * inv, sz * inv
    if distribution == MF_GGX:
        lensq = sx * sx + sy * sy
        if lensq > 0.0:
            il = 1.0 / math.sqrt(lensq)
            t1x, t1y, t1z = -sy * il, sx * il, 0.0
        else:
            t1x, t1y, t1z = 1.0, 0.0, 0.0
        t2x = sy * t1z - sz * t1y
        t2y = sz * t1x - sx * t1z
        t2z = sx * t1y - sy * t1x
        r = math.sqrt(u1)
        phi = 2.0 * math.pi * u2
        p1 = r * math.cos(phi)
        p2 = r * math.sin(phi)
        s = 0.5 * (1.0 + sz)
        p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
        pz = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
        nx = p1 * t1x + p2 * t2x + pz * sx
        ny = p1 * t1y + p2 * t2y + pz * sy
        nz = p1 * t1z + p2 * t2z + pz * sz
        mx, my, mz = alpha * nx, alpha * ny, max(nz, 1e-300)
    else:
        sin_t = math.sqrt(sx * sx + sy * sy)
        cos_phi, sin_phi = 1.0, 0.0
        if sin_t > 1e-300:
            cos_phi, sin_phi = sx / sin_t, sy / sin_t
        ax, ay = _beckmann_visible_slopes(sz, u1, u2)
        slope_x = alpha * (cos_phi * ax - sin_phi * ay)
        slope_y = alpha * (sin_phi * ax + cos_phi * ay)
        mx, my, mz = -slope_x, -slope_y, 1.0
    inv = 1.0 / math.sqrt(mx * mx + my * my + mz * mz)
    return mx * inv, my * inv, mz * inv


@numba.njit(cache=True, nogil=True)
def transmittance(mat, mu):
    """A rough plastic's interface transmittance t(mu) from its table (linear in mu)."""
    x = min(max(mu, 0.0), 1.0) * (MF_TABLE_SIZE - 1)
    k = min(int(x), MF_TABLE_SIZE - 2)
    f = x - k
    return (1.0 - f) * mat[MF_TABLE + k] + f * mat[MF_TABLE + k + 1]


@numba.njit(cache=True, nogil=True)
def interface_fresnel(mat, cos_i):
    """The interface's F times specular_reflectance per channel at wi.h = cos_i."""
    if mat[KIND] == KIND_ROUGH_PLASTIC:
        f = fresnel_dielectric(cos_i, mat[MF_ETA])
        return f * mat[MF_SPECULAR], f * mat[MF_SPECULAR + 1], f * mat[MF_SPECULAR + 2]
    return (
        fresnel_conductor(cos_i, mat[MF_ETA], mat[MF_K]) * mat[MF_SPECULAR],
        fresnel_conductor(cos_i, mat[MF_ETA + 1], mat[MF_K + 1]) * mat[MF_SPECULAR + 1],
        fresnel_conductor(cos_i, mat[MF_ETA + 2], mat[MF_K + 2]) * mat[MF_SPECULAR + 2],
    )


@numba.njit(cache=True, nogil=True)
def _half(wix, wiy, wiz, wox, woy, woz):
    hx, hy, hz = wix + wox, wiy + woy, wiz + woz
    norm = math.sqrt(hx * hx + hy * hy + hz * hz)
    if norm <= 0.0:
        return 0.0, 0.0, 0.0, False
    return hx / norm, hy / norm, hz / norm, True


@numba.njit(cache=True, nogil=True)
def mf_specular_eval(mat, wix, wiy, wiz, wox, woy, woz):
    """The interface's lobe f_s(wi, wo) per channel; 0 unless wi.z > 0 and wo.z > 0."""
    if wiz <= 0.0 or woz <= 0.0:
        return 0.0, 0.0, 0.0
    hx, hy, hz, ok = _half(wix, wiy, wiz, wox, woy, woz)
    if not ok:
        return 0.0, 0.0, 0.0
    dist, alpha = mat[MF_DISTRIBUTION], mat[MF_ALPHA]
    cih = wix * hx + wiy * hy + wiz * hz
    coh = wox * hx + woy * hy + woz * hz
    g = smith_g1(dist, alpha, wiz, cih) * smith_g1(dist, alpha, woz, coh)
    if g <= 0.0:
        return 0.0, 0.0, 0.0
    value = ndf(dist, alpha, hz) * g / (4.0 * wiz * woz)
    f0, f1, f2 = interface_fresnel(mat, cih)
    return value * f0, value * f1, value * f2


@numba.njit(cache=True, nogil=True)
def mf_specular_pdf(mat, wox, woy, woz, wix, wiy, wiz):
    """Density of ``mf_specular_sample``'s wi for this wo: G1(wo, h) D(h) / (4 wo.z),
    h = normalize(wi + wo); over the whole sphere (wi below the horizon included)."""
    if woz <= 0.0:
        return 0.0
    hx, hy, hz, ok = _half(wix, wiy, wiz, wox, woy, woz)
    if not ok:
        return 0.0
    dist, alpha = mat[MF_DISTRIBUTION], mat[MF_ALPHA]
    coh = wox * hx + woy * hy + woz * hz
    return smith_g1(dist, alpha, woz, coh) * ndf(dist, alpha, hz) / (4.0 * woz)


@numba.njit(cache=True, nogil=True)
def mf_specular_sample(mat, wox, woy, woz, u1, u2):
    """wi reflected from wo about a visible normal drawn from (u1, u2). Returns (wix, wiy,
    wiz, pdf) with ``mf_specular_pdf``'s density; wi may lie below the horizon (absorbed
    by the caller), and pdf is 0 where wo is."""
    if woz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0
    mx, my, mz = visible_normal(mat[MF_DISTRIBUTION], mat[MF_ALPHA], wox, woy, woz, u1, u2)
    dot = wox * mx + woy * my + woz * mz
    wix, wiy, wiz = 2.0 * dot * mx - wox, 2.0 * dot * my - woy, 2.0 * dot * mz - woz
    return wix, wiy, wiz, mf_specular_pdf(mat, wox, woy, woz, wix, wiy, wiz)


@numba.njit(cache=True, nogil=True)
def mf_p_specular(mat, woz):
    """Probability that ``mf_sample`` samples the interface for wo.z = woz: 1 for a
    conductor; for a plastic Mitsuba's rule (the module's docstring), kept in [P_MIN, 1 - P_MIN]
    where both parts reflect."""
    if mat[KIND] != KIND_ROUGH_PLASTIC:
        return 1.0
    kd = mat[KD] + mat[KD + 1] + mat[KD + 2]
    s = mat[MF_SPECULAR] + mat[MF_SPECULAR + 1] + mat[MF_SPECULAR + 2]
    if s <= 0.0:
        return 0.0
    if kd <= 0.0:
        return 1.0
    w = mat[MF_SPECULAR_WEIGHT]
    t = transmittance(mat, woz)
    ps = (1.0 - t) * w
    pd = t * (1.0 - w)
    p = ps / (ps + pd) if ps + pd > 0.0 else 0.5
    return min(max(p, P_MIN), 1.0 - P_MIN)


@numba.njit(cache=True, nogil=True)
def mf_diffuse_exitance(mat, cos_out):
    """The factor of KD / pi * E' in the diffuse radiance leaving at cos_out: t(cos_out)
    for a plastic (0 for a conductor: it has no diffuse part)."""
    if mat[KIND] != KIND_ROUGH_PLASTIC:
        return 0.0
    return transmittance(mat, cos_out)


@numba.njit(cache=True, nogil=True)
def mf_deposit_weight(mat, cos_in):
    """What a photon arriving at cos_in adds to a plastic's density estimate per unit
    power: N t(cos_in) (``MF_DIFFUSE_NORM``), so E' = E for uniform light; 1 for a conductor."""
    if mat[KIND] != KIND_ROUGH_PLASTIC:
        return 1.0
    return mat[MF_DIFFUSE_NORM] * transmittance(mat, cos_in)


@numba.njit(cache=True, nogil=True)
def mf_eval(mat, wix, wiy, wiz, wox, woy, woz):
    """f(wi, wo) per channel: the interface's lobe, plus a plastic's substrate."""
    if wiz <= 0.0 or woz <= 0.0:
        return 0.0, 0.0, 0.0
    s0, s1, s2 = mf_specular_eval(mat, wix, wiy, wiz, wox, woy, woz)
    if mat[KIND] != KIND_ROUGH_PLASTIC:
        return s0, s1, s2
    d = _INV_PI * mat[MF_DIFFUSE_NORM] * transmittance(mat, wiz) * transmittance(mat, woz)
    return s0 + mat[KD] * d, s1 + mat[KD + 1] * d, s2 + mat[KD + 2] * d


@numba.njit(cache=True, nogil=True)
def mf_pdf(mat, wox, woy, woz, wix, wiy, wiz):
    """Density of ``mf_sample``'s wi for this wo over the whole sphere."""
    p = mf_p_specular(mat, woz)
    value = p * mf_specular_pdf(mat, wox, woy, woz, wix, wiy, wiz) if p > 0.0 else 0.0
    if p < 1.0:
        value += (1.0 - p) * max(0.0, wiz) * _INV_PI
    return value


@numba.njit(cache=True, nogil=True)
def mf_sample(mat, wox, woy, woz, u1, u2, u3):
    """wi for wo from uniform numbers: u1 < ``mf_p_specular`` samples the interface with
    (u2, u3), otherwise the cosine-weighted hemisphere. Returns (wix, wiy, wiz, pdf), pdf
    ``mf_pdf``'s; wi may lie below the horizon (absorbed by the caller)."""
    p = mf_p_specular(mat, woz)
    if u1 < p:
        wix, wiy, wiz, _ = mf_specular_sample(mat, wox, woy, woz, u2, u3)
    else:
        phi = 2.0 * math.pi * u3
        radius = math.sqrt(u2)
        wix, wiy, wiz = radius * math.cos(phi), radius * math.sin(phi), math.sqrt(1.0 - u2)
    return wix, wiy, wiz, mf_pdf(mat, wox, woy, woz, wix, wiy, wiz)
