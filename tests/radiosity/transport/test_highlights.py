"""The emitters' direct highlights in closed form inside the solver: which emitters
become parts (radiosity.scene.emitter_parts), what each glossy vertex sees of them
(transport.highlights.visibility), and the solution's radiance against numeric
integration and against the gathered estimator it replaces."""

import math
import textwrap

import numpy as np
import pytest
from analytic import PENUMBRA, PENUMBRA_LAMP_HALF
from scene_files import scene_from

from radiosity.scene.emitter_parts import MAX_OBJECT_PARTS, emitter_parts, object_parts
from radiosity.transport import highlights
from radiosity.transport.embree import RayTracer
from radiosity.transport.solve import SolveOptions, solve

SPHERE_OVER_PLATE = """
    [materials.plate]
    diffuse = 0.1
    specular = 0.6
    exponent = {exponent}
    [materials.lamp]
    emission = [40.0, 20.0, 10.0]
    [[objects]]
    name = "plate"
    builtin = "quad"
    material = "plate"
    scale = 0.6
    [[objects]]
    name = "lamp"
    builtin = "sphere"
    material = "lamp"
    scale = 0.06
    translate = [0.05, 0.5, 0.1]
"""


def test_parts_of_spheres_convex_polygons_and_everything_else(tmp_path):
    scene = scene_from(tmp_path, """
        [materials.lamp]
        emission = 1.0
        [[objects]]
        name = "ball"
        builtin = "sphere"
        material = "lamp"
        scale = 0.5
        translate = [0, 3, 0]
        [[objects]]
        name = "panel"
        builtin = "quad"
        material = "lamp"
        scale = [2, 1, 1]
        rotate_deg = [180, 0, 0]
        translate = [0, 5, 0]
        [[objects]]
        name = "box"
        builtin = "cube"
        material = "lamp"
        translate = [3, 0, 0]
    """)
    ball = object_parts(scene.object("ball"))
    assert [p.kind for p in ball] == ["sphere"]
    assert ball[0].area == pytest.approx(scene.object("ball").area)  # the mesh's power
    np.testing.assert_allclose(ball[0].points[0], [0, 3, 0], atol=1e-9)
    panel = object_parts(scene.object("panel"))
    assert [p.kind for p in panel] == ["polygon"] and len(panel[0].points) == 4
    np.testing.assert_allclose(panel[0].normal, [0, -1, 0], atol=1e-12)  # it emits downwards
    assert panel[0].area == pytest.approx(2.0)
    box = object_parts(scene.object("box"))  # six faces, each a square
    assert len(box) == 6 and all(len(p.points) == 4 for p in box)
    parts, names = emitter_parts(scene)
    assert set(names) == {"ball", "panel", "box"} and len(parts) == 8
    # a cap on the scene's parts: the brightest objects first, the others gathered
    parts, names = emitter_parts(scene, max_parts=3)
    assert names == ("ball", "panel")  # pi Le area: 9.8 and 6.3; the box (six parts) no longer fits


def test_a_non_convex_emitter_is_its_triangles_and_a_large_mesh_is_gathered(tmp_path):
    # an L of three unit squares (six triangles): not convex, so its triangles
    obj_text = """
        [materials.lamp]
        emission = 1.0
        [[objects]]
        name = "ell"
        mesh = "ell.obj"
        material = "lamp"
    """
    (tmp_path / "ell.obj").write_text(textwrap.dedent("""
        v 0 0 0
        v 1 0 0
        v 2 0 0
        v 0 0 1
        v 1 0 1
        v 2 0 1
        v 0 0 2
        v 1 0 2
        f 1 4 5
        f 1 5 2
        f 2 5 6
        f 2 6 3
        f 4 7 8
        f 4 8 5
    """))
    scene = scene_from(tmp_path, obj_text)
    parts = object_parts(scene.object("ell"))
    assert len(parts) == 6 and all(len(p.points) == 3 for p in parts)
    assert sum(p.area for p in parts) == pytest.approx(3.0)
    many = scene.refined(0.25)  # more triangles than an object may have parts
    assert len(object_parts(many.object("ell"))) > MAX_OBJECT_PARTS
    assert emitter_parts(many) == ((), ())


def test_visibility_of_a_lamp_behind_a_half_plane_occluder(tmp_path):
    # PENUMBRA: a square lamp (side 0.2) at height 1 over a floor, a black half-plane at
    # height 0.5 hiding x_lamp < -x: a floor point sees the fraction (0.1 - max(-0.1, -x)) / 0.2
    text = PENUMBRA.replace('[materials.floor]\n    diffuse = 0.5', '[materials.floor]\n    diffuse = 0.3\n    specular = 0.5\n    exponent = 50')
    scene = scene_from(tmp_path, text).refined(0.05)
    parts, names = emitter_parts(scene)
    assert names == ("lamp",)
    floor = scene.object("floor")
    merged = scene.merged()
    tracer = RayTracer(merged.positions, merged.faces)
    vis = highlights.visibility(tracer, parts, floor.positions, floor.normals, 256, tracer.epsilon)[:, 0]
    x = floor.positions[:, 0]
    h = PENUMBRA_LAMP_HALF
    expected = np.clip((h - np.maximum(-h, -x)) / (2 * h), 0.0, 1.0)
    assert np.abs(vis - expected).max() < 0.03
    assert (vis[x < -0.12] == 0).all() and (vis[x > 0.12] == 1).all()
    # the same points for every vertex: a smooth function of position, not noise
    order = np.argsort(x)
    band = (x[order] > -0.1) & (x[order] < 0.1)
    assert (np.diff(vis[order][band]) >= -0.03).all()


