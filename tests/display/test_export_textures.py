"""``vlights export`` of textured objects (display/export.py, version 3): a textured
object's uvs as TEXCOORD_0 (glTF's v down the image), its image as the material's base
colour texture (a PNG of the sRGB codes, repeating, mipmapped), kd as the base colour
factor and in the mesh's extras, the irradiance as ``_IRRADIANCE``.

The file is read twice: by ``load_export`` (the texture of an 8-bit source exactly,
the uvs within float32 rounding, the irradiance and kd exactly) and byte by byte from
the GLB's chunks (the accessors, the PNG, the sampler), independently of trimesh.
"""

import dataclasses
import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from display_fixtures import lit_model
from PIL import Image
from test_export import bits_equal, glb_header, rewrite_json, validate

from display.export import FILE, SAMPLER, TEXTURED_VERSION, UNTEXTURED_VERSION, export_glb, srgb8
from display.export_reader import load_export
from fitting import FittedModel, load_fit
from radiosity.files.errors import InputError
from radiosity.physics.materials import srgb_to_linear
from radiosity.physics.textures import TexturedDiffuse, linear_to_srgb8

SRGB8 = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)  # the linear value of each 8-bit code
KDS = {"wall": (0.7, 0.55, 0.35), "tile": (0.3, 0.45, 0.6)}


def wall_uvs(p):
    """The wall ([-1, 1]^2): u over [0, 3], v over [0, 2] (the image repeats)."""
    return np.stack([(p[:, 0] + 1) * 1.5, (p[:, 1] + 1) * 1.0], axis=1)


def tile_uvs(p):
    """The tile ([-0.4, 0.4]^2): shifted, v partly negative (repeating)."""
    return np.stack([(p[:, 0] + 0.4) * 2.0 + 0.3, (p[:, 1] + 0.4) * 1.5 - 0.2], axis=1)


def textured_model(per_light, rng, float_tile=False, emitted_scale=0.5, uv_scale=1.0, tiles=True):
    """``lit_model`` with both objects textured: random 8-bit sRGB images (each texel its
    own colour: asymmetric; 8 x 6 on the wall, 4 x 5 on the tile), planar uvs (times
    ``uv_scale``: more repeats, a minified image), random irradiance per vertex.
    ``float_tile``: the tile's image is not an 8-bit decoding (the export rounds it);
    ``tiles`` False: the tile is not textured. The emitted colour is scaled by
    ``emitted_scale`` so that the texture shows in an image."""
    base = lit_model(per_light, rng)
    objects = []
    for o, uvs, shape in ((base.objects[0], wall_uvs, (6, 8, 3)), (base.objects[1], tile_uvs, (5, 4, 3))):
        texture = SRGB8[rng.integers(20, 256, shape)]
        if float_tile and o.name == "tile":
            texture = rng.uniform(0.05, 1.0, shape).astype(np.float32)
        textured = TexturedDiffuse(uvs=uvs(o.positions.astype(np.float64)) * uv_scale,
                                   irradiance=rng.uniform(4.0, 10.0, (len(o.positions), 3)), texture=texture,
                                   kd=KDS[o.name])
        objects.append(dataclasses.replace(o, emitted=(o.emitted * emitted_scale).astype(np.float32),
                                           textured=textured if tiles or o.name != "tile" else None))
    return FittedModel(objects=tuple(objects), source="test", model="mixed", camera=base.camera)


@pytest.fixture(params=["per-light", "shared"])
def exported(request, tmp_path_factory, cli, rng):
    """(the model as fit.npz gives it back, DIR) after ``vlights export fit.npz -o DIR``."""
    base = tmp_path_factory.mktemp(f"export-textured-{request.param}")
    textured_model(request.param == "per-light", rng).save(base / "fit.npz")
    code, out, err = cli("export", base / "fit.npz", "-o", base / "web", "--no-page")
    assert code == 0 and err == "", (code, out, err)
    assert "2 textured" in out
    return load_fit(base / "fit.npz"), base / "web"


def uv_tolerance(uvs):
    """How far float32 rounding moves uvs through glTF's 1 - v and back: an ulp or two of
    the largest magnitude met (|v|, |1 - v|)."""
    return 4 * np.finfo(np.float32).eps * (1.0 + np.abs(uvs).max())


