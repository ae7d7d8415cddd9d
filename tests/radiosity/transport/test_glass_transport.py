"""Glass through the transport, against answers known in closed form.

- A furnace: under uniform radiance 1, clear smooth glass (a solid sphere and a thin pane)
  shows exactly 1 everywhere: a wrong Fresnel choice, a lost or doubled 1 / eta^2, a wrong
  side for the new ray (light trapped inside or leaking) all show. A clear rough ball shows
  at most 1, its single-scattering loss.
- A thin pane between a small lamp and a diffuse floor lets through 1 - R of the light
  at the lamp's incidence, R = 2F / (1 + F): the path tracer (light only through BSDF
  samples: shadow rays stop at glass) and the solver's photons (straight through) alike.
- The photons' energy closes with glass: emitted = escaped + absorbed + backface +
  terminated, absorbing glass adding to the absorbed power what its transmittance keeps.
"""

import numpy as np
import pytest

from radiosity.files.camera import Camera
from radiosity.scene.loaders import load_scene
from radiosity.scene.microfacet import fresnel_dielectric
from radiosity.transport.pathtrace import PathTracer, camera_rays, scene_of_solution
from radiosity.transport.solve import SolveOptions, solve

FURNACE = """<?xml version="1.0"?>
<scene version="3.0.0">
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere" id="ball"><float name="radius" value="0.5"/>
        <bsdf type="dielectric"><float name="int_ior" value="{eta}"/><float name="ext_ior" value="1"/></bsdf></shape>
    <shape type="rectangle" id="pane">
        <transform name="to_world"><scale value="0.4"/><rotate y="1" angle="35"/><translate x="1.1"/></transform>
        <bsdf type="thindielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
    </shape>
    <shape type="sphere" id="rough"><point name="center" x="-1.1" y="0" z="0"/><float name="radius" value="0.4"/>
        <bsdf type="roughdielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/>
        <string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf></shape>
</scene>
"""


def _scene(tmp_path, text, name="scene.xml"):
    path = tmp_path / name
    path.write_text(text)
    return load_scene(path)


@pytest.mark.parametrize("eta", [1.5, 2.4])
def test_clear_glass_in_a_furnace_shows_the_furnace(tmp_path, eta):
    scene = _scene(tmp_path, FURNACE.format(eta=eta))
    camera = Camera((0.0, 0.3, 3.0), (0.0, 0.0, 0.0), fov_deg=60, width=40, height=24)
    with PathTracer(scene) as tracer:
        image = tracer.render(camera, 64, seed=3)
    rays = camera_rays(camera)  # pixels whose corners' rays meet the rough ball (a margin for the box filter)
    sx, sy = np.meshgrid(np.linspace(-1, 1, 41), np.linspace(1, -1, 25))
    d = rays.forward + sx[..., None] * rays.right + sy[..., None] * rays.up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    to_centre = np.array([-1.1, 0.0, 0.0]) - rays.eye
    along = d @ to_centre
    corner = along**2 - (to_centre @ to_centre - 0.45**2) > 0.0
    rough = corner[:-1, :-1] | corner[1:, :-1] | corner[:-1, 1:] | corner[1:, 1:]
    clear = ~rough
    radiance = image.radiance[..., 0]
    # clear glass: 1, within the Monte Carlo error of Russian roulette and the lost deep paths
    z = (radiance[clear] - 1.0) / np.maximum(image.standard_error[..., 0][clear], 1e-3)
    assert np.abs(z).max() < 5.0 and abs(radiance[clear].mean() - 1.0) < 0.01, (np.abs(z).max(), radiance[clear].mean())
    assert radiance[rough].max() < 1.0 + 5 * image.standard_error[..., 0][rough].max()
    assert radiance[rough].min() < 0.97  # the rough ball's loss is seen (the test tells it apart)


PANE = """<?xml version="1.0"?>
<scene version="3.0.0">
    <shape type="rectangle" id="floor"><transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
    {pane}
    <shape type="rectangle" id="lamp">
        <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="2"/></transform>
        <emitter type="area"><rgb name="radiance" value="20"/></emitter>
    </shape>
</scene>
"""
PANE_SHAPE = """<shape type="rectangle" id="pane">
        <transform name="to_world"><scale value="1.5"/><rotate x="1" angle="-90"/><translate y="1"/></transform>
        <bsdf type="thindielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>"""


def _pane_transmits():
    """The irradiance at the floor's centre through the thin pane over that without it: 1 -
    R(theta), R = 2F / (1 + F), weighted over the 0.6 x 0.6 lamp 2 above (midpoint rule)."""
    x, z = np.meshgrid(*(2 * [np.linspace(-0.3, 0.3, 201)[:-1] + 0.0015]))
    r2 = x**2 + z**2 + 4.0
    cos = 2.0 / np.sqrt(r2)
    weight = cos * cos / r2
    f = fresnel_dielectric(cos, 1.5)
    return float(np.sum(weight * (1.0 - 2.0 * f / (1.0 + f))) / np.sum(weight))


PANE_TRANSMITS = _pane_transmits()
# the floor's light the pane sends back down adds about R x (the floor's albedo 0.5) x the
# share of the floor's light that reaches the pane: the expected ratio lies in
# [PANE_TRANSMITS, PANE_TRANSMITS * (1 + R / 2)], R about 0.08


