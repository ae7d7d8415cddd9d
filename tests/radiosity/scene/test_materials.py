"""Tests for radiosity.scene.material_kernels: sampling against its density, energy, albedo,
reciprocity, numerical extremes and material validation.

The sampler is checked by a chi-square goodness-of-fit test over the whole
sphere, binned in a frame about the mirror direction that the test builds itself;
a companion test shows the same machinery rejects a slightly wrong sampler.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from radiosity.files.errors import InputError
from radiosity.scene.material_kernels import (
    EMISSION,
    EXPONENT,
    KD,
    KS,
    NCOL,
    P_SPECULAR,
    Material,
    albedo,
    eval_brdf,
    onb,
    pack_materials,
    pdf,
    sample,
)

SEED = 1994  # Lafortune & Willems

ONE_MINUS_ULP = 1.0 - 2.0**-53  # largest double below 1


def rng_for(*key: float) -> np.random.Generator:
    """A generator seeded from SEED and the test case, so each case is reproducible alone."""
    return np.random.default_rng([SEED, *(int(round(1000 * k)) for k in key)])


def glossy(kd: float, ks: float, exponent: float) -> Material:
    return Material("test", (kd, kd, kd), (ks, ks, ks), exponent)


def outgoing(theta_deg: float, phi_deg: float = 40.0) -> np.ndarray:
    """Unit vector at theta_deg from the normal, azimuth phi_deg, shape (3,)."""
    theta, phi = math.radians(theta_deg), math.radians(phi_deg)
    s = math.sin(theta)
    return np.array([s * math.cos(phi), s * math.sin(phi), math.cos(theta)])


def reflect(w: np.ndarray) -> np.ndarray:
    return w * np.array([-1.0, -1.0, 1.0])


def random_hemisphere(rng: np.random.Generator, count: int) -> np.ndarray:
    """Uniform unit vectors with z > 0, shape (count, 3)."""
    v = rng.normal(size=(count, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v


# ---------------------------------------------------------------------------
# Chi-square goodness of fit of `sample` against `pdf`
# ---------------------------------------------------------------------------

CHI2_SAMPLES = 1_000_000
CHI2_MATERIALS = {"glossy": (0.0, 1.0), "mixed": (0.3, 0.6)}
CHI2_EXPONENTS = (1, 10, 100, 1000)
CHI2_ANGLES = (0, 30, 60, 85)
CHI2_CASES = [
    (kind, n, angle) for kind in CHI2_MATERIALS for n in CHI2_EXPONENTS for angle in CHI2_ANGLES
]
# By default a Latin-square subset runs (~5 s): every exponent with both materials, each
# material at every angle; the whole grid (~20 s) is marked slow.
CHI2_FAST = {
    ("glossy", 1, 85), ("glossy", 10, 60), ("glossy", 100, 30), ("glossy", 1000, 0),
    ("mixed", 1, 30), ("mixed", 10, 0), ("mixed", 100, 85), ("mixed", 1000, 60),
}
# Family-wise 1% false-alarm rate over all goodness-of-fit cases (Sidak).
CHI2_LEVEL = 1.0 - (1.0 - 0.01) ** (1.0 / len(CHI2_CASES))
FINE_ALPHA_BINS, COARSE_ALPHA_BINS, PHI_BINS = 40, 20, 32
CELL_GAUSS_POINTS = 8
MIN_EXPECTED = 5.0


def mirror_frame(wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, b, r): an orthonormal frame about r = reflect(wo), by Gram-Schmidt."""
    r = reflect(wo)
    helper = np.array([1.0, 0.0, 0.0]) if abs(r[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = helper - (helper @ r) * r
    t /= np.linalg.norm(t)
    return t, np.cross(r, t), r


def alpha_edges(exponent: float) -> np.ndarray:
    """Bins in the angle from the mirror direction: fine inside the lobe, coarse beyond."""
    lobe = min(math.pi, 6.0 * math.sqrt(2.0 / (exponent + 1.0)))
    edges = np.linspace(0.0, lobe, FINE_ALPHA_BINS + 1)
    if lobe < math.pi:
        edges = np.concatenate((edges, np.linspace(lobe, math.pi, COARSE_ALPHA_BINS + 1)[1:]))
    return edges


def cell_counts(wi: np.ndarray, frame, edges: np.ndarray) -> np.ndarray:
    """Histogram of directions wi (N, 3) over (alpha, phi) cells, shape (len(edges)-1, PHI_BINS)."""
    t, b, r = frame
    alpha = np.arctan2(np.linalg.norm(np.cross(wi, r), axis=1), wi @ r)
    phi = np.mod(np.arctan2(wi @ b, wi @ t), 2.0 * math.pi)
    n_alpha = len(edges) - 1
    ia = np.clip(np.searchsorted(edges, alpha, side="right") - 1, 0, n_alpha - 1)
    ip = np.clip((phi * (PHI_BINS / (2.0 * math.pi))).astype(np.int64), 0, PHI_BINS - 1)
    return np.bincount(ia * PHI_BINS + ip, minlength=n_alpha * PHI_BINS).reshape(n_alpha, PHI_BINS)


def cell_probabilities(material: Material, wo: np.ndarray, frame, edges: np.ndarray) -> np.ndarray:
    """Integral of pdf over each (alpha, phi) cell: tensor Gauss-Legendre, sin(alpha) Jacobian."""
    t, b, r = frame
    x, w = np.polynomial.legendre.leggauss(CELL_GAUSS_POINTS)
    a_half = 0.5 * np.diff(edges)[:, None]
    alpha = edges[:-1, None] + a_half * (1.0 + x)  # (A, G)
    alpha_weights = a_half * w * np.sin(alpha)
    phi_edges = np.linspace(0.0, 2.0 * math.pi, PHI_BINS + 1)
    p_half = 0.5 * np.diff(phi_edges)[:, None]
    phi = phi_edges[:-1, None] + p_half * (1.0 + x)  # (P, G)
    phi_weights = p_half * w
    around = np.cos(phi)[..., None] * t + np.sin(phi)[..., None] * b  # (P, G, 3)
    dirs = (
        np.cos(alpha)[:, :, None, None, None] * r
        + np.sin(alpha)[:, :, None, None, None] * around[None, None]
    )  # (A, G, P, G, 3)
    density = pdf(material, wo, dirs.reshape(-1, 3)).reshape(dirs.shape[:-1])
    return np.einsum("agpq,ag,pq->ap", density, alpha_weights, phi_weights)


def chi_square_test(
    sampled: Material, tested: Material, theta_deg: float, rng: np.random.Generator
) -> tuple[float, str]:
    """Sample `sampled`, test the histogram against `tested`'s pdf. Returns (p-value, report)."""
    wo = outgoing(theta_deg)
    frame = mirror_frame(wo)
    edges = alpha_edges(tested.exponent)
    wi, _ = sample(sampled, wo, rng.random((CHI2_SAMPLES, 3)))
    observed = cell_counts(wi, frame, edges).ravel()
    expected = CHI2_SAMPLES * cell_probabilities(tested, wo, frame, edges).ravel()
    assert expected.sum() == pytest.approx(CHI2_SAMPLES, rel=1e-3), "cell quadrature is inaccurate"

    # Cells expecting fewer than MIN_EXPECTED samples are pooled into one; the pool is
    # dropped if it is empty and nothing is expected there, and a sample where nothing
    # is expected makes the statistic infinite.
    alpha_deg = np.degrees(edges)
    small = expected < MIN_EXPECTED
    cells = list(np.flatnonzero(~small))
    obs, exp = list(observed[~small]), list(expected[~small])
    if observed[small].sum() > 0 or expected[small].sum() > 0:
        cells.append(None)
        obs.append(observed[small].sum())
        exp.append(expected[small].sum())
    obs, exp = np.array(obs, dtype=np.float64), np.array(exp)
    with np.errstate(divide="ignore"):
        terms = (obs - exp) ** 2 / exp
    statistic = terms.sum()
    p_value = stats.chi2.sf(statistic, len(obs) - 1)

    lines = [f"chi2 = {statistic:.1f}, {len(obs) - 1} dof, p = {p_value:.3g}; worst cells:"]
    for k in np.argsort(terms)[::-1][:5]:
        if cells[k] is None:
            where = f"{small.sum()} pooled cells"
        else:
            ia, ip = divmod(cells[k], PHI_BINS)
            where = (
                f"alpha {alpha_deg[ia]:.2f}..{alpha_deg[ia + 1]:.2f} deg, "
                f"phi {360 * ip / PHI_BINS:.1f}..{360 * (ip + 1) / PHI_BINS:.1f} deg"
            )
        lines.append(f"  {where}: observed {obs[k]:.0f}, expected {exp[k]:.1f}")
    return p_value, "\n".join(lines)


@pytest.mark.parametrize(
    "kind,exponent,theta_deg",
    [pytest.param(*case, marks=() if case in CHI2_FAST else pytest.mark.slow) for case in CHI2_CASES],
)
def test_sample_matches_pdf_chi_square(kind, exponent, theta_deg):
    material = glossy(*CHI2_MATERIALS[kind], exponent)
    rng = rng_for(1, exponent, theta_deg, kind == "mixed")
    p_value, report = chi_square_test(material, material, theta_deg, rng)
    assert p_value >= CHI2_LEVEL, f"{kind} n={exponent} theta={theta_deg}: {report}"


@pytest.mark.parametrize("exponent", [10, 100])
def test_chi_square_rejects_wrong_exponent(exponent):
    """Power check: samples of exponent 1.25 n must fail against the pdf of exponent n."""
    p_value, report = chi_square_test(
        glossy(0.0, 1.0, 1.25 * exponent), glossy(0.0, 1.0, exponent), 30, rng_for(2, exponent)
    )
    assert p_value < CHI2_LEVEL, f"a wrong sampler passed: {report}"


# ---------------------------------------------------------------------------
# Energy: Monte Carlo albedo from sample/eval_brdf/pdf
# ---------------------------------------------------------------------------

ENERGY_SAMPLES = 200_000
ENERGY_ANGLES = (0, 30, 60, 75, 85)


ENERGY_MATERIALS = [(0.0, 1.0), (0.5, 0.5), (0.2, 0.8)]
ENERGY_EXPONENTS = [1, 10, 100, 1000, 1e4]
# By default the mixed material at every exponent and the others at one each (~4 s);
# the whole grid (~9 s) is marked slow.
ENERGY_FAST = {(0.2, 0.8, n) for n in ENERGY_EXPONENTS} | {(0.0, 1.0, 1000), (0.5, 0.5, 10)}


@pytest.mark.parametrize(
    "kd,ks,exponent",
    [
        pytest.param(kd, ks, n, marks=() if (kd, ks, n) in ENERGY_FAST else pytest.mark.slow)
        for n in ENERGY_EXPONENTS
        for kd, ks in ENERGY_MATERIALS
    ],
)
def test_monte_carlo_albedo(kd, ks, exponent):
    material = glossy(kd, ks, exponent)
    rng = rng_for(3, kd, exponent)
    for theta_deg in ENERGY_ANGLES:
        wo = outgoing(theta_deg)
        wi, density = sample(material, wo, rng.random((ENERGY_SAMPLES, 3)))
        valid = wi[:, 2] > 0.0
        weight = np.zeros((ENERGY_SAMPLES, 3))
        f = eval_brdf(material, wi[valid], wo)
        weight[valid] = f * (wi[valid, 2] / density[valid])[:, None]
        estimate = weight.mean(axis=0)
        std_error = weight.std(axis=0, ddof=1) / math.sqrt(ENERGY_SAMPLES)
        case = (
            f"kd={kd} ks={ks} n={exponent} theta={theta_deg}: "
            f"MC albedo {estimate[0]:.6f} +- {std_error[0]:.2g}"
        )

        assert np.all(estimate <= 1.01), f"energy gain, {case}"
        exact = albedo(material, wo[2])
        assert np.all(np.abs(estimate - exact) <= 4 * std_error + 1e-3), (
            f"{case}, albedo() {exact[0]:.6f}"
        )
        if theta_deg == 0:
            assert np.all(np.abs(estimate - (kd + ks)) <= 4 * std_error + 1e-4), (
                f"{case}, expected {kd + ks}"
            )


# ---------------------------------------------------------------------------
# albedo()
# ---------------------------------------------------------------------------


def test_albedo_reproduces_published_falloff_for_n100():
    table = {0: 1.00, 30: 0.87, 60: 0.50, 75: 0.26, 85: 0.10}
    rho = albedo(glossy(0.0, 1.0, 100), np.cos(np.radians(list(table))))
    assert rho.shape == (len(table), 3)
    np.testing.assert_allclose(rho[:, 0], list(table.values()), atol=0.01)


@pytest.mark.parametrize("exponent", [0, 1, 10, 1000, 1e5])
def test_albedo_is_kd_plus_ks_at_normal_incidence(exponent):
    material = Material("test", (0.1, 0.2, 0.3), (0.6, 0.5, 0.4), exponent)
    np.testing.assert_allclose(albedo(material, 1.0), [0.7, 0.7, 0.7], rtol=0, atol=1e-12)


@pytest.mark.parametrize("exponent", [1, 10])
@pytest.mark.parametrize("theta_deg", [20, 50, 80])
def test_albedo_matches_brute_force_integration(exponent, theta_deg):
    """Midpoint rule of eval_brdf * cos over the hemisphere on a 1000 x 2000 grid."""
    material = Material("test", (0.1, 0.2, 0.0), (0.6, 0.7, 1.0), exponent)
    n_theta, n_phi = 1000, 2000
    theta = (np.arange(n_theta) + 0.5) * (0.5 * math.pi / n_theta)
    phi = (np.arange(n_phi) + 0.5) * (2.0 * math.pi / n_phi)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    wi = np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), ct), axis=-1)
    wi = wi.reshape(-1, 3)
    f = eval_brdf(material, wi, outgoing(theta_deg)).reshape(n_theta, n_phi, 3)
    cell = (0.5 * math.pi / n_theta) * (2.0 * math.pi / n_phi)
    brute = np.einsum("tpc,t->c", f, (ct * st)[:, 0]) * cell
    exact = albedo(material, math.cos(math.radians(theta_deg)))
    np.testing.assert_allclose(exact, brute, rtol=0, atol=1e-4)


