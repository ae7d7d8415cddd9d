"""The path tracer against answers known in closed form.

Each test fails on a wrong path tracer: a wrong throughput or roulette weight (the
Lambert furnace), a wrong BRDF sample, pdf or MIS weight (the albedo of a glossy quad
inside an emitting enclosure: both techniques see the same light, and only their
correct combination gives the true directional albedo at every angle), a wrong light
sample or pixel filter (the emitting square over a plane), non-determinism, or a
convergence slower than Monte Carlo's.
"""


import numpy as np
import pytest
from analytic import SQUARE_LIGHT, polygon_irradiance
from scene_files import scene_from
from scipy.ndimage import binary_dilation

from radiosity.files.camera import Camera
from radiosity.files.errors import InputError
from radiosity.scene.loaders import load_scene
from radiosity.scene.material_kernels import albedo
from radiosity.transport import pathtrace
from radiosity.transport.pathtrace import PathTracer


def render(scene, camera, spp, seed=1, threads=None):
    with PathTracer(scene, threads=threads) as tracer:
        return tracer.render(camera, spp, seed=seed)


def assert_within_monte_carlo_error(image, expected, where, bound=5.0):
    """Every pixel of ``where`` within ``bound`` standard errors of ``expected``, and the
    squared z-scores averaging about 1 (the error estimate is honest, not inflated)."""
    z = (image.radiance[where] - expected[where]) / np.maximum(image.standard_error[where], 1e-12)
    assert np.abs(z).max() < bound, np.abs(z).max()
    assert 0.6 < np.mean(z**2) < 1.5, np.mean(z**2)


# -- furnaces ------------------------------------------------------------------------------


def test_lambert_furnace_is_le_over_one_minus_rho(tmp_path):
    scene = scene_from(
        tmp_path,
        """
        [materials.wall]
        diffuse = 0.5
        emission = 1.0
        [[objects]]
        name = "sphere"
        builtin = "sphere"
        flip = true
        material = "wall"
        """,
    )
    camera = Camera((0, 0, 0), (0, 0, 1), fov_deg=90, width=16, height=16)
    image = render(scene, camera, 1024)  # paths of geometric length: their spread needs many samples to be known
    expected = np.full(image.radiance.shape, 1.0 / (1.0 - 0.5))
    assert_within_monte_carlo_error(image, expected, np.ones(image.radiance.shape[:2], bool))
    assert abs(image.radiance.mean() / 2.0 - 1) < 0.01


ENCLOSED_QUAD = """
    [materials.sky]
    diffuse = 0.0
    emission = 1.0
    [materials.glossy]
    diffuse = 0.1
    specular = 0.8
    exponent = {exponent}
    [[objects]]
    name = "sky"
    builtin = "sphere"
    flip = true
    scale = 20
    material = "sky"
    [[objects]]
    name = "quad"
    builtin = "quad"
    scale = 4
    material = "glossy"
"""


