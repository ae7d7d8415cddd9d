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
import textwrap

import numpy as np
import pytest

from radiosity.formats.material import Material, Microfacet
from radiosity.scene import microfacet
from radiosity.scene.kinds import oracle
from radiosity.scene.loaders import load_scene
from radiosity.transport.pathtrace import scene_of_solution
from radiosity.transport.solve import SolveOptions, solve

SPHERE = """
    [materials.wall]
    diffuse = 0.5
    emission = 1.0
    [[objects]]
    name = "sphere"
    builtin = "sphere"
    subdivisions = 3
    flip = true
    material = "wall"
"""


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
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(SPHERE))
    scene = load_scene(path)
    objects = tuple(dataclasses.replace(o, material=material) for o in scene.objects)
    return dataclasses.replace(scene, objects=objects)


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
