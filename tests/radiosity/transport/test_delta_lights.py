"""Delta lights (points, spots, directions) through the solver and the path tracer,
against answers known in closed form:

- the spot's profile (Mitsuba 3's) inside, across and outside its transition, and its
  power (I times the profile's solid angle);
- the photons: each kind's photons carry its power (a point's and a spot's all caught
  by a closed black sphere around them, a direction's by a square facing it);
- irradiance I cos / d^2 (times the profile for a spot) and E cos at every vertex of a
  diffuse plane (the density estimate's noise and its kernel's blur aside);
- a glossy plane's closed-form highlight of a point light against numpy, and the rest
  of its radiance its diffuse part alone;
- the gather's sample of a delta light at glossy hits: a glossy plate seeing a point
  light in a glossy wall, against the path tracer;
- the path tracer: every pixel of a plane lit by each kind against the closed form
  (the light's estimate is exact: only where in the pixel the sample lands varies).
"""

import dataclasses
import math

import numpy as np
import pytest
from scene_files import scene_from

from radiosity.files.camera import Camera
from radiosity.physics.directions import grid_lookup_weights
from radiosity.physics.emitters import SpotProfile, spot_falloff
from radiosity.transport.pathtrace import PathTracer
from radiosity.transport.solve import SolveOptions, solve

KD = np.array([0.5, 0.6, 0.7])
INTENSITY = np.array([3.0, 2.0, 1.0])
POINT = (0.2, 0.6, -0.1)
SUN = np.array([0.3, -1.0, 0.2]) / np.linalg.norm([0.3, -1.0, 0.2])
IRRADIANCE = np.array([1.0, 0.5, 2.0])


def toml(values):
    """A TOML array of numbers."""
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"



def plane_scene(tmp_path, light, scale=2.0, extra=""):
    """A diffuse square (kd ``KD``, side ``scale``, facing +y at y = 0) and one light."""
    return scene_from(tmp_path, f"""
        [materials.floor]
        diffuse = {toml(KD)}
        {extra}
        [[objects]]
        name = "floor"
        builtin = "quad"
        material = "floor"
        scale = {scale}
        [[lights]]
        {light}
    """)


POINT_LIGHT = f'kind = "point"\nposition = {toml(POINT)}\nintensity = {toml(INTENSITY)}'
SPOT_LIGHT = f'kind = "spot"\nposition = {toml(POINT)}\ndirection = [0.3, -1, 0.1]\nintensity = {toml(INTENSITY)}\n' \
             'cutoff_deg = 40\nbeam_deg = 25'
DIRECTIONAL = f'kind = "directional"\ndirection = {toml(SUN)}\nirradiance = {toml(IRRADIANCE)}'


def point_irradiance(x, position=POINT, intensity=INTENSITY, spot=None):
    """I cos / d^2 (times the spot's profile) at points x (N, 3) of the plane y = 0 facing +y."""
    to = np.asarray(position) - x
    d = np.linalg.norm(to, axis=1)
    cos = np.maximum(to[:, 1] / d, 0)
    profile = 1.0
    if spot is not None:
        angle = np.degrees(np.arccos(np.clip((-to / d[:, None]) @ spot.axis, -1, 1)))
        profile = spot.falloff(angle)
    return (profile * cos / d**2)[:, None] * intensity


# -- the spot's profile ----------------------------------------------------------------------


