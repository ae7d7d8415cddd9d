"""Textures from mesh files given directly as a scene: an MTL's map_Kd and a glTF's
baseColorTexture become the object's diffuse texture (kd the factor alone), not
mirrored or flipped (an asymmetric image: each corner its own colour); a mesh
without texture coordinates falls back to the image's mean colour with a warning."""

import json
import warnings

import numpy as np
import pytest
import trimesh
from PIL import Image
from scene_files import gltf_square

from radiosity.files.errors import SceneWarning
from radiosity.physics.materials import fresnel_kd_limit
from radiosity.physics.textures import lookup, srgb_to_linear
from radiosity.scene.loaders import load_scene

# a 2 x 2 image: red top-left, green top-right, blue bottom-left, grey (128) bottom-right
IMAGE = [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [128, 128, 128]]]
GREY = float(srgb_to_linear(128 / 255))

SQUARE = """\
mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
{vt}usemtl {material}
f 1{t1} 2{t2} 3{t3}
f 1{t1} 3{t3} 4{t4}
"""


def _png(path):
    Image.fromarray(np.asarray(IMAGE, dtype=np.uint8), "RGB").save(path)


def _obj(tmp_path, material="pic", uvs=True, name="a.obj"):
    vt = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n" if uvs else ""
    t = {f"t{i}": f"/{i}" if uvs else "" for i in range(1, 5)}
    (tmp_path / name).write_text(SQUARE.format(vt=vt, material=material, **t))
    return tmp_path / name


def _corner_colours(obj):
    """The texel read near each corner of the unit square (x, y) seen from +z: the
    uv of the vertex there, pulled a quarter towards the centre."""
    out = {}
    for corner in ((0, 1), (1, 1), (0, 0), (1, 0)):
        i = np.argmin(np.linalg.norm(obj.positions[:, :2] - corner, axis=1))
        uv = obj.uvs[i] * 0.5 + 0.25
        out[corner] = np.round(lookup(obj.texture, uv), 4).tolist()
    return out


EXPECTED = {(0, 1): [1.0, 0.0, 0.0], (1, 1): [0.0, 1.0, 0.0], (0, 0): [0.0, 0.0, 1.0], (1, 0): [round(GREY, 4)] * 3}


def test_an_mtl_map_kd_is_a_texture_multiplying_kd(tmp_path):
    _png(tmp_path / "t.png")
    (tmp_path / "m.mtl").write_text("newmtl pic\nKd 0.5 0.6 0.7\nmap_Kd t.png\n")
    obj = load_scene(_obj(tmp_path)).objects[0]
    assert obj.textured and obj.texture.shape == (2, 2, 3)
    assert obj.material.diffuse == (0.5, 0.6, 0.7)  # the factor alone: the image multiplies it per point
    assert _corner_colours(obj) == EXPECTED


def test_an_mtl_map_kd_without_kd_multiplies_one(tmp_path):
    _png(tmp_path / "t.png")
    (tmp_path / "m.mtl").write_text("newmtl pic\nmap_Kd t.png\n")
    obj = load_scene(_obj(tmp_path)).objects[0]
    assert obj.textured and obj.material.diffuse == (1.0, 1.0, 1.0)
    assert _corner_colours(obj) == EXPECTED


def test_a_map_kd_on_a_mesh_without_uvs_is_its_mean_colour_with_one_warning(tmp_path):
    _png(tmp_path / "t.png")
    (tmp_path / "m.mtl").write_text("newmtl pic\nKd 0.5 0.5 0.5\nmap_Kd t.png\n")
    path = _obj(tmp_path, uvs=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obj = load_scene(path).objects[0]
    said = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert len(said) == 1 and "without texture coordinates" in said[0] and "mean colour" in said[0]
    mean = (np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]]).sum(axis=0) + GREY) / 4
    assert not obj.textured and obj.uvs is None
    assert np.allclose(obj.material.diffuse, 0.5 * mean)
    assert obj.material.name == "pic (mean texture)"


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_a_gltf_base_colour_texture_is_a_texture_multiplying_the_factor(tmp_path, suffix):
    _png(tmp_path / "t.png")
    material = {"name": "pic", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "baseColorFactor": [0.6, 0.8, 1.0, 1.0], "metallicFactor": 0.0,
        "roughnessFactor": 1.0}}
    path = gltf_square(tmp_path, material)
    if suffix == ".glb":  # the same file packed into one binary, image and all
        glb = trimesh.load(path).export(file_type="glb")
        path = tmp_path / "m.glb"
        path.write_bytes(glb)
    obj = load_scene(path).objects[0]
    assert obj.textured
    # 8-bit factors through trimesh; a rough dielectric is diffuse: kd = the factor alone
    assert np.allclose(obj.material.diffuse, [0.6, 0.8, 1.0], atol=1 / 255) and obj.material.specular == (0, 0, 0)
    assert _corner_colours(obj) == EXPECTED