def plane_hits(camera, height=0.0, sub=1):
    """Where rays through ``sub`` x ``sub`` points of each pixel meet the plane y =
    height: (H, W, sub*sub, 3) points and (H, W, sub*sub, 3) unit directions."""
    right, up, forward = camera.basis
    t = np.tan(np.radians(camera.fov_y_deg) / 2)
    offsets = (np.arange(sub) + 0.5) / sub
    x = (2 * (np.arange(camera.width)[:, None] + offsets[None, :]) / camera.width - 1) * t * camera.width / camera.height
    y = (1 - 2 * (np.arange(camera.height)[:, None] + offsets[None, :]) / camera.height) * t
    d = forward + x[None, :, None, :, None] * right + y[:, None, :, None, None] * up  # (H, W, sub_y, sub_x, 3)
    d = d.reshape(camera.height, camera.width, sub * sub, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    s = (height - camera.eye[1]) / d[..., 1]
    return np.asarray(camera.eye) + s[..., None] * d, d, s


@pytest.mark.parametrize("exponent", [1.0, 100.0, 1e5])
def test_glossy_quad_in_an_emitting_enclosure_shows_its_true_albedo(tmp_path, exponent):
    """A convex surface lit by uniform radiance 1 from every direction reflects its
    directional albedo rho(theta_o), which falls towards grazing for the specular lobe."""
    scene = scene_from(tmp_path, ENCLOSED_QUAD.format(exponent=exponent))
    camera = Camera((0, 0.6, -1.0), (0, 0, 0.6), fov_deg=80, width=24, height=24)
    image = render(scene, camera, 256)
    points, d, s = plane_hits(camera, sub=8)  # the box filter: 64 points of each pixel
    on_quad = (np.abs(points[..., 0]) < 2) & (np.abs(points[..., 2]) < 2) & (s > 0)
    inside, sky = on_quad.all(axis=2), ~on_quad.any(axis=2)
    # a sliver of the quad can still lie between the points: no sky pixel next to it
    sky &= ~binary_dilation(~sky)
    cos_out = np.clip(-d[..., 1], 0, 1)
    material = scene.object("quad").material
    expected = np.ones(image.radiance.shape)  # the enclosure, seen directly
    expected[inside] = albedo(material, cos_out[inside].ravel()).reshape(-1, 64, 3).mean(axis=1)
    assert inside.sum() > 150 and sky.sum() > 50
    # the view spans angles where the specular albedo changes (from ~30 to ~80 degrees)
    assert cos_out[inside].min() < 0.25 and cos_out[inside].max() > 0.85
    assert_within_monte_carlo_error(image, expected, inside)
    assert np.array_equal(image.radiance[sky], expected[sky].astype(np.float32))
    assert np.all(image.standard_error[sky] == 0)


MICROFACET_PLATE = """<?xml version="1.0"?>
<scene version="3.0.0">
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="rectangle" id="quad">
        <transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/></transform>
        {bsdf}
    </shape>
</scene>
"""


@pytest.mark.parametrize("bsdf", [
    '<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>'
    '<rgb name="diffuse_reflectance" value="0.6, 0.3, 0.1"/></bsdf>',
    '<bsdf type="roughconductor"><float name="alpha" value="0.3"/><string name="material" value="Cu"/></bsdf>',
])
def test_a_microfacet_quad_under_a_uniform_sky_shows_its_own_model_s_albedo(tmp_path, bsdf):
    """Under uniform radiance 1 a convex surface shows its directional albedo: the
    microfacet model's (the oracle's quadrature), not its Phong stand-in's."""
    path = tmp_path / "plate.xml"
    path.write_text(MICROFACET_PLATE.format(bsdf=bsdf))
    scene = load_scene(path)
    camera = Camera((0, 0.6, -1.0), (0, 0, 0.6), fov_deg=80, width=24, height=24)
    image = render(scene, camera, 256)
    points, d, s = plane_hits(camera, sub=8)
    inside = ((np.abs(points[..., 0]) < 2) & (np.abs(points[..., 2]) < 2) & (s > 0)).all(axis=2)
    cos_out = np.clip(-d[..., 1], 0, 1)
    material = scene.object("quad").material
    assert material.microfacet is not None
    expected = np.zeros(image.radiance.shape)
    expected[inside] = albedo(material, cos_out[inside].ravel()).reshape(-1, 64, 3).mean(axis=1)
    assert inside.sum() > 150 and cos_out[inside].min() < 0.25
    assert_within_monte_carlo_error(image, expected, inside)
    stand_in = albedo(material, cos_out[inside].ravel(), microfacet_models=False).reshape(-1, 64, 3).mean(axis=1)
    assert np.abs(stand_in - expected[inside]).max() > 0.05  # the test tells the model from the stand-in


# -- an emitting square above a diffuse plane -----------------------------------------------



def test_square_light_over_a_plane_gives_the_closed_form_irradiance(tmp_path):
    scene = scene_from(tmp_path, SQUARE_LIGHT)
    camera = Camera((0, 0.3, -0.7), (0, 0, 0.05), fov_deg=60, width=32, height=32)
    image = render(scene, camera, 256, seed=4)
    points, _, s = plane_hits(camera, sub=4)  # the box filter: 16 points of each pixel
    on_floor = (np.abs(points[..., 0]) < 0.5) & (np.abs(points[..., 2]) < 0.5) & (s > 0)
    lamp = scene.object("lamp").positions[:4]
    radiance = np.zeros(on_floor.shape)
    flat = points[on_floor]
    radiance[on_floor] = 0.5 / np.pi * polygon_irradiance(flat, np.array([0, 1.0, 0]), lamp, 1.0)
    floor_pixels = on_floor.all(axis=2)
    assert floor_pixels.sum() > 500
    expected = np.repeat(radiance.mean(axis=2)[..., None], 3, axis=2)
    assert_within_monte_carlo_error(image, expected, floor_pixels)
    ratio = image.radiance[floor_pixels].sum() / expected[floor_pixels].sum()
    assert abs(ratio - 1) < 0.01


# -- determinism and convergence -------------------------------------------------------------


def test_same_seed_same_image_whatever_the_threads_and_passes():
    scene = load_scene("cornell-teapot")
    camera = scene.camera.sized(20, 16)
    one = render(scene, camera, 5, seed=9, threads=1)
    two = render(scene, camera, 5, seed=9, threads=2)
    assert np.array_equal(one.radiance, two.radiance)
    assert np.array_equal(one.standard_error, two.standard_error)
    other = render(scene, camera, 5, seed=10, threads=2)
    assert not np.array_equal(one.radiance, other.radiance)


def test_progressive_passes_report_the_running_image():
    scene = load_scene("cornell")
    camera = scene.camera.sized(8, 8)
    seen = []
    with PathTracer(scene) as tracer:
        final = tracer.render(camera, 11, callback=lambda spp, image: seen.append((spp, image)))
    assert [spp for spp, _ in seen] == [1, 2, 4, 8, 11]
    assert np.array_equal(seen[-1][1].radiance, final.radiance)
    assert final.stats["paths"] == 11 * 64 and final.stats["rays"] > final.stats["paths"]


def test_four_times_the_samples_halve_the_error():
    # the diffuse box, the light out of view: no caustics or light-edge pixels, whose
    # heavy-tailed samples make an RMS over a few hundred pixels a noisy measure
    scene = load_scene("cornell")
    camera = Camera(scene.camera.eye, (278, 0, 0), fov_deg=39.3, width=24, height=24)
    with PathTracer(scene) as tracer:
        reference = tracer.render(camera, 1024, seed=1).radiance.astype(np.float64)
        rms = [
            np.sqrt(np.mean((tracer.render(camera, spp, seed=2).radiance - reference) ** 2)) for spp in (16, 64)
        ]
    # with the reference's own noise the expected ratio is sqrt((1/16 + 1/1024) / (1/64 + 1/1024)) = 1.96
    assert 1.8 < rms[0] / rms[1] < 2.15, rms


# -- extremes and bad input ------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_scene_scale_does_not_change_the_image(tmp_path, scale):
    text = SQUARE_LIGHT.replace('material = "floor"', f'material = "floor"\n    scale = {scale}')
    text = text.replace("scale = 0.5", f"scale = {0.5 * scale}").replace(
        "translate = [0.1, 0.4, 0.05]", f"translate = [{0.1 * scale}, {0.4 * scale}, {0.05 * scale}]"
    )
    camera = Camera((0, 0.22, -1.2), (0, 0, 0), fov_deg=45, width=16, height=16)
    base = render(scene_from(tmp_path, SQUARE_LIGHT), camera, 16, seed=3).radiance
    scaled_camera = Camera((0, 0.22 * scale, -1.2 * scale), (0, 0, 0), fov_deg=45, width=16, height=16)
    scaled = render(scene_from(tmp_path, text), scaled_camera, 16, seed=3).radiance
    assert np.isfinite(scaled).all()
    assert abs(scaled.sum() / base.sum() - 1) < 0.01


def test_bright_lights_and_a_single_sample_stay_finite(tmp_path):
    scene = scene_from(tmp_path, SQUARE_LIGHT.replace("emission = 1.0", "emission = 1e8"))
    camera = Camera((0, 0.22, -1.2), (0, 0, 0), fov_deg=45, width=6, height=5)
    image = render(scene, camera, 1)
    assert image.radiance.shape == (5, 6, 3)
    assert np.isfinite(image.radiance).all() and image.radiance.max() > 1e6
    assert np.all(image.standard_error == 0)  # one sample: no spread known, none claimed


def test_sample_counts_and_seeds_out_of_range_are_refused():
    scene = load_scene("cornell")
    camera = scene.camera.sized(4, 4)
    with PathTracer(scene) as tracer:
        for spp in (0, -1, pathtrace.MAX_SPP + 1, 2.5):
            with pytest.raises(InputError, match="--spp"):
                tracer.render(camera, spp)
        with pytest.raises(InputError, match="--seed"):
            tracer.render(camera, 1, seed=-1)


def test_pass_plan_doubles_up_to_its_cap():
    assert pathtrace.pass_plan(1) == [1]
    assert pathtrace.pass_plan(11) == [1, 1, 2, 4, 3]
    plan = pathtrace.pass_plan(100)
    assert sum(plan) == 100 and max(plan) == pathtrace.MAX_PASS_SAMPLES


def test_disjoint_sample_ranges_are_independent_halves_of_one_render():
    scene = load_scene("cornell")
    camera = scene.camera.sized(10, 8)
    with PathTracer(scene) as tracer:
        whole = tracer.render(camera, 8, seed=2).radiance.astype(np.float64)
        first = tracer.render(camera, 4, seed=2).radiance.astype(np.float64)
        second = tracer.render(camera, 4, seed=2, first_sample=4).radiance.astype(np.float64)
    assert np.allclose((first + second) / 2, whole, rtol=1e-5, atol=1e-6)
    assert not np.allclose(first, second)
