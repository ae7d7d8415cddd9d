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

from radiosity.formats.errors import SceneWarning
from radiosity.scene.loaders import load_scene
from radiosity.scene.textures import lookup, srgb_to_linear

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


def _gltf(tmp_path, material, name="m.gltf", copies=1):
    """A unit square in z = 0 facing +z, glTF texture coordinates (v down: y = 1 is v = 0);
    ``copies`` nodes of it, each one higher in z."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    texcoords = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    blob = positions.tobytes() + texcoords.tobytes() + indices.tobytes()
    (tmp_path / "m.bin").write_bytes(blob)
    gltf = {
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": list(range(copies))}],
        "nodes": [{"mesh": 0, "name": f"square{i}", "translation": [0, 0, i]} for i in range(copies)],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [material],
        "textures": [{"source": 0}],
        "images": [{"uri": "t.png"}],
        "buffers": [{"uri": "m.bin", "byteLength": len(blob)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }
    (tmp_path / name).write_text(json.dumps(gltf))
    return tmp_path / name


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_a_gltf_base_colour_texture_is_a_texture_multiplying_the_factor(tmp_path, suffix):
    _png(tmp_path / "t.png")
    material = {"name": "pic", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "baseColorFactor": [0.6, 0.8, 1.0, 1.0], "metallicFactor": 0.0,
        "roughnessFactor": 1.0}}
    path = _gltf(tmp_path, material)
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
    obj = load_scene(_gltf(tmp_path, material)).objects[0]
    assert obj.textured
    assert np.allclose(obj.material.specular, 0.04) and np.allclose(obj.material.diffuse, 0.96)  # base 1 x (1 - ks)
    assert obj.material.exponent > 0


def test_objects_of_one_textured_material_share_its_image(tmp_path):
    _png(tmp_path / "t.png")
    material = {"name": "pic", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}
    scene = load_scene(_gltf(tmp_path, material, copies=2))
    assert len(scene.objects) == 2 and all(o.textured for o in scene.objects)
    assert scene.objects[0].texture is scene.objects[1].texture
