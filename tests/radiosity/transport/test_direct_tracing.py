"""Kernels that call Embree directly (``embree.intersect1`` / ``occluded1`` from numba)
against the way rays were traced before: embreex's batched ``EmbreeScene.run``, with
Python between wavefronts. Hits must be bit-identical to embreex's on random rays, and
a gather block must give the same bits as the readable oracle (tests/oracles/wavefront.py)
driven wavefront by wavefront through embreex, a path-traced tile as its own kernels
driven so; a photon batch (traced in waves) the
same bits photon by photon and as one wave, and the same sums up to the order of their
terms in waves of any size."""

import dataclasses

import numpy as np
import pytest
from oracles import wavefront

from radiosity.physics import directions
from radiosity.physics.materials import fresnel_kd_limit
from radiosity.scene.loaders import load_scene
from radiosity.scene.material_kernels import Material, pack_materials
from radiosity.transport import gather, pathtrace, records, solve
from radiosity.transport import photons as photons_kernel
from radiosity.transport.embree import MISS, Hits, RayTracer, new_rayhit, origin_offset

embreex = pytest.importorskip("embreex")
from embreex import rtcore_scene  # noqa: E402
from embreex.mesh_construction import TriangleMesh  # noqa: E402


class EmbreexTracer:
    """The batched tracer as it was: embreex, tnear 0, one call per wavefront."""

    def __init__(self, positions, faces):
        self.epsilon = origin_offset(positions)
        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = TriangleMesh(self._scene, np.ascontiguousarray(positions[faces], dtype=np.float32))

    def intersect(self, origins, directions):
        out = self._scene.run(np.ascontiguousarray(origins), np.ascontiguousarray(directions), output=1)
        return Hits(out["primID"], out["tfar"], out["u"], out["v"])

    def occluded(self, origins, directions, distances):
        out = self._scene.run(
            np.ascontiguousarray(origins), np.ascontiguousarray(directions),
            dists=np.array(distances, dtype=np.float32), query="OCCLUDED",
        )
        return out != MISS


def with_fresnel(scene):
    """The scene with each glossy material given a Fresnel term (a plastic: ks 1, F0 0.04
    and 0.9 in one channel, kd within its energy limit): the kernels' Fresnel paths."""
    new = {}
    for name, m in scene.materials.items():
        if m.is_glossy:
            f0 = (0.04, 0.04, 0.9)
            limit = fresnel_kd_limit((1.0,) * 3, f0, m.exponent)
            new[name] = Material(name, diffuse=tuple(np.minimum(m.diffuse, limit)), specular=(1.0,) * 3,
                                 exponent=m.exponent, emission=m.emission, fresnel=f0)
    objects = tuple(dataclasses.replace(o, material=new.get(o.material.name, o.material)) for o in scene.objects)
    return dataclasses.replace(scene, objects=objects)


@pytest.fixture(scope="module", params=["plain", "fresnel"])
def teapot(request):
    scene = load_scene("cornell-teapot").refined(150.0)
    if request.param == "fresnel":
        scene = with_fresnel(scene)
        assert any(m.fresnel is not None for m in scene.materials.values())
    merged = scene.merged()
    sa = solve.scene_arrays(scene, merged, origin_offset(merged.positions))
    with RayTracer(merged.positions, merged.faces, threads=2) as tracer:
        yield scene, merged, sa, tracer, EmbreexTracer(merged.positions, merged.faces)


def random_rays(rng, merged, n, epsilon):
    """Incoherent rays: origins on the surfaces (offset off their front), directions
    over the front hemisphere; and a fifth from anywhere in the box in any direction."""
    tri = rng.integers(0, len(merged.faces), n)
    bary = rng.dirichlet([1, 1, 1], n)
    p = merged.positions.astype(np.float64)[merged.faces[tri]]
    points = np.einsum("nk,nkc->nc", bary, p)
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where((np.einsum("ij,ij->i", d, normal) < 0)[:, None], -d, d)
    origins = points + epsilon * normal
    free = rng.random(n) < 0.2
    lo, hi = merged.positions.min(axis=0), merged.positions.max(axis=0)
    origins[free] = rng.uniform(lo, hi, (free.sum(), 3))
    return origins.astype(np.float32), d.astype(np.float32)


