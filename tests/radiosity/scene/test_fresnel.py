"""The Fresnel term of the material model against known answers.

Each test fails on a wrong Fresnel model: a wrong albedo quadrature (against brute-force
integration of the BRDF), a non-reciprocal term, a material that reflects more than it
receives at the energy limits, a sampler whose density is not its pdf (chi-square), a
contract change that alters files without Fresnel, or kernels that changed the bits of
materials without it.
"""

import dataclasses

import numpy as np
import pytest
from test_materials import CHI2_LEVEL, chi_square_test, rng_for

from radiosity.files.errors import InputError
from radiosity.physics.materials import (
    FRESNEL_NORMALISATION,
    _schlick_albedo_rows,
    fresnel_kd_limit,
    fresnel_ks_limit,
    schlick_albedo,
    specular_albedo,
)
from radiosity.scene.material_kernels import (
    F0,
    HAS_FRESNEL,
    NCOL,
    P_SPECULAR,
    Material,
    albedo,
    eval_brdf,
    pack_materials,
    pdf,
    sample,
)

PLASTIC = dict(diffuse=(0.4, 0.3, 0.2), specular=(1.0, 1.0, 1.0), fresnel=(0.04, 0.04, 0.04))
METAL = dict(diffuse=(0.0, 0.0, 0.0), specular=(1.0, 1.0, 1.0), fresnel=(0.95, 0.64, 0.54))


def fresnel_material(exponent, **kw):
    return Material("m", exponent=exponent, **kw)