def test_the_spots_profile_inside_across_and_outside_its_transition():
    """Mitsuba 3's falloff_curve: 1 inside the beam, linear in the angle across the
    transition, 0 at and beyond the cutoff."""
    spot = SpotProfile([0, 0, 1], 30.0, 20.0)
    angles = np.array([0.0, 10.0, 19.999, 20.0, 22.5, 25.0, 27.5, 29.999, 30.0, 31.0, 90.0, 180.0])
    expected = np.clip((30.0 - angles) / 10.0, 0, 1)
    expected[angles >= 30.0] = 0
    assert np.allclose(spot.falloff(angles), expected, atol=1e-9)
    assert spot_falloff(math.radians(25.0), math.radians(30.0), math.radians(20.0)) == pytest.approx(0.5)
    # no transition (beam = cutoff): a hard edge; a zero beam: a cone
    hard = SpotProfile([0, 0, 1], 15.0, 15.0)
    assert hard.falloff([14.99, 15.0, 15.01]).tolist() == [1.0, 0.0, 0.0]
    assert SpotProfile([0, 0, 1], 20.0, 0.0).falloff([0.0, 10.0]).tolist() == pytest.approx([1.0, 0.5])


@pytest.mark.parametrize("cutoff, beam", [(20.0, 15.0), (40.0, 25.0), (90.0, 0.0), (10.0, 10.0), (180.0, 120.0)])
def test_the_spots_solid_angle_is_the_profiles_integral(cutoff, beam):
    spot = SpotProfile([0, 1, 0], cutoff, beam)
    theta = np.linspace(0, 180, 400_001)
    mid = 0.5 * (theta[1:] + theta[:-1])
    numeric = 2 * np.pi * np.sum(spot.falloff(mid) * np.sin(np.radians(mid))) * np.radians(theta[1] - theta[0])
    assert spot.solid_angle() == pytest.approx(numeric, rel=1e-4)  # a hard edge costs the midpoint rule a little


# -- the photons' power ----------------------------------------------------------------------


@pytest.mark.parametrize("light, power", [
    (POINT_LIGHT, 4 * np.pi * INTENSITY),
    (SPOT_LIGHT, SpotProfile([0.3, -1, 0.1], 40, 25).solid_angle() * INTENSITY),
])
def test_a_point_lights_photons_carry_its_power(tmp_path, light, power):
    """Inside a closed black sphere every photon lands at once: what lands is what the
    light emits (a spot's photons, weighted by its profile, to Monte Carlo noise)."""
    scene = scene_from(tmp_path, f"""
        [materials.black]
        diffuse = 0.0
        [[objects]]
        name = "room"
        builtin = "sphere"
        material = "black"
        scale = 3
        flip = true
        [[lights]]
        {light}
    """)
    solution = solve(scene, SolveOptions(quality="draft", photons=200_000, threads=2, grid=4, extra_gather=0,
                                         max_edge=2.0))
    energy = {k: np.asarray(v) for k, v in solution.stats["energy"].items() if k != "photon_hits"}
    assert np.allclose(energy["emitted"], power, rtol=1e-12)
    assert np.allclose(energy["incident"], power, rtol=3e-3 if "spot" in light else 1e-9)
    assert np.allclose(energy["escaped"], 0) and np.allclose(energy["absorbed"], power, rtol=3e-3)


def test_a_directional_lights_photons_carry_its_power(tmp_path):
    """E pi R^2 leaves the disk of the bounding sphere; a square facing the light catches
    E times its area, a tilted one E cos times it (the rest escapes)."""
    for tilt, cos in ((0.0, 1.0), (60.0, 0.5)):
        scene = plane_scene(tmp_path, 'kind = "directional"\ndirection = [0, -1, 0]\nirradiance = [1, 2, 3]')
        if tilt:
            scene = scene_from(tmp_path, f"""
                [materials.floor]
                diffuse = {toml(KD)}
                [[objects]]
                name = "floor"
                builtin = "quad"
                material = "floor"
                scale = 2
                rotate_deg = [{tilt}, 0, 0]
                [[lights]]
                kind = "directional"
                direction = [0, -1, 0]
                irradiance = [1, 2, 3]
            """)
        solution = solve(scene, SolveOptions(quality="draft", photons=400_000, threads=2, max_edge=1.0))
        energy = {k: np.asarray(v) for k, v in solution.stats["energy"].items() if k != "photon_hits"}
        e = np.array([1.0, 2.0, 3.0])
        lo, hi = scene.bounds
        radius = 0.5 * np.linalg.norm(hi - lo)
        assert np.allclose(energy["emitted"], e * np.pi * radius**2, rtol=1e-3)  # the disk a hair larger
        assert np.allclose(energy["incident"], e * 4.0 * cos, rtol=0.01), (tilt, energy["incident"])
        assert np.allclose(energy["emitted"], energy["escaped"] + energy["absorbed"], rtol=0.01)  # in expectation