@pytest.mark.parametrize("exponent", [1, 3, 10, 100, 1e3, 1e4, 1e5])
def test_albedo_decreases_towards_grazing(exponent):
    cos_theta = np.cos(np.radians(np.linspace(0.0, 90.0, 901)))
    rho = albedo(glossy(0.0, 1.0, exponent), cos_theta)[:, 0]
    assert np.all(np.isfinite(rho))
    assert np.all(np.diff(rho) < 0.0)
    assert rho[0] == pytest.approx(1.0, abs=1e-12)
    assert rho[-1] > 0.0


def test_albedo_shapes_and_domain():
    material = glossy(0.2, 0.7, 10)
    assert albedo(material, 0.5).shape == (3,)
    assert albedo(material, [0.5]).shape == (1, 3)
    with pytest.raises(ValueError):
        albedo(material, 1.5)
    with pytest.raises(ValueError):
        albedo(material, -0.1)


# ---------------------------------------------------------------------------
# Reciprocity and extremes
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("exponent", [0, 1, 10, 100, 1000])
def test_brdf_is_reciprocal(exponent):
    material = Material("test", (0.2, 0.3, 0.4), (0.5, 0.4, 0.3), exponent)
    rng = rng_for(4, exponent)
    wi, wo = random_hemisphere(rng, 10_000), random_hemisphere(rng, 10_000)
    # Also pairs near the mirror configuration, where the lobe is large.
    wi[:5000] = reflect(wo[:5000]) + 0.05 * rng.normal(size=(5000, 3))
    wi[:5000, 2] = np.abs(wi[:5000, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    forward, backward = eval_brdf(material, wi, wo), eval_brdf(material, wo, wi)
    assert np.all(forward > 0.0)
    np.testing.assert_allclose(forward, backward, rtol=1e-12, atol=0)


EXTREME_EXPONENTS = (0, 1, 1e4, 1e5)
EXTREME_Z = (1e-8, 1e-4, 1.0)
EXTREME_U = (0.0, 1e-300, 0.5, 1.0 - 1e-12, ONE_MINUS_ULP)


def grazing(z: float, phi_deg: float = 40.0) -> np.ndarray:
    """Unit vector with the given z (cos theta)."""
    s = math.sqrt((1.0 - z) * (1.0 + z))
    phi = math.radians(phi_deg)
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


@pytest.mark.parametrize("exponent", EXTREME_EXPONENTS)
@pytest.mark.parametrize("kd,ks", [(0.0, 1.0), (0.4, 0.6)])
def test_sample_pdf_eval_finite_at_extremes(kd, ks, exponent):
    material = glossy(kd, ks, exponent)
    rng = rng_for(5, kd, exponent)
    corners = np.array(np.meshgrid(EXTREME_U, EXTREME_U, EXTREME_U)).reshape(3, -1).T
    u = np.concatenate((corners, rng.random((20_000, 3))))
    for z in EXTREME_Z:
        wo = grazing(z)
        wi, density = sample(material, wo, u)
        case = f"kd={kd} ks={ks} n={exponent} wo.z={z}"
        assert np.all(np.isfinite(wi)) and np.all(np.isfinite(density)), case
        np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-12, err_msg=case)
        valid = wi[:, 2] > 0.0
        assert valid.any(), case
        assert np.all(density[valid] > 0.0), case
        assert np.all(density >= 0.0), case
        recomputed = pdf(material, wo, wi)
        assert np.all(np.isfinite(recomputed)) and np.all(recomputed >= 0.0), case
        # Away from 90 degrees off the mirror direction, where the n = 0 lobe jumps from
        # 1 to 0 and the sampler's exact cos alpha ~ 1e-16 may round to <= 0 in pdf().
        smooth = valid & (np.abs(wi @ reflect(wo)) > 1e-9)
        np.testing.assert_allclose(recomputed[smooth], density[smooth], rtol=1e-6, err_msg=case)
        f = eval_brdf(material, wi, wo)
        assert np.all(np.isfinite(f)) and np.all(f >= 0.0), case
        weight = f[valid] * (wi[valid, 2] / density[valid])[:, None]
        assert np.all(np.isfinite(weight)), case


@pytest.mark.parametrize("exponent", EXTREME_EXPONENTS)
def test_mirror_direction_rounding_is_clamped(exponent):
    """cos alpha computed slightly above 1 must give the peak value, not more, not NaN."""
    material = glossy(0.2, 0.8, exponent)
    wo = np.array([[0.6, 0.0, 0.8], [0.0, 0.6, 0.8], [1e-8, 0.0, 1.0], [0.0, 0.0, 1.0]])
    wo *= 1.0 + 4e-16  # |wo|^2 = cos alpha > 1 by a few ulps
    wi = reflect(wo)
    peak_f = 0.2 / math.pi + 0.8 * (exponent + 2.0) / (2.0 * math.pi)
    peak_pdf = 0.2 * wi[:, 2] / math.pi + 0.8 * (exponent + 1.0) / (2.0 * math.pi)
    np.testing.assert_allclose(eval_brdf(material, wi, wo), peak_f, rtol=1e-9)
    np.testing.assert_allclose(pdf(material, wo, wi), peak_pdf, rtol=1e-9)


def test_onb_is_orthonormal_and_right_handed():
    rng = rng_for(6)
    poles_and_equator = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [1, 0, -0.0], [0, 1, 0], [1e-9, 0, -1]]
    normals = np.concatenate(
        (random_hemisphere(rng, 1000), random_hemisphere(rng, 1000) * [1, 1, -1], poles_and_equator)
    )
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for n in normals:
        tx, ty, tz, bx, by, bz = onb(*n)
        frame = np.array([[tx, ty, tz], [bx, by, bz], n])
        np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(np.cross(frame[0], frame[1]), n, atol=1e-12)


