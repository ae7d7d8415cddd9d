"""``vlights export`` of a fit with an environment (display/export.py, version 4): its
image as float32 in a bufferView of the GLB's buffer, row 0 first, and its size, scale,
rotation and kind in the scene's extras.

Read back twice: by ``load_export`` (the image bit for bit, scale and rotation exactly,
the objects as without it) and byte by byte from the GLB's chunks, independently of
trimesh. A file without an environment keeps its version (2, or 3 with a textured
object) and has no trace of one.
"""

import dataclasses
import struct

import numpy as np
import pytest
from display_fixtures import lit_model
from scipy.spatial.transform import Rotation
from test_export import bits_equal, glossy_model, rewrite_json, validate
from test_export_textures import chunks, textured_model, uv_tolerance

from display.export import ENVIRONMENT_VERSION, FILE, TEXTURED_VERSION, UNTEXTURED_VERSION, export_glb
from display.export_reader import load_export
from fitting import load_fit
from radiosity.files.errors import InputError
from radiosity.physics.environment import EnvironmentLight

TURN = Rotation.from_euler("xyz", [20, -70, 10], degrees=True).as_matrix()  # float64 with no short decimal form


def environment_map(rng, rows=9, columns=16, scale=1.7):
    """An asymmetric map (each texel random, float32 values with no short decimal form), turned."""
    return EnvironmentLight.from_image(rng.uniform(0.1, 3.0, (rows, columns, 3)).astype(np.float32), scale, TURN,
                                       source="sky.exr")


def assert_same_environment(got, want):
    assert got is not None
    assert got.image.dtype == np.float32 and bits_equal(got.image, want.image)
    assert got.rotation.dtype == np.float64 and np.array_equal(got.rotation, want.rotation)
    assert got.scale == want.scale and got.constant == want.constant and got.source == want.source


def assert_same_objects(got, want):
    """Every array bit for bit, but a textured object's uvs: within float32 rounding
    (glTF's 1 - v and back, as without an environment)."""
    assert got.names == want.names
    for a, b in zip(want.objects, got.objects, strict=True):
        for key, value in a.arrays().items():
            if key.endswith("uvs"):
                assert np.allclose(b.arrays()[key], value, rtol=0, atol=uv_tolerance(value)), f"{a.name}/{key}"
            else:
                assert bits_equal(b.arrays()[key], value), f"{a.name}/{key}"


@pytest.mark.parametrize("kind", ["map", "constant", "textured", "glossy"])
def test_the_environment_round_trips(tmp_path, rng, kind):
    if kind == "constant":
        env = EnvironmentLight.uniform([0.3, 1.0 / 3.0, 2.5], 0.8, TURN, source="constant")
    else:
        env = environment_map(rng)
    base = {"textured": lambda: textured_model(True, rng), "glossy": lambda: glossy_model(True, rng)}.get(
        kind, lambda: lit_model(True, rng))()
    model = dataclasses.replace(base, environment=env)
    (tmp_path / FILE).write_bytes(export_glb(model))
    back = load_export(tmp_path / FILE)
    assert_same_environment(back.environment, env)
    assert_same_objects(back, model)
    if kind == "textured":
        for a, b in zip(model.objects, back.objects, strict=True):
            assert bits_equal(b.textured.texture, a.textured.texture) and b.textured.kd == a.textured.kd
    if kind == "glossy":
        assert [p.to_dict() for p in back.emitters] == [p.to_dict() for p in model.emitters]
        assert all(o.probe is not None and o.highlight is not None for o in back.objects)
    header, _ = chunks(tmp_path / FILE)
    assert header["scenes"][0]["extras"]["version"] == ENVIRONMENT_VERSION == 4  # with an environment, no delta part