# -- irradiance at the vertices ------------------------------------------------------------------


def vertex_irradiance(solution, name="floor"):
    o = solution.object(name)
    return o.positions.astype(np.float64), np.pi * o.radiance[:, 0, :].astype(np.float64) / KD


@pytest.mark.parametrize("kind", ["point", "spot"])
def test_a_point_light_over_a_diffuse_plane_gives_i_cos_over_d_squared(tmp_path, kind):
    scene = plane_scene(tmp_path, POINT_LIGHT if kind == "point" else SPOT_LIGHT)
    solution = solve(scene, SolveOptions(quality="draft", photons=2_000_000, threads=2, max_edge=0.08))
    x, e = vertex_irradiance(solution)
    spot = scene.lights[0].spot
    expected = point_irradiance(x, spot=spot)
    if spot is None:
        ratio = e / expected
        assert np.allclose(np.median(ratio, axis=0), 1, atol=0.01), np.median(ratio, axis=0)
        assert np.percentile(np.abs(ratio - 1), 90) < 0.06
    else:
        # inside the beam: the closed form; across the transition, within the kernel's blur of it
        way = (x - POINT) / np.linalg.norm(x - POINT, axis=1)[:, None]
        angle = np.degrees(np.arccos(np.clip(way @ spot.axis, -1, 1)))
        inside = angle < 22
        ratio = e[inside] / expected[inside]
        assert inside.sum() > 50
        assert np.allclose(np.median(ratio, axis=0), 1, atol=0.015), np.median(ratio, axis=0)
        assert np.percentile(np.abs(ratio - 1), 90) < 0.08
        outside = angle > 50  # beyond the cutoff and the kernel's reach
        assert outside.sum() > 50 and np.all(e[outside] < 1e-3 * expected[inside].max()), e[outside].max()
        across = (angle > 28) & (angle < 37)
        assert np.allclose(e[across].sum(axis=0), expected[across].sum(axis=0), rtol=0.06)
    # the whole plane's power: the energy tally's incident power against the closed form's integral
    energy = np.asarray(solution.stats["energy"]["incident"])
    g = (np.arange(800) + 0.5) / 800 * 2 - 1
    grid = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    points = np.stack([grid[:, 0], np.zeros(len(grid)), grid[:, 1]], axis=1)
    assert np.allclose(energy, point_irradiance(points, spot=spot).sum(axis=0) * 4 / len(points), rtol=0.01)


def test_a_point_light_outside_the_scene_sends_its_photons_at_it(tmp_path):
    """A point light far above a plane (outside its bounding sphere: a lamp by the
    camera): its photons go into the cone that holds the scene, so most of them land;
    the irradiance is I cos / d^2 all the same, and the power they leave out counts as
    escaped, so the tally still closes."""
    far = (0.5, 4.0, -0.3)
    scene = plane_scene(tmp_path, f'kind = "point"\nposition = {toml(far)}\nintensity = {toml(INTENSITY * 20)}')
    solution = solve(scene, SolveOptions(quality="draft", photons=400_000, threads=2, max_edge=0.1))
    x, e = vertex_irradiance(solution)
    ratio = e / point_irradiance(x, position=far, intensity=INTENSITY * 20)
    assert np.allclose(np.median(ratio, axis=0), 1, atol=0.01) and np.percentile(np.abs(ratio - 1), 90) < 0.05
    stats = solution.stats
    assert stats["energy"]["photon_hits"] > 0.5 * stats["photons"]  # 4 % would land spread over every direction
    energy = {k: np.asarray(v) for k, v in stats["energy"].items() if k != "photon_hits"}
    assert np.allclose(energy["emitted"], 4 * np.pi * INTENSITY * 20, rtol=1e-12)
    assert np.allclose(energy["emitted"], energy["escaped"] + energy["absorbed"], rtol=0.01)
    distance = np.linalg.norm(far)  # from the plane's centre, its bounding sphere's
    cone = 2 * np.pi * (1 - np.sqrt(1 - (solution_radius(scene) / distance) ** 2))
    assert np.allclose(energy["unreached"], INTENSITY * 20 * (4 * np.pi - cone), rtol=1e-4)  # 4 ray offsets wider


