"""The solver with microfacet materials, against the integral equation.

The inside of an emitting sphere made of a rough plastic or a rough conductor: light
arriving at angle theta left its source at the same angle (the sphere's chords), so the
radiance obeys L(mu_o) = Le + int f(wi, wo) L(mu_i) mu_i dwi, solved here by Nystrom on
the oracle's BRDF (``radiosity.scene.kinds``); albedos kept about 0.5 or less, so that
what the gather's bounded depth leaves out stays far below the tolerance. The photons' deposits (a plastic's
substrate reached through the interface's transmittance), their scattering (visible
normals), the gather's glossy hits and its grid (the microfacet lobe at every direction)
must all be right for the solver's grid to match it; the Phong stand-in does not (checked).
"""

import dataclasses

import numpy as np
import pytest
from test_fresnel_transport import EMITTING_SPHERE, scene_from, with_material

from radiosity.physics.emitters import emitter_grid
from radiosity.physics.materials import Material, Microfacet
from radiosity.scene import microfacet
from radiosity.scene.kinds import oracle
from radiosity.scene.loaders import load_scene
from radiosity.transport.pathtrace import scene_of_solution
from radiosity.transport.solve import SolveOptions, solve


def furnace_reference(material, nodes=96, phi_points=256):
    """(mu, L(mu)) inside an emitting sphere of ``material`` (emission 1), by Nystrom."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, weight = 0.5 * (x + 1), 0.5 * w
    phi = (np.arange(phi_points) + 0.5) * 2 * np.pi / phi_points
    sin = np.sqrt(1 - mu**2)
    wo = np.stack([sin, np.zeros(nodes), mu], axis=-1)  # (O, 3)
    wi = np.stack([sin[:, None] * np.cos(phi), sin[:, None] * np.sin(phi), np.repeat(mu[:, None], phi_points, 1)],
                  axis=-1).reshape(-1, 3)  # (I * P, 3)
    reference = oracle(material)
    kernel = np.empty((nodes, nodes, 3))
    for o in range(nodes):
        f = reference.eval(wi, np.broadcast_to(wo[o], wi.shape)).reshape(nodes, phi_points, 3)
        kernel[o] = f.sum(axis=1) * (2 * np.pi / phi_points) * mu[:, None]
    radiance = np.stack([np.linalg.solve(np.eye(nodes) - kernel[:, :, c] * weight[None, :], np.ones(nodes))
                         for c in range(3)], axis=-1)
    return mu, radiance


def sphere_of(tmp_path, material):
    """The Fresnel tests' emitting sphere (seen from inside) made of ``material``."""
    return with_material(scene_from(tmp_path, EMITTING_SPHERE), "wall", dataclasses.replace(material, name="wall"))


AU = microfacet.METALS["Au"]
MATERIALS = {
    "plastic ggx": Material("wall", (0.3, 0.3, 0.3), (1.0, 1.0, 1.0), 30.0, emission=(1.0,) * 3,
                            fresnel=(0.04,) * 3,
                            microfacet=Microfacet("roughplastic", "ggx", 0.3, (1.49,) * 3,
                                                  diffuse_reflectance=(0.7, 0.5, 0.3))),
    "conductor beckmann": Material("wall", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 10.0, emission=(1.0,) * 3,
                                   fresnel=(0.9, 0.7, 0.3),
                                   microfacet=Microfacet("roughconductor", "beckmann", 0.4, AU[0], AU[1],
                                                         (0.5, 0.5, 0.5))),
}


@pytest.mark.parametrize("name", list(MATERIALS))
def test_a_microfacet_furnace_matches_the_integral_equation(tmp_path, name):
    material = MATERIALS[name]
    scene = sphere_of(tmp_path, material)
    opts = SolveOptions(photons=200_000, gather_samples=64, light_samples=8, grid=8, max_edge=10.0, seed=2,
                        emitter_highlights=False)
    solution = solve(scene, opts)
    obj = solution.object("sphere")
    # what ``vlights truth`` of the solution path-traces: the model itself
    assert scene_of_solution(solution).object("sphere").material.microfacet == material.microfacet
    mu, reference = furnace_reference(material)
    expected = np.stack([np.interp(obj.directions[:, 2], mu, reference[:, c]) for c in range(3)], axis=-1)
    measured = obj.radiance.mean(axis=0)
    assert np.ptp(expected) > 0.02 * expected.mean()  # the answer varies with the direction
    assert np.abs(measured / expected - 1).max() < 0.03, (measured / expected)
    # the stand-in's answer is another one: the test tells them apart
    stand_in = dataclasses.replace(material, microfacet=None)
    mu, phong = furnace_reference(stand_in)
    other = np.stack([np.interp(obj.directions[:, 2], mu, phong[:, c]) for c in range(3)], axis=-1)
    assert np.abs(other / expected - 1).max() > 0.06


LIT_PLATE = """<?xml version="1.0"?>
<scene version="3.0.0">
    <shape type="rectangle" id="plate">
        <transform name="to_world"><rotate x="1" angle="-90"/></transform>
        <bsdf type="roughconductor"><float name="alpha" value="0.2"/><string name="material" value="Cu"/></bsdf>
    </shape>
    <shape type="rectangle" id="glossy">
        <transform name="to_world"><rotate x="1" angle="-90"/><translate x="3"/></transform>
        <bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf>
    </shape>
    <shape type="rectangle" id="lamp">
        <transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate x="1.5" y="2"/></transform>
        <emitter type="area"><rgb name="radiance" value="10"/></emitter>
    </shape>
    {POINT_LIGHT}
</scene>
"""
POINT_LIGHT = '<emitter type="point"><point name="position" x="1.5" y="1" z="0.5"/><rgb name="intensity" value="3"/></emitter>'
LIT_PLATE = LIT_PLATE.replace("{POINT_LIGHT}", POINT_LIGHT)


