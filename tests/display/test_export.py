"""``vlights export``: fit.npz -> DIR/scene.glb (display/export.py).

The glTF is read back with trimesh independently of ``display.export_reader.load_export``;
every array must come back bit for bit in float32, and shading the re-read arrays with
``fitting.model.shade_arrays`` must equal shading the fit. A version 3 fit (emitter
highlights and reflection probes, ``glossy_model``) must come back from
``load_export`` equal, array for array, and shade the same. The Khronos validator runs
where node and the npm package ``gltf-validator`` are installed (see ``validator_path``).
"""

import dataclasses
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from display_fixtures import CAMERA, assert_refused, listing, lit_model
from test_code_shape import OUTSIDE

from display.export import (
    DELTA_VERSION,
    FILE,
    FORMAT,
    OWN_PARTS_VERSION,
    READS,
    UNTEXTURED_VERSION,
    VERSION,
    export_glb,
)
from display.export_reader import load_export
from fitting import FittedModel, load_fit
from fitting.model import PARTS, Highlight, shade_arrays
from fitting.probe import Probe, albedo_table
from radiosity.files.errors import InputError
from radiosity.physics.emitters import EmitterPart, SpotProfile
from radiosity.physics.materials import Microfacet

# Emitter parts in front of the tiny scene, each seen in it from test_web's camera: a
# sphere lamp in the tile, a square panel and a triangle in the wall, and a sphere that
# is a part of the tile itself (its highlight would be on the tile: the tile does not
# reflect its own parts; the wall's is hidden behind the tile).
LAMPS = (
    EmitterPart("sphere", [[0.25, 0.15, -1.0]], 0.15, [20.0, 16.0, 12.0], "lamp"),
    EmitterPart("polygon", [[-1.45, -1.1, -1.4], [-0.95, -1.1, -1.4], [-0.95, -0.7, -1.4], [-1.45, -0.7, -1.4]],
                0.0, [16.0, 20.0, 28.0], "panel"),
    EmitterPart("sphere", [[-0.15, -0.15, -1.0]], 0.1, [30.0, 30.0, 30.0], "tile"),
    EmitterPart("polygon", [[0.6, 0.6, -1.2], [1.0, 0.6, -1.2], [0.8, 0.95, -1.2]], 0.0, [24.0, 12.0, 6.0], "shade"),
)


# Delta parts in front of the tiny scene (a version 5 fit): a point light and a spot
# whose highlights show on the wall and the tile from test_web's camera (the spot's
# cone cutting across the wall's), and a directional light.
DELTA_LAMPS = (
    EmitterPart("point", [[0.4, 0.3, -2.5]], 0.0, [3.0, 2.5, 2.0], "bulb"),
    EmitterPart("point", [[-0.6, 0.5, -2.2]], 0.0, [4.0, 4.0, 6.0], "torch", SpotProfile([-0.3, -0.5, 2.2], 16.0, 9.0)),
    EmitterPart("direction", [[-0.15, -0.1, 1.0]], 0.0, [0.8, 0.6, 0.4], "sun"),
)


GOLD = Microfacet("roughconductor", "ggx", 0.15, (0.143, 0.374, 1.442), (3.983, 2.385, 1.603))
SATIN = Microfacet("roughplastic", "beckmann", 0.3, (1.5, 1.5, 1.5), diffuse_reflectance=(0.2, 0.3, 0.4))


def microfacet_model(rng, lamps=LAMPS[:2] + DELTA_LAMPS):
    """``glossy_model`` with microfacet lobes drawing the highlights (a version 8 fit):
    the wall GGX gold, the tile Beckmann satin."""
    base = glossy_model(True, rng, lamps=lamps)
    objects = tuple(dataclasses.replace(o, highlight=dataclasses.replace(o.highlight, microfacet=mf))
                    for o, mf in zip(base.objects, (GOLD, SATIN), strict=True))
    return dataclasses.replace(base, objects=objects)


