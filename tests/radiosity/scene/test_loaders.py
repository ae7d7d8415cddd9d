"""radiosity.scene.loaders and model on awkward input: text mesh files that are not UTF-8
or start with a byte-order mark, a missing material library, glTF's emissive strength,
numbers and coordinates beyond what single precision and the ray tracer hold, and no
numpy runtime warning on the way."""

import base64
import json
import struct
import sys
import textwrap
import warnings

import numpy as np
import pytest

from radiosity.files.errors import InputError, SceneWarning
from radiosity.scene import geometry
from radiosity.scene.loaders import load_scene
from radiosity.scene.material_kernels import Material
from radiosity.scene.meshfiles import decode_text
from radiosity.scene.model import MAX_COORDINATE, Scene, build_object

BOM = b"\xef\xbb\xbf"
TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


@pytest.fixture(autouse=True)
def no_charset_detection(monkeypatch):
    """Our decoding must not depend on charset_normalizer (trimesh's fallback)."""
    monkeypatch.setitem(sys.modules, "charset_normalizer", None)


def write_bytes(path, data):
    path.write_bytes(data)
    return path


def toml_scene(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(text))
    return path


# -- text encodings --------------------------------------------------------------------------


def test_decode_text():
    assert decode_text(BOM + b"v 1 2 3\n") == "v 1 2 3\n"
    assert decode_text("# café\n".encode()) == "# café\n"
    assert decode_text("# café\n".encode("latin-1")) == "# café\n"


@pytest.mark.parametrize("encoding", ["latin-1", "utf-8-bom"])
def test_obj_and_mtl_in_latin1_or_with_a_bom_keep_their_materials(tmp_path, encoding):
    def encode(text):
        return BOM + text.encode("utf-8") if encoding == "utf-8-bom" else text.encode("latin-1")

    # the first line of each file is a keyword, so a stray byte-order mark would hide it
    write_bytes(tmp_path / "pièces.mtl", encode(
        "newmtl café\nKd 0.2 0.3 0.4\nKs 0.5 0.5 0.5\nNs 64\n# modèle exporté\nnewmtl lampe\nKe 5 4 3\n"
    ))
    obj = write_bytes(tmp_path / "scene.obj", encode(
        "mtllib pièces.mtl\n# créé par un exportateur ancien\n" + TRIANGLE_OBJ
        + "v 0 0 1\nusemtl café\nf 1 3 2\nf 1 2 4\nusemtl lampe\nf 1 4 3\n"
    ))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = load_scene(obj)
    materials = {o.material.name: o.material for o in scene.objects}
    assert materials["café"].diffuse == (0.2, 0.3, 0.4) and materials["café"].exponent == 64
    assert materials["lampe"].emission == (5, 4, 3)
    assert sum(o.n_triangles for o in scene.objects) == 3


ASCII_STL = """solid {name}
 facet normal 0 0 1
  outer loop
   vertex 0 0 0
   vertex 1 0 0
   vertex 0 1 0
  endloop
 endfacet
endsolid {name}
"""


@pytest.mark.parametrize("data", [
    ASCII_STL.format(name="pièce").encode("latin-1"),
    BOM + ASCII_STL.format(name="piece").encode("utf-8"),
], ids=["latin-1", "utf-8-bom"])
def test_ascii_stl_in_latin1_or_with_a_bom(tmp_path, data):
    scene = load_scene(write_bytes(tmp_path / "part.stl", data))
    (o,) = scene.objects
    assert o.n_triangles == 1 and o.area == pytest.approx(0.5)


def test_binary_stl_is_not_decoded(tmp_path):
    # a binary STL whose header starts like an ASCII one and holds bytes that are not UTF-8
    header = b"solid \xe9\xe8 binary".ljust(80, b"\xff")
    facet = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0)
    scene = load_scene(write_bytes(tmp_path / "part.stl", header + struct.pack("<I", 1) + facet))
    assert scene.objects[0].area == pytest.approx(2.0)


def test_latin1_mesh_named_in_a_toml_scene(tmp_path):
    write_bytes(tmp_path / "m.obj", ("# été\n" + TRIANGLE_OBJ + "f 1 2 3\n").encode("latin-1"))
    scene = load_scene(toml_scene(tmp_path, """
        [materials.m]
        diffuse = 0.5
        [[objects]]
        name = "t"
        mesh = "m.obj"
        material = "m"
    """))
    assert scene.object("t").n_triangles == 1


def test_missing_material_library_warns_and_uses_the_default(tmp_path):
    obj = write_bytes(tmp_path / "lost.obj", ("mtllib nowhere.mtl\n" + TRIANGLE_OBJ + "usemtl gold\nf 1 2 3\n").encode())
    with pytest.warns(SceneWarning, match="material library 'nowhere.mtl' not found") as record:
        scene = load_scene(obj)
    assert len(record) == 1 and "\n" not in str(record[0].message)
    (o,) = scene.objects
    assert o.material.diffuse == (0.8, 0.8, 0.8) and not o.material.is_glossy and not o.material.is_emitter


# -- glTF emissive strength -------------------------------------------------------------------


