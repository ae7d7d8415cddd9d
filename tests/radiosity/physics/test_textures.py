"""Diffuse textures: the lookup (numpy reference and kernel agree, orientation,
repeat, bilinear), reading images (sRGB decoded), texture coordinates through welding,
crease normals and refinement (seams kept, uvs interpolated like positions), and the
scene files that give them (TOML ``diffuse_texture``, OBJ ``vt``, glTF TEXCOORD_0)."""

import textwrap

import numba
import numpy as np
import pytest
from PIL import Image

from radiosity.files.errors import InputError
from radiosity.physics import textures
from radiosity.physics.textures import atlas, lookup, read_texture, srgb_to_linear, texel
from radiosity.scene import geometry
from radiosity.scene.loaders import load_scene
from radiosity.scene.model import build_object


@numba.njit(cache=False)
def _texel_rows(pixels, offsets, sizes, k, uv):
    out = np.empty((len(uv), 3))
    for i in range(len(uv)):
        out[i] = texel(pixels, offsets, sizes, k, uv[i, 0], uv[i, 1])
    return out


def write_png(path, rgb8):
    Image.fromarray(np.asarray(rgb8, dtype=np.uint8), "RGB").save(path)
    return path


# -- the lookup --------------------------------------------------------------------------


def test_texel_centres_read_their_texel_with_row_zero_at_the_top(rng):
    tex = rng.random((3, 5, 3)).astype(np.float32)
    i, j = np.meshgrid(np.arange(3), np.arange(5), indexing="ij")
    uv = np.stack([(j + 0.5) / 5, 1 - (i + 0.5) / 3], axis=-1)
    assert np.allclose(lookup(tex, uv), tex, atol=1e-12)
    # v up: the top-left texel is at u small, v near 1; the bottom-left at v near 0
    assert np.allclose(lookup(tex, [0.1, 5 / 6]), tex[0, 0]) and np.allclose(lookup(tex, [0.1, 1 / 6]), tex[2, 0])


def test_lookup_repeats_and_is_bilinear_between_centres(rng):
    tex = rng.random((4, 6, 3)).astype(np.float32)
    uv = rng.random((200, 2))
    shifted = uv + rng.integers(-3, 4, size=(200, 2))
    assert np.allclose(lookup(tex, shifted), lookup(tex, uv), atol=1e-9)
    # halfway between two horizontal neighbours' centres: their mean
    assert np.allclose(lookup(tex, [1.0 / 6, 1 - 0.5 / 4]), 0.5 * (tex[0, 0] + tex[0, 1]))
    # across the repeating edge: halfway between the last and the first column
    assert np.allclose(lookup(tex, [0.0, 1 - 0.5 / 4]), 0.5 * (tex[0, 5] + tex[0, 0]))


def test_the_kernel_lookup_gives_the_same_bits_as_the_reference(rng):
    images = [rng.random((h, w, 3)).astype(np.float32) for h, w in ((3, 5), (1, 1), (7, 2))]
    pixels, offsets, sizes = atlas(images)
    assert pixels.dtype == np.float32 and offsets.tolist() == [0, 45, 48]
    uv = np.concatenate([rng.random((300, 2)), rng.normal(scale=40, size=(300, 2))])
    for k, image in enumerate(images):
        assert np.array_equal(_texel_rows(pixels, offsets, sizes, k, uv), lookup(image, uv))


def test_a_constant_texture_reads_exactly_its_value(rng):
    tex = np.full((5, 7, 3), np.float32(0.3))
    pixels, offsets, sizes = atlas([tex])
    values = _texel_rows(pixels, offsets, sizes, 0, rng.normal(scale=3, size=(100, 2)))
    assert np.all(values == np.float64(np.float32(0.3)))


def test_images_are_srgb_decoded(tmp_path):
    path = write_png(tmp_path / "t.png", [[[0, 188, 255], [12, 100, 200]]])
    tex = read_texture(path, "here")
    assert tex.dtype == np.float32 and tex.shape == (1, 2, 3)
    assert np.allclose(tex[0, 0], [0.0, ((188 / 255 + 0.055) / 1.055) ** 2.4, 1.0], atol=1e-7)
    assert np.allclose(tex[0, 1], srgb_to_linear(np.array([12, 100, 200]) / 255), atol=1e-7)


def test_bad_texture_files_are_refused_in_one_line(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"not an image at all")
    with pytest.raises(InputError, match="cannot read texture"):
        read_texture(tmp_path / "bad.png", "here")
    with pytest.raises(InputError, match="here"):
        read_texture(tmp_path / "missing.png", "here")


# -- texture coordinates through the mesh operations ----------------------------------------


