"""The gather's per-direction kernel against a brute-force numpy evaluation."""

import numpy as np
import pytest

from radiosity.physics import directions
from radiosity.scene.material_kernels import Material, pack_materials
from radiosity.transport import gather, records


def _cone_directions(rng, count):
    """Unit directions on the hemisphere, with the map's awkward ones among them: the
    pole, the horizon, the square's diagonals and edges (the octants' seams)."""
    w = rng.normal(size=(count, 3))
    w[:, 2] = np.abs(w[:, 2])
    w[: count // 10, 2] = 0.0  # on the horizon
    w[count // 10 : count // 5, :2] *= rng.choice([0.0, 1e-9, 1e-3], (count // 5 - count // 10, 1))  # at the pole
    seams = slice(count // 5, count // 3)
    angle = rng.integers(0, 8, seams.stop - seams.start) * np.pi / 4 + rng.choice([0.0, 1e-12, -1e-12], seams.stop - seams.start)
    w[seams, 0], w[seams, 1] = np.cos(angle), np.sin(angle)
    return w / np.linalg.norm(w, axis=1, keepdims=True)


@pytest.mark.parametrize("grid_n", [5, 16, 44, 128])
def test_lobe_window_holds_every_cell_of_the_cone(rng, grid_n):
    """Every grid direction within the cone is in its window, whatever the direction
    (pole, horizon, octant seams) and the cone (from a hundredth of a cell to wider
    than the hemisphere)."""
    dirs = directions.grid_directions(grid_n)
    w = _cone_directions(rng, 3000)
    cones = rng.choice([1e-4, 1e-2, 0.05, 0.2, 0.5, 0.69, 1.2, 2.0], len(w)) * rng.uniform(0.5, 1.0, len(w))
    for r, cone in zip(w, cones):
        i_lo, i_hi, j_lo, j_hi = gather.lobe_window(r[0], r[1], r[2], cone, grid_n)
        inside = np.flatnonzero(dirs @ r > np.cos(cone))
        i, j = inside % grid_n, inside // grid_n
        assert ((i >= i_lo) & (i <= i_hi) & (j >= j_lo) & (j <= j_hi)).all(), (r, cone)


def test_lobe_window_is_the_cone_at_the_pole_and_tight_elsewhere(rng):
    """At the pole the window is the square of half-side sqrt(1 - cos cone), to a cell;
    elsewhere a narrow cone's window (here 5 cells wide) holds at most a few times the
    cells it covers: its box around the cone, a cell of rounding on each side, and more
    where the map stretches the cone (the square window it replaced, 1 / 0.7 square
    units per radian of cone everywhere, held 5.3 times them at the median here)."""
    grid_n = 64
    dirs = directions.grid_directions(grid_n)
    for cone in (0.05, 0.2, 0.6):
        r = np.sqrt(1 - np.cos(cone))
        i_lo, i_hi, j_lo, j_hi = gather.lobe_window(0.0, 0.0, 1.0, cone, grid_n)
        expected_lo = np.floor((1 - r) * 0.5 * grid_n - 0.5)
        expected_hi = np.ceil((1 + r) * 0.5 * grid_n - 0.5)
        assert abs(i_lo - expected_lo) <= 1 and abs(i_hi - expected_hi) <= 1
        assert (i_lo, i_hi) == (j_lo, j_hi)
    ratios = []
    for r in _cone_directions(rng, 400):
        if r[2] < 0.3:
            continue  # near the horizon the cone is cut: its cells are fewer than its window's
        i_lo, i_hi, j_lo, j_hi = gather.lobe_window(r[0], r[1], r[2], 0.15, grid_n)
        covered = np.count_nonzero(dirs @ r > np.cos(0.15))
        ratios.append((i_hi - i_lo + 1) * (j_hi - j_lo + 1) / covered)
    assert np.median(ratios) < 3.0 and max(ratios) < 5.0, (np.median(ratios), max(ratios))


@pytest.mark.parametrize("exponent, grid_n", [(0.0, 6), (1.0, 8), (8.0, 9), (120.0, 17), (1000.0, 40), (1e4, 64)])
def test_windowed_outputs_equal_brute_force(rng, exponent, grid_n):
    ks = np.array([0.5, 0.3, 0.1])
    material = Material("m", diffuse=(0.2, 0.2, 0.2), specular=tuple(ks), exponent=exponent)
    mat = pack_materials([material])[0]
    blocks, n_light, n_gather = 3, 7, 25

    def hemisphere(count):
        w = rng.normal(size=(count, 3))
        w[:, 2] = np.abs(w[:, 2]) + 1e-3
        return w / np.linalg.norm(w, axis=1, keepdims=True)

    light_wi = hemisphere(blocks * n_light)
    light_le = rng.uniform(0, 5, (blocks * n_light, 3))
    light_pdf = rng.uniform(0.5, 3, blocks * n_light) * (rng.random(blocks * n_light) > 0.2)
    visible = rng.random(blocks * n_light) > 0.3
    gather_wi = hemisphere(blocks * n_gather)
    incoming = rng.uniform(0, 2, (blocks * n_gather, 3)) * (rng.random((blocks * n_gather, 1)) > 0.1)
    dirs = directions.grid_directions(grid_n)
    # put some sample mirrors exactly on grid directions (the lobe's peak)
    gather_wi[:grid_n] = dirs[rng.integers(0, len(dirs), grid_n)] * [-1, -1, 1]
    emission = np.array([0.1, 0.0, 0.2])
    diffuse = rng.uniform(0, 1, (blocks, 3))
    out = np.empty((blocks, len(dirs), 3))
    light = records.empty_light_samples(blocks * n_light)._replace(
        wi=light_wi, radiance=light_le, pdf=light_pdf, visible=visible
    )
    samples = records.empty_gather_samples(blocks * n_gather)._replace(wi=gather_wi, incoming=incoming)
    variance = np.empty(blocks)
    gather.gather_outputs(mat, emission, diffuse, light, samples, dirs, out, variance)

    expected = np.empty_like(out)
    truncated = np.empty_like(out)
    bound = np.empty((blocks, 3))
    expected_variance = np.empty(blocks)
    lum = np.array(gather.LUMINANCE)
    cos_min = np.exp(np.log(gather.LOBE_CUTOFF) / exponent) if exponent > 0 else 0.0
    norm = (exponent + 2) / (2 * np.pi)
    for b in range(blocks):
        lw = light_wi[b * n_light:(b + 1) * n_light]
        lp = light_pdf[b * n_light:(b + 1) * n_light]
        use = (lp > 0) & visible[b * n_light:(b + 1) * n_light]
        mis = n_light * lp / (n_light * lp + n_gather * lw[:, 2] / np.pi)
        w_light = np.where(use, lw[:, 2] / np.where(use, lp, 1) / n_light * mis, 0)[:, None] * light_le[b * n_light:(b + 1) * n_light]
        gw = gather_wi[b * n_gather:(b + 1) * n_gather]
        w_gather = np.pi / n_gather * incoming[b * n_gather:(b + 1) * n_gather]
        mirrors = np.concatenate([lw, gw]) * [-1, -1, 1]
        weights = np.concatenate([w_light, w_gather])
        cos = np.clip(mirrors @ dirs.T, 0, 1)  # (S, D)
        lobe = np.where(mirrors @ dirs.T > 0, cos**exponent, 0.0)
        expected[b] = emission + diffuse[b] + norm * ks * (lobe.T @ weights)
        kept = np.where(mirrors @ dirs.T > cos_min, lobe, 0.0)
        truncated[b] = emission + diffuse[b] + norm * ks * (kept.T @ weights)
        # each sample's term in luminance, per direction; unused samples are zero terms
        terms = norm * kept * (weights @ (ks * lum))[:, None]  # (S, D)
        expected_variance[b] = sum(
            (group**2).sum(axis=0) - group.sum(axis=0) ** 2 / len(group)
            for group in (terms[:n_light], terms[n_light:])
        ).clip(0).sum()
        # each sample loses at most LOBE_CUTOFF of its peak, norm * ks * weight
        bound[b] = norm * ks * gather.LOBE_CUTOFF * weights.sum(axis=0)
    # exactly the truncated sum, up to the table's interpolation
    assert np.allclose(out, truncated, rtol=1e-5, atol=1e-12)
    # and the truncation loses no more than it may
    assert (np.abs(out - expected) <= bound[:, None, :] * (1 + 1e-5) + 1e-12).all()
    # the variance of each vertex's estimate, from the spread of its samples' terms
    assert np.allclose(variance, expected_variance, rtol=1e-5, atol=1e-12) and (variance > 0).all()
