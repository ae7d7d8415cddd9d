"""Extra gather passes where the gather is noisy (``transport.regather``): decided by
the neighbours, within the budget, and the answer unchanged."""

import textwrap

import numpy as np
import pytest
from analytic import GLOSSY_RELAY, glossy_relay_radiance

from radiosity.files.errors import InputError
from radiosity.scene.loaders import load_scene
from radiosity.transport import gather, regather
from radiosity.transport import solve as solve_module
from radiosity.transport.solve import SolveOptions, solve


def grid_mesh(n):
    """An n x n grid of vertices, two triangles a cell."""
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_pass_seeds_are_distinct_and_pass_0_is_the_solve_seed():
    seeds = [regather.pass_seed(7, k) for k in range(200)]
    assert seeds[0] == 7 and len(set(seeds)) == 200
    assert all(0 <= s < 2**63 for s in seeds)
    assert regather.pass_seed(2**63 - 1, 5) < 2**63
    assert regather.pass_seed(8, 1) != regather.pass_seed(7, 1)


def test_a_vertex_pass_count_ignores_its_own_noise():
    faces = grid_mesh(7)
    r = np.random.default_rng(1).uniform(0.5, 1.5, 49)
    base = regather.neighbour_noise(faces, 49, r)
    centre = 24  # the middle of the grid
    spiked = r.copy()
    spiked[centre] = 1e6  # an outlier at the centre
    after = regather.neighbour_noise(faces, 49, spiked)
    assert after[centre] == base[centre]
    changed = np.flatnonzero(after != base)
    # the outlier raises the estimate of exactly the vertices within two rings of it
    ring1 = np.unique(faces[(faces == centre).any(axis=1)])
    ring2 = np.unique(faces[np.isin(faces, ring1).any(axis=1)])
    assert set(changed) == set(ring2) - {centre}
    # and the estimate is the plain mean over those neighbours
    others = np.setdiff1d(ring2, [centre])
    assert np.isclose(base[centre], r[others].mean())


def test_an_isolated_vertex_gets_the_object_mean():
    faces = np.array([[0, 1, 2]])
    r = np.array([1.0, 2.0, 3.0, 10.0])  # vertex 3 belongs to no triangle
    got = regather.neighbour_noise(faces, 4, r)
    assert np.allclose(got, [2.5, 2.0, 1.5, 4.0])


@pytest.mark.parametrize("budget", [0.1, 0.5, 2.0, 100.0])
def test_the_plan_keeps_to_its_budget(budget):
    predicted = np.random.default_rng(2).lognormal(-6, 1.5, 5000)
    passes, tolerance = regather.plan_passes(predicted, 0.02, budget)
    assert passes.min() >= 1 and passes.max() <= regather.MAX_PASSES
    assert (passes - 1).sum() <= budget * len(predicted)
    if tolerance > 0.02:  # the budget was binding: the tolerance rose until it fit
        assert (passes - 1).sum() > 0.9 * budget * len(predicted)
    else:  # every vertex reaches the tolerance, unless capped
        reached = predicted / passes <= 0.02**2 * (1 + 1e-9)
        assert (reached | (passes == regather.MAX_PASSES)).all()
    # the noisiest vertices get the most passes
    order = np.argsort(predicted)
    assert (np.diff(passes[order]) >= 0).all()


def test_no_budget_or_no_vertices_means_one_pass():
    p, _ = regather.plan_passes(np.ones(10), 0.01, 0.0)
    assert (p == 1).all()
    p, _ = regather.plan_passes(np.zeros(0), 0.01, 1.0)
    assert len(p) == 0


@pytest.fixture(scope="module")
def relay(tmp_path_factory):
    path = tmp_path_factory.mktemp("relay") / "scene.toml"
    path.write_text(textwrap.dedent(GLOSSY_RELAY))
    return load_scene(path)


def test_extra_passes_keep_the_answer_and_pass_0_bits(relay, monkeypatch):
    # gather paths end after the floor, as the quadrature does (no plate -> floor -> plate)
    monkeypatch.setattr(solve_module, "MAX_GATHER_DEPTH", 2)
    opts = dict(photons=20_000, gather_samples=1024, light_samples=4, grid=8, max_edge=0.05, seed=3)
    plain = solve(relay, SolveOptions(extra_gather=0.0, **opts))
    extra = solve(relay, SolveOptions(extra_gather=3.0, gather_tolerance=0.01, **opts))
    info = extra.stats["regather"]["plate"]
    assert plain.stats["regather"]["plate"]["extra_passes"] == 0
    assert 0 < info["extra_passes"] <= 3.0 * len(extra.object("plate").positions)
    # each extra pass of a vertex traces at least its 1024 gather rays (the floor's own
    # noise, its sharp reflection of the lamp, is in closed form and asks for none)
    assert info["max_passes"] > 1
    assert extra.stats["gather_rays"] >= plain.stats["gather_rays"] + 1024 * info["extra_passes"]
    p0, p1 = plain.object("plate"), extra.object("plate")
    # a vertex with one pass keeps pass 0's bits (pass 0 uses the solve's own seed)
    same = (p0.radiance == p1.radiance).all(axis=(1, 2))
    assert same.sum() == len(p0.positions) - info["regathered"]
    # against the quadrature: pass 0 alone, and the mean of every vertex's passes
    t, n = p0.tangents.astype(float), p0.normals.astype(float)
    b = np.cross(n, t)
    expected = np.stack(
        [
            glossy_relay_radiance(
                p0.positions[v].astype(float), p0.directions.astype(float) @ np.stack([t[v], b[v], n[v]])
            )
            for v in range(len(p0.positions))
        ]
    )
    lum = np.array(gather.LUMINANCE)
    bright = expected > 0.1 * expected.max()
    errors = []
    for sol in (p0, p1):
        relative = (sol.radiance.astype(float) @ lum)[bright] / expected[bright] - 1
        errors.append(np.sqrt(np.mean(relative**2)))
        assert abs(relative.mean()) < 0.03, relative.mean()
    # measured: mean +1.6 % and +0.8 % (standard error about 1.2 %), RMS 8.9 % with pass 0
    # alone and 3.9 % with every vertex's 4 passes (1/sqrt(4) would give 4.4 %)
    assert errors[1] < 0.6 * errors[0], errors


def test_bad_extra_gather_knobs_are_refused(relay):
    for knob in (dict(extra_gather=-1.0), dict(gather_tolerance=float("nan")), dict(extra_gather=float("inf"))):
        with pytest.raises(InputError, match="--extra-gather|--gather-tolerance"):
            SolveOptions(**knob).resolved(relay)


def test_lobe_light_reaches_the_gather(relay):
    opts = dict(photons=5_000, gather_samples=16, light_samples=1, grid=4, max_edge=0.1, extra_gather=0.0)
    on = solve(relay, SolveOptions(**opts))
    off = solve(relay, SolveOptions(lobe_light=False, **opts))
    assert on.settings["lobe_light"] and not off.settings["lobe_light"]
    # the light samples at the floor's glossy hits are extra shadow rays
    assert on.stats["gather_rays"] > off.stats["gather_rays"]
    assert not np.array_equal(on.object("plate").radiance, off.object("plate").radiance)
