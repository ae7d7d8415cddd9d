"""The path tracer on textured surfaces: the diffuse albedo at a hit is kd *
texture(uv at the hit).

A diffuse quad inside an enclosure of uniform radiance 1 reflects exactly its albedo,
so every pixel of it must show kd * texture(uv), averaged over the pixel (the box
filter), within the Monte Carlo error; a checker is resolved square by square; and a
texture that changes nothing (white, or a constant folded into kd) changes no bit.
"""

import textwrap

import numpy as np
import pytest
from PIL import Image
from test_pathtrace import assert_within_monte_carlo_error, plane_hits, render, scene_from

from radiosity.files.camera import Camera
from radiosity.physics.textures import lookup, read_texture
from radiosity.scene.loaders import load_scene

ENCLOSED_TEXTURED_QUAD = """
    [materials.sky]
    diffuse = 0.0
    emission = 1.0
    [materials.picture]
    diffuse = [0.9, 0.8, 0.7]
    diffuse_texture = "t.png"
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
    material = "picture"
"""

CAMERA = Camera((0, 3.0, -0.01), (0, 0, 0), up=(0, 0, -1), fov_deg=70, width=32, height=32)


def write_png(path, rgb8):
    Image.fromarray(np.asarray(rgb8, dtype=np.uint8), "RGB").save(path)


def expected_image(scene, camera, sub=8):
    """kd * texture(uv) averaged over ``sub`` x ``sub`` points of each pixel on the quad
    (the builtin quad's uvs: u = x / 4 + 1/2, v = 1/2 - z / 4), 1 (the sky) elsewhere;
    and the masks of the pixels wholly on the quad and wholly on the sky."""
    points, _, s = plane_hits(camera, sub=sub)
    on_quad = (np.abs(points[..., 0]) < 2) & (np.abs(points[..., 2]) < 2) & (s > 0)
    quad = scene.object("quad")
    uv = np.stack([points[..., 0] / 4 + 0.5, 0.5 - points[..., 2] / 4], axis=-1)
    albedo = np.asarray(quad.material.diffuse) * lookup(quad.texture, uv)
    expected = np.where(on_quad[..., None], albedo, 1.0).mean(axis=2)
    return expected, on_quad.all(axis=2), ~on_quad.any(axis=2)


def test_a_textured_quad_in_a_furnace_shows_kd_times_its_texture(tmp_path, rng):
    write_png(tmp_path / "t.png", rng.integers(0, 256, size=(3, 4, 3)))  # asymmetric: each texel its own colour
    scene = scene_from(tmp_path, ENCLOSED_TEXTURED_QUAD)
    image = render(scene, CAMERA, 256)
    expected, inside, sky = expected_image(scene, CAMERA)
    assert inside.sum() > 400
    assert_within_monte_carlo_error(image, expected, inside)
    assert np.all(image.radiance[sky] == 1.0)
    # the image is not mirrored or flipped: a mirrored expectation is far off
    flipped = expected[::-1]
    z = (image.radiance[inside] - flipped[inside]) / np.maximum(image.standard_error[inside], 1e-12)
    assert np.mean(z**2) > 50


def test_a_checker_texture_is_resolved(tmp_path):
    cells = (np.add.outer(np.arange(8), np.arange(8)) % 2).astype(np.uint8)
    write_png(tmp_path / "t.png", np.kron(np.repeat((cells * 200 + 20)[..., None], 3, axis=2), np.ones((4, 4, 1))))
    scene = scene_from(tmp_path, ENCLOSED_TEXTURED_QUAD)
    image = render(scene, CAMERA, 64)
    expected, inside, _ = expected_image(scene, CAMERA)
    dark_level, light_level = srgb(20) * 0.9, srgb(220) * 0.9
    light = inside & (expected[..., 0] > 0.98 * light_level)  # pixels inside a light square
    dark = inside & (expected[..., 0] < 1.02 * dark_level)
    assert light.sum() > 50 and dark.sum() > 50
    assert abs(image.radiance[light][:, 0].mean() / light_level - 1) < 0.03
    assert abs(image.radiance[dark][:, 0].mean() / dark_level - 1) < 0.1
    assert_within_monte_carlo_error(image, expected, inside)


def srgb(byte):
    c = byte / 255
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


@pytest.mark.parametrize("value", [255, 150])
def test_a_texture_that_changes_nothing_changes_no_bit(tmp_path, value):
    """A constant texture t gives the bits of the untextured material with kd * t."""
    write_png(tmp_path / "t.png", np.full((2, 3, 3), value))
    textured = scene_from(tmp_path, ENCLOSED_TEXTURED_QUAD.replace("scale = 20", "scale = 5"))
    t = float(read_texture(tmp_path / "t.png", "t")[0, 0, 0])
    kd = ", ".join(repr(k * t) for k in (0.9, 0.8, 0.7))
    plain = scene_from(tmp_path, ENCLOSED_TEXTURED_QUAD.replace("scale = 20", "scale = 5").replace(
        'diffuse = [0.9, 0.8, 0.7]\n    diffuse_texture = "t.png"', f"diffuse = [{kd}]"))
    assert plain.object("quad").texture is None and textured.object("quad").texture is not None
    camera = Camera((0, 1.5, -2.5), (0, 0, 0), fov_deg=60, width=16, height=12)
    one, two = render(textured, camera, 8, seed=3), render(plain, camera, 8, seed=3)
    assert np.array_equal(one.radiance, two.radiance)
    assert np.array_equal(one.standard_error, two.standard_error)


def test_a_texture_lights_its_surroundings_with_its_colour(tmp_path):
    """The texture on indirect bounces: a wall above a lamp facing down is lit only by
    the floor under it, white with a red texture: the wall is red and nothing else."""
    write_png(tmp_path / "t.png", [[[255, 0, 0]]])
    text = textwrap.dedent("""
        [materials.lamp]
        diffuse = 0.0
        emission = 5.0
        [materials.wall]
        diffuse = 0.8
        [materials.floor]
        diffuse = 0.8
        diffuse_texture = "t.png"
        [[objects]]
        name = "floor"
        builtin = "quad"
        scale = 2
        material = "floor"
        [[objects]]
        name = "wall"
        builtin = "quad"
        rotate_deg = [-90, 0, 0]
        translate = [0, 2.05, 1]
        material = "wall"
        [[objects]]
        name = "lamp"
        builtin = "quad"
        scale = 0.5
        flip = true
        translate = [0, 1.5, 0]
        material = "lamp"
    """)
    (tmp_path / "s.toml").write_text(text)
    scene = load_scene(tmp_path / "s.toml")
    camera = Camera((0, 2.05, -2.5), (0, 2.05, 1), fov_deg=10, width=16, height=16)
    image = render(scene, camera, 64)
    wall = image.radiance.reshape(-1, 3).mean(axis=0)  # the wall above the lamp sees the lamp's back only
    assert wall[0] > 0.002 and wall[1] == 0 and wall[2] == 0  # only the floor's red reaches it
