"""The solver and the path tracer with Fresnel materials, against known answers.

Each test fails on a wrong Fresnel path in the transport: a photon deposit not weighted
by what the diffuse part lets in, a gather that forgets F or b(cos_o) (the glossy
furnace, whose answer comes from the integral equation), a path tracer whose sampling
or pdf does not follow the wo-dependent lobe choice (the enclosure shows the true
albedo at every angle), or a solver and a path tracer that disagree on a glossy floor
lit and seen at grazing angles.
"""

import dataclasses

import numpy as np
import pytest
from scene_files import scene_from
from test_pathtrace import ENCLOSED_QUAD

from radiosity.files.camera import Camera
from radiosity.physics.materials import FRESNEL_NORMALISATION, fresnel_kd_limit
from radiosity.scene.material_kernels import Material, albedo
from radiosity.transport.pathtrace import PathTracer
from radiosity.transport.solve import SolveOptions, solve

F0 = 0.04



EMITTING_SPHERE = """
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


def with_material(scene, name, material):
    """The scene with material ``name`` replaced (TOML scenes have no Fresnel key)."""
    objects = tuple(
        dataclasses.replace(o, material=material) if o.material.name == name else o for o in scene.objects
    )
    return dataclasses.replace(scene, objects=objects)


def fresnel_furnace_reference(kd, ks, n, f0, le, nodes=160, phi_points=2048):
    """Radiance L(cos theta) leaving the inside of an emitting sphere of a Fresnel material,
    by Nystrom on the integral equation (as ``analytic.glossy_furnace_reference``): light
    arriving at angle theta left its source at the same angle, so L(mu_o) = Le + int K
    L(mu_i) dmu_i with K = int_0^2pi f(wi, wo) mu_i dphi, f the Fresnel BRDF written
    out here (Schlick at the half vector, (21/20) b b for the diffuse part)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, weight = 0.5 * (x + 1), 0.5 * w
    phi = (np.arange(phi_points) + 0.5) * 2 * np.pi / phi_points
    sin = np.sqrt(1 - mu**2)
    cross = sin[:, None, None] * sin[None, :, None] * np.cos(phi)
    cos_alpha = mu[:, None, None] * mu[None, :, None] - cross  # wi . reflect(wo)
    dot = mu[:, None, None] * mu[None, :, None] + cross  # wi . wo
    cos_h = np.sqrt(np.clip(0.5 * (1 + dot), 0, 1))
    fresnel = f0 + (1 - f0) * (1 - cos_h) ** 5
    lobe = np.maximum(cos_alpha, 0.0) ** n * fresnel
    b = 1 - (1 - mu) ** 5
    diffuse = kd / np.pi * FRESNEL_NORMALISATION * b[:, None] * b[None, :] * 2 * np.pi
    kernel = diffuse + ks * (n + 2) / (2 * np.pi) * lobe.sum(axis=2) * (2 * np.pi / phi_points)
    kernel = kernel * mu[None, :]
    radiance = np.linalg.solve(np.eye(nodes) - kernel * weight[None, :], np.full(nodes, le))
    return mu, radiance


def test_fresnel_glossy_furnace_matches_the_integral_equation(tmp_path):
    ks, n = 1.0, 10.0
    kd = min(0.6, float(fresnel_kd_limit([ks] * 3, [F0] * 3, n)[0]))
    scene = scene_from(tmp_path, EMITTING_SPHERE)
    wall = Material("wall", diffuse=(kd,) * 3, specular=(ks,) * 3, exponent=n, emission=(1.0,) * 3, fresnel=(F0,) * 3)
    scene = with_material(scene, "wall", wall)
    opts = SolveOptions(photons=200_000, gather_samples=64, light_samples=8, grid=8, max_edge=10.0, seed=2)
    obj = solve(scene, opts).object("sphere")
    mu, reference = fresnel_furnace_reference(kd, ks, n, F0, 1.0)
    expected = np.interp(obj.directions[:, 2], mu, reference)
    measured = obj.radiance[:, :, 0].mean(axis=0)
    # the answer varies with direction: b(cos_o) dims the diffuse part towards grazing
    assert np.ptp(expected) > 0.05 * expected.mean()
    assert np.abs(measured / expected - 1).max() < 0.03, (measured, expected)




