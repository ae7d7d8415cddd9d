"""Environment light through the solver (photons, density, gather) and the path tracer,
against answers known in closed form:

- an upward quad under a constant environment L and nothing else: irradiance pi L,
  outgoing radiance kd L (photons and the path tracer), and in every direction
  L times the true directional albedo for a glossy quad (the gather's escaping rays);
- a diffuse sphere of albedo rho under constant L: radiance rho L everywhere;
- the photon energy bookkeeping closes with the environment's photons;
- camera rays that miss see the environment;
- a glossy quad under a map with a small bright sun: the path tracer's MIS (the sun
  by light sampling, the lobe by BRDF sampling) against a quadrature of the map.
"""


import numpy as np
from analytic import phong
from scene_files import scene_from

from radiosity.files.camera import Camera
from radiosity.physics.environment import Environment
from radiosity.scene.material_kernels import albedo
from radiosity.transport.pathtrace import PathTracer
from radiosity.transport.solve import SolveOptions, solve

QUAD = """
[materials.grey]
diffuse = [0.5, 0.6, 0.7]
{extra}
[[objects]]
name = "quad"
builtin = "quad"
material = "grey"
[environment]
radiance = [1.0, 2.0, 0.5]
"""
L = np.array([1.0, 2.0, 0.5])
KD = np.array([0.5, 0.6, 0.7])


def energy_closes(stats, rtol=0.01):
    e = {k: np.asarray(v) for k, v in stats["energy"].items() if k != "photon_hits"}
    assert np.allclose(e["emitted"], e["escaped"] + e["absorbed"] + e["backface"] + e["terminated"], rtol=rtol)
    return e


def test_quad_under_a_constant_environment_solver(tmp_path):
    scene = scene_from(tmp_path, QUAD.format(extra=""))
    solution = solve(scene, SolveOptions(quality="draft", photons=300_000, threads=2, max_edge=0.25))
    radiance = solution.objects[0].radiance[:, 0, :]
    assert np.allclose(radiance.mean(axis=0), KD * L, rtol=0.015)
    assert np.abs(radiance / (KD * L) - 1).max() < 0.25
    e = energy_closes(solution.stats)
    assert np.allclose(e["incident"], np.pi * L * 1.0, rtol=0.02)  # irradiance pi L on the unit quad
    assert solution.stats["photons"] == 300_000


def test_glossy_quad_reflects_the_environment_by_its_true_albedo(tmp_path):
    """Radiance L * albedo(wo) in every direction of the grid: the diffuse part from the
    photons, the glossy part from gather rays that leave the scene."""
    extra = "specular = 0.25\nexponent = 40\n"
    scene = scene_from(tmp_path, QUAD.format(extra=extra))
    material = scene.objects[0].material
    solution = solve(scene, SolveOptions(quality="draft", photons=300_000, gather_samples=256, grid=8, threads=2,
                                         max_edge=0.5, extra_gather=0))
    obj = solution.objects[0]
    expected = albedo(material, np.clip(obj.directions[:, 2], 0, 1).astype(np.float64)) * L  # (D, 3)
    mean = obj.radiance.mean(axis=0)  # over the vertices: (D, 3)
    assert np.allclose(mean, expected, rtol=0.04)


def test_sphere_of_albedo_rho_under_constant_light(tmp_path):
    scene = scene_from(tmp_path, """
        [materials.grey]
        diffuse = 0.6
        [[objects]]
        name = "ball"
        builtin = "sphere"
        material = "grey"
        [environment]
        radiance = 2.0
    """)
    solution = solve(scene, SolveOptions(quality="draft", photons=300_000, threads=2))
    radiance = solution.objects[0].radiance[:, 0, :]
    assert np.allclose(radiance.mean(), 1.2, rtol=0.015)
    assert np.abs(radiance / 1.2 - 1).max() < 0.3
    energy_closes(solution.stats)
    camera = Camera(eye=(0, 0, 4), look_at=(0, 0, 0), up=(0, 1, 0), fov_deg=30, width=24, height=24)
    with PathTracer(scene, threads=2) as tracer:
        image = tracer.render(camera, 32, seed=2)
    on_sphere = np.zeros((24, 24), bool)
    on_sphere[8:16, 8:16] = True  # well inside the silhouette (radius about 8.9 pixels)
    z = (image.radiance[on_sphere] - 1.2) / np.maximum(image.standard_error[on_sphere], 1e-12)
    assert np.abs(z).max() < 5 and 0.5 < np.mean(z**2) < 1.6
    assert np.allclose(image.radiance[0, 0], 2.0)  # a corner sees the environment itself