def test_hits_and_occlusion_are_bit_identical_to_embreex(rng, teapot):
    _, merged, _, tracer, reference = teapot
    origins, dirs = random_rays(rng, merged, 200_000, tracer.epsilon)
    ours, theirs = tracer.intersect(origins, dirs), reference.intersect(origins, dirs)
    hit = theirs.triangle != MISS
    assert 0.5 < hit.mean() < 1.0
    assert np.array_equal(ours.triangle, theirs.triangle)
    for a, b in ((ours.t, theirs.t), (ours.u, theirs.u), (ours.v, theirs.v)):
        assert np.array_equal(a[hit], b[hit])
    assert (ours.t[~hit] == np.inf).all() and (ours.u[~hit] == 0).all() and (ours.v[~hit] == 0).all()
    # segments ending before, at about and beyond the hit
    distances = np.where(hit, theirs.t, 1e3).astype(np.float32) * rng.choice([0.5, 0.999, 1.001, 2.0], len(hit))
    distances = distances.astype(np.float32)
    blocked = tracer.occluded(origins, dirs, distances)
    assert np.array_equal(blocked, reference.occluded(origins, dirs, distances))
    assert 0.2 < blocked.mean() < 0.8


def test_hits_on_a_random_triangle_soup_are_bit_identical_to_embreex(rng):
    corners = rng.normal(size=(3000, 3, 3)).astype(np.float32)
    positions = corners.reshape(-1, 3)
    faces = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    origins = rng.normal(size=(50_000, 3)).astype(np.float32)
    d = rng.normal(size=(50_000, 3))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    with RayTracer(positions, faces, threads=1) as tracer:
        ours = tracer.intersect(origins, d)
        blocked = tracer.occluded(origins, d, np.full(len(d), 0.5, np.float32))
    reference = EmbreexTracer(positions, faces)
    theirs = reference.intersect(origins, d)
    hit = theirs.triangle != MISS
    assert np.array_equal(ours.triangle, theirs.triangle) and hit.mean() > 0.5
    assert all(np.array_equal(a[hit], b[hit]) for a, b in zip(ours[1:], theirs[1:]))
    assert np.array_equal(blocked, reference.occluded(origins, d, np.full(len(d), 0.5, np.float32)))


def test_an_empty_scene_misses_everything():
    with RayTracer(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32)) as tracer:
        hits = tracer.intersect(np.zeros((3, 3), np.float32), np.tile(np.float32([0, 0, 1]), (3, 1)))
        assert (hits.triangle == MISS).all()


# -- whole batches: the same bits as the embreex wavefronts -----------------------------------


def embreex_photon_wavefront(sa, reference, seed, first, count, total):
    """The photon tally of photons first .. first + count - 1 traced wavefront by
    wavefront through embreex (the oracle's ``emit_photons``, then per depth
    ``bounce_photons``), and the rays traced."""
    batch = records.PhotonBatch(seed, first, count, total, solve.MAX_PHOTON_DEPTH)
    expected = records.empty_tally(len(sa.positions))
    photons = records.empty_rays(count)
    wavefront.emit_photons(sa, seed, first, total, photons)
    out = records.empty_rays(count)
    depth = rays = 0
    while len(photons.ids):
        hits = reference.intersect(photons.origins, photons.directions)
        rays += len(photons.ids)
        n = wavefront.bounce_photons(sa, batch, depth, photons, hits, expected, out)
        photons = records.Rays(*(a[:n].copy() for a in out))
        depth += 1
    return expected, rays


def test_each_photon_gives_the_same_bits_as_the_embreex_wavefront(teapot):
    # ``trace_photons`` goes in waves, the wavefront every photon one bounce at a time:
    # a photon alone has the same rays and deposits in the same order either way, so
    # its tally must match bit for bit
    _, _, sa, tracer, reference = teapot
    seed, total = 3, 1_000_000
    bounced = 0
    for pid in np.linspace(0, 500_000, 150).astype(int):
        expected, rays = embreex_photon_wavefront(sa, reference, seed, pid, 1, total)
        before = tracer.rays_cast
        got = solve.trace_photon_batch(tracer, sa, seed, pid, 1, total)
        assert tracer.rays_cast - before == rays
        bounced += rays > 1
        for a, b in zip(got, expected):
            assert np.array_equal(a, b), pid
    assert bounced > 50