# ---------------------------------------------------------------------------
# Material and the packed table
# ---------------------------------------------------------------------------

BAD_MATERIALS = {
    "nan diffuse": ({"diffuse": (0.5, math.nan, 0.5)}, "finite"),
    "infinite specular": ({"specular": (math.inf, 0.0, 0.0)}, "finite"),
    "infinite emission": ({"emission": (0.0, 0.0, math.inf)}, "finite"),
    "negative diffuse": ({"diffuse": (-0.1, 0.5, 0.5)}, "negative"),
    "negative specular": ({"specular": (0.0, -1e-3, 0.0)}, "negative"),
    "negative emission": ({"emission": (1.0, -2.0, 1.0)}, "negative"),
    "diffuse above 1": ({"diffuse": (1.2, 0.0, 0.0), "specular": (0.0, 0.0, 0.0)}, "above 1"),
    "specular above 1": ({"diffuse": (0.0, 0.0, 0.0), "specular": (0.0, 0.0, 1.5)}, "above 1"),
    "energy gain": ({"diffuse": (0.5, 0.7, 0.5), "specular": (0.5, 0.4, 0.5)}, "green"),
    "negative exponent": ({"exponent": -1.0}, "negative"),
    "nan exponent": ({"exponent": math.nan}, "finite"),
    "infinite exponent": ({"exponent": math.inf}, "finite"),
    "huge exponent": ({"exponent": 2e6}, "maximum"),
    "two channels": ({"diffuse": (0.5, 0.5)}, "3 numbers"),
    "not numbers": ({"diffuse": ("red", 0.5, 0.5)}, "3 numbers"),
}