def sphere_reflection(lamp, x, n, wo, ks, exponent, steps=300):
    """ks (n+2)/(2 pi) integral over the lamp's cap of cos^n(alpha) cos(theta_i) Le dwi, midpoint rule."""
    centre, radius = lamp.positions.mean(axis=0), math.sqrt(lamp.area / (4 * math.pi))
    c = centre - x
    d = np.linalg.norm(c)
    c /= d
    beta = math.asin(radius / d)
    t = np.cross(c, [1.0, 0, 0])
    t /= np.linalg.norm(t)
    b = np.cross(c, t)
    u = (np.arange(steps) + 0.5) / steps
    ct = 1 - u * (1 - math.cos(beta))
    st = np.sqrt(1 - ct**2)
    phi = 2 * np.pi * u
    wi = (ct[:, None, None] * c + st[:, None, None] * (np.cos(phi)[None, :, None] * t + np.sin(phi)[None, :, None] * b))
    wi = wi.reshape(-1, 3)
    mirror = 2 * (n @ wo) * n - wo
    lobe = ks * (exponent + 2) / (2 * np.pi) * np.maximum(wi @ mirror, 0) ** exponent * np.maximum(wi @ n, 0)
    return lobe.mean() * 2 * np.pi * (1 - math.cos(beta))


@pytest.mark.parametrize("exponent", [50.0, 2000.0])
def test_a_sphere_lamps_highlight_on_a_plate_against_numeric_integration(tmp_path, exponent):
    scene = scene_from(tmp_path, SPHERE_OVER_PLATE.format(exponent=exponent))
    sol = solve(scene, SolveOptions(photons=200_000, gather_samples=16, light_samples=4, grid=16, max_edge=0.1, seed=2))
    assert [p.kind for p in sol.emitters] == ["sphere"]
    plate = sol.object("plate")
    lamp = scene.object("lamp")
    highlight = sol.highlights("plate")
    assert (plate.visibility == 1).all()  # nothing between them
    le = np.array([40.0, 20.0, 10.0])
    relative = []
    for v in range(0, plate.num_vertices, 5):
        x = plate.positions[v].astype(float)
        n = plate.normals[v].astype(float)
        world = plate.directions.astype(float) @ np.stack([plate.tangents[v], plate.bitangents[v], plate.normals[v]]).astype(float)
        for d in range(0, len(world), 11):
            expected = sphere_reflection(lamp, x, n, world[d], 0.6, exponent)
            if expected < 1e-3:
                continue
            got = highlight[v, d] / le
            np.testing.assert_allclose(got, got[0])  # white lobe: the lamp's colour alone
            relative.append(got[0] / expected - 1)
    relative = np.abs(relative)
    assert len(relative) > 10
    # the default 8 nodes: within 0.5 % mostly; a mirror direction inside the cap by less
    # than a lobe width of its edge is the hardest case (measured: up to 2.6 % at n = 2000)
    assert np.median(relative) < 0.005 and relative.max() < 0.03
    # the solution holds it: its radiance minus the closed form is the rest (here the
    # diffuse part, the lamp's light reflected diffusely; nothing else is glossy)
    rest = plate.radiance - highlight
    assert np.ptp(rest[:, :, 0], axis=1).max() < 1e-3 * plate.radiance.max()


def test_closed_form_and_gathered_highlights_agree(tmp_path):
    # the estimator it replaces: the same expected radiance, the gathered one noisier
    scene = scene_from(tmp_path, SPHERE_OVER_PLATE.format(exponent=30.0))
    opts = dict(photons=200_000, gather_samples=256, light_samples=64, grid=8, max_edge=0.1, seed=4, extra_gather=0.0)
    closed = solve(scene, SolveOptions(emitter_highlights=True, **opts)).object("plate").radiance
    gathered = solve(scene, SolveOptions(emitter_highlights=False, **opts)).object("plate").radiance
    bright = closed[..., 0] > 0.2 * closed[..., 0].max()
    ratio = gathered[..., 0][bright] / closed[..., 0][bright]
    assert abs(ratio.mean() - 1) < 0.01
    assert 0.01 < np.sqrt(np.mean((ratio - 1) ** 2)) < 0.2  # the gathered one's noise