def brute_force_albedo(material, cos_theta, nodes=400):
    """int f(wi, wo) cos_i dwi by a product Gauss rule in (cos_i, phi) over the hemisphere,
    finer than the lobe for the exponents tested."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, mu_w = 0.5 * (x + 1), 0.5 * w
    phi = (np.arange(2 * nodes) + 0.5) * np.pi / nodes
    mm, pp = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - mm**2)
    wi = np.stack([s * np.cos(pp), s * np.sin(pp), mm], axis=-1).reshape(-1, 3)
    wo = np.array([np.sqrt(1 - cos_theta**2), 0.0, cos_theta])
    f = eval_brdf(material, wi, wo).reshape(nodes, 2 * nodes, 3)
    return np.einsum("ijc,i,i->c", f, mu * mu_w, np.full(nodes, np.pi / nodes))


def test_schlick_quadrature_gives_the_phong_albedo_without_its_weight():
    c = np.concatenate([np.linspace(0, 1, 41), [1e-6, 0.999999]])
    for n in (0.0, 1.0, 10.0, 1e3, 1e6):
        np.testing.assert_allclose(_schlick_albedo_rows(n, c, 0.0), specular_albedo(n, c), atol=1e-12)


def test_schlick_albedo_limits():
    """A mirror (n -> inf) reflects at the mirror direction only, where wi.h = cos theta:
    Q -> (1 - c)^5 c (Phong's lobe albedo is cos theta); a cosine lobe at normal
    incidence weighs (1 - cos(theta_i / 2))^5: small but positive."""
    c = np.linspace(0.05, 1.0, 20)
    np.testing.assert_allclose(schlick_albedo(1e6, c), (1 - c) ** 5 * c, atol=2e-5)
    q0 = schlick_albedo(0.0, 1.0)[0]
    assert 0.0 < q0 < 0.05


@pytest.mark.parametrize("exponent", [0.0, 5.0, 50.0])
@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 80.0])
@pytest.mark.parametrize("kind", ["plastic", "metal"])
def test_fresnel_albedo_matches_brute_force_integration(kind, exponent, theta_deg):
    material = fresnel_material(exponent, **(PLASTIC if kind == "plastic" else METAL))
    c = np.cos(np.radians(theta_deg))
    np.testing.assert_allclose(albedo(material, c), brute_force_albedo(material, c), rtol=2e-4, atol=2e-5)


def test_fresnel_diffuse_part_is_kd_b_at_every_incidence():
    """Without a lobe (ks tiny) the albedo is kd (1 - (1 - c)^5): kd at normal
    incidence, 0 at grazing, and 21/20 normalises it."""
    m = fresnel_material(10.0, diffuse=(0.5, 0.5, 0.5), specular=(1e-9,) * 3, fresnel=(0.04,) * 3)
    for c in (1.0, 0.5, 0.1):
        assert brute_force_albedo(m, c)[0] == pytest.approx(0.5 * (1 - (1 - c) ** 5), rel=1e-4)
    assert FRESNEL_NORMALISATION == pytest.approx(21 / 20)


@pytest.mark.parametrize("exponent", [0.0, 3.0, 100.0])
def test_fresnel_brdf_is_reciprocal(exponent, rng):
    m = fresnel_material(exponent, diffuse=(0.3, 0.2, 0.1), specular=(0.9, 0.9, 0.9), fresnel=(0.04, 0.5, 0.9))
    wi, wo = rng.normal(size=(2, 2000, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    np.testing.assert_allclose(eval_brdf(m, wi, wo), eval_brdf(m, wo, wi), rtol=1e-12, atol=0)


def test_fresnel_lobe_rises_towards_grazing():
    """At the mirror direction the lobe is weighted by F(cos theta): F0 at normal
    incidence, towards 1 at grazing (a constant ks cannot do this)."""
    m = fresnel_material(1e4, diffuse=(0.0,) * 3, specular=(1.0,) * 3, fresnel=(0.04,) * 3)
    peak = []
    for theta in (0.0, 80.0):
        t = np.radians(theta)
        wo = np.array([np.sin(t), 0.0, np.cos(t)])
        wi = np.array([-np.sin(t), 0.0, np.cos(t)])
        peak.append(eval_brdf(m, wi, wo)[0, 0] / ((1e4 + 2) / (2 * np.pi)))
    assert peak[0] == pytest.approx(0.04)
    assert peak[1] == pytest.approx(0.04 + 0.96 * (1 - np.cos(np.radians(80.0))) ** 5)


@pytest.mark.parametrize("exponent", [0.0, 1.0, 10.0, 100.0, 1e4])
@pytest.mark.parametrize("f0", [0.0, 0.04, 0.5, 1.0])
def test_albedo_is_at_most_one_at_the_energy_limits(exponent, f0):
    """ks at its limit (the specular albedo reaching 1 somewhere), and ks = 1 with kd at
    its limit: the albedo stays <= 1 at every incidence, finely sampled between the
    check's grid points."""
    cos = np.linspace(0.0, 1.0, 401)  # three points in each interval of the check's 129-point grid
    ks_max = float(fresnel_ks_limit([f0] * 3, exponent)[0])
    full = fresnel_material(exponent, diffuse=(0.0,) * 3, specular=(ks_max,) * 3, fresnel=(f0,) * 3)
    rho = albedo(full, cos)
    assert rho.max() <= 1.0 + 1e-4 and rho.max() >= 1.0 - 1e-3
    ks = min(1.0, ks_max)
    kd = float(fresnel_kd_limit([ks] * 3, [f0] * 3, exponent)[0])
    if f0 < 1.0:
        assert kd > 0.0
    both = fresnel_material(exponent, diffuse=(min(kd, 1.0),) * 3, specular=(ks,) * 3, fresnel=(f0,) * 3)
    rho = albedo(both, cos)
    assert rho.max() <= 1.0 + 1e-4


@pytest.mark.parametrize("exponent", [1.0, 200.0])
def test_monte_carlo_albedo_with_fresnel_is_at_most_one(exponent, rng):
    ks = 1.0
    kd = float(fresnel_kd_limit([ks] * 3, [0.04] * 3, exponent)[0])
    m = fresnel_material(exponent, diffuse=(kd,) * 3, specular=(ks,) * 3, fresnel=(0.04,) * 3)
    for theta in (0.0, 60.0, 85.0):
        c = np.cos(np.radians(theta))
        wo = np.array([np.sqrt(1 - c * c), 0.0, c])
        wi, p = sample(m, wo, rng.random((200_000, 3)))
        ok = wi[:, 2] > 0
        est = np.where(ok[:, None], eval_brdf(m, wi, wo) * wi[:, 2:3] / np.maximum(p, 1e-300)[:, None], 0.0)
        mean, err = est.mean(axis=0), est.std(axis=0) / np.sqrt(len(est))
        assert np.all(mean <= 1.01)
        np.testing.assert_allclose(mean, albedo(m, c), atol=5 * err.max() + 1e-4)


@pytest.mark.parametrize(
    "exponent, theta_deg", [(1.0, 0.0), (10.0, 60.0), (100.0, 30.0), (100.0, 85.0), (1000.0, 70.0)]
)
def test_sample_matches_pdf_chi_square_with_fresnel(exponent, theta_deg):
    """The lobe choice follows wo (p_specular): the histogram still follows the pdf."""
    m = fresnel_material(exponent, diffuse=(0.4, 0.3, 0.2), specular=(1.0,) * 3, fresnel=(0.04,) * 3)
    p_value, report = chi_square_test(m, m, theta_deg, rng_for(7, exponent, theta_deg))
    assert p_value >= CHI2_LEVEL, f"n={exponent} theta={theta_deg}: {report}"


def test_pdf_integrates_to_one_with_fresnel():
    m = fresnel_material(20.0, diffuse=(0.4, 0.3, 0.2), specular=(1.0,) * 3, fresnel=(0.04,) * 3)
    x, w = np.polynomial.legendre.leggauss(400)
    mu, phi = x, (np.arange(800) + 0.5) * np.pi / 400  # the whole sphere
    mm, pp = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - mm**2)
    wi = np.stack([s * np.cos(pp), s * np.sin(pp), mm], axis=-1).reshape(-1, 3)
    for theta in (0.0, 70.0, 88.0):
        t = np.radians(theta)
        density = pdf(m, np.array([np.sin(t), 0.0, np.cos(t)]), wi).reshape(400, 800)
        assert np.einsum("ij,i->", density, w) * np.pi / 400 == pytest.approx(1.0, abs=1e-3)