def gltf_triangles(materials):
    """A glTF tree (with its binary buffer apart) of one triangle per material, side by side."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    indices = np.array([0, 1, 2], np.uint16).tobytes() + b"\0\0"
    tree = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": list(range(len(materials)))}],
        "nodes": [{"mesh": i, "name": m["name"], "translation": [2.0 * i, 0, 0]} for i, m in enumerate(materials)],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": i}]}
            for i in range(len(materials))
        ],
        "materials": materials,
        "buffers": [{"byteLength": len(positions) + len(indices)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(positions), "target": 34962},
            {"buffer": 0, "byteOffset": len(positions), "byteLength": 6, "target": 34963},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
    }
    return tree, positions + indices


def write_gltf(path, materials):
    tree, blob = gltf_triangles(materials)
    if path.suffix == ".gltf":
        tree["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        path.write_text(json.dumps(tree))
        return path
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks)
    return path


def emissive(name, factor, extension=None):
    """A black glTF material emitting ``factor``, with KHR_materials_emissive_strength ``extension``."""
    material = {
        "name": name,
        "emissiveFactor": factor,
        "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0, "roughnessFactor": 1.0},
    }
    if extension is not None:
        material["extensions"] = {"KHR_materials_emissive_strength": extension}
    return material


@pytest.mark.parametrize("suffix", [".gltf", ".glb"])
def test_gltf_emissive_strength_multiplies_the_emission(tmp_path, suffix):
    path = write_gltf(tmp_path / f"lamps{suffix}", [
        emissive("bright", [1.0, 0.5, 0.25], {"emissiveStrength": 40.0}),
        emissive("plain", [1.0, 1.0, 1.0]),
        emissive("default", [0.5, 0.5, 0.5], {}),  # the extension's default strength is 1
    ])
    scene = load_scene(path)
    assert scene.object("bright").material.emission == pytest.approx((40.0, 20.0, 10.0))
    assert scene.object("plain").material.emission == pytest.approx((1.0, 1.0, 1.0))
    assert scene.object("default").material.emission == pytest.approx((0.5, 0.5, 0.5))
    assert np.allclose(scene.object("plain").positions.min(axis=0), [2, 0, 0])


@pytest.mark.parametrize(
    "strength, match",
    [(-1.0, "must be a number >= 0"), ("x", "must be a number >= 0"), (1e300, "emission red = 1e\\+300 is above")],
)
def test_bad_gltf_emissive_strength_is_refused(tmp_path, strength, match):
    path = write_gltf(tmp_path / "lamp.glb", [emissive("lamp", [1.0, 1.0, 1.0], {"emissiveStrength": strength})])
    with pytest.raises(InputError, match=match) as info:
        load_scene(path)
    assert "'lamp'" in str(info.value) and "\n" not in str(info.value)


# -- single precision -----------------------------------------------------------------------------

CUBE = """
    [materials.m]
    diffuse = 0.5
    {material}
    [[objects]]
    name = "box"
    builtin = "cube"
    material = "m"
    {extra}
"""


@pytest.mark.parametrize(
    "material, extra, match",
    [
        ("", "translate = [1e300, 0, 0]", "'translate' = 1e\\+300 is beyond the single-precision range"),
        ("", "scale = 1e39", "'scale' = 1e\\+39 is beyond the single-precision range"),
        ("", "rotate_deg = [0, -1e39, 0]", "'rotate_deg' = -1e\\+39"),
        ("emission = 1e300", "", "'emission' = 1e\\+300"),
        ("", "scale = 1e11", "object 'box': 'scale' put its coordinates at 5e\\+10"),
        ("", "scale = 1e5\ntranslate = [0, 0, 3e10]", "'scale' and 'translate' put its coordinates at 3e\\+10"),
        ("", "scale = 1e-20", "1.73e-20 units across, below the 1e-09"),
        ("", "translate = [1e6, 0, 0]", "move it nearer the origin"),
    ],
    ids=["translate", "scale", "rotate", "emission", "scaled-out", "moved-out", "tiny", "far"],
)
def test_numbers_beyond_single_precision_are_refused_naming_the_key(tmp_path, material, extra, match):
    path = toml_scene(tmp_path, CUBE.format(material=material, extra=extra))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(InputError, match=match) as info:
            load_scene(path)
    assert "\n" not in str(info.value)


def test_the_limits_themselves_load(tmp_path):
    for extra in ("scale = 1e9", "scale = 1e-8", "translate = [1e3, 0, 0]"):
        load_scene(toml_scene(tmp_path, CUBE.format(material="emission = 3e38", extra=extra)))


def test_mesh_file_coordinates_beyond_the_ray_tracer_are_refused(tmp_path):
    write_bytes(tmp_path / "far.obj", b"v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(InputError, match="coordinates reach 1e\\+300, beyond"):
            load_scene(tmp_path / "far.obj")
        # the same file scaled down in a scene is fine
        scene = load_scene(toml_scene(tmp_path, """
            [materials.m]
            diffuse = 0.5
            [[objects]]
            name = "far"
            mesh = "far.obj"
            material = "m"
            scale = [1e-292, 1e-292, 1e-292]
        """))
    assert scene.object("far").positions.max() == pytest.approx(1e8)


def test_scene_built_in_code_is_checked_too():
    white = Material("w", (0.5, 0.5, 0.5))
    far = build_object("a", white, [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(InputError, match="beyond the \\+-1e\\+10"):
        Scene("s", (far.__class__(**{**far.__dict__, "positions": far.positions * 2 * MAX_COORDINATE}),))


def test_extreme_refinement_lengths_give_no_runtime_warning():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert geometry.refine(p, f, 1e308)[1].shape == (1, 3)
        with pytest.raises(InputError, match="would make about inf triangles"):
            geometry.refine(p, f, 1e-200)
        moved, _, _ = geometry.apply_transform(np.diag([1e300, 1e300, 1e300, 1.0]), p * 1e10, f)
        assert np.isinf(moved).any()
