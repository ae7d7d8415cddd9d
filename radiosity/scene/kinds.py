"""The material kinds: each defined once, by a numpy oracle of its evaluation, sampling
density and albedo, beside the numba kernels that run it.

A material is of one kind (``kind_of``): ``"phong"`` (Lambert plus modified Phong, with
or without Schlick's Fresnel: ``radiosity.physics.materials``), ``"roughplastic"`` or
``"roughconductor"`` (a ``Microfacet`` model: ``radiosity.scene.microfacet_kernels``).
Every kernel of the project that shades a surface goes through the dispatch of
``radiosity.scene.material_kernels`` (``brdf_eval``, ``brdf_pdf``, ``brdf_sample``,
``deposit_weight``, ``diffuse_exitance``), which reads the row's ``KIND`` column; the
oracle of each kind (``oracle``) is plain numpy, written from the formulas, and the tests
(tests/radiosity/scene/test_material_kinds.py) hold the kernels to it for every kind in
``KINDS``: values and densities at many (wi, wo) pairs with the extremes (grazing, the
mirror direction, the smallest and largest roughness or exponent), the sampler by a
chi-square test against the oracle's density, energy and reciprocity.

Adding a kind: its parameters (a record in ``radiosity.physics.materials`` and its file
key, a versioned addition in docs/formats.md), its columns in ``radiosity.scene.columns``
and a ``KIND_*`` code, its kernels and their branch in the dispatch, its oracle here and a
row of ``KINDS`` (the tests then cover it), and how the displays draw it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from radiosity.physics.materials import Material
from radiosity.scene import microfacet
from radiosity.scene.columns import KIND_PHONG, KIND_ROUGH_CONDUCTOR, KIND_ROUGH_PLASTIC
from radiosity.scene.material_kernels import P_SPECULAR_MIN, albedo, microfacet_reference

__all__ = ["KINDS", "Kind", "MicrofacetOracle", "PhongOracle", "kind_of", "oracle"]


def _unit_rows(w) -> np.ndarray:
    return np.atleast_2d(np.asarray(w, dtype=np.float64))


class PhongOracle:
    """numpy evaluation of the Phong kind (``radiosity.physics.materials``'s formulas)."""

    def __init__(self, material: Material):
        self.material = material
        self.kd = np.asarray(material.diffuse)
        self.ks = np.asarray(material.specular)
        self.n = material.exponent
        self.f0 = None if material.fresnel is None else np.asarray(material.fresnel)

    def _lobe(self, cos_alpha):
        c = np.clip(cos_alpha, 0.0, 1.0)
        with np.errstate(divide="ignore"):
            return np.where(cos_alpha > 0.0, np.exp(self.n * np.log(np.maximum(c, 1e-300))), 0.0)

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo), (N, 3)."""
        wi, wo = _unit_rows(wi), _unit_rows(wo)
        ok = (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)
        cos_alpha = wi[:, 2] * wo[:, 2] - wi[:, 0] * wo[:, 0] - wi[:, 1] * wo[:, 1]
        specular = ((self.n + 2.0) / (2.0 * math.pi) * self._lobe(cos_alpha))[:, None] * self.ks
        if self.f0 is None:
            value = self.kd / math.pi + specular
        else:
            cos_h = np.sqrt(np.clip(0.5 * (1.0 + np.sum(wi * wo, axis=1)), 0.0, 1.0))
            f = self.f0 + (1.0 - self.f0) * ((1.0 - cos_h) ** 5)[:, None]
            b = lambda c: 1.0 - (1.0 - np.clip(c, 0.0, 1.0)) ** 5  # noqa: E731
            value = (21.0 / 20.0 / math.pi * b(wi[:, 2]) * b(wo[:, 2]))[:, None] * self.kd + specular * f
        return np.where(ok[:, None], value, 0.0)

    def p_specular(self, cos_o) -> np.ndarray:
        kd, ks = self.kd.mean(), self.ks.mean()
        cos_o = np.asarray(cos_o, dtype=np.float64)
        if self.f0 is None:
            return np.full(cos_o.shape, ks / (kd + ks) if kd + ks > 0.0 else 0.0)
        b = 1.0 - (1.0 - np.clip(cos_o, 0.0, 1.0)) ** 5
        f0 = self.f0.mean()
        s = ks * (f0 + (1.0 - f0) * (1.0 - b))
        d = kd * b
        if ks <= 0.0:
            return np.zeros(cos_o.shape)
        return np.maximum(s / (d + s), P_SPECULAR_MIN)

    def pdf(self, wo, wi) -> np.ndarray:
        """The sampler's density of wi for wo over the whole sphere, (N,)."""
        wi, wo = _unit_rows(wi), _unit_rows(wo)
        p = self.p_specular(wo[:, 2])
        cos_alpha = wi[:, 2] * wo[:, 2] - wi[:, 0] * wo[:, 0] - wi[:, 1] * wo[:, 1]
        specular = (self.n + 1.0) / (2.0 * math.pi) * self._lobe(cos_alpha)
        return (1.0 - p) * np.maximum(wi[:, 2], 0.0) / math.pi + p * specular

    def albedo(self, cos_theta) -> np.ndarray:
        """Directional albedo (N, 3), by deterministic quadrature."""
        return albedo(self.material, np.atleast_1d(np.asarray(cos_theta, dtype=np.float64)))


