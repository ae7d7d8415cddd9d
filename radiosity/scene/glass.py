"""numpy oracle of the glass kinds (``radiosity.physics.materials.Glass``), written from the
formulas (Walter et al. 2007; Mitsuba 3's ``dielectric``, ``thindielectric`` and
``roughdielectric``), which tests hold the kernels (``radiosity.scene.glass_kernels``)
to. Conventions are the kernels': z the outward normal, wo and wi pointing away from the
surface on either side, eta the index inside over outside.

- ``reflectance(glass, cos_o)``: the probability that a smooth kind reflects at wo.z =
  cos_o (Fresnel's from wo's side; a thin sheet's summed over its two faces).
- ``RoughDielectric``: ``eval`` (the BSDF, importance-transport form: no 1 / eta^2 on
  refraction), ``pdf`` (the visible-normal sampler's density over the sphere).
"""

from __future__ import annotations

import numpy as np

from radiosity.physics.materials import Glass
from radiosity.scene.microfacet import fresnel_dielectric, masking, ndf

__all__ = ["RoughDielectric", "reflectance"]


def reflectance(glass: Glass, cos_o) -> np.ndarray:
    """The smooth kinds' probability of reflection at wo.z = cos_o (array; either side)."""
    cos_o = np.asarray(cos_o, dtype=np.float64)
    if glass.kind == "thindielectric":
        f = fresnel_dielectric(np.abs(cos_o), glass.eta)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(f < 1.0, f + (1.0 - f) ** 2 * f / (1.0 - f * f), 1.0)
    eta_ti = np.where(cos_o >= 0.0, glass.eta, 1.0 / glass.eta)
    return fresnel_dielectric(np.abs(cos_o), eta_ti)


class RoughDielectric:
    """A rough dielectric interface's BSDF and its sampler's density, by the formulas."""

    def __init__(self, glass: Glass):
        if glass.kind != "roughdielectric":
            raise ValueError(f"RoughDielectric needs a roughdielectric, got {glass.kind}")
        self.glass = glass

    def _geometry(self, wi, wo):
        """(reflected, m turned to wo's side, eta_ti, wo and wi in the frame turned to wo's side)."""
        wi, wo = np.atleast_2d(np.asarray(wi, np.float64)), np.atleast_2d(np.asarray(wo, np.float64))
        side = np.where(wo[:, 2] >= 0.0, 1.0, -1.0)[:, None]
        o, i = wo * side, wi * side
        eta_ti = np.where(side[:, 0] > 0.0, self.glass.eta, 1.0 / self.glass.eta)
        reflected = i[:, 2] > 0.0
        m = np.where(reflected[:, None], o + i, -(o + eta_ti[:, None] * i))
        m = m / np.linalg.norm(m, axis=1, keepdims=True)
        m = m * np.where(m[:, 2] < 0.0, -1.0, 1.0)[:, None]
        return reflected, m, eta_ti, o, i

    def _parts(self, wi, wo):
        g = self.glass
        reflected, m, eta_ti, o, i = self._geometry(wi, wo)
        cos_om, cos_im = np.sum(o * m, axis=1), np.sum(i * m, axis=1)
        f = fresnel_dielectric(np.clip(cos_om, 0.0, 1.0), eta_ti)
        d = ndf(g.distribution, g.alpha, m[:, 2])
        g_o = masking(g.distribution, g.alpha, o[:, 2], cos_om)
        g_i = masking(g.distribution, g.alpha, i[:, 2], cos_im)
        denominator = cos_om + eta_ti * cos_im
        jacobian = np.where(reflected, 1.0 / (4.0 * np.abs(cos_om)), eta_ti ** 2 * np.abs(cos_im) / denominator ** 2)
        ok = (cos_om > 0.0) & (o[:, 2] > 0.0) & np.where(reflected, cos_im > 0.0, cos_im < 0.0)
        return reflected, f, d, g_o, g_i, cos_om, jacobian, ok, o, i

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo) per channel, (N, 3): F D G / (4 |wo.z wi.z|) reflected, (1 - F) D G
        eta_ti^2 |wi.m| |wo.m| / (|wo.z wi.z| (wo.m + eta_ti wi.m)^2) refracted; G = G1 G1."""
        reflected, f, d, g_o, g_i, cos_om, jacobian, ok, o, i = self._parts(wi, wo)
        common = d * g_o * g_i * jacobian * np.abs(cos_om) / np.abs(o[:, 2] * i[:, 2])
        value = np.where(reflected, f, 1.0 - f) * common
        scale = np.where(reflected[:, None], np.asarray(self.glass.specular_reflectance),
                         np.asarray(self.glass.specular_transmittance))
        return np.where(ok[:, None], value[:, None] * scale, 0.0)

    def pdf(self, wo, wi) -> np.ndarray:
        """The density of the kernels' sampler: D_wo(m) F or (1 - F) times the Jacobian, D_wo
        the visible normals' density G1(wo, m) (wo.m) D(m) / wo.z."""
        reflected, f, d, g_o, g_i, cos_om, jacobian, ok, o, i = self._parts(wi, wo)
        visible = g_o * np.clip(cos_om, 0.0, None) * d / o[:, 2]
        return np.where(ok, visible * np.where(reflected, f, 1.0 - f) * jacobian, 0.0)