def test_a_photon_batch_sums_the_same_deposits_as_the_embreex_wavefront(teapot):
    # a whole batch: the same rays, hits and deposits; the sums differ only by the
    # order of their terms (wave by wave against depth by depth), so by rounding
    _, _, sa, tracer, reference = teapot
    seed, first, count, total = 3, 70_000, 20_000, 1_000_000
    assert count > 10 * records.PHOTON_WAVE  # many waves
    expected, rays = embreex_photon_wavefront(sa, reference, seed, first, count, total)
    before = tracer.rays_cast
    got = solve.trace_photon_batch(tracer, sa, seed, first, count, total)
    assert tracer.rays_cast - before == rays > count
    assert got.tally[records.T_HITS] == expected.tally[records.T_HITS]
    for a, b in zip(got, expected):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
        assert not np.array_equal(a, np.zeros_like(a))


def test_a_batch_traced_as_one_wave_gives_the_same_bits_as_the_embreex_wavefront(teapot):
    # one wave is the wavefront itself: every photon at depth d, then depth d + 1, the
    # survivors packed in order; so the sums have the same terms in the same order
    _, _, sa, tracer, reference = teapot
    seed, first, count, total = 5, 3_000, 3_000, 1_000_000
    expected, rays = embreex_photon_wavefront(sa, reference, seed, first, count, total)
    got = records.empty_tally(len(sa.positions))
    traced = photons_kernel.trace_photons(
        tracer.embree, sa, records.PhotonBatch(seed, first, count, total, solve.MAX_PHOTON_DEPTH, count), got
    )
    assert traced == rays
    for a, b in zip(got, expected):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("wave", [1, 7, 64, 5_000])
def test_the_wave_size_changes_only_the_rounding(teapot, wave):
    # waves of 1 (photon by photon), odd sizes with a short last wave, and more than
    # the batch: the same rays and hits, sums equal to rounding
    _, _, sa, tracer, _ = teapot
    seed, first, count, total = 2, 500, 2_500, 1_000_000
    sums = []
    for w in (records.PHOTON_WAVE, wave):
        acc = records.empty_tally(len(sa.positions))
        rays = photons_kernel.trace_photons(
            tracer.embree, sa, records.PhotonBatch(seed, first, count, total, solve.MAX_PHOTON_DEPTH, w), acc
        )
        sums.append((rays, acc))
    (rays_a, a), (rays_b, b) = sums
    assert rays_a == rays_b > count
    assert a.tally[records.T_HITS] == b.tally[records.T_HITS]
    for x, y in zip(a, b):
        assert np.allclose(x, y, rtol=1e-12, atol=1e-12 * np.abs(y).max())


def test_a_gather_block_gives_the_same_bits_as_the_embreex_wavefront(rng, teapot):
    gather_block_against_the_oracle(rng, *teapot)


def test_a_gather_block_with_delta_lights_gives_the_same_bits_as_the_embreex_wavefront(rng):
    """The delta lights' sample at the glossy hits (a point, a spot, a sun) too."""
    from radiosity.physics.emitters import EmitterPart, SpotProfile

    lights = (EmitterPart("point", [[278.0, 450.0, 280.0]], 0.0, [4e4, 3e4, 2e4], "bulb"),
              EmitterPart("point", [[100.0, 500.0, 100.0]], 0.0, [9e4] * 3, "torch", SpotProfile([1, -2, 1], 35, 20)),
              EmitterPart("direction", [[0.2, -1.0, 0.3]], 0.0, [1.0, 1.0, 1.0], "sun"))
    scene = dataclasses.replace(load_scene("cornell-teapot").refined(150.0), lights=lights)
    merged = scene.merged()
    sa = solve.scene_arrays(scene, merged, origin_offset(merged.positions))
    assert len(sa.lights.kinds) == 3
    with RayTracer(merged.positions, merged.faces, threads=2) as tracer:
        gather_block_against_the_oracle(rng, scene, merged, sa, tracer, EmbreexTracer(merged.positions, merged.faces))