def _seamed_strip():
    """Two unit squares side by side in z = 0 sharing the edge x = 1, as a texture's seam:
    the left square maps u 0..1, the right one u 0..1 again (the shared edge's two copies
    have u = 1 and u = 0)."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]], float)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0], [1, 0], [1, 1], [0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    return positions, faces, uvs


def test_welding_keeps_a_seam_and_merges_what_agrees():
    positions, faces, uvs = _seamed_strip()
    p, f, uv = geometry.weld(np.vstack([positions, positions[:1]]), np.vstack([faces, [[8, 1, 2]]]), 1e-9,
                             uvs=np.vstack([uvs, uvs[:1]]))
    assert len(p) == 8  # the duplicate of vertex 0 (same uv) merged; the seam's copies (other uvs) kept
    assert np.array_equal(uv[f], np.vstack([uvs, uvs[:1]])[np.vstack([faces, [[8, 1, 2]]])])


def test_a_textured_object_is_smooth_across_its_seam_and_keeps_its_uvs():
    positions, faces, uvs = _seamed_strip()
    positions[[1, 2, 4, 7], 2] = 0.2  # a slight ridge along the seam: smooth at the default crease angle
    tex = np.ones((2, 2, 3), np.float32)
    obj = build_object("strip", None, positions, faces, uvs=uvs, texture=tex)
    assert obj.n_vertices == 8 and obj.textured
    on_seam = np.nonzero(np.isclose(obj.positions[:, 0], 1))[0]
    assert len(on_seam) == 4
    for y in (0.0, 1.0):  # the two copies of each seam point share one normal, other uvs
        pair = on_seam[np.isclose(obj.positions[on_seam, 1], y)]
        assert len(pair) == 2 and np.allclose(obj.normals[pair[0]], obj.normals[pair[1]])
        assert sorted(obj.uvs[pair, 0]) == [0.0, 1.0]
    # the uv at every corner is the one it was given (u = x on the left square, x - 1 on the right)
    left = obj.positions[obj.faces][:, :, 0].mean(axis=1) < 1
    x = obj.positions[obj.faces][..., 0]
    assert np.allclose(obj.uvs[obj.faces][..., 0], np.where(left[:, None], x, x - 1))


@pytest.mark.parametrize("how", ["refine", "density", "split"])
def test_refinement_interpolates_uvs_like_positions(how):
    positions, faces, uvs = _seamed_strip()
    normals = np.tile([0.0, 0.0, 1.0], (8, 1))
    if how == "refine":
        p, f, _, uv = geometry.refine(positions, faces, 0.2, normals=normals, uvs=uvs)
    elif how == "density":
        p, f, _, uv = geometry.refine_density(positions, faces, np.full(8, 6.0), normals=normals, uvs=uvs)
    else:
        p, f, _, uv = geometry.split_edges(positions, faces, [[0, 2], [4, 5]], normals=normals, uvs=uvs)
    assert len(f) > len(faces) and len(uv) == len(p)
    # uvs are affine in position on each square: u = x (left), x - 1 (right); v = y
    x = p[f][..., 0]
    left = x.mean(axis=1) < 1
    assert np.allclose(uv[f][..., 0], np.where(left[:, None], x, x - 1))
    assert np.allclose(uv[f][..., 1], p[f][..., 1])


def test_refined_objects_keep_their_texture():
    positions, faces, uvs = _seamed_strip()
    tex = np.ones((2, 2, 3), np.float32)
    obj = build_object("strip", None, positions, faces, uvs=uvs, texture=tex)
    fine = obj.refined(0.3)
    assert fine.texture is obj.texture and fine.uvs.shape == (fine.n_vertices, 2)
    coarse = build_object("strip", None, positions, faces)
    assert coarse.uvs is None and coarse.refined(0.3).uvs is None


# -- scene files ---------------------------------------------------------------------------


QUAD_SCENE = """
    [materials.picture]
    diffuse = 0.8
    diffuse_texture = "t.png"
    [[objects]]
    name = "picture"
    builtin = "{builtin}"
    material = "picture"
"""


def _asymmetric_png(tmp_path):
    """A 2 x 2 image, each texel its own colour: red top-left, green top-right, blue
    bottom-left, white bottom-right."""
    return write_png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])


def _colour_at(obj, point):
    """The texture's colour at the vertex nearest ``point``."""
    i = np.argmin(np.linalg.norm(obj.positions - point, axis=1))
    return np.round(lookup(obj.texture, obj.uvs[i] * 0.5 + 0.25)).astype(int)  # the texel of that corner


