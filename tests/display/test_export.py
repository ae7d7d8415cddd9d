"""``vlights export``: fit.npz -> DIR/scene.glb (display/export.py).

The glTF is read back with trimesh independently of ``display.export.load_export``;
every array must come back bit for bit in float32, and shading the re-read arrays with
``fitting.model.shade_arrays`` must equal shading the fit. The Khronos validator runs
where node and the npm package ``gltf-validator`` are installed (see ``validator_path``).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from display_fixtures import assert_refused, listing, lit_model

from display.export import FILE, FORMAT, VERSION, load_export
from fitting import FittedModel, load_fit
from fitting.model import shade_arrays


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
    assert extras["format"] == FORMAT == "vlights.fit.gltf" and extras["version"] == VERSION == 1
    assert extras["objects"] == list(model.names)
    assert extras["camera"] == {"eye": [0.5, 0.25, -6.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
                                "fov_y_deg": 40.0}


def test_a_fit_without_a_camera_has_none_in_the_extras(tmp_path, cli, rng):
    lit_model(True, rng, camera=None).save(tmp_path / "fit.npz")
    assert cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")[0] == 0
    assert "camera" not in glb_header(tmp_path / "web" / FILE)["scenes"][0]["extras"]
    assert load_export(tmp_path / "web" / FILE).camera is None


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
    node, package = shutil.which("node"), validator_path()
    if node is None or package is None:
        pytest.skip("node or the npm package gltf-validator is not installed (see validator_path)")
    _, _, out = exported
    run = subprocess.run([node, "-e", VALIDATE_JS, str(package.resolve()), str(out / FILE)],
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
    for word in ("fit.npz", "scene.glb", "_EMITTED", "_SPECULAR_0"):
        assert word in out
    for word in ("Contract", "DESIGN", "shared/"):
        assert word not in out


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
