"""The light sample at the glossy hits of gather paths (``gather.trace_gather``)
against deterministic quadrature: it changes the noise, not the answer.

A glossy plate looks down at a glossy floor that reflects a small lamp; the lamp faces
the floor, so the plate sees only its back: every bit of light the plate reflects
arrives over a glossy hit on the floor. Sampling the floor's lobe alone finds the lamp
rarely (the heavy-tailed outliers that showed as blotches on the satin block); a light sample at the floor hit, weighted by the balance heuristic against the
lobe's own sample, finds it on every path. Both must give the double integral
lamp -> floor -> plate, computed here by the midpoint rule over floor and lamp (gather
paths cut after that bounce: ``max_depth`` 2).
"""

import textwrap

import numpy as np
import pytest
from analytic import GLOSSY_RELAY, glossy_relay_radiance

from radiosity.physics import directions
from radiosity.scene.loaders import load_scene
from radiosity.transport import gather, records, solve
from radiosity.transport.embree import RayTracer, origin_offset


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    path = tmp_path_factory.mktemp("lobe") / "scene.toml"
    path.write_text(textwrap.dedent(GLOSSY_RELAY))
    scene = load_scene(path).refined(0.05)
    merged = scene.merged()
    sa = solve.scene_arrays(scene, merged, origin_offset(merged.positions))
    with RayTracer(merged.positions, merged.faces, threads=1) as tracer:
        yield scene, merged, sa, tracer


def gather_passes(setup, lobe_light, passes, seed0):
    """The plate's radiance (passes, V, D) luminance, from gather passes of 1024 rays,
    with the irradiance zero (the floor and the plate are purely specular)."""
    scene, merged, sa, tracer = setup
    index = [o.name for o in scene.objects].index("plate")
    plate = scene.objects[index]
    vertices = merged.vertex_offset[index] + np.arange(plate.n_vertices, dtype=np.int64)
    dirs = directions.grid_directions(8)
    irradiance = np.zeros((len(sa.positions), 3))
    out = []
    for p in range(passes):
        block = records.GatherBlock(seed0 + p, vertices, 4, 32, 2, lobe_light)
        values, _ = solve.gather_block(tracer, sa, irradiance, block, plate.material, dirs)
        out.append(values @ np.array(gather.LUMINANCE))
    return np.array(out), plate, dirs


def test_light_over_a_glossy_hit_matches_quadrature_with_less_noise(setup):
    with_sample, plate, dirs = gather_passes(setup, True, 8, 100)
    lobe_only, _, _ = gather_passes(setup, False, 8, 200)
    # the directions of the grid in world space, per vertex (the vertex's frame)
    t, n = plate.tangents.astype(float), plate.normals.astype(float)
    b = np.cross(n, t)
    expected = np.stack(
        [
            glossy_relay_radiance(plate.positions[v].astype(float), dirs @ np.stack([t[v], b[v], n[v]]))
            for v in range(plate.n_vertices)
        ]
    )  # (V, D)
    bright = expected > 0.1 * expected.max()
    assert bright.sum() > 200 and expected.max() > 0.01
    # measured: with the light sample -0.2 % on average, 2.8 % RMS per vertex-direction
    # (8 passes); the lobe alone -0.3 % and 31 % (its standard error over the 51
    # vertices is about 4 %)
    relative = with_sample.mean(axis=0)[bright] / expected[bright] - 1
    assert abs(relative.mean()) < 0.01 and np.sqrt(np.mean(relative**2)) < 0.06, relative
    assert abs(np.mean(lobe_only.mean(axis=0)[bright] / expected[bright] - 1)) < 0.05
    # the noise of one pass, relative to the answer (measured: 7 % against 86 %)
    noise = [
        np.sqrt(np.mean((e[:, bright] - e.mean(axis=0)[bright]) ** 2 / expected[bright] ** 2))
        for e in (with_sample, lobe_only)
    ]
    assert noise[0] < 0.25 * noise[1], noise