# -- the record and the table ---------------------------------------------------------------


def test_material_without_fresnel_writes_no_key_and_packs_zeros():
    plain = Material("p", diffuse=(0.5, 0.5, 0.5), specular=(0.3, 0.3, 0.3), exponent=10)
    assert "fresnel" not in plain.to_dict()
    row = pack_materials([plain])[0]
    assert row.shape == (NCOL,) and np.all(row[F0 : F0 + 3] == 0) and row[HAS_FRESNEL] == 0
    assert row[P_SPECULAR] == pytest.approx(0.3 / 0.8)


def test_material_with_fresnel_round_trips_and_packs():
    m = fresnel_material(30.0, **PLASTIC)
    d = m.to_dict()
    assert d["fresnel"] == [0.04, 0.04, 0.04]
    assert Material("m", **d) == m
    row = pack_materials([m])[0]
    assert list(row[F0 : F0 + 3]) == [0.04, 0.04, 0.04] and row[HAS_FRESNEL] == 1.0


@pytest.mark.parametrize(
    "kw, message",
    [
        (dict(diffuse=(0.9,) * 3, specular=(1.0,) * 3, fresnel=(0.2,) * 3), "diffuse red"),
        (dict(diffuse=(0.0,) * 3, specular=(3.0,) * 3, fresnel=(0.5,) * 3), "reflects more than 1"),
        (dict(diffuse=(0.5,) * 3, specular=(0.0,) * 3, fresnel=(0.04,) * 3), "needs a positive specular"),
        (dict(diffuse=(0.5,) * 3, specular=(1.0,) * 3, fresnel=(0.04, 2.0, 0.0)), "fresnel green"),
        (dict(diffuse=(0.5,) * 3, specular=(1.0,) * 3, fresnel=(0.04, 0.04)), "fresnel must be 3 numbers"),
    ],
)
def test_bad_fresnel_material_raises_input_error(kw, message):
    with pytest.raises(InputError, match=message):
        Material("bad", exponent=10.0, **kw)


def test_a_plastic_may_have_kd_plus_ks_above_one_with_fresnel():
    """ks is the interface's scale: kd 0.9 with ks 1 and F0 0.04 reflects at most 0.94
    at normal incidence (without Fresnel kd + ks = 1.9 would be refused)."""
    m = fresnel_material(100.0, diffuse=(0.9,) * 3, specular=(1.0,) * 3, fresnel=(0.04,) * 3)
    assert albedo(m, 1.0)[0] == pytest.approx(0.9 + 0.04 + 0.96 * schlick_albedo(100.0, 1.0)[0])
    with pytest.raises(InputError, match="above 1"):
        dataclasses.replace(m, fresnel=None)