def test_a_textured_fit_round_trips(exported, rng):
    """load_export gives the textured term back: the 8-bit texture exactly, the uvs within
    float32 rounding, the irradiance and kd exactly; every other array bit for bit; and
    the shading (the textured term included) within that rounding."""
    model, out = exported
    back = load_export(out / FILE)
    assert back.names == model.names
    for a, b in zip(model.objects, back.objects, strict=True):
        ta, tb = a.textured, b.textured
        assert tb is not None and tb.kd == ta.kd == KDS[a.name]
        assert bits_equal(tb.texture, ta.texture)
        assert bits_equal(tb.irradiance, ta.irradiance)
        assert tb.uvs.dtype == np.float32 and tb.uvs.shape == ta.uvs.shape
        assert np.abs(tb.uvs - ta.uvs).max() <= uv_tolerance(ta.uvs)
        for key, want in a.arrays().items():
            if key not in ("uvs", "texture", "irradiance"):
                assert bits_equal(b.arrays()[key], want), f"{a.name}/{key}"
        w = rng.normal(size=(len(a.positions), 5, 3))
        w /= np.linalg.norm(w, axis=-1, keepdims=True)
        assert np.allclose(b.shade(w), a.shade(w), rtol=1e-5, atol=1e-6)
        without = dataclasses.replace(a, textured=None).shade(w)
        assert np.abs(a.shade(w) - without).min() > 0.05  # the textured term does contribute


def accessor(header, binary, index):
    """Accessor ``index`` of a GLB read from its binary chunk: (count, n) float32."""
    acc = header["accessors"][index]
    view = header["bufferViews"][acc["bufferView"]]
    width = {"VEC2": 2, "VEC3": 3}[acc["type"]]
    assert acc["componentType"] == 5126 and view.get("byteStride", 4 * width) == 4 * width
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.frombuffer(binary, np.float32, acc["count"] * width, start).reshape(-1, width)


def chunks(path):
    """The JSON header and the binary chunk of a GLB."""
    data = Path(path).read_bytes()
    length = int.from_bytes(data[12:16], "little")
    binary_length, kind = struct.unpack("<I4s", data[20 + length:28 + length])
    assert kind == b"BIN\x00"
    return json.loads(data[20:20 + length]), data[28 + length:28 + length + binary_length]


def test_the_textured_schema_byte_by_byte(exported):
    """Without trimesh: version 3; TEXCOORD_0 is (u, 1 - v) in float32; the material's
    baseColorTexture is a PNG whose row 0 is the texture's top row, in the texture's sRGB
    codes; its sampler repeats, mipmapped; baseColorFactor is [kd, 1]; kd in the mesh's
    extras; _IRRADIANCE the irradiance's float32 bits."""
    model, out = exported
    header, binary = chunks(out / FILE)
    assert header["scenes"][0]["extras"]["version"] == TEXTURED_VERSION == 3
    assert header["samplers"] == [SAMPLER]
    assert SAMPLER == {"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}
    for mesh in header["meshes"]:
        obj = model.object(mesh["name"])
        t = obj.textured
        assert mesh["extras"]["textured"] == {"kd": list(KDS[obj.name])}
        primitive = mesh["primitives"][0]
        uv = accessor(header, binary, primitive["attributes"]["TEXCOORD_0"])
        assert np.array_equal(uv[:, 0], t.uvs[:, 0])
        assert np.abs(uv[:, 1] - (1.0 - t.uvs[:, 1].astype(np.float64))).max() <= uv_tolerance(t.uvs)
        assert bits_equal(accessor(header, binary, primitive["attributes"]["_IRRADIANCE"]), t.irradiance)
        material = header["materials"][primitive["material"]]
        assert material["name"] == obj.name and material["doubleSided"] is True
        pbr = material["pbrMetallicRoughness"]
        assert pbr["baseColorFactor"] == [*KDS[obj.name], 1.0]
        assert pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] == 1.0
        texture = header["textures"][pbr["baseColorTexture"]["index"]]
        assert texture["sampler"] == 0
        image = header["images"][texture["source"]]
        assert image["mimeType"] == "image/png"
        view = header["bufferViews"][image["bufferView"]]
        png = binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
        pixels = Image.open(io.BytesIO(png))
        assert pixels.format == "PNG" and pixels.mode == "RGB"
        codes = np.asarray(pixels)
        assert codes.shape == t.texture.shape
        assert np.array_equal(SRGB8[codes], t.texture)  # row 0 the top row, the sRGB codes
        assert not np.array_equal(codes, codes[::-1])  # not vacuous: the image is not symmetric


def test_a_float_texture_is_rounded_to_8_bit_srgb(tmp_path, rng):
    """A texture that is no 8-bit decoding comes back as the nearest 8-bit sRGB codes:
    within half a code of its encoding; the 8-bit one beside it exactly."""
    model = textured_model(True, rng, float_tile=True)
    tile = model.object("tile").textured.texture
    assert linear_to_srgb8(tile) is None
    (tmp_path / FILE).write_bytes(export_glb(model))
    back = load_export(tmp_path / FILE)
    encoded = np.where(tile <= 0.0031308, 12.92 * tile.astype(np.float64),
                       1.055 * tile.astype(np.float64) ** (1 / 2.4) - 0.055)
    codes = linear_to_srgb8(back.object("tile").textured.texture)
    assert codes is not None and np.array_equal(codes, srgb8(tile))
    assert np.abs(codes / 255.0 - encoded).max() <= 0.5 / 255 + 1e-9
    assert bits_equal(back.object("wall").textured.texture, model.object("wall").textured.texture)