def test_the_environment_byte_by_byte(tmp_path, rng):
    """Without trimesh: the scene extras' entry (doubles written exactly) and its
    bufferView, H * W * 3 little-endian float32, row 0 first, pixels left to right, RGB,
    referred to by no accessor."""
    env = environment_map(rng, rows=5, columns=7)
    (tmp_path / FILE).write_bytes(export_glb(dataclasses.replace(lit_model(False, rng), environment=env)))
    header, binary = chunks(tmp_path / FILE)
    entry = header["scenes"][0]["extras"]["environment"]
    assert entry == {"width": 7, "height": 5, "scale": 1.7, "rotation": TURN.tolist(), "constant": False,
                     "source": "sky.exr", "bufferView": entry["bufferView"]}
    view = header["bufferViews"][entry["bufferView"]]
    assert view["buffer"] == 0 and view["byteLength"] == 5 * 7 * 3 * 4 and "byteStride" not in view
    raw = binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]]
    values = struct.unpack(f"<{5 * 7 * 3}f", raw)
    j, i, c = 3, 5, 2
    assert values[(j * 7 + i) * 3 + c] == env.image[j, i, c]  # row j, column i, channel c
    assert bits_equal(np.array(values, np.float32).reshape(5, 7, 3), env.image)
    assert all(a["bufferView"] != entry["bufferView"] for a in header["accessors"])


def test_without_an_environment_the_file_has_none(tmp_path, rng):
    for model, version in ((lit_model(True, rng), UNTEXTURED_VERSION), (textured_model(False, rng), TEXTURED_VERSION)):
        (tmp_path / FILE).write_bytes(export_glb(model))
        header, binary = chunks(tmp_path / FILE)
        extras = header["scenes"][0]["extras"]
        assert extras["version"] == version and "environment" not in extras
        assert sum(v["byteLength"] for v in header["bufferViews"]) == len(binary)  # no extra bytes
        assert load_export(tmp_path / FILE).environment is None
    assert (UNTEXTURED_VERSION, TEXTURED_VERSION) == (2, 3)


def test_vlights_export_of_a_fit_with_an_environment(tmp_path, cli, rng):
    model = dataclasses.replace(lit_model(True, rng), environment=environment_map(rng))
    model.save(tmp_path / "fit.npz")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web", "--no-page")
    assert code == 0 and err == "", (code, out, err)
    assert ", a 16 x 9 environment," in out
    back = load_export(tmp_path / "web" / FILE)
    assert_same_environment(back.environment, load_fit(tmp_path / "fit.npz").environment)
    validate(tmp_path / "web" / FILE)  # the Khronos validator: no errors, no warnings (where installed)


@pytest.mark.parametrize("edit, message", [
    (lambda e, h: e.pop("bufferView"), "needs 'width', 'height', 'scale', 'rotation'"),
    (lambda e, h: e.update(width=8), r"bufferView \d+ must hold 9 x 8 x 3 float32 \(864 bytes\)"),
    (lambda e, h: e.update(height=0), "'width' and 'height' must be whole numbers >= 1"),
    (lambda e, h: e.update(bufferView=99), r"bufferView 99 does not exist"),
    (lambda e, h: e.update(constant="no"), "'constant' must be true or false"),
    (lambda e, h: e.update(rotation=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]), "the rotation is not orthonormal"),
    (lambda e, h: e.update(scale=-1.0), "scale must be a finite number >= 0"),
    (lambda e, h: h["bufferViews"][e["bufferView"]].update(byteOffset=10 ** 9), "must hold 9 x 16 x 3 float32"),
], ids=["no-view", "width", "height", "view", "constant", "rotation", "scale", "offset"])
def test_a_bad_environment_is_refused_in_one_line(tmp_path, rng, edit, message):
    path = tmp_path / FILE
    path.write_bytes(export_glb(dataclasses.replace(lit_model(True, rng), environment=environment_map(rng))))
    rewrite_json(path, lambda header: edit(header["scenes"][0]["extras"]["environment"], header))
    with pytest.raises(InputError, match=message) as error:
        load_export(path)
    assert "scene extras 'environment'" in str(error.value) and "\n" not in str(error.value)