def test_a_textured_glossy_gltf_keeps_its_specular_and_scales_kd(tmp_path):
    _png(tmp_path / "t.png")
    material = {"name": "pic", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.3}}
    obj = load_scene(gltf_square(tmp_path, material)).objects[0]
    assert obj.textured
    # glTF's Schlick F0 = 0.04 (a dielectric), ks 1; kd the factor (1) within the energy bound, the image multiplies it
    assert np.allclose(obj.material.fresnel, 0.04) and np.allclose(obj.material.specular, 1.0)
    limit = fresnel_kd_limit(np.ones(3), np.full(3, 0.04), obj.material.exponent)
    assert np.allclose(obj.material.diffuse, np.minimum(1.0, limit))
    assert obj.material.exponent > 0


def test_objects_of_one_textured_material_share_its_image(tmp_path):
    _png(tmp_path / "t.png")
    material = {"name": "pic", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}
    scene = load_scene(gltf_square(tmp_path, material, copies=2))
    assert len(scene.objects) == 2 and all(o.textured for o in scene.objects)
    assert scene.objects[0].texture is scene.objects[1].texture


# -- the built-ins' texture coordinates (a TOML diffuse_texture on them) ---------------------------------------


def _ccw_in_uv(obj):
    """Each triangle's signed area in (u, v), seen as it is from its front."""
    c = obj.uvs[obj.faces]
    return (c[:, 1, 0] - c[:, 0, 0]) * (c[:, 2, 1] - c[:, 0, 1]) - (c[:, 1, 1] - c[:, 0, 1]) * (c[:, 2, 0] - c[:, 0, 0])


def _builtin(tmp_path, builtin, extra=""):
    _png(tmp_path / "t.png")
    (tmp_path / "s.toml").write_text(
        f'[materials.pic]\ndiffuse = 1\ndiffuse_texture = "t.png"\n'
        f'[[objects]]\nname = "it"\nbuiltin = "{builtin}"\nmaterial = "pic"\n{extra}')
    return load_scene(tmp_path / "s.toml").object("it")


def test_the_builtin_sphere_is_mapped_latitude_longitude_unmirrored(tmp_path):
    obj = _builtin(tmp_path, "sphere")
    assert obj.textured and (_ccw_in_uv(obj) > 0).all()  # unmirrored seen from outside, no triangle across the seam
    assert np.ptp(obj.uvs[obj.faces][..., 0], axis=1).max() < 0.25
    p = obj.positions
    away = np.hypot(p[:, 0], p[:, 2]) > 1e-6  # not a pole
    u = np.mod(0.5 + np.arctan2(p[:, 0], p[:, 2]) / (2 * np.pi), 1.0)
    assert np.allclose(np.mod(obj.uvs[away, 0] - u[away] + 0.5, 1.0) - 0.5, 0, atol=1e-9)
    assert np.allclose(obj.uvs[:, 1], 0.5 + np.arcsin(np.clip(p[:, 1], -1, 1)) / np.pi, atol=1e-9)
    # facing +z, up +y: the upper right reads the image's top-right quarter (green), the lower left its
    # bottom-left (blue), and the lookup at the point says so
    for point, colour in (([0.3, 0.3, 0.9], EXPECTED[(1, 1)]), ([-0.3, -0.3, 0.9], EXPECTED[(0, 0)])):
        i = np.argmin(np.linalg.norm(p - np.asarray(point) / np.linalg.norm(point), axis=1))
        quarter = (obj.uvs[i] > 0.5).astype(float)  # (1, 1): top right
        assert np.round(lookup(obj.texture, 0.25 + 0.5 * quarter), 4).tolist() == colour