def test_an_untextured_file_has_no_texture_and_the_old_version(tmp_path, rng):
    """No textured object: version 2, no material, texture, image, sampler or uvs (the
    same file as before textures)."""
    header = None
    for model in (lit_model(True, rng), textured_model(False, rng)):
        plain = dataclasses.replace(model, objects=tuple(dataclasses.replace(o, textured=None) for o in model.objects))
        (tmp_path / FILE).write_bytes(export_glb(plain))
        header = glb_header(tmp_path / FILE)
        assert header["scenes"][0]["extras"]["version"] == UNTEXTURED_VERSION == 2
        assert not {"materials", "textures", "images", "samplers"} & header.keys()
        for mesh in header["meshes"]:
            assert "textured" not in mesh["extras"]
            assert set(mesh["primitives"][0]["attributes"]) & {"TEXCOORD_0", "_IRRADIANCE"} == set()
        assert all(o.textured is None for o in load_export(tmp_path / FILE).objects)


def test_one_textured_object_beside_an_untextured_one(tmp_path, rng):
    model = textured_model(True, rng)
    mixed = dataclasses.replace(model, objects=(dataclasses.replace(model.objects[0], textured=None), model.objects[1]))
    (tmp_path / FILE).write_bytes(export_glb(mixed))
    header = glb_header(tmp_path / FILE)
    assert header["scenes"][0]["extras"]["version"] == 3 and len(header["materials"]) == 1
    back = load_export(tmp_path / FILE)
    assert back.objects[0].textured is None
    assert bits_equal(back.objects[1].textured.texture, model.objects[1].textured.texture)


@pytest.mark.parametrize("same_array", [True, False])
def test_objects_that_share_an_image_share_its_png_image_and_texture(tmp_path, rng, same_array):
    """Two objects with one image (the very array, as fit.npz's reader gives it, or an
    equal copy): one PNG, one image, one texture, which both materials (each the object's
    own, with its own kd) name; read back, both objects hold one array, bit for bit the
    image. A third object's different image is a texture of its own."""
    model = textured_model(True, rng)
    wall = model.object("wall").textured
    image = wall.texture if same_array else wall.texture.copy()
    tile = dataclasses.replace(model.object("tile").textured, texture=image)
    third = dataclasses.replace(model.objects[1], name="tile2")
    objects = (model.objects[0], dataclasses.replace(model.objects[1], textured=tile), third)
    shared = dataclasses.replace(model, objects=objects)
    (tmp_path / FILE).write_bytes(export_glb(shared))
    header, binary = chunks(tmp_path / FILE)
    assert len(header["images"]) == len(header["textures"]) == 2 and header["samplers"] == [SAMPLER]
    assert len({i["bufferView"] for i in header["images"]}) == 2
    assert len(header["materials"]) == 3
    used = {}
    for mesh in header["meshes"]:
        material = header["materials"][mesh["primitives"][0]["material"]]
        assert material["name"] == mesh["name"]
        used[mesh["name"]] = material["pbrMetallicRoughness"]["baseColorTexture"]["index"]
    assert used["wall"] == used["tile"] != used["tile2"]
    back = load_export(tmp_path / FILE)
    assert back.object("wall").textured.texture is back.object("tile").textured.texture
    assert bits_equal(back.object("tile").textured.texture, wall.texture)
    assert bits_equal(back.object("tile2").textured.texture, model.object("tile").textured.texture)
    assert back.object("tile").textured.kd == model.object("tile").textured.kd


def test_the_khronos_validator_finds_no_errors_in_a_textured_export(exported):
    validate(exported[1] / FILE)


@pytest.mark.parametrize("edit, fragment", [
    (lambda h: h["meshes"][1]["extras"]["textured"].pop("kd"), "object 'tile' 'textured' needs 'kd'"),
    (lambda h: h["meshes"][1]["extras"]["textured"].update(kd=[1, 2]), "object 'tile' 'textured' needs 'kd'"),
    (lambda h: h["materials"][0]["pbrMetallicRoughness"].pop("baseColorTexture"),
     "object 'wall' is textured but its material has no baseColorTexture"),
    (lambda h: h["meshes"][0]["primitives"][0].pop("material"), "object 'wall' is textured but has no TEXCOORD_0"),
    (lambda h: h["meshes"][0]["primitives"][0]["attributes"].pop("TEXCOORD_0"), "object 'wall' is textured but has no TEXCOORD_0"),
    (lambda h: h["meshes"][1]["primitives"][0]["attributes"].pop("_IRRADIANCE"), "object 'tile' has no vertex attribute _IRRADIANCE"),
])
def test_a_broken_textured_object_is_refused_in_one_line(tmp_path, rng, edit, fragment):
    path = tmp_path / FILE
    path.write_bytes(export_glb(textured_model(True, rng)))
    rewrite_json(path, edit)
    with pytest.raises(InputError, match=fragment) as info:
        load_export(path)
    assert "\n" not in str(info.value)
