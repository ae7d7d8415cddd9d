"""Every material kind's numba kernels against its numpy oracle (radiosity.scene.kinds).

For each kind of ``KINDS`` and a set of its materials spanning the extremes (Phong
exponents 1 to 1e5 with and without Fresnel; GGX and Beckmann plastics and conductors of
roughness 1e-4 to 4): f and the sampler's density at many (wi, wo) pairs (random, grazing
to 1e-8, the mirror direction, below the horizon) equal the oracle's; sampled directions
follow the oracle's density (chi-square over cells of the half vector); the Monte Carlo
albedo of sample / eval / pdf equals the oracle's quadrature and never exceeds 1; f is
reciprocal; nothing is NaN or infinite. A new kind joins by a row of ``MATERIALS``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from radiosity.physics.materials import Material, Microfacet
from radiosity.scene import microfacet
from radiosity.scene.kinds import KINDS, kind_of, oracle
from radiosity.scene.material_kernels import eval_brdf, pdf, sample

AL = microfacet.METALS["Al"]
CU = microfacet.METALS["Cu"]


def _plastic(distribution, alpha, kd=(0.5, 0.4, 0.3), **extra):
    return Material("plastic", (0.3, 0.3, 0.3), (1.0, 1.0, 1.0), 20.0, fresnel=(0.04, 0.04, 0.04),
                    microfacet=Microfacet("roughplastic", distribution, alpha, (1.49,) * 3, diffuse_reflectance=kd,
                                          **extra))


def _conductor(distribution, alpha, metal=AL, scale=(1.0, 1.0, 1.0)):
    return Material("metal", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 20.0, fresnel=(0.9, 0.9, 0.9),
                    microfacet=Microfacet("roughconductor", distribution, alpha, metal[0], metal[1], scale))


MATERIALS = {
    "phong n=1": Material("p", (0.5, 0.5, 0.5), (0.4, 0.4, 0.4), 1.0),
    "phong n=100": Material("p", (0.2, 0.3, 0.1), (0.7, 0.6, 0.8), 100.0),
    "phong n=1e5": Material("p", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 1e5),
    "phong fresnel": Material("p", (0.5, 0.5, 0.5), (1.0, 1.0, 1.0), 50.0, fresnel=(0.04, 0.04, 0.04)),
    "plastic ggx 0.15": _plastic("ggx", 0.15),
    "plastic ggx 1e-3": _plastic("ggx", 1e-3),
    "plastic beckmann 0.05": _plastic("beckmann", 0.05),
    "plastic beckmann 0.5 nonlinear": _plastic("beckmann", 0.5, nonlinear=True),
    "plastic ggx 2": _plastic("ggx", 2.0, kd=(0.9, 0.1, 0.5)),
    "conductor ggx 0.05 Al": _conductor("ggx", 0.05),
    "conductor beckmann 0.3 Cu": _conductor("beckmann", 0.3, CU),
    "conductor beckmann 1e-4": _conductor("beckmann", 1e-4),
    "conductor ggx 4": _conductor("ggx", 4.0, CU, (0.8, 1.0, 0.5)),
    "conductor beckmann 1 mirror": _conductor("beckmann", 1.0, ((0.0,) * 3, (1.0,) * 3)),
}
# the materials the statistical tests run by default (the rest are marked slow)
FAST = {"phong n=100", "phong fresnel", "plastic ggx 0.15", "plastic beckmann 0.05", "conductor ggx 0.05 Al",
        "conductor beckmann 0.3 Cu"}


def _param(name):
    return pytest.param(name, marks=() if name in FAST else pytest.mark.slow)


def test_every_kind_has_materials_here():
    assert {kind_of(m).name for m in MATERIALS.values()} == {k.name for k in KINDS}


def direction(theta_deg, phi_deg=40.0):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def pairs(seed=7, count=3000):
    """(wi, wo) rows: random over the sphere (some below the horizon), grazing ones, the
    mirror direction and its neighbours, normal incidence."""
    rng = np.random.default_rng(seed)
    wi = rng.normal(size=(count, 3))
    wo = rng.normal(size=(count, 3))
    wo[:, 2] = np.abs(wo[:, 2])
    extra_wo, extra_wi = [], []
    for theta in (0.0, 1e-6, 30.0, 60.0, 85.0, 89.9, 90.0 - 1e-6):
        w = direction(theta)
        extra_wo += [w] * 5
        mirror = w * np.array([-1.0, -1.0, 1.0])
        extra_wi += [mirror, direction(theta + 0.01, 220.0), w, direction(89.99999, 10.0),
                     direction(0.0)]
    wi = np.concatenate([wi, extra_wi])
    wo = np.concatenate([wo, extra_wo])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    return wi, wo


@pytest.mark.parametrize("name", list(MATERIALS))
def test_eval_and_pdf_equal_the_oracle(name):
    material = MATERIALS[name]
    reference = oracle(material)
    wi, wo = pairs()
    f = eval_brdf(material, wi, wo)
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)
    np.testing.assert_allclose(f, reference.eval(wi, wo), rtol=1e-9, atol=1e-12, err_msg=name)
    density = pdf(material, wo, wi)
    assert np.all(np.isfinite(density)) and np.all(density >= 0.0)
    np.testing.assert_allclose(density, reference.pdf(wo, wi), rtol=1e-9, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_reciprocal(name):
    material = MATERIALS[name]
    wi, wo = pairs(seed=8)
    up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    np.testing.assert_allclose(eval_brdf(material, wi[up], wo[up]), eval_brdf(material, wo[up], wi[up]),
                               rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_sampler_reports_its_density_and_stays_finite(name):
    material = MATERIALS[name]
    rng = np.random.default_rng(11)
    for theta in (0.0, 45.0, 80.0, 89.999999):
        wo = direction(theta)
        u = rng.random((20000, 3))
        u[:4] = [[0.0, 0.0, 0.0], [1 - 2**-53, 1 - 2**-53, 1 - 2**-53], [0.0, 1 - 2**-53, 0.5], [0.5, 1e-300, 0.0]]
        wi, density = sample(material, wo, u)
        assert np.all(np.isfinite(wi)) and np.all(np.isfinite(density)), f"{name} theta {theta}"
        np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-9)
        np.testing.assert_allclose(density, pdf(material, wo, wi), rtol=1e-7, atol=1e-12)


# -- the sampler's distribution: chi-square over cells of the half vector ---------------

PHI_CELLS = 12
X_EDGES = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 1.4, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0, 300.0, 1e3, 3e3, np.inf])  # tan(theta_h) / width


def _width(material):
    if material.microfacet is not None:
        return material.microfacet.alpha
    return math.sqrt(2.0 / (material.exponent + 2.0))  # a Phong lobe's half-vector spread


def _cell_probabilities(reference, wo, width, sub=32):
    """P(cell) = int pdf(wi(h)) 4 |wo.h| dh over each (tan theta_h / width, phi_h) cell."""
    theta_edges = np.arctan(width * X_EDGES)
    probabilities = np.zeros((len(X_EDGES) - 1, PHI_CELLS))
    g, gw = np.polynomial.legendre.leggauss(sub)
    for i in range(len(X_EDGES) - 1):
        t0, t1 = theta_edges[i], theta_edges[i + 1]
        theta = t0 + (t1 - t0) * 0.5 * (g + 1.0)
        for j in range(PHI_CELLS):
            p0, p1 = 2 * math.pi * j / PHI_CELLS, 2 * math.pi * (j + 1) / PHI_CELLS
            phi = p0 + (p1 - p0) * 0.5 * (g + 1.0)
            tt, pp = np.meshgrid(theta, phi, indexing="ij")
            h = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
            dot = h @ wo
            wi = 2.0 * dot[:, None] * h - wo
            weight = (np.outer(gw, gw) * 0.25 * (t1 - t0) * (p1 - p0)).ravel() * np.sin(tt).ravel()
            probabilities[i, j] = np.sum(weight * reference.pdf(wo, wi) * 4.0 * np.maximum(dot, 0.0))
    return probabilities


def _cell_counts(wi, wo, width):
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    x = np.sqrt(np.maximum(1.0 - h[:, 2] ** 2, 0.0)) / np.maximum(h[:, 2], 1e-300) / width
    i = np.clip(np.searchsorted(X_EDGES, x, side="right") - 1, 0, len(X_EDGES) - 2)
    phi = np.mod(np.arctan2(h[:, 1], h[:, 0]), 2 * math.pi)
    j = np.minimum((phi / (2 * math.pi) * PHI_CELLS).astype(int), PHI_CELLS - 1)
    return np.bincount(i * PHI_CELLS + j, minlength=(len(X_EDGES) - 1) * PHI_CELLS).reshape(len(X_EDGES) - 1, -1)


SAMPLES = 400_000


@pytest.mark.parametrize("name", [_param(n) for n in MATERIALS])
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_sampler_follows_the_oracle_density_chi_square(name, theta):
    material = MATERIALS[name]
    wo = direction(theta)
    reference = oracle(material)
    expected = _cell_probabilities(reference, wo, _width(material))
    if material.microfacet is not None:  # every sample's half vector is above the horizon
        assert expected.sum() == pytest.approx(1.0, abs=2e-3), f"{name}: the density sums to {expected.sum()}"
    wi, _ = sample(material, wo, np.random.default_rng([5, int(theta)]).random((SAMPLES, 3)))
    above = (wi + wo)[:, 2] > 0.0  # a Phong lobe's samples far below the horizon have h.z <= 0
    counts = _cell_counts(wi[above], wo, _width(material)).ravel()
    # the cells, those expecting under 20 samples pooled, and the half vectors below the horizon
    # a microfacet sampler's half vectors are all above the horizon: its cells hold all the
    # mass, up to the quadrature's error, which is taken out
    expected = expected.ravel() * SAMPLES / (expected.sum() if material.microfacet is not None else 1.0)
    keep = expected >= 20.0
    observed = np.concatenate([counts[keep], [counts[~keep].sum(), (~above).sum()]])
    expected = np.concatenate([expected[keep], [expected[~keep].sum(), max(SAMPLES - expected.sum(), 0.0)]])
    pooled = expected > 0.5
    statistic = np.sum((observed[pooled] - expected[pooled]) ** 2 / expected[pooled])
    p_value = stats.chi2.sf(statistic, pooled.sum() - 1)
    assert p_value > 1e-4, f"{name} theta {theta}: chi2 {statistic:.1f} on {keep.sum()} cells, p {p_value:.2g}"


def test_the_chi_square_rejects_a_wrong_roughness():
    """Power: samples of alpha 0.165 judged against the density of alpha 0.15 fail."""
    material, wrong = _conductor("ggx", 0.15), _conductor("ggx", 0.165)
    wo = direction(45.0)
    expected = _cell_probabilities(oracle(material), wo, 0.15).ravel() * SAMPLES
    wi, _ = sample(wrong, wo, np.random.default_rng(3).random((SAMPLES, 3)))
    counts = _cell_counts(wi, wo, 0.15).ravel()
    keep = expected >= 20.0
    statistic = np.sum((counts[keep] - expected[keep]) ** 2 / expected[keep])
    assert stats.chi2.sf(statistic, keep.sum()) < 1e-6


# -- energy -------------------------------------------------------------------------------


@pytest.mark.parametrize("name", [_param(n) for n in MATERIALS])
def test_monte_carlo_albedo_equals_the_oracle_and_stays_below_one(name):
    material = MATERIALS[name]
    reference = oracle(material)
    rng = np.random.default_rng(17)
    for theta in (0.0, 30.0, 60.0, 80.0, 88.0):
        wo = direction(theta)
        wi, density = sample(material, wo, rng.random((200_000, 3)))
        ok = (wi[:, 2] > 0.0) & (density > 0.0)
        weight = np.zeros((len(wi), 3))
        weight[ok] = eval_brdf(material, wi[ok], wo) * (wi[ok, 2] / density[ok])[:, None]
        estimate = weight.mean(axis=0)
        error = weight.std(axis=0) / math.sqrt(len(wi))
        exact = reference.albedo(math.cos(math.radians(theta)))[0]
        assert np.all(estimate <= 1.0 + 4 * error + 1e-3), f"{name} theta {theta}: albedo {estimate}"
        assert np.all(np.abs(estimate - exact) <= 4 * error + 3e-3), (
            f"{name} theta {theta}: Monte Carlo {estimate} +- {error}, oracle {exact}")


@pytest.mark.parametrize("name", [n for n in MATERIALS if "plastic" in n or "conductor" in n])
def test_the_photons_albedo_table_is_the_oracle_s_albedo(name):
    from radiosity.scene.material_kernels import albedo_table

    material = MATERIALS[name]
    cos = np.linspace(0.0, 1.0, 129)
    np.testing.assert_allclose(albedo_table(material, 129), oracle(material).albedo(cos), atol=2e-3)
