"""The gather's per-direction kernel against a brute-force numpy evaluation."""

import numpy as np
import pytest

from radiosity.formats import directions
from radiosity.scene.materials import Material, pack_materials
from radiosity.transport import gather, records


def test_concentric_map_never_shrinks_angles_below_the_window_bound(rng):
    p = rng.uniform(-1, 1, (400_000, 2))
    q = np.clip(p + rng.normal(scale=rng.choice([0.3, 0.03, 0.003], len(p))[:, None], size=p.shape), -1, 1)
    wp = directions.square_to_hemisphere(p[:, 0], p[:, 1])
    wq = directions.square_to_hemisphere(q[:, 0], q[:, 1])
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", wp, wq), -1, 1))
    distance = np.abs(p - q).max(axis=1)
    ok = distance > 1e-9
    assert (angle[ok] / distance[ok]).min() > 1.0 / gather.SQUARE_PER_RADIAN


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