def test_path_tracer_quad_and_background(tmp_path):
    """kd L on the quad, within Monte Carlo error; and the background is the map (an
    asymmetric one: a pixel's mean over its area, from the numpy reference)."""
    scene = scene_from(tmp_path, QUAD.format(extra=""))
    camera = Camera(eye=(0, 3, 0.001), look_at=(0, 0, 0), up=(0, 0, -1), fov_deg=12, width=12, height=12)
    with PathTracer(scene, threads=2) as tracer:
        image = tracer.render(camera, 64, seed=3)
    z = (image.radiance - KD * L) / np.maximum(image.standard_error, 1e-12)
    assert np.abs(z).max() < 5 and 0.5 < np.mean(z**2) < 1.6

    rng = np.random.default_rng(4)
    sky = (0.1 + rng.random((6, 12, 3)) * 3).astype(np.float32)
    env = Environment.from_image(sky, 2.0)
    np.save(tmp_path / "sky.npy", sky)
    scene = scene_from(tmp_path, QUAD.format(extra="").replace('radiance = [1.0, 2.0, 0.5]', 'image = "sky.npy"\nscale = 2'))
    camera = Camera(eye=(0, -2, 0), look_at=(1, -2.5, 0.3), up=(0, 1, 0), fov_deg=90, width=8, height=6)
    with PathTracer(scene, threads=2) as tracer:
        image = tracer.render(camera, 64, seed=5)
    # the numpy reference: each pixel's mean of the map over its area (a fine grid of points)
    right, up, forward = camera.basis
    half_h = np.tan(np.radians(camera.fov_y_deg) / 2)
    half_w = half_h * camera.width / camera.height
    s = (np.arange(32) + 0.5) / 32
    expected = np.empty((6, 8, 3))
    for py in range(6):
        for px in range(8):
            sx = 2 * (px + s[None, :]) / 8 - 1
            sy = 1 - 2 * (py + s[:, None]) / 6
            d = forward + (sx * half_w)[..., None] * right + (sy * half_h)[..., None] * up
            d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).reshape(-1, 3)
            expected[py, px] = env.radiance(d).mean(axis=0)
    z = (image.radiance - expected) / np.maximum(image.standard_error, 1e-12)
    assert np.abs(z).max() < 5, np.abs(z).max()


def sun_sky(h=64, w=128):
    """A smooth sky with a sun about 3 degrees wide, 20000 times brighter."""
    v = (np.arange(h) / (h - 1))[:, None]
    u = ((np.arange(w) + 0.5) / w)[None, :]
    sky = np.stack([0.3 + 0.2 * u + 0 * v, 0.4 + 0.3 * v + 0 * u, 0.8 - 0.3 * v + 0 * u], axis=-1)
    sky[20:22, 50:52] = 2e4
    return sky.astype(np.float32)


def reflected(env, kd, ks, n, normal, wo, points=1 << 21, seed=0):
    """int f(wi, wo) cos L(wi) dwi over the upper hemisphere, by stratified quadrature
    in (phi, cos theta) fine enough for the sun and the lobe."""
    side = int(np.sqrt(points))
    g = (np.arange(side) + 0.5) / side
    cz, ph = np.meshgrid(g, 2 * np.pi * g)
    r = np.sqrt(1 - cz**2)
    t = np.array([1.0, 0, 0])
    b = np.cross(normal, t)
    wi = (r * np.cos(ph))[..., None] * t + (r * np.sin(ph))[..., None] * b + cz[..., None] * normal
    wi = wi.reshape(-1, 3)
    f = kd / np.pi + phong(ks, n, normal, wi, np.broadcast_to(wo, wi.shape))[:, None]
    return (f * env.radiance(wi) * cz.reshape(-1, 1)).sum(axis=0) * 2 * np.pi / len(wi)


def test_path_tracer_mis_glossy_quad_under_a_sun(tmp_path):
    """The sun in the diffuse part (light sampling finds it) and the map in a glossy
    lobe (BRDF sampling does): both must be right and neither noisy."""
    sky = sun_sky()
    np.save(tmp_path / "sky.npy", sky)
    scene = scene_from(tmp_path, """
        [materials.glossy]
        diffuse = 0.3
        specular = 0.6
        exponent = 300
        [[objects]]
        name = "quad"
        builtin = "quad"
        material = "glossy"
        scale = 100
        [environment]
        image = "sky.npy"
    """)
    env = scene.environment
    eye = np.array([0.0, 40.0, 60.0])
    camera = Camera(eye=tuple(eye), look_at=(0, 0, 0), up=(0, 1, 0), fov_deg=0.5, width=4, height=4)
    wo = eye / np.linalg.norm(eye)
    expected = reflected(env, 0.3, 0.6, 300.0, np.array([0.0, 1.0, 0.0]), wo)
    with PathTracer(scene, threads=2) as tracer:
        image = tracer.render(camera, 256, seed=7)
    mean = image.radiance.reshape(-1, 3).mean(axis=0)
    error = np.sqrt((image.standard_error.reshape(-1, 3) ** 2).sum(axis=0)) / 16
    assert np.all(np.abs(mean - expected) < 4 * error + 0.01 * expected), (mean, expected, error)
    assert np.all(error / expected < 0.02), error / expected  # 4096 paths: low noise despite the sun


def test_the_solution_file_keeps_the_environment(tmp_path):
    """Solution version 3 carries the environment (its image, scale, rotation), so
    that `vlights truth` on a solution path-traces the same sky and a display draws it."""
    from scipy.spatial.transform import Rotation

    from radiosity.files.solution import Solution
    from radiosity.scene.model import Scene
    from radiosity.transport.pathtrace import scene_of_solution

    sky = np.random.default_rng(5).random((6, 10, 3)).astype(np.float32)
    rotation = Rotation.from_euler("xyz", [10, 40, -5], degrees=True).as_matrix()
    base = scene_from(tmp_path, QUAD.format(extra=""))
    scene = Scene(name="sky", objects=base.objects, environment=Environment.from_image(sky, 2.5, rotation))
    sol = solve(scene, SolveOptions(photons=2_000, max_edge=10.0, seed=1))
    assert sol.version == 3
    sol.save(tmp_path / "s.npz")
    back = Solution.load(tmp_path / "s.npz")
    env = back.environment
    assert np.array_equal(env.image, sky) and env.scale == 2.5 and np.allclose(env.rotation, rotation, atol=0)
    again = scene_of_solution(back).environment
    assert isinstance(again, Environment)
    directions = np.random.default_rng(1).normal(size=(50, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    assert np.array_equal(again.radiance(directions), scene.environment.radiance(directions))