def solution_radius(scene):
    """The radius of the disk a solve's directional photons start from (its bounding
    sphere, a hair larger than the box's: ``batches``)."""
    lo, hi = scene.bounds
    return 0.5 * np.linalg.norm(hi - lo) * (1 + 1e-4)


def test_a_directional_light_over_a_diffuse_plane_gives_e_cos(tmp_path):
    scene = plane_scene(tmp_path, DIRECTIONAL)
    solution = solve(scene, SolveOptions(quality="draft", photons=1_000_000, threads=2, max_edge=0.1))
    _, e = vertex_irradiance(solution)
    expected = IRRADIANCE * -SUN[1]
    assert np.allclose(e.mean(axis=0), expected, rtol=0.01)
    assert np.percentile(np.abs(e / expected - 1), 90) < 0.06


# -- the glossy highlight in closed form -------------------------------------------------------


def phong_highlight(x, n, wo, ks, exponent, position, intensity, fresnel=None):
    """f_s(wi, wo) I cos / d^2 by numpy, per point x (N, 3) and view wo (N, D, 3): the
    modified-Phong lobe about the mirror of wo, ks weighted by Schlick's F(n . wo)."""
    to = np.asarray(position) - x
    d = np.linalg.norm(to, axis=1)
    wi = to / d[:, None]
    wn = np.einsum("vdi,vi->vd", wo, n)
    r = 2 * wn[..., None] * n[:, None, :] - wo
    lobe = np.maximum(np.einsum("vdi,vi->vd", r, wi), 0) ** exponent
    ks = np.asarray(ks) * (1 if fresnel is None else
                           (fresnel + (1 - np.asarray(fresnel)) * (1 - np.clip(wn, 0, 1))[..., None] ** 5))
    cos = np.maximum(np.einsum("vi,vi->v", wi, n), 0) / d**2
    return ks * ((exponent + 2) / (2 * np.pi) * lobe * cos[:, None])[..., None] * np.asarray(intensity)