class MicrofacetOracle:
    """numpy evaluation of a microfacet kind: ``radiosity.scene.microfacet``'s reference
    BRDF, and the sampler's density written from its definition (the visible normals'
    density G1(wo, h) D(h) / (4 wo.z) for the interface; a plastic mixes it with the
    cosine-weighted hemisphere by Mitsuba's probability, ``microfacet_kernels``)."""

    def __init__(self, material: Material):
        self.material = material
        self.model = material.microfacet
        self.brdf = microfacet_reference(self.model)

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo), (N, 3)."""
        wi, wo = _unit_rows(wi), _unit_rows(wo)
        wi, wo = np.broadcast_arrays(wi, wo)
        return self.brdf.eval(wi, wo)

    def specular_pdf(self, wo, wi) -> np.ndarray:
        wi, wo = np.broadcast_arrays(_unit_rows(wi), _unit_rows(wo))
        h = wi + wo
        h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
        dist, alpha = self.model.distribution, self.model.alpha
        coh = np.sum(wo * h, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            value = microfacet.masking(dist, alpha, wo[:, 2], coh) * microfacet.ndf(dist, alpha, h[:, 2]) / (4.0 * wo[:, 2])
        return np.where(wo[:, 2] > 0.0, np.nan_to_num(value), 0.0)

    def p_specular(self, cos_o) -> np.ndarray:
        cos_o = np.asarray(cos_o, dtype=np.float64)
        if self.model.kind == "roughconductor":
            return np.ones(cos_o.shape)
        s, d = np.mean(self.model.specular_reflectance), np.mean(self.model.diffuse_reflectance)
        if s <= 0.0:
            return np.zeros(cos_o.shape)
        if d <= 0.0:
            return np.ones(cos_o.shape)
        w = s / (s + d)
        t = self.brdf.transmittance(cos_o)
        ps, pd = (1.0 - t) * w, t * (1.0 - w)
        return np.clip(ps / (ps + pd), P_SPECULAR_MIN, 1.0 - P_SPECULAR_MIN)

    def pdf(self, wo, wi) -> np.ndarray:
        """The sampler's density of wi for wo over the whole sphere, (N,)."""
        wi, wo = np.broadcast_arrays(_unit_rows(wi), _unit_rows(wo))
        p = self.p_specular(wo[:, 2])
        return p * self.specular_pdf(wo, wi) + (1.0 - p) * np.maximum(wi[:, 2], 0.0) / math.pi

    def albedo(self, cos_theta) -> np.ndarray:
        """Directional albedo (N, 3), by quadrature over microfacet normals."""
        return microfacet.directional_albedo(self.brdf, np.atleast_1d(np.asarray(cos_theta, dtype=np.float64)))


@dataclass(frozen=True)
class Kind:
    """One material kind: its name, its ``KIND`` code in the packed table, its oracle."""

    name: str
    code: float
    oracle: type


KINDS = (
    Kind("phong", KIND_PHONG, PhongOracle),
    Kind("roughplastic", KIND_ROUGH_PLASTIC, MicrofacetOracle),
    Kind("roughconductor", KIND_ROUGH_CONDUCTOR, MicrofacetOracle),
)


def kind_of(material: Material) -> Kind:
    """The ``Kind`` the transport kernels evaluate for ``material``."""
    name = "phong" if material.microfacet is None else material.microfacet.kind
    return next(k for k in KINDS if k.name == name)


def oracle(material: Material):
    """The numpy oracle of ``material``'s kind."""
    return kind_of(material).oracle(material)