@pytest.mark.parametrize("case", list(BAD_MATERIALS))
def test_bad_material_raises_input_error(case):
    changes, keyword = BAD_MATERIALS[case]
    fields = {"diffuse": (0.5, 0.5, 0.5), "specular": (0.2, 0.2, 0.2), "exponent": 20.0} | changes
    with pytest.raises(InputError) as error:
        Material("varnished oak", **fields)
    message = str(error.value)
    assert "'varnished oak'" in message
    assert keyword in message
    assert "\n" not in message


def test_energy_gain_message_gives_the_sum():
    with pytest.raises(InputError, match=r"1\.1 in the green channel"):
        Material("m", (0.5, 0.7, 0.5), (0.5, 0.4, 0.5), 10)


def test_good_material_is_normalised():
    # Red is kd + ks = 1 + 5e-7: within the tolerance for rounding in scene files.
    m = Material(
        "light", [np.float32(0.5), 0, 1], (0.5 + 5e-7, 0.2, 0), np.int64(50), (18, 15.6, 8)
    )
    for value in (*m.diffuse, *m.specular, m.exponent, *m.emission):
        assert type(value) is float
    assert m.is_glossy and m.is_emitter and m.is_reflective
    assert json.loads(json.dumps(m.to_dict())) == {
        "diffuse": [0.5, 0.0, 1.0],
        "specular": [0.5 + 5e-7, 0.2, 0.0],
        "exponent": 50.0,
        "emission": [18.0, 15.6, 8.0],
    }
    matte = Material("matte", (0.7, 0.7, 0.7))
    assert not matte.is_glossy and not matte.is_emitter and matte.is_reflective
    assert not Material("black", (0, 0, 0)).is_reflective


def test_pack_materials_layout():
    materials = [
        Material("a", (0.1, 0.2, 0.3), (0.4, 0.5, 0.6), 7.0, (1.0, 2.0, 3.0)),
        Material("b", (0.6, 0.6, 0.6)),
        Material("c", (0.0, 0.0, 0.0), (0.9, 0.9, 0.9), 100.0),
        Material("d", (0.0, 0.0, 0.0)),
    ]
    table = pack_materials(materials)
    assert table.shape == (4, NCOL) and table.dtype == np.float64 and table.flags.c_contiguous
    np.testing.assert_array_equal(table[0, KD : KD + 3], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(table[0, KS : KS + 3], [0.4, 0.5, 0.6])
    np.testing.assert_array_equal(table[0, EMISSION : EMISSION + 3], [1.0, 2.0, 3.0])
    assert table[0, EXPONENT] == 7.0
    np.testing.assert_allclose(table[:, P_SPECULAR], [0.5 / 0.7, 0.0, 1.0, 0.0])
    assert pack_materials([]).shape == (0, NCOL)