def gather_block_against_the_oracle(rng, scene, merged, sa, tracer, reference):
    index = [o.name for o in scene.objects].index("teapot")
    teapot_object = scene.objects[index]
    first = merged.vertex_offset[index]
    irradiance = rng.uniform(0, 5, (len(sa.positions), 3))
    vertices = np.linspace(first, first + teapot_object.n_vertices - 1, 60).astype(np.int64)  # top to bottom
    block = records.GatherBlock(5, vertices, 4, 5, solve.MAX_GATHER_DEPTH)
    dirs = directions.grid_directions(9)

    b, n_gather = len(block.vertices), block.strata**2
    light = records.empty_light_samples(b * block.n_light)
    samples = records.empty_gather_samples(b * n_gather)
    gather.make_gather_rays(sa, block, light, samples)
    valid = light.pdf > 0
    light.visible[valid] = ~reference.occluded(light.origins[valid], light.directions[valid], light.distances[valid])
    paths = records.Rays(np.arange(b * n_gather), np.ones((b * n_gather, 3)), samples.origins, samples.directions)
    out = records.empty_rays(b * n_gather)
    pdf, out_pdf = np.zeros(b * n_gather), np.zeros(b * n_gather)
    rayhit = new_rayhit()  # the glossy hits' light samples are traced inside shade_paths
    lobe_samples = 0
    for depth in range(block.max_depth):
        if not len(paths.ids):
            break
        hits = reference.intersect(paths.origins, paths.directions)
        n, traced = wavefront.shade_paths(
            (tracer.embree, rayhit), sa, irradiance, block, depth, (paths, pdf, hits), samples, (out, out_pdf)
        )
        lobe_samples += traced
        paths = records.Rays(*(a[:n].copy() for a in out))
        pdf = out_pdf[:n].copy()
    assert lobe_samples > 0  # paths met glossy surfaces and sampled the light there
    expected, expected_variance = np.empty((b, len(dirs), 3)), np.empty(b)
    material = teapot_object.material
    diffuse = (np.asarray(material.diffuse) / np.pi)[None, :] * irradiance[block.vertices]
    gather.gather_outputs(
        pack_materials([material])[0],
        np.asarray(material.emission, float),
        diffuse,
        light,
        samples,
        dirs,
        expected,
        expected_variance,
    )
    assert valid.any() and light.visible.any() and not light.visible[valid].all()

    got, variance = solve.gather_block(tracer, sa, irradiance, block, material, dirs)
    assert np.array_equal(got, expected)
    assert np.array_equal(variance, expected_variance) and (variance > 0).any()


def test_a_path_traced_tile_gives_the_same_bits_as_the_embreex_wavefront(teapot):
    scene, _, sa, tracer, reference = teapot
    camera = scene.camera.sized(24, 16)
    cam = pathtrace.camera_rays(camera)
    tile = pathtrace.Tile(4, 30, 200, 2, 3, camera.width, camera.height)
    n = tile.pixels * tile.samples
    paths, spare = pathtrace.empty_paths(n), pathtrace.empty_paths(n)
    shadow = pathtrace.empty_shadow_rays(n)
    pathtrace.start_paths(cam, tile, paths)
    radiance = np.zeros((n, 3))
    for depth in range(pathtrace.MAX_DEPTH):
        if n == 0:
            break
        live = pathtrace.Paths(*(a[:n] for a in paths))
        hits = reference.intersect(live.origins, live.directions)
        n_shadow, n = pathtrace.shade(sa, tile, depth, live, hits, radiance, shadow, spare)
        if n_shadow:
            head = pathtrace.ShadowRays(*(a[:n_shadow] for a in shadow))
            blocked = reference.occluded(head.origins, head.directions, head.distances)
            pathtrace.add_visible(head, blocked, radiance)
        paths, spare = spare, paths
    total, squares = np.zeros((tile.pixels, 3)), np.zeros((tile.pixels, 3))
    pathtrace.pixel_sums(tile, radiance, total, squares)
    assert total.any()

    _, got_total, got_squares = pathtrace.trace_tile(tracer, sa, cam, tile)
    assert np.array_equal(got_total, total) and np.array_equal(got_squares, squares)
