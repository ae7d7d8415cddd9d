"""The reflection probe (fitting.probe, fitting.glossy.fit_probe_part): the octahedral
map and its seamless look-up, the box projection by hand, a synthetic environment seen
through a known probe recovered, unseen texels finite and smooth, and the extremes."""

import numpy as np
import pytest

from fitting import glossy, probe
from fitting.data import FitData
from radiosity.physics.directions import grid_directions
from radiosity.physics.materials import specular_albedo


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_directions(n, seed=0):
    return unit(np.random.default_rng(seed).normal(size=(n, 3)))


def test_octahedral_map_round_trips_and_covers_the_square():
    u = random_directions(5000)
    uv = probe.encode(u)
    assert (uv >= 0).all() and (uv <= 1).all()
    np.testing.assert_allclose(probe.decode(uv), u, atol=1e-12)
    # both hemispheres fill the square: the upper inside |p| <= 1, the lower outside
    p = 2 * uv - 1
    assert ((np.abs(p).sum(axis=1) <= 1 + 1e-12) == (u[:, 2] >= 0)).all()


def test_look_up_weights_sum_to_one_and_reproduce_texel_centres():
    m = 8
    texels = np.random.default_rng(1).random((m, m, 3))
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    centres = probe.decode(np.stack([(i + 0.5) / m, (j + 0.5) / m], axis=-1))
    np.testing.assert_allclose(probe.look_up(texels, centres), texels, atol=1e-12)
    _, w = probe.texels(random_directions(1000), m)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    assert (w >= 0).all()


@pytest.mark.parametrize("m", [4, 16, 33])
def test_the_look_up_is_continuous_across_the_octahedrons_seams(m):
    # a smooth function of direction, stored at the texel centres: its look-up must not
    # jump where the square folds (the lower hemisphere's edges and corners)
    def f(u):
        return np.stack([1 + u[..., 0], 2 + u[..., 1] * u[..., 2], 1.5 + 0.5 * u[..., 2]], axis=-1)

    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    texels = f(probe.decode(np.stack([(i + 0.5) / m, (j + 0.5) / m], axis=-1)))
    # pairs of nearby directions straddling the seams (z < 0, near x = 0 or y = 0, and the pole)
    base = unit(np.concatenate([
        np.stack([np.linspace(-1, 1, 200), np.zeros(200), -np.ones(200)], axis=1),
        np.stack([np.zeros(200), np.linspace(-1, 1, 200), -np.ones(200)], axis=1),
        [[0.0, 0.0, -1.0]],
    ]))
    eps = 1e-7
    for axis in (0, 1):
        shift = np.zeros(3)
        shift[axis] = eps
        a = probe.look_up(texels, unit(base + shift))
        b = probe.look_up(texels, unit(base - shift))
        assert np.abs(a - b).max() < 1e-5
    # and the look-up stays near the function everywhere (bilinear error of a smooth map)
    u = random_directions(4000)
    assert np.abs(probe.look_up(texels, u) - f(u)).max() < 8.0 / m


def test_box_projection_by_hand():
    box = np.array([[0.0, 0.0, 0.0], [10.0, 4.0, 6.0]])
    centre = np.array([5.0, 2.0, 3.0])
    x = np.array([[2.0, 1.0, 1.0]])
    n = np.array([[0.0, 1.0, 0.0]])
    # view from (1, 1, 0) normalised: its mirror about n = y is (-1, 1, 0) normalised
    w = unit(np.array([[1.0, 1.0, 0.0]]))
    # from (2, 1, 1) along (-1, 1, 0)/sqrt2 the ray leaves through x = 0 at t = 2 sqrt2: point (0, 3, 1)
    expected = unit(np.array([0.0, 3.0, 1.0]) - centre)
    np.testing.assert_allclose(probe.box_directions(x, w, n, centre, box), expected[None], atol=1e-9)
    # a point outside the box (touching or beyond its wall) is clamped in: finite
    out = probe.box_directions(np.array([[12.0, -1.0, 3.0]]), w, n, centre, box)
    assert np.isfinite(out).all() and np.linalg.norm(out) == pytest.approx(1.0)