def test_a_microfacet_object_draws_every_emitter_in_closed_form_with_its_own_lobe(tmp_path):
    """The lamp's and the point light's highlights on a microfacet object are in closed form
    with its own lobe (radiosity.physics.ltc), as a Phong object's are with its: both parts
    named, their visibility kept, the grid holding them so (the gather leaves them out); what
    the lamp adds to the plate's grid is that closed form, and it is the oracle's BRDF
    integrated over the lamp to the closed form's accuracy (the plate: Beckmann copper)."""
    path = tmp_path / "plate.xml"
    path.write_text(LIT_PLATE)
    scene = load_scene(path)
    options = SolveOptions(photons=20_000, gather_samples=64, light_samples=16, grid=8, max_edge=10.0)
    solution = solve(scene, options)
    assert solution.microfacet_highlights and solution.version == 8
    for name in ("plate", "glossy"):
        assert sorted(p.kind for p in solution.parts_of(name)) == ["point", "polygon"]
        assert solution.object(name).visibility.shape == (len(solution.object(name).positions), 2)
        assert solution.lobe_of(name) == scene.object(name).material.microfacet.to_dict()
    # the lamp alone (the point light under it lights its back, which lights the plate)
    path.write_text(LIT_PLATE.replace(POINT_LIGHT, ""))
    scene = load_scene(path)
    solution = solve(scene, options)
    dark = dataclasses.replace(scene, objects=tuple(o for o in scene.objects if o.name != "lamp"))
    unlit = solve(dark, options)
    plate = solution.object("plate")
    added = plate.radiance.astype(np.float64) - unlit.object("plate").radiance
    closed = emitter_grid(solution.parts_of("plate"), plate.positions, plate.normals, plate.tangents,
                          plate.directions, (1, 1, 1), 1.0, visibility=plate.visibility,
                          microfacet=solution.lobe_of("plate"))
    assert closed.max() > 0.5  # the highlight is there to be found
    np.testing.assert_allclose(added, closed, atol=2e-3 * closed.max())
    expected = lamp_reflection(oracle(scene.object("plate").material), plate)
    assert abs(closed.mean() / expected.mean() - 1) < 0.1, (closed.mean(), expected.mean())
    assert np.abs(closed - expected).max() < 0.25 * expected.max()


def lamp_reflection(reference, obj, points=48):
    """The lamp's light reflected at each vertex of ``obj`` into each grid direction,
    (V, D, 3): the BRDF times Le cos_i cos_l / r^2 integrated over LIT_PLATE's lamp
    (0.6 x 0.6 at height 2 over x = 1.5, facing down; Le 10) by the midpoint rule."""
    u = (np.arange(points) + 0.5) / points * 0.6 - 0.3
    lamp = np.stack(np.meshgrid(1.5 + u, [2.0], u, indexing="ij"), axis=-1).reshape(-1, 3)
    area = (0.6 / points) ** 2
    out = np.zeros((len(obj.positions), len(obj.directions), 3))
    for v, (x, n, t) in enumerate(zip(obj.positions, obj.normals, obj.tangents)):
        b = np.cross(n, t)
        frame = np.stack([t, b, n])  # rows: world to local
        to = lamp - x
        r2 = np.sum(to * to, axis=1)
        wi_world = to / np.sqrt(r2)[:, None]
        weight = 10.0 * np.maximum(wi_world @ n, 0.0) * np.maximum(wi_world[:, 1], 0.0) / r2 * area
        wi = wi_world @ frame.T
        for d, wo in enumerate(obj.directions.astype(np.float64)):
            out[v, d] = weight @ reference.eval(wi, np.broadcast_to(wo, wi.shape))
    return out


def test_without_closed_forms_a_microfacet_object_keeps_the_delta_lights_in_its_grid(tmp_path):
    path = tmp_path / "plate.xml"
    path.write_text(LIT_PLATE)
    solution = solve(load_scene(path), SolveOptions(photons=20_000, gather_samples=16, light_samples=4, grid=8,
                                                    max_edge=10.0, emitter_highlights=False))
    plate = solution.object("plate")
    assert solution.emitters == () and plate.emitter_parts is None and plate.visibility is None
    assert plate.radiance.max() > 0.1


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
@pytest.mark.parametrize("alpha", [0.005, 0.05, 0.3])
def test_the_grid_s_lobe_cone_leaves_out_at_most_the_cutoff_of_the_lobe(distribution, alpha):
    """What lies beyond half the cone, in the projected distribution of normals D cos
    (the share of reflected light a direction that far from the mirror could get), is the
    gather's LOBE_CUTOFF, to 1 %."""
    from radiosity.scene.material_kernels import pack_materials
    from radiosity.transport.gather import LOBE_CUTOFF, microfacet_cone

    material = Material("m", (0.0,) * 3, (1.0,) * 3, 10.0, fresnel=(0.9,) * 3,
                        microfacet=Microfacet("roughconductor", distribution, alpha, AU[0], AU[1]))
    half = 0.5 * microfacet_cone(pack_materials([material])[0])
    theta = np.linspace(half, 0.5 * np.pi, 200_001)
    density = microfacet.ndf(distribution, alpha, np.cos(theta)) * np.cos(theta) * np.sin(theta) * 2 * np.pi
    beyond = np.trapezoid(density, theta)
    assert beyond == pytest.approx(LOBE_CUTOFF, rel=0.01)