def glossy_model(per_light, rng, camera=CAMERA, nodes=8, lamps=LAMPS):
    """``lit_model`` as a version 3 fit: both objects reflect the emitter parts ``lamps``
    (default ``LAMPS``; the tile not its own), each part's visibility random per vertex,
    and each has a reflection probe (4 x 4 and 8 x 8 random texels, random per-vertex
    weights). With ``DELTA_LAMPS`` among the parts, a version 5 fit."""
    base = lit_model(per_light, rng, camera)
    objects = []
    for o, (ks, exponent, m, f0) in zip(base.objects, (((0.3, 0.3, 0.25), 20.0, 4, None),
                                                       ((0.5, 0.45, 0.4), 30.0, 8, np.array([0.04, 0.3, 0.9]))),
                                        strict=True):  # the second a Fresnel material's
        v = len(o.positions)
        highlight = Highlight(lamps, nodes, np.array(ks), exponent,
                              rng.uniform(0.3, 1.0, (v, len(lamps))).astype(np.float32), f0)
        probe = Probe(rng.uniform(0, 2, (m, m, 3)).astype(np.float32), np.array([0.0, 0.0, -0.8]),
                      np.array([[-1.5, -1.5, -2.5], [1.5, 1.5, 0.3]]), albedo_table(exponent))
        objects.append(dataclasses.replace(o, highlight=highlight, probe=probe,
                                           probe_weight=rng.uniform(0, 0.6, (v, 3)).astype(np.float32)))
    return FittedModel(objects=tuple(objects), source="test", model="mixed", camera=camera, emitters=lamps,
                       emitter_nodes=nodes)


@pytest.fixture(params=["per-light", "shared"])
def exported(request, tmp_path_factory, cli, rng):
    """(the model, fit.npz, DIR) after ``vlights export fit.npz -o DIR``."""
    base = tmp_path_factory.mktemp(f"export-{request.param}")
    model = lit_model(request.param == "per-light", rng)
    model.save(base / "fit.npz")
    code, out, err = cli("export", base / "fit.npz", "-o", base / "web")
    assert code == 0 and err == "", (code, out, err)
    assert f"wrote {base / 'web' / FILE}" in out
    return load_fit(base / "fit.npz"), base / "fit.npz", base / "web"


def glb_header(path):
    """The JSON chunk of a .glb file."""
    data = Path(path).read_bytes()
    assert data[:4] == b"glTF"
    return json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])


def read_with_trimesh(path):
    """{name: (mesh, extras)} read with trimesh alone, and the scene's extras."""
    header = glb_header(path)
    scene = trimesh.load(path, file_type="glb", force="scene", process=False)
    extras = {m["name"]: m["extras"] for m in header["meshes"]}
    return {name: (scene.geometry[name], extras[name]) for name in extras}, header["scenes"][0]["extras"]


def test_round_trip_is_bit_exact_and_shades_the_same(exported, rng):
    model, _, out = exported
    meshes, _ = read_with_trimesh(out / FILE)
    assert list(meshes) == list(model.names)
    for obj in model.objects:
        mesh, extras = meshes[obj.name]
        attributes = mesh.vertex_attributes
        k = obj.n_lights
        got = {
            "positions": np.asarray(mesh.vertices, np.float32),
            "normals": np.asarray(mesh.vertex_normals, np.float32),
            "faces": np.asarray(mesh.faces, np.int32),
            "emitted": np.asarray(attributes["_EMITTED"]),
            "light_pos": np.asarray(extras["light_pos"], np.float32).reshape(k, 4),
            "light_rgb": np.asarray(extras["light_rgb"], np.float32).reshape(k, 3),
            "shininess": np.asarray(extras["shininess"], np.float32).reshape(k),
        }
        assert got["emitted"].dtype == np.float32
        specular_keys = sorted(a for a in attributes if a.startswith("_SPECULAR"))
        if k == 0:
            assert specular_keys == [] and extras["per_light"] is False
            got["specular"] = np.zeros((len(got["positions"]), 3), np.float32)
            assert not obj.specular.any()
        elif obj.per_light:
            assert specular_keys == [f"_SPECULAR_{i}" for i in range(k)] and extras["per_light"] is True
            got["specular"] = np.stack([np.asarray(attributes[f"_SPECULAR_{i}"]) for i in range(k)], axis=1)
        else:
            assert specular_keys == ["_SPECULAR"] and extras["per_light"] is False
            got["specular"] = np.asarray(attributes["_SPECULAR"])
        assert extras["lights"] == k and extras["name"] == obj.name
        for key, want in obj.arrays().items():
            assert got[key].dtype == want.dtype, key
            assert got[key].shape == want.shape, key
            assert np.array_equal(got[key].view(np.uint8), want.view(np.uint8)), f"{obj.name}/{key} differs"

        w = rng.normal(size=(len(got["positions"]), 5, 3))
        w /= np.linalg.norm(w, axis=-1, keepdims=True)
        lights = (got["light_pos"], got["light_rgb"], got["shininess"])
        spec = got["specular"][:, None]
        again = shade_arrays(got["emitted"][:, None], spec, got["normals"][:, None], got["positions"][:, None], lights, w)
        first = shade_arrays(obj.emitted[:, None], obj.specular[:, None], obj.normals[:, None],
                             obj.positions[:, None], obj.lights, w)
        assert np.array_equal(again, first)
        if k:
            assert (again != got["emitted"][:, None]).any()  # the lights do contribute