@pytest.mark.parametrize("fresnel", [None, [0.04, 0.1, 0.2]])
def test_a_point_lights_highlight_on_a_glossy_plane_is_its_closed_form(tmp_path, fresnel):
    """The solution's highlights (what a display subtracts and draws per pixel) are the
    lobe at the light's one direction, and what remains of the radiance is the diffuse
    part (the plane sees nothing else)."""
    scene = plane_scene(tmp_path, POINT_LIGHT, extra="specular = 0.3\n        exponent = 30")
    if fresnel is not None:  # (a TOML material has none: Mitsuba's plastics and glTF's metals do)
        floor = scene.objects[0]
        material = dataclasses.replace(floor.material, specular=(0.5, 0.5, 0.5), fresnel=tuple(fresnel))
        scene = dataclasses.replace(scene, objects=(dataclasses.replace(floor, material=material),))
    solution = solve(scene, SolveOptions(quality="draft", photons=1_000_000, threads=2, max_edge=0.2, grid=12))
    obj = solution.object("floor")
    assert [p.kind for p in solution.emitters] == ["point"] and solution.lights[0].to_dict() == solution.emitters[0].to_dict()
    assert np.all(obj.visibility == 1.0)
    x = obj.positions.astype(np.float64)
    n = obj.normals.astype(np.float64)
    t = obj.tangents.astype(np.float64)
    b = np.cross(n, t)
    dirs = obj.directions.astype(np.float64)
    wo = dirs[None, :, 0:1] * t[:, None] + dirs[None, :, 1:2] * b[:, None] + dirs[None, :, 2:3] * n[:, None]
    m = obj.material
    expected = phong_highlight(x, n, wo, m["specular"], m["exponent"], POINT, INTENSITY,
                               None if fresnel is None else np.array(fresnel))
    highlights = solution.highlights("floor")
    assert np.allclose(highlights, expected, rtol=1e-5, atol=1e-12)  # float32 directions, not quite unit
    assert expected.max() > 1.0  # a highlight to see
    rest = obj.radiance - highlights
    diffuse = KD / np.pi * point_irradiance(x)
    if fresnel is None:
        ratio = rest.mean(axis=1) / diffuse
        assert np.allclose(np.median(ratio, axis=0), 1, atol=0.02), np.median(ratio, axis=0)


# -- the gather's sample of delta lights at glossy hits ------------------------------------------


def test_the_gather_finds_a_point_light_in_a_glossy_neighbour(tmp_path):
    """A glossy plate (black but for its lobe) sees a point light reflected in a glossy
    wall: only the gather's sample of the light at the wall's hits can find it (no ray
    hits a delta light). Its radiance toward the wall against the path tracer's."""
    scene = scene_from(tmp_path, """
        [materials.plate]
        diffuse = 0.0
        specular = 0.8
        exponent = 8
        [materials.wall]
        diffuse = 0.0
        specular = 0.9
        exponent = 20
        [[objects]]
        name = "plate"
        builtin = "quad"
        material = "plate"
        scale = 0.1
        [[objects]]
        name = "wall"
        builtin = "quad"
        material = "wall"
        scale = 4
        rotate_deg = [0, 0, 90]
        translate = [1, 0, 0]
        [[lights]]
        kind = "point"
        position = [0.2, 1.0, 0.0]
        intensity = 10
    """)
    solution = solve(scene, SolveOptions(quality="draft", photons=100_000, threads=2, max_edge=1.0, grid=48,
                                         gather_samples=4096, extra_gather=0))
    plate = solution.object("plate")
    wo = np.array([-0.7, 0.45, 0.0])  # the wall (at x = 1) in its mirror direction
    wo /= np.linalg.norm(wo)
    t, n = plate.tangents[0].astype(np.float64), plate.normals[0].astype(np.float64)
    idx, weight = grid_lookup_weights(np.array([wo @ t, wo @ np.cross(n, t), wo @ n]), 48)

    def toward_wo(radiance):  # the vertices' mean (a tiny plate) of the grids' value at wo
        return (weight[:, None] * np.asarray(radiance, np.float64)[:, idx]).sum(axis=1).mean(axis=0)

    ours = toward_wo(plate.radiance)
    camera = Camera(eye=tuple(5 * wo), look_at=(0, 0, 0), up=(0, 1, 0), fov_deg=0.2, width=2, height=2)
    with PathTracer(scene, threads=2) as tracer:
        truth = tracer.render(camera, 4096, seed=3).radiance.reshape(-1, 3).mean(axis=0)
    # most of it is the wall's reflection of the light, which only the gather's light sample finds
    assert toward_wo(plate.radiance - solution.highlights("plate")).min() > 0.5 * ours.max() > 0.05, ours
    assert np.allclose(ours, truth, rtol=0.04), (ours, truth)  # 1.7 %: the grid's interpolation and both noises


# -- the path tracer against the closed forms -----------------------------------------------------