def test_albedo_table_is_the_specular_albedo():
    table = probe.albedo_table(120.0)
    mu = np.linspace(0, 1, probe.ALBEDO_POINTS)
    np.testing.assert_allclose(table, specular_albedo(120.0, mu))
    n = np.array([[0.0, 0.0, 1.0]])
    w = unit(np.array([[0.6, 0.0, 0.8]]))
    exact = specular_albedo(120.0, np.array([0.8]))[0]
    assert probe.albedo_factor(table, n, w)[0] == pytest.approx(exact, rel=2e-3)


def _sphere_object(count=400, radius=0.3, centre=(2.0, 1.5, 2.0), grid=8, seed=2):
    """Vertices on a small sphere inside the box, unit normals out, the grid's directions in world space."""
    rng = np.random.default_rng(seed)
    normals = random_directions(count, seed)
    positions = np.asarray(centre) + radius * normals
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    tangents = unit(np.cross(normals, helper))
    bitangents = np.cross(normals, tangents)
    local = grid_directions(grid)
    views = local[None, :, 0:1] * tangents[:, None] + local[None, :, 1:2] * bitangents[:, None] + local[None, :, 2:3] * normals[:, None]
    weights = np.full((count, grid * grid), 1.0 / (count * grid * grid))
    return positions, normals, views, weights, rng


def test_a_known_probe_is_recovered_from_its_own_reflections():
    box = np.array([[0.0, 0.0, 0.0], [4.0, 3.0, 4.0]])
    centre = np.array([2.0, 1.5, 2.0])
    positions, normals, views, weights, rng = _sphere_object()
    m = 8
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    dirs = probe.decode(np.stack([(i + 0.5) / m, (j + 0.5) / m], axis=-1))
    truth = np.stack([1 + 0.5 * dirs[..., 0], 0.7 + 0.3 * dirs[..., 1], 0.4 + 0.3 * (dirs[..., 2] > 0)], axis=-1)
    albedo = probe.albedo_table(50.0)
    known = probe.Probe(truth.astype(np.float32), centre, box, albedo)
    emitted = 0.05 + 0.1 * rng.random((len(positions), 3))
    weight = 0.5 + 0.5 * rng.random((len(positions), 3))
    radiance = emitted[:, None] + weight[:, None] * probe.probe_values(known, positions[:, None], views, normals[:, None])
    data = FitData(radiance=radiance, views=views, normals=normals, weights=weights, positions=positions)
    found, e, s, _ = glossy.fit_probe_part(data, radiance, None, m, centre, box, albedo, rounds=12)
    model = e[:, None] + s[:, None] * probe.probe_values(found, positions[:, None], views, normals[:, None])
    assert np.sqrt(np.mean((model - radiance) ** 2) / np.mean(radiance**2)) < 2e-3
    # the probe itself, up to the free scale between P and s, where the data see it
    seen = np.zeros(m * m, bool)
    idx, w = probe.texels(probe.box_directions(positions[:, None], views, normals[:, None], centre, box).reshape(-1, 3), m)
    seen[idx[w > 0.2]] = True
    ratio = np.asarray(found.texels, float).reshape(-1, 3)[seen] / truth.reshape(-1, 3)[seen]
    assert np.std(ratio / ratio.mean(axis=0), axis=0).max() < 0.02