@pytest.mark.parametrize("builtin", ["quad", "disk", "cube"])
def test_a_toml_diffuse_texture_maps_onto_the_builtins_unmirrored(tmp_path, builtin):
    _asymmetric_png(tmp_path)
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin=builtin)))
    obj = load_scene(tmp_path / "s.toml").object("picture")
    assert obj.textured and obj.texture.shape == (2, 2, 3) and obj.material.diffuse == (0.8, 0.8, 0.8)
    red, green, blue = [1, 0, 0], [0, 1, 0], [0, 0, 1]
    if builtin == "quad":  # seen from +y with -z up: top-left is (-x, -z)
        corners = {(-0.5, 0, -0.5): red, (0.5, 0, -0.5): green, (-0.5, 0, 0.5): blue}
    elif builtin == "disk":  # seen from +z with +y up; the disk's rim at 135 degrees is near the top-left texel
        corners = {(-0.7, 0.7, 0): red, (0.7, 0.7, 0): green, (-0.7, -0.7, 0): blue}
    else:  # the front (+z) face, seen from +z with +y up
        front = obj.normals[:, 2] > 0.99
        obj = type(obj)(obj.name, obj.material, obj.positions[front], obj.normals[front], obj.tangents[front],
                        obj.faces[:0], uvs=obj.uvs[front], texture=obj.texture)
        corners = {(-0.5, 0.5, 0.5): red, (0.5, 0.5, 0.5): green, (-0.5, -0.5, 0.5): blue}
    for point, colour in corners.items():
        assert _colour_at(obj, np.array(point)).tolist() == colour, point


def test_a_texture_on_a_mesh_without_uvs_is_refused_in_one_line(tmp_path):
    _asymmetric_png(tmp_path)
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="cornell:floor")))
    with pytest.raises(InputError, match="no texture coordinates"):
        load_scene(tmp_path / "s.toml")
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="x")).replace(
        'builtin = "x"', 'mesh = "m.obj"'))
    with pytest.raises(InputError, match="has no texture coordinates"):
        load_scene(tmp_path / "s.toml")


@pytest.mark.parametrize("value", ["1e300", "2e6", "-1.5e6"])
def test_texture_coordinates_beyond_a_million_are_refused_in_one_line(tmp_path, value):
    """A held-out input: an OBJ's vt of 1e300 ended in scipy's ValueError in the weld."""
    _asymmetric_png(tmp_path)
    (tmp_path / "m.obj").write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt {value} 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="x")).replace(
        'builtin = "x"', 'mesh = "m.obj"'))
    with pytest.raises(InputError) as refused:
        load_scene(tmp_path / "s.toml")
    message = str(refused.value)
    assert "texture coordinates reach" in message and "beyond the +-1e+06" in message and "\n" not in message


def test_a_missing_texture_is_refused_in_one_line(tmp_path):
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="quad")))
    with pytest.raises(InputError, match=r"\[materials.picture\].*not found"):
        load_scene(tmp_path / "s.toml")


OBJ_SQUARE = """\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3
f 1/1 3/3 4/4
"""


def test_obj_texture_coordinates_have_v_up(tmp_path):
    """OBJ's vt: (0, 0) is the image's bottom-left corner."""
    _asymmetric_png(tmp_path)
    (tmp_path / "m.obj").write_text(OBJ_SQUARE)
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="x")).replace(
        'builtin = "x"', 'mesh = "m.obj"'))
    obj = load_scene(tmp_path / "s.toml").object("picture")
    assert _colour_at(obj, np.array([0.0, 1.0, 0.0])).tolist() == [1, 0, 0]  # top-left: red
    assert _colour_at(obj, np.array([1.0, 0.0, 0.0])).tolist() == [1, 1, 1]  # bottom-right: white


def test_gltf_texture_coordinates_run_down_and_are_flipped(tmp_path):
    """glTF's TEXCOORD_0: (0, 0) is the image's top-left corner (trimesh flips v)."""
    from scene_files import gltf_square

    _asymmetric_png(tmp_path)
    # trimesh keeps TEXCOORD_0 only on a primitive with a material
    gltf_square(tmp_path, {"name": "picture", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}})
    (tmp_path / "s.toml").write_text(textwrap.dedent(QUAD_SCENE.format(builtin="x")).replace(
        'builtin = "x"', 'mesh = "m.gltf"'))
    obj = load_scene(tmp_path / "s.toml").object("picture")
    assert _colour_at(obj, np.array([0.0, 1.0, 0.0])).tolist() == [1, 0, 0]  # top-left: red
    assert _colour_at(obj, np.array([1.0, 0.0, 0.0])).tolist() == [1, 1, 1]  # bottom-right: white


def test_textures_module_names_its_conventions():
    assert "v up" in textures.__doc__ and "repeat" in textures.__doc__
