"""numba kernels of the glass kinds (``radiosity.physics.materials.Glass``): a dielectric
interface that reflects and transmits, on either face.

Conventions differ from the reflecting kinds' in one way: the local frame's z is the
surface's outward normal as the mesh gives it (not turned toward the arriving ray), so
wo.z < 0 means the path arrives from inside. wo points away from the surface (toward
where the path came from); the sampled wi points away from it too, on either side.

``glass_sample`` draws wi and returns the sample's weight f |wi.z| / pdf per channel,
as Mitsuba 3 does (the choice between reflection and refraction made with the Fresnel
reflectance, so it cancels from the weight), and the density pdf of the sample (0 for the
smooth kinds, whose directions are discrete: a path that leaves them counts an emitter it
hits in full). ``radiance`` True scales a refracted sample by 1 / eta_ti^2, eta_ti the
index ratio of the side wi enters over wo's side (radiance is compressed into the
smaller solid angle of the denser side); the photons carry power (``radiance`` False).

- dielectric: reflect with probability F(|wo.z|, eta_ti) (Fresnel's, 1 under total
  internal reflection), else refract by Snell's law.
- thindielectric: R = F + T^2 F / (1 - F^2) (the two faces' reflections summed); reflect
  with probability R, else pass straight through (wi = -wo), never scaled.
- roughdielectric: a microfacet normal m drawn from the visible normals of wo's side
  (``microfacet_kernels.visible_normal``), then reflect about m with probability F(wo.m),
  else refract through m; weight G1(wi, m) (a direction on m's wrong side is absorbed).

The numpy oracle (``radiosity.scene.glass``) evaluates the same models from their
formulas; tests/radiosity/scene/test_glass.py holds these kernels to it.
"""

from __future__ import annotations

import math

import numba

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.scene.columns import (
    GLASS_TRANSMITTANCE,
    KIND,
    KIND_THIN_DIELECTRIC,
    MF_ALPHA,
    MF_DISTRIBUTION,
    MF_ETA,
    MF_SPECULAR,
)
from radiosity.scene.microfacet_kernels import fresnel_dielectric, ndf, smith_g1, visible_normal


@numba.njit(cache=True, nogil=True)
def _refract(wox, woy, woz, mx, my, mz, cos_om, eta_ti):
    """wo refracted through the unit normal m (wo.m = cos_om > 0, wo on m's side) into the
    side of index ratio eta_ti; (0, 0, 0) under total internal reflection."""
    sin2_t = (1.0 - cos_om * cos_om) / (eta_ti * eta_ti)
    if sin2_t >= 1.0:
        return 0.0, 0.0, 0.0
    cos_t = math.sqrt(1.0 - sin2_t)
    k = cos_om / eta_ti - cos_t
    return -wox / eta_ti + k * mx, -woy / eta_ti + k * my, -woz / eta_ti + k * mz


@numba.njit(cache=True, nogil=True)
def glass_sample(mat, wox, woy, woz, u1, u2, u3, radiance):
    """wi for wo from uniform numbers (u1 picks reflection or transmission, u2 and u3 a
    rough interface's normal). Returns (wix, wiy, wiz, w0, w1, w2, pdf): the weight f
    |wi.z| / pdf per channel and the density (0 for a smooth kind's discrete directions;
    a rough kind's per unit solid angle). A weight of 0 is an absorbed sample."""
    eta = mat[MF_ETA]
    outside = woz >= 0.0
    eta_ti = eta if outside else 1.0 / eta
    kind = mat[KIND]
    if mat[MF_ALPHA] <= 0.0:
        if kind == KIND_THIN_DIELECTRIC:
            f = fresnel_dielectric(woz, eta)
            if f < 1.0:
                f += (1.0 - f) * (1.0 - f) * f / (1.0 - f * f)
            if u1 < f:
                return -wox, -woy, woz, mat[MF_SPECULAR], mat[MF_SPECULAR + 1], mat[MF_SPECULAR + 2], 0.0
            t = GLASS_TRANSMITTANCE
            return -wox, -woy, -woz, mat[t], mat[t + 1], mat[t + 2], 0.0
        f = fresnel_dielectric(woz, eta_ti)
        if u1 < f:
            return -wox, -woy, woz, mat[MF_SPECULAR], mat[MF_SPECULAR + 1], mat[MF_SPECULAR + 2], 0.0
        side = 1.0 if outside else -1.0
        wix, wiy, wiz = _refract(wox, woy, woz, 0.0, 0.0, side, abs(woz), eta_ti)
        scale = 1.0 / (eta_ti * eta_ti) if radiance else 1.0
        t = GLASS_TRANSMITTANCE
        return wix, wiy, wiz, mat[t] * scale, mat[t + 1] * scale, mat[t + 2] * scale, 0.0
    # rough: in the frame turned to wo's side
    side = 1.0 if outside else -1.0
    ox, oy, oz = wox * side, woy * side, woz * side
    distribution, alpha = mat[MF_DISTRIBUTION], mat[MF_ALPHA]
    if oz <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0
    mx, my, mz = visible_normal(distribution, alpha, ox, oy, oz, u2, u3)
    inv = 1.0 / math.sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx * inv, my * inv, mz * inv
    cos_om = ox * mx + oy * my + oz * mz
    if cos_om <= 0.0:
        return 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0
    f = fresnel_dielectric(cos_om, eta_ti)
    d_visible = smith_g1(distribution, alpha, oz, cos_om) * cos_om * ndf(distribution, alpha, mz) / oz
    if u1 < f:
        ix, iy, iz = 2.0 * cos_om * mx - ox, 2.0 * cos_om * my - oy, 2.0 * cos_om * mz - oz
        cos_im = cos_om
        g = smith_g1(distribution, alpha, iz, cos_im) if iz > 0.0 else 0.0
        pdf = f * d_visible / (4.0 * cos_om)
        w = (mat[MF_SPECULAR] * g, mat[MF_SPECULAR + 1] * g, mat[MF_SPECULAR + 2] * g)
    else:
        ix, iy, iz = _refract(ox, oy, oz, mx, my, mz, cos_om, eta_ti)
        cos_im = ix * mx + iy * my + iz * mz
        g = smith_g1(distribution, alpha, iz, cos_im) if iz < 0.0 else 0.0
        denominator = cos_om + eta_ti * cos_im
        pdf = (1.0 - f) * d_visible * eta_ti * eta_ti * abs(cos_im) / (denominator * denominator)
        scale = g / (eta_ti * eta_ti) if radiance else g
        t = GLASS_TRANSMITTANCE
        w = (mat[t] * scale, mat[t + 1] * scale, mat[t + 2] * scale)
    return ix * side, iy * side, iz * side, w[0], w[1], w[2], pdf