def test_load_export_gives_the_fit_back(exported):
    model, _, out = exported
    back = load_export(out / FILE)
    assert back.names == model.names and back.source == model.source and back.model == model.model
    assert back.camera.to_dict() == model.camera.to_dict()
    for a, b in zip(model.objects, back.objects, strict=True):
        for key, want in a.arrays().items():
            assert np.array_equal(b.arrays()[key], want), f"{a.name}/{key}"


def test_scene_extras_hold_the_format_and_the_camera(exported):
    model, _, out = exported
    _, extras = read_with_trimesh(out / FILE)
    assert extras["format"] == FORMAT == "vlights.fit.gltf" and VERSION == 8
    assert extras["version"] == UNTEXTURED_VERSION == 2  # no textured object, no environment: the version before them
    assert "environment" not in extras
    assert extras["objects"] == list(model.names)
    assert extras["emitters"] == [] and extras["emitter_table"] == [] and extras["emitter_nodes"] == 8
    assert extras["camera"] == {"eye": [0.5, 0.25, -6.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
                                "fov_y_deg": 40.0}


def test_a_camera_along_x_keeps_its_axis_in_the_extras(tmp_path, cli, rng):
    camera = dataclasses.replace(CAMERA, fov_deg=70.0, fov_axis="x", width=1280, height=720)
    lit_model(True, rng, camera=camera).save(tmp_path / "fit.npz")
    assert cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")[0] == 0
    extras = glb_header(tmp_path / "web" / FILE)["scenes"][0]["extras"]["camera"]
    assert extras == camera.to_dict() and extras["fov_axis"] == "x" and extras["film"] == [1280, 720]
    assert extras["fov_y_deg"] == camera.fov_y_deg  # what a page that knows no axis draws
    assert load_export(tmp_path / "web" / FILE).camera == camera


def test_a_fit_without_a_camera_has_none_in_the_extras(tmp_path, cli, rng):
    lit_model(True, rng, camera=None).save(tmp_path / "fit.npz")
    assert cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")[0] == 0
    assert "camera" not in glb_header(tmp_path / "web" / FILE)["scenes"][0]["extras"]
    assert load_export(tmp_path / "web" / FILE).camera is None


# ------------------------------------------------------------------------------ version 3 fits

@pytest.fixture(params=["per-light", "shared"])
def exported_v3(request, tmp_path_factory, cli, rng):
    """(the model, fit.npz, DIR) of ``glossy_model`` after ``vlights export``."""
    base = tmp_path_factory.mktemp(f"export-v3-{request.param}")
    glossy_model(request.param == "per-light", rng).save(base / "fit.npz")
    code, out, err = cli("export", base / "fit.npz", "-o", base / "web")
    assert code == 0 and err == "", (code, out, err)
    assert "4 emitter parts highlighted on 2 objects, 2 reflection probes" in out
    return load_fit(base / "fit.npz"), base / "fit.npz", base / "web"


def bits_equal(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def test_a_version_3_fit_round_trips(exported_v3, rng):
    """load_export gives the fit back: every array bit for bit (visibility, probe texels
    and weights among them), the highlight's and the probe's numbers exactly, the same
    emitter parts; and ``shade`` (whole, and each part alone) equal to the fit's."""
    model, _, out = exported_v3
    back = load_export(out / FILE)
    assert back.names == model.names and back.camera.to_dict() == model.camera.to_dict()
    assert [p.to_dict() for p in back.emitters] == [p.to_dict() for p in model.emitters] == [p.to_dict() for p in LAMPS]
    assert back.emitter_nodes == model.emitter_nodes == 8
    for a, b in zip(model.objects, back.objects, strict=True):
        assert a.arrays().keys() == b.arrays().keys() >= {"visibility", "probe", "probe_weight"}
        for key, want in a.arrays().items():
            assert bits_equal(b.arrays()[key], want), f"{a.name}/{key}"
        ha, hb = a.highlight, b.highlight
        assert hb.parts is back.emitters and hb.nodes == ha.nodes
        assert bits_equal(hb.ks, ha.ks) and hb.exponent == ha.exponent
        assert (ha.fresnel is None) == (hb.fresnel is None)
        assert ha.fresnel is None or bits_equal(hb.fresnel, ha.fresnel)
        for key in ("texels", "centre", "box", "albedo"):
            assert bits_equal(getattr(b.probe, key), getattr(a.probe, key)), f"{a.name}/probe {key}"
        assert bits_equal(b.probe_weight, a.probe_weight)
        w = rng.normal(size=(len(a.positions), 5, 3))
        w /= np.linalg.norm(w, axis=-1, keepdims=True)
        for parts in (PARTS, *((p,) for p in PARTS)):
            assert np.array_equal(b.shade(w, parts=parts), a.shade(w, parts=parts)), (a.name, parts)
        assert not np.array_equal(a.shade(w), a.shade(w, parts=("lights",)))  # the probe and emitters do contribute


def test_a_version_3_fit_in_the_gltf(exported_v3):
    """The schema, read with trimesh alone: _PROBE and _VISIBILITY_j (three parts each,
    padded with 0), the highlight and the probe in the mesh's extras, the emitter parts
    and their table (display.glsl.emitter_table, float32 bits) in the scene's."""
    from display.glsl import TABLE_WIDTH, emitter_table

    model, _, out = exported_v3
    meshes, extras = read_with_trimesh(out / FILE)
    p = len(LAMPS)
    assert extras["version"] == 2 and extras["emitter_nodes"] == 8
    assert extras["emitters"] == [part.to_dict() for part in LAMPS]
    table = np.asarray(extras["emitter_table"], np.float32)
    assert table.shape == (p, TABLE_WIDTH * 4)
    assert bits_equal(table.reshape(p, TABLE_WIDTH, 4), emitter_table(LAMPS)[:p])
    for obj in model.objects:
        mesh, info = meshes[obj.name]
        attributes = mesh.vertex_attributes
        v = len(obj.positions)
        assert sorted(a for a in attributes if a.startswith(("_PROBE", "_VISIBILITY"))) == [
            "_PROBE", "_VISIBILITY_0", "_VISIBILITY_1"]
        visibility = np.concatenate([np.asarray(attributes[f"_VISIBILITY_{j}"]) for j in range(2)], axis=1)
        assert visibility.dtype == np.float32 and visibility.shape == (v, 6)
        assert bits_equal(visibility[:, :p], obj.highlight.visibility) and not visibility[:, p:].any()
        assert bits_equal(np.asarray(attributes["_PROBE"]), obj.probe_weight)
        fresnel = {} if obj.highlight.fresnel is None else {"fresnel": obj.highlight.fresnel.tolist()}
        assert info["highlight"] == {"ks": obj.highlight.ks.tolist(), "exponent": obj.highlight.exponent, **fresnel}
        probe = info["probe"]
        assert probe.keys() == {"size", "centre", "box", "albedo", "texels"}
        assert probe["size"] == obj.probe.size and probe["centre"] == obj.probe.centre.tolist()
        assert probe["box"] == obj.probe.box.tolist() and probe["albedo"] == obj.probe.albedo.tolist()
        assert bits_equal(np.asarray(probe["texels"], np.float32), obj.probe.texels.reshape(-1))


def test_visibility_of_many_parts_packs_three_to_an_attribute(tmp_path, rng):
    """Seven parts: _VISIBILITY_0 .. _2, the last with one part and two zeros; read back exact."""
    model = glossy_model(True, rng)
    lamps = tuple(EmitterPart("sphere", [[0.2 * i - 0.6, 0.1, -1.2]], 0.05, [5.0, 5.0, 5.0], f"lamp{i}")
                  for i in range(7))
    objects = tuple(dataclasses.replace(o, highlight=Highlight(
        lamps, 8, o.highlight.ks, o.highlight.exponent, rng.uniform(0, 1, (len(o.positions), 7)).astype(np.float32)))
        for o in model.objects)
    model = dataclasses.replace(model, objects=objects, emitters=lamps)
    (tmp_path / FILE).write_bytes(export_glb(model))
    meshes, _ = read_with_trimesh(tmp_path / FILE)
    for obj in model.objects:
        attributes = meshes[obj.name][0].vertex_attributes
        assert sorted(a for a in attributes if a.startswith("_VISIBILITY")) == [f"_VISIBILITY_{j}" for j in range(3)]
        assert not np.asarray(attributes["_VISIBILITY_2"])[:, 1:].any()
    back = load_export(tmp_path / FILE)
    for a, b in zip(model.objects, back.objects, strict=True):
        assert bits_equal(b.highlight.visibility, a.highlight.visibility)


def own_parts_model(rng, count=40):
    """``glossy_model`` whose scene has ``count`` small sphere lamps (more than the 31 one
    object may draw) and each object names its own 16 of them (a version 6 fit): the
    wall the first 16, the tile every other one from the 9th."""
    model = glossy_model(True, rng)
    lamps = tuple(EmitterPart("sphere", [[0.23 * (i % 8) - 0.8, 0.3 * (i // 8) - 0.6, -1.2]], 0.08,
                              [25.0, 20.0 + 0.2 * i, 15.0], f"lamp{i}") for i in range(count))  # an 8 x 5 grid
    chosen = (tuple(range(16)), tuple(range(8, 40, 2)))
    objects = tuple(dataclasses.replace(o, highlight=Highlight(
        tuple(lamps[i] for i in own), 8, o.highlight.ks, o.highlight.exponent,
        rng.uniform(0, 1, (len(o.positions), len(own))).astype(np.float32), o.highlight.fresnel, own))
        for o, own in zip(model.objects, chosen, strict=True))
    return dataclasses.replace(model, objects=objects, emitters=lamps)


def test_objects_own_parts_make_a_version_6_file_that_round_trips(tmp_path, rng):
    """40 emitter parts, each object drawing its own 16: version 6 (the lowest that holds
    them), the scene's 40 entries and table rows, each mesh's ``highlight.parts``, its
    visibility of its own parts; load_export gives the fit back, shading the same, and
    fit.npz (version 6) too. Said to be version 5, the file is refused in one line."""
    model = own_parts_model(rng)
    assert model.version == 6
    path = tmp_path / FILE
    path.write_bytes(export_glb(model))
    meshes, extras = read_with_trimesh(path)
    assert extras["version"] == OWN_PARTS_VERSION == 6 and len(extras["emitters"]) == len(extras["emitter_table"]) == 40
    for obj in model.objects:
        assert meshes[obj.name][1]["highlight"]["parts"] == list(obj.highlight.indices)
    back = load_export(path)
    model.save(tmp_path / "fit.npz")
    again = load_fit(tmp_path / "fit.npz")
    w = rng.normal(size=(len(model.objects[1].positions), 4, 3))
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    for a, b, c in zip(model.objects, back.objects, again.objects, strict=True):
        assert b.highlight.indices == c.highlight.indices == a.highlight.indices
        assert bits_equal(b.highlight.visibility, a.highlight.visibility)
        ww = w if len(a.positions) == len(w) else w[:len(a.positions)]
        assert np.array_equal(b.shade(ww), a.shade(ww)) and np.array_equal(c.shade(ww), a.shade(ww))
    rewrite_json(path, lambda header: header["scenes"][0]["extras"].update(version=5))
    with pytest.raises(InputError, match="has 40 parts; a file holds at most 31"):
        load_export(path)
    path.write_bytes(export_glb(model))  # a mesh naming a part the scene does not have: one line
    rewrite_json(path, lambda header: header["meshes"][0]["extras"]["highlight"].update(parts=[0, 99]))
    with pytest.raises(InputError, match="must name at most 31 distinct parts of the scene's 40") as info:
        load_export(path)
    assert "\n" not in str(info.value)


def test_a_highlight_of_other_parts_is_refused(rng):
    """The file holds one list of emitter parts: a highlight of others cannot be written."""
    model = glossy_model(True, rng)
    with pytest.raises(ValueError, match="not the model's"):
        export_glb(dataclasses.replace(model, emitters=LAMPS[:1]))
    with pytest.raises(ValueError, match="not the model's"):
        export_glb(dataclasses.replace(model, emitter_nodes=4))


def rewrite_json(path, edit):
    """Rewrite the JSON chunk of the .glb at ``path`` with ``edit(header)`` (in place)."""
    data = Path(path).read_bytes()
    length = int.from_bytes(data[12:16], "little")
    header = json.loads(data[20:20 + length])
    edit(header)
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    rest = data[20 + length:]
    body = len(text).to_bytes(4, "little") + b"JSON" + text + rest
    Path(path).write_bytes(data[:8] + (12 + len(body)).to_bytes(4, "little") + body)


def test_version_1_files_are_still_read(tmp_path, rng):
    """A version 1 file (no emitters, no probes: what export wrote before) loads as before;
    a version it does not know is refused in one line."""
    model = lit_model(True, rng)
    path = tmp_path / FILE
    path.write_bytes(export_glb(model))

    def to_version_1(header):
        extras = header["scenes"][0]["extras"]
        extras["version"] = 1
        for key in ("emitters", "emitter_nodes", "emitter_table"):
            del extras[key]

    rewrite_json(path, to_version_1)
    assert READS == (1, 2, 3, 4, 5, 6, 7, 8)
    back = load_export(path)
    assert back.names == model.names and back.emitters == ()
    for a, b in zip(model.objects, back.objects, strict=True):
        assert b.highlight is None and b.probe is None
        for key, want in a.arrays().items():
            assert bits_equal(b.arrays()[key], want), f"{a.name}/{key}"
    rewrite_json(path, lambda header: header["scenes"][0]["extras"].update(version=9))
    with pytest.raises(InputError, match="is not a vlights.fit.gltf version 1, 2, 3, 4, 5, 6, 7 or 8 file"):
        load_export(path)


def test_microfacet_lobes_make_a_version_7_file_that_round_trips(tmp_path, rng):
    """A highlight with a microfacet lobe: version 7, its extras holding the model and the
    lobe the page draws (highlight_lobe's numbers), load_export giving the fit back,
    shading the same; the table of transformed cosines in shading.js is the renderer's."""
    import base64
    import re

    from display.export import shading_module
    from radiosity.physics.ltc import highlight_lobe, table_texture

    model = microfacet_model(rng)
    path = tmp_path / FILE
    path.write_bytes(export_glb(model))
    meshes, extras = read_with_trimesh(path)
    assert extras["version"] == 7
    wall = meshes[model.objects[0].name][1]["highlight"]
    lobe = highlight_lobe(GOLD)
    assert wall["microfacet"] == GOLD.to_dict()
    assert wall["lobe"] == {"code": 1, "alpha": 0.15, "ks": lobe.ks.tolist(), "f0": lobe.f0.tolist()}
    assert meshes[model.objects[1].name][1]["highlight"]["lobe"]["code"] == 2
    back = load_export(path)
    assert [o.highlight.microfacet for o in back.objects] == [GOLD, SATIN]
    w = rng.normal(size=(len(model.objects[1].positions), 4, 3))
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    for a, b in zip(model.objects, back.objects, strict=True):
        ww = w if len(a.positions) == len(w) else w[:len(a.positions)]
        assert np.array_equal(b.shade(ww), a.shade(ww))
    text = shading_module()
    size = int(re.search(r"LTC_SIZE = (\d+);", text).group(1))
    data = np.frombuffer(base64.b64decode(re.search(r"LTC_TABLE = '([^']+)';", text).group(1)), "<f4")
    assert np.array_equal(data.reshape(2 * size, 2 * size, 4), table_texture())
    rewrite_json(path, lambda header: header["meshes"][0]["extras"]["highlight"]["microfacet"].update(alpha=-1))
    with pytest.raises(InputError, match="alpha"):
        load_export(path)


def test_delta_parts_make_a_version_5_file_that_round_trips(tmp_path, rng):
    """A point, a spot and a direction among the emitter parts: version 5 (the lowest
    that holds them), their entries and table rows as display.glsl lays them out, and
    load_export gives the fit back, shading the same; the same file said to be version 4
    is refused (a version 4 file holds no delta part); without them, version 2 still."""
    from display.glsl import TABLE_WIDTH, emitter_table

    lamps = LAMPS[:2] + DELTA_LAMPS
    model = glossy_model(True, rng, lamps=lamps)
    path = tmp_path / FILE
    path.write_bytes(export_glb(model))
    _, extras = read_with_trimesh(path)
    assert extras["version"] == DELTA_VERSION == 5
    assert extras["emitters"] == [part.to_dict() for part in lamps]
    assert extras["emitters"][3]["spot"] == {"axis": list(DELTA_LAMPS[1].spot.axis), "cutoff_deg": 16.0, "beam_deg": 9.0}
    table = np.asarray(extras["emitter_table"], np.float32).reshape(len(lamps), TABLE_WIDTH, 4)
    assert bits_equal(table, emitter_table(lamps)[:len(lamps)])
    assert table[2:, 0, 0].tolist() == [2, 2, 3]  # point, point, direction
    assert table[3, 5, :3].tolist() == pytest.approx([np.radians(16), np.radians(9), 1.0])  # the spot's angles
    back = load_export(path)
    assert [p.to_dict() for p in back.emitters] == [p.to_dict() for p in lamps]
    w = rng.normal(size=(len(model.objects[1].positions), 4, 3))
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    for a, b in zip(model.objects, back.objects, strict=True):
        ww = w if len(a.positions) == len(w) else w[:len(a.positions)]
        assert np.array_equal(b.shade(ww), a.shade(ww))
    rewrite_json(path, lambda header: header["scenes"][0]["extras"].update(version=4))
    with pytest.raises(InputError, match="kind 'point' is not one of sphere, polygon"):
        load_export(path)
    path.write_bytes(export_glb(glossy_model(True, rng)))
    assert read_with_trimesh(path)[1]["version"] == UNTEXTURED_VERSION == 2


def test_a_probe_without_its_weight_is_refused(tmp_path, rng):
    path = tmp_path / FILE
    path.write_bytes(export_glb(glossy_model(False, rng)))
    rewrite_json(path, lambda header: header["meshes"][1]["extras"]["probe"].pop("texels"))
    with pytest.raises(InputError, match="object 'tile' 'probe' needs"):
        load_export(path)


def validator_path():
    """The npm package gltf-validator (2.0.0-dev.3.10): $VLIGHTS_GLTF_VALIDATOR (its
    directory), else /tmp/gltfv/node_modules/gltf-validator (``cd /tmp/gltfv && npm
    install gltf-validator``); None when absent."""
    path = Path(os.environ.get("VLIGHTS_GLTF_VALIDATOR", "/tmp/gltfv/node_modules/gltf-validator"))
    return path if (path / "package.json").is_file() else None


VALIDATE_JS = """
const fs = require("fs");
const validator = require(process.argv[1]);
validator.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2])), {maxIssues: 0})
  .then((report) => console.log(JSON.stringify(report)))
  .catch((error) => { console.error(String(error)); process.exit(1); });
"""


def test_the_khronos_validator_finds_no_errors(exported):
    validate(exported[2] / FILE)


def test_the_khronos_validator_finds_no_errors_in_a_version_3_export(exported_v3):
    validate(exported_v3[2] / FILE)


def validate(path):
    """The Khronos validator's report of the .glb ``path``: no errors, no warnings."""
    node, package = shutil.which("node"), validator_path()
    if node is None or package is None:
        pytest.skip("node or the npm package gltf-validator is not installed (see validator_path)")
    run = subprocess.run([node, "-e", VALIDATE_JS, str(package.resolve()), str(path)],
                         capture_output=True, text=True, timeout=120, check=False)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    issues = report["issues"]
    errors = [m for m in issues["messages"] if m["severity"] == 0]
    assert issues["numErrors"] == 0, errors
    assert issues["numWarnings"] == 0, [m for m in issues["messages"] if m["severity"] == 1]
    assert report["mimeType"] == "model/gltf-binary"


@pytest.fixture
def a_fit(tmp_path, rng):
    path = tmp_path / "fit.npz"
    lit_model(True, rng).save(path)
    return path


def test_bad_inputs_are_refused_in_one_line(a_fit, tiny_pair, tmp_path, cli, no_gl):
    _, solution = tiny_pair
    before = listing(tmp_path)
    assert_refused(cli("export", solution, "-o", tmp_path / "web"), "is a solution.npz, not a fit.npz", command="export")
    assert_refused(cli("export", tmp_path / "nothing.npz", "-o", tmp_path / "web"), "not found", command="export")
    assert_refused(cli("export", tmp_path, "-o", tmp_path / "web"), "is a directory", command="export")
    (tmp_path / "notes.txt").write_text("x")
    assert_refused(cli("export", tmp_path / "notes.txt", "-o", tmp_path / "web"), "is not a fit.npz", command="export")
    assert listing(tmp_path) == sorted([*before, "notes.txt"])


def test_unusable_outputs_are_refused_before_any_work(a_fit, tmp_path, cli, no_gl, monkeypatch):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "web" / FILE).mkdir(parents=True)
    (tmp_path / "ro").mkdir()
    real = os.access

    def access(path, mode, *args, **kwargs):  # we may run as root, for whom chmod does not bite
        if os.path.abspath(os.fspath(path)) == str(tmp_path / "ro") and mode & os.W_OK:
            return False
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    before = listing(tmp_path)
    cases = [
        (tmp_path / "afile", "exists and is not a directory"),
        (tmp_path / "afile" / "web", "is a file, not a directory"),
        (tmp_path / "nowhere" / "web", "does not exist"),
        (tmp_path / "ro", "permission denied"),
        (tmp_path / "ro" / "web", "permission denied"),
        (tmp_path / "web", "is not a file"),
    ]
    for out, fragment in cases:
        assert_refused(cli("export", a_fit, "-o", out), "-o", fragment, command="export")
    assert listing(tmp_path) == before


def test_a_failed_write_leaves_no_file(a_fit, tmp_path, cli, monkeypatch):
    import display.outputs

    (tmp_path / "old").mkdir()
    (tmp_path / "old" / FILE).write_bytes(b"the old file")

    def full_disk(*_args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(display.outputs.os, "replace", full_disk)
    assert_refused(cli("export", a_fit, "-o", tmp_path / "new"), "No space left on device", command="export")
    assert not (tmp_path / "new").exists()
    assert_refused(cli("export", a_fit, "-o", tmp_path / "old"), "No space left on device", command="export")
    assert listing(tmp_path / "old") == [FILE]
    assert (tmp_path / "old" / FILE).read_bytes() == b"the old file"


def test_help_names_the_attributes_and_no_design_document(cli):
    code, out, _ = cli("export", "--help")
    assert code == 0
    for word in ("fit.npz", "scene.glb", "_EMITTED", "_SPECULAR_0", "_PROBE", "_VISIBILITY_0", "TEXCOORD_0",
                 "_IRRADIANCE"):
        assert word in out
    assert not OUTSIDE.search(out), out


def test_every_object_is_a_root_node_whatever_its_name(tmp_path, rng):
    """trimesh's default root frame is called "world": an object of that name must not
    become the parent of the others."""
    import dataclasses

    from display.export import write_export

    model = lit_model(True, rng)
    renamed = tuple(dataclasses.replace(o, name=n) for o, n in zip(model.objects, ["world", "GLTF"], strict=True))
    path = write_export(FittedModel(objects=renamed), tmp_path / "web")
    header = glb_header(path)
    assert [n["name"] for n in header["nodes"]] == ["world", "GLTF"]
    assert header["scenes"][0]["nodes"] == [0, 1] and all("children" not in n for n in header["nodes"])
    assert load_export(path).names == ("world", "GLTF")