def pixel_means(camera, shade, sub=16):
    """(each pixel's mean of ``shade(points (N, 3), views (N, 3))`` over where its rays
    meet the square [-1, 1]^2 of the plane y = 0, the fraction of them that meet it)
    (``sub`` x ``sub`` rays a pixel; those that miss count 0)."""
    right, up, forward = camera.basis
    half_h = np.tan(np.radians(camera.fov_y_deg) / 2)
    half_w = half_h * camera.width / camera.height
    s = (np.arange(sub) + 0.5) / sub
    out = np.zeros((camera.height, camera.width, 3))
    cover = np.zeros((camera.height, camera.width))
    eye = np.asarray(camera.eye, np.float64)
    for py in range(camera.height):
        for px in range(camera.width):
            sx = (2 * (px + s[None, :]) / camera.width - 1) * half_w
            sy = (1 - 2 * (py + s[:, None]) / camera.height) * half_h
            d = (forward + sx[..., None] * right + sy[..., None] * up).reshape(-1, 3)
            t = -eye[1] / d[:, 1]
            x = eye + t[:, None] * d
            on = (t > 0) & (np.abs(x[:, 0]) < 1) & (np.abs(x[:, 2]) < 1)
            value = np.zeros((len(d), 3))
            if on.any():
                value[on] = shade(x[on], -d[on] / np.linalg.norm(d[on], axis=1, keepdims=True))
            out[py, px] = value.mean(axis=0)
            cover[py, px] = on.mean()
    return out, cover


@pytest.mark.parametrize("kind", ["point", "spot", "directional", "glossy point"])
def test_the_path_tracer_against_the_closed_forms(tmp_path, kind):
    """A plane under each light, seen from above: kd / pi times the irradiance (plus the
    lobe for the glossy plane) in every pixel. A delta light's estimate is exact, so the
    only noise is where in the pixel each sample lands (a box filter's)."""
    light = {"point": POINT_LIGHT, "spot": SPOT_LIGHT, "directional": DIRECTIONAL, "glossy point": POINT_LIGHT}[kind]
    extra = "specular = 0.3\n        exponent = 12" if kind == "glossy point" else ""
    scene = plane_scene(tmp_path, light, extra=extra)
    spot = scene.lights[0].spot
    camera = Camera(eye=(0.3, 2.5, 1.2), look_at=(0, 0, 0), up=(0, 1, 0), fov_deg=45, width=24, height=18)

    def shade(x, wo):
        if kind == "directional":
            e = np.broadcast_to(IRRADIANCE * -SUN[1], x.shape)
        else:
            e = point_irradiance(x, spot=spot)
        out = KD / np.pi * e
        if kind == "glossy point":
            out = out + phong_highlight(x, np.tile([0.0, 1, 0], (len(x), 1)), wo[:, None], [0.3] * 3, 12.0,
                                        POINT, INTENSITY)[:, 0]
        return out

    expected, cover = pixel_means(camera, shade)
    with PathTracer(scene, threads=2) as tracer:
        image = tracer.render(camera, 64, seed=5)
    inside = (cover == 1)[..., None]  # the plane's edge pixels: how many samples land on it is noise too
    error = np.abs(image.radiance - expected)
    assert np.all(error <= np.where(inside, 5 * image.standard_error + 2e-3 * expected.max() + 1e-6, np.inf)), error.max()
    assert inside.mean() > 0.4
    assert np.allclose(image.radiance.mean(axis=(0, 1)), expected.mean(axis=(0, 1)), rtol=0.01)
    lit = (expected.max(axis=2) > 1e-3).mean()
    assert expected.max() > 0.05 and lit > (0.1 if kind == "spot" else 0.5)
    if kind == "spot":  # the pool's edge is in the picture, the floor beyond it dark
        assert ((expected.max(axis=2) < 1e-6) & (image.radiance.max(axis=2) == 0)).mean() > 0.2