def test_unseen_texels_are_finite_and_smooth():
    # the object sees only the upper half of the surroundings (its views come from above):
    # texels it never sees take their neighbours' values through the smoothness term
    box = np.array([[0.0, 0.0, 0.0], [4.0, 3.0, 4.0]])
    centre = np.array([2.0, 1.5, 2.0])
    positions, normals, views, weights, rng = _sphere_object(count=300, seed=4)
    up = normals[:, 1] > 0.3
    positions, normals, views, weights = positions[up], normals[up], views[up], weights[up]
    radiance = 0.2 + 0.1 * np.sin(3 * views[..., :1]) + np.zeros(3)
    data = FitData(radiance=radiance, views=views, normals=normals, weights=weights / weights.sum(), positions=positions)
    found, e, s, _ = glossy.fit_probe_part(data, radiance, None, 16, centre, box, probe.albedo_table(20.0))
    t = np.asarray(found.texels, float)
    assert np.isfinite(t).all() and (t >= 0).all()
    u = probe.box_directions(positions[:, None], views, normals[:, None], centre, box).reshape(-1, 3)
    idx, _ = probe.texels(u, 16)
    unseen = np.setdiff1d(np.arange(256), idx.ravel())
    assert len(unseen) > 10
    # no unseen texel strays beyond the range of the seen ones
    seen_values = t.reshape(-1, 3)[np.unique(idx)]
    assert (t.reshape(-1, 3)[unseen] <= seen_values.max(axis=0) * 1.05 + 1e-9).all()


@pytest.mark.parametrize("scale", [0.0, 1e-8, 1e8])
def test_radiance_zero_tiny_and_huge(scale):
    # the same fit at every scale of radiance (the per-vertex solve is scaled column by column)
    box = np.array([[0.0, 0.0, 0.0], [4.0, 3.0, 4.0]])
    centre = np.array([2.0, 1.5, 2.0])
    positions, normals, views, weights, rng = _sphere_object(count=100)
    m = 8
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    dirs = probe.decode(np.stack([(i + 0.5) / m, (j + 0.5) / m], axis=-1))
    albedo = probe.albedo_table(30.0)
    known = probe.Probe((1 + 0.5 * dirs).astype(np.float32), centre, box, albedo)
    shape = 0.1 + 0.1 * rng.random((len(positions), 1, 3)) + probe.probe_values(known, positions[:, None], views, normals[:, None])

    def fitted(radiance):
        data = FitData(radiance=radiance, views=views, normals=normals, weights=weights / weights.sum(), positions=positions)
        found, e, s, _ = glossy.fit_probe_part(data, radiance, None, m, centre, box, albedo)
        return e[:, None] + s[:, None] * probe.probe_values(found, positions[:, None], views, normals[:, None])

    model = fitted(scale * shape)
    assert np.isfinite(model).all()
    if scale == 0:
        assert not model.any()
        return
    np.testing.assert_allclose(model / scale, fitted(shape), rtol=1e-6, atol=1e-9)
    assert np.sqrt(np.mean((model / scale - shape) ** 2) / np.mean(shape**2)) < 5e-3


def test_light_caps_of_a_lobe_below_the_horizon_are_the_ceiling_without_a_warning():
    # a light far below a vertex's horizon with an exponent of 1e4: its lobe's peak
    # cos((theta - 90 deg) / 2)^p is subnormal, the cap brightest / peak overflows;
    # it is the ceiling 1e200, and nothing is printed (users saw "overflow in divide")
    import warnings

    from fitting.data import FitData
    from fitting.glossy import _light_caps

    data = FitData(radiance=np.full((1, 4, 3), 2.0), views=np.tile([0.0, 0.0, 1.0], (1, 4, 1)),
                   normals=np.array([[0.0, 0.0, 1.0]]), weights=np.full((1, 4), 0.25), positions=np.zeros((1, 3)))
    half = np.arccos(np.exp(np.log(1e-310) / 1e4))  # the half angle whose peak is 1e-310
    theta = np.pi / 2 + 2 * half
    below = [np.sin(theta), 0.0, np.cos(theta), 0.0]
    lights = (np.array([below, [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, -1.0, 0.0]]), np.ones((3, 3)), np.full(3, 1e4))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        caps = _light_caps(data, lights)
    assert caps.shape == (1, 3, 3)
    assert np.all(caps[0, :, 0] == 1e200)  # overflowed: the ceiling
    assert np.all(np.isfinite(caps[0, :, 1])) and np.all(caps[0, :, 1] > 0)
    assert np.all(caps[0, :, 2] == 0.0)  # straight below: the peak underflows to 0, so no coefficient