def _floor_centre(image):
    """The mean radiance of the image's central 16 x 16 pixels and its standard error."""
    middle = (slice(8, 24), slice(8, 24))
    return image.radiance[middle].mean(), np.sqrt(np.sum(image.standard_error[middle] ** 2)) / image.radiance[middle].size


def test_a_thin_pane_passes_one_minus_its_reflectance_in_the_path_tracer(tmp_path):
    camera = Camera((0.0, 0.5, 0.001), (0.0, 0.0, 0.0), fov_deg=30, width=32, height=32)
    images = []
    for name, pane in (("open.xml", ""), ("pane.xml", PANE_SHAPE)):
        with PathTracer(_scene(tmp_path, PANE.format(pane=pane), name)) as tracer:
            images.append(tracer.render(camera, 1024 if pane else 64, seed=5))
    (through, error), (open_, _) = _floor_centre(images[1]), _floor_centre(images[0])
    ratio, margin = through / open_, 4.0 * error / open_
    assert error / through < 0.01  # the test can tell
    assert PANE_TRANSMITS - margin < ratio < PANE_TRANSMITS * 1.04 + margin, (ratio, margin, PANE_TRANSMITS)


def test_a_thin_pane_passes_one_minus_its_reflectance_in_the_photons(tmp_path):
    options = SolveOptions(quality="draft", photons=400_000, threads=2, max_edge=0.2, seed=2)
    centre = []
    for name, pane in (("open.xml", ""), ("pane.xml", PANE_SHAPE)):
        solution = solve(_scene(tmp_path, PANE.format(pane=pane), name), options)
        floor = solution.object("floor")
        near = np.hypot(floor.positions[:, 0], floor.positions[:, 2]) < 0.4
        centre.append(floor.radiance[near, 0, 0].mean())
        if pane:
            e = {k: np.asarray(v) for k, v in solution.stats["energy"].items() if k != "photon_hits"}
            closes = e["escaped"] + e["absorbed"] + e["backface"] + e["terminated"]
            np.testing.assert_allclose(closes, e["emitted"], rtol=0.01)
            glass = solution.object("pane")
            assert np.all(glass.radiance == 0.0) and glass.material["glass"]["kind"] == "thindielectric"
            # the truth of a solution (vlights truth, compare) traces the same glass
            assert scene_of_solution(solution).object("pane").material.glass.kind == "thindielectric"
    assert PANE_TRANSMITS * 0.98 < centre[1] / centre[0] < PANE_TRANSMITS * 1.04 * 1.02, (centre, PANE_TRANSMITS)


def test_absorbing_glass_adds_what_it_keeps_to_the_absorbed_power(tmp_path):
    text = PANE.format(pane=PANE_SHAPE.replace(
        '<float name="ext_ior" value="1"/>', '<float name="ext_ior" value="1"/>'
        '<rgb name="specular_transmittance" value="0.5, 0.25, 0.0"/>'))
    solution = solve(_scene(tmp_path, text), SolveOptions(quality="draft", photons=200_000, threads=2, max_edge=0.4))
    e = {k: np.asarray(v) for k, v in solution.stats["energy"].items() if k != "photon_hits"}
    np.testing.assert_allclose(e["escaped"] + e["absorbed"] + e["backface"] + e["terminated"], e["emitted"], rtol=0.01)
    # the lamp's light meets the pane first: what it does not reflect it absorbs in blue, half in red
    assert e["absorbed"][2] > 0.6 * e["emitted"][2]
    assert e["absorbed"][0] < e["absorbed"][1] < e["absorbed"][2]


MIRROR_ROOM = """<?xml version="1.0"?>
<scene version="3.0.0">
    <shape type="rectangle" id="floor"><transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
    <shape type="rectangle" id="mirror"><transform name="to_world"><scale value="0.5"/><translate y="0.5" z="-1"/></transform>
        <bsdf type="conductor"><string name="material" value="Ag"/></bsdf></shape>
    <shape type="rectangle" id="lamp">
        <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="2"/></transform>
        <emitter type="area"><rgb name="radiance" value="20"/></emitter>
    </shape>
</scene>
"""


def test_a_perfect_mirror_is_stored_without_a_grid_and_still_reflects_light(tmp_path):
    """The solver gathers no grid for a perfect mirror (the displays draw what it reflects):
    its object holds D = 1 and radiance 0 (solution version 7); its photons still reflect, so
    the floor under the lamp is brighter with the mirror than without it."""
    options = SolveOptions(quality="draft", photons=200_000, threads=2, max_edge=0.3, seed=2)
    with_mirror = solve(_scene(tmp_path, MIRROR_ROOM, "mirror.xml"), options)
    mirror = with_mirror.object("mirror")
    assert mirror.radiance.shape[1] == 1 and not mirror.radiance.any()
    assert mirror.visibility is None and mirror.emitter_parts is None
    path = tmp_path / "s.npz"
    with_mirror.save(path)
    from radiosity.files.solution import load_solution

    assert load_solution(path).version == 7
    scene = _scene(tmp_path, MIRROR_ROOM.replace('<bsdf type="conductor"><string name="material" value="Ag"/></bsdf>',
                                                 '<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>'),
                   "black.xml")
    without = solve(scene, options)
    floor = with_mirror.object("floor")
    near = floor.positions[:, 2] < -0.5  # the floor in front of the mirror
    assert floor.radiance[near, 0, 0].mean() > 1.01 * without.object("floor").radiance[near, 0, 0].mean()