def test_the_builtin_cylinder_is_mapped_around_and_up(tmp_path):
    obj = _builtin(tmp_path, "cylinder", "segments = 16\n")
    assert obj.textured and (_ccw_in_uv(obj) > 0).all()
    p = obj.positions
    assert np.allclose(obj.uvs[:, 1], p[:, 2])
    u = np.mod(np.arctan2(p[:, 1], p[:, 0]) / (2 * np.pi), 1.0)
    seam = np.isclose(obj.uvs[:, 0], 1.0)
    assert np.allclose(obj.uvs[~seam, 0], u[~seam]) and seam.sum() == 2  # the seam's second copy, top and bottom
    assert obj.n_vertices == 34


def test_the_builtin_teapot_maps_each_patch_upright_and_unmirrored(tmp_path):
    obj = _builtin(tmp_path, "teapot", "resolution = 6\n")
    plain = load_scene_untextured_teapot(6)
    assert obj.textured and (_ccw_in_uv(obj) > 0).all()
    assert len(obj.faces) == len(plain.faces)  # the same triangles, each patch's own vertices
    area = lambda o: np.linalg.norm(np.cross(*(o.positions[o.faces[:, k]] - o.positions[o.faces[:, 0]]  # noqa: E731
                                                for k in (1, 2))), axis=1).sum()
    assert area(obj) == pytest.approx(area(plain), rel=1e-12)
    # on the body's side (radius about 1.4 to 2, height 0.5 to 2), v grows with height
    t = obj.faces
    centre = obj.positions[t].mean(axis=1)
    side = (np.hypot(centre[:, 0], centre[:, 2]) > 1.3) & (centre[:, 1] > 0.5) & (centre[:, 1] < 2.0) & \
        (np.abs(centre[:, 2]) > 0.5)  # away from the spout and the handle
    dv = obj.uvs[t[side]][:, :, 1]
    dy = obj.positions[t[side]][:, :, 1]
    slope = [np.polyfit(y, v, 1)[0] for y, v in zip(dy, dv, strict=True) if np.ptp(y) > 1e-3]
    assert np.mean(np.array(slope) > 0) > 0.99


def load_scene_untextured_teapot(resolution):
    from radiosity.scene import builtins
    from radiosity.scene.model import build_object

    positions, faces = builtins.mesh("teapot", resolution=resolution)
    return build_object("plain", None, positions, faces)


def test_a_textured_metal_warns_that_its_specular_colour_is_the_mean_and_an_untextured_one_does_not(tmp_path):
    _png(tmp_path / "t.png")
    metal = {"name": "pic", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.5,
                                                     "roughnessFactor": 0.3}}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        obj = load_scene(gltf_square(tmp_path, metal)).objects[0]
    said = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert len(said) == 1 and "takes the texture's mean" in said[0]
    mean = (np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]]).sum(axis=0) + GREY) / 4
    f0 = mean * 0.5 + 0.04 * 0.5  # Schlick's F0 mixed to the base colour's mean by metallic
    assert np.allclose(obj.material.fresnel, f0, atol=1e-6) and np.allclose(obj.material.specular, 1.0)
    limit = fresnel_kd_limit(np.ones(3), f0, obj.material.exponent)
    assert np.allclose(obj.material.diffuse, np.minimum(0.5, limit), atol=1e-6)  # the factor 1 (1 - metallic) alone
    plain = {"name": "plain", "pbrMetallicRoughness": {"metallicFactor": 0.5, "roughnessFactor": 0.3}}
    gltf = json.loads(gltf_square(tmp_path, plain, name="plain.gltf").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        assert not load_scene(tmp_path / "plain.gltf").objects[0].textured, gltf["materials"]