@pytest.mark.parametrize("exponent", [3.0, 300.0])
def test_fresnel_quad_in_an_emitting_enclosure_shows_its_true_albedo(tmp_path, exponent):
    """Uniform radiance 1 from every direction: the path traced quad shows its albedo
    kd b(theta) + ks (F0 S + (1 - F0) Q), which rises or falls with the view's angle."""
    scene = scene_from(tmp_path, ENCLOSED_QUAD.format(exponent=exponent))
    kd = float(fresnel_kd_limit([1.0] * 3, [F0] * 3, exponent)[0]) * 0.9
    glossy = Material("glossy", diffuse=(kd, 0.5 * kd, 0.2), specular=(1.0,) * 3, exponent=exponent,
                      fresnel=(F0, F0, 0.5))
    scene = with_material(scene, "glossy", glossy)
    camera = Camera((0, 0.6, -1.0), (0, 0, 0.6), fov_deg=80, width=16, height=16)
    with PathTracer(scene) as tracer:
        image = tracer.render(camera, 256, seed=3)
    right, up, forward = camera.basis
    t = np.tan(np.radians(camera.fov_y_deg) / 2)
    offsets = (np.arange(8) + 0.5) / 8
    x = (2 * (np.arange(16)[:, None] + offsets[None, :]) / 16 - 1) * t
    y = (1 - 2 * (np.arange(16)[:, None] + offsets[None, :]) / 16) * t
    d = forward + x[None, :, None, :, None] * right + y[:, None, :, None, None] * up
    d = d.reshape(16, 16, 64, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    s = -camera.eye[1] / d[..., 1]
    points = np.asarray(camera.eye) + s[..., None] * d
    inside = ((np.abs(points[..., 0]) < 2) & (np.abs(points[..., 2]) < 2) & (s > 0)).all(axis=2)
    cos_out = np.clip(-d[..., 1], 0, 1)
    expected = albedo(glossy, cos_out[inside].ravel()).reshape(-1, 64, 3).mean(axis=1)
    assert inside.sum() > 100 and cos_out[inside].min() < 0.3
    z = (image.radiance[inside] - expected) / np.maximum(image.standard_error[inside], 1e-12)
    assert np.abs(z).max() < 5.0, np.abs(z).max()
    assert 0.5 < np.mean(z**2) < 1.6, np.mean(z**2)


GRAZING_FLOOR = """
    [materials.floor]
    diffuse = 0.3
    [materials.lamp]
    emission = 30.0
    [[objects]]
    name = "floor"
    builtin = "quad"
    scale = 2.0
    material = "floor"
    [[objects]]
    name = "lamp"
    builtin = "quad"
    material = "lamp"
    scale = 0.25
    rotate_deg = [-80, 0, 0]
    translate = [0.0, 0.18, 1.2]
"""


def test_solver_and_path_tracer_agree_on_a_grazing_glossy_floor(tmp_path):
    """A Fresnel plastic floor lit by a lamp low over its far end: the solver's radiance
    at the brightest grazing directions of its grid (70 to 85 degrees from the normal,
    where the lobe's Fresnel weight is 4 to 12 times its normal value) against the path
    tracer's, a one-pixel camera of a tiny field of view looking back along each of
    those directions at its vertex."""
    n = 30.0
    kd = min(0.3, float(fresnel_kd_limit([1.0] * 3, [F0] * 3, n)[0]))
    floor = Material("floor", diffuse=(kd,) * 3, specular=(1.0,) * 3, exponent=n, fresnel=(F0,) * 3)
    scene = with_material(scene_from(tmp_path, GRAZING_FLOOR), "floor", floor)
    sol = solve(scene, SolveOptions(photons=400_000, gather_samples=256, light_samples=64, grid=24, max_edge=0.1,
                                    seed=4))
    obj = sol.object("floor")
    grazing = (obj.directions[:, 2] > 0.09) & (obj.directions[:, 2] < 0.35)
    central = np.linalg.norm(obj.positions[:, [0, 2]], axis=1) < 0.5
    value = np.where(central[:, None] & grazing[None, :], obj.radiance[:, :, 1], 0.0)
    picks = np.argsort(value, axis=None)[::-1][:: 7][:10]  # bright pairs, spread out
    solver, traced, error = [], [], []
    with PathTracer(scene) as tracer:
        for k, flat in enumerate(picks):
            vert, d = np.unravel_index(flat, value.shape)
            frame = np.stack([obj.tangents[vert], obj.bitangents[vert], obj.normals[vert]]).astype(float)
            w = obj.directions[d].astype(float) @ frame  # world direction towards the viewer
            p = obj.positions[vert].astype(float)
            camera = Camera(tuple(p + 0.3 * w), tuple(p), fov_deg=0.05, width=1, height=1)
            image = tracer.render(camera, 4096, seed=10 + k)
            solver.append(obj.radiance[vert, d])
            traced.append(image.radiance[0, 0])
            error.append(image.standard_error[0, 0])
    solver, traced, error = np.array(solver), np.array(traced), np.array(error)
    assert np.all(obj.directions[[np.unravel_index(f, value.shape)[1] for f in picks], 2] < 0.35)
    # the two estimators of the same radiance agree, in sum and pair by pair
    assert abs(solver[:, 1].sum() / traced[:, 1].sum() - 1) < 0.05, (solver[:, 1], traced[:, 1])
    assert np.all(np.abs(solver[:, 1] / traced[:, 1] - 1) < 0.15 + 4 * error[:, 1] / traced[:, 1])
