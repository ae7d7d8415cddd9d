"""fit.npz's reader and writer (``load_fit``, ``FittedModel.save``) and ``shade``'s shapes."""

import json

import numpy as np
import pytest
from refusals import input_error

from fitting import FittedModel, FittedObject, load_fit, shade
from fitting.model import directional
from radiosity.files.camera import Camera

NAME = "ball"


def model(rng, n_vertices=5, lights=2, camera=None, info=None):
    positions = rng.normal(size=(n_vertices, 3))
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    dirs = rng.normal(size=(lights, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    obj = FittedObject(
        name=NAME, positions=positions.astype(np.float32), normals=normals.astype(np.float32),
        faces=np.array([[0, 1, 2], [2, 3, 4]], np.int32)[: max(1, n_vertices - 3)],
        emitted=rng.uniform(0, 1, (n_vertices, 3)).astype(np.float32),
        specular=rng.uniform(0, 1, (n_vertices, 3)).astype(np.float32),
        light_pos=directional(dirs).astype(np.float32), light_rgb=rng.uniform(0, 2, (lights, 3)).astype(np.float32),
        shininess=np.full(lights, 30.0, np.float32), info=info or {"method": "paper", "error": {"relative_rms": 0.1}},
    )
    return FittedModel(objects=(obj,), source="scene.toml", model="test", settings={"lights": lights}, camera=camera)


@pytest.fixture
def good_file(rng, tmp_path):
    path = tmp_path / "fit.npz"
    model(rng).save(path)
    return path


def rewrite(path, meta=None, arrays=None, drop=()):
    """The file at ``path`` rewritten with numpy.savez: ``meta(dict)`` edits the meta in
    place, ``arrays`` replaces arrays by key, ``drop`` removes keys."""
    with np.load(path, allow_pickle=False) as npz:
        content = {k: npz[k] for k in npz.files}
    data = json.loads(str(content["meta"]))
    if meta is not None:
        meta(data)
    content["meta"] = np.array(json.dumps(data))
    content.update(arrays or {})
    for key in drop:
        del content[key]
    np.savez(path, **content)
    return path


def refused(path, *words):
    return input_error(lambda: load_fit(path), *words, names=str(path))


def test_round_trip_keeps_everything(rng, tmp_path):
    camera = Camera(eye=(1, 2, 3), look_at=(0, 0, 0), fov_deg=50.0)
    m = model(rng, camera=camera)
    m.save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    a, b = m.object(NAME), back.object(NAME)
    for key in ("positions", "normals", "faces", "emitted", "specular", "light_pos", "light_rgb", "shininess"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert b.info == a.info and back.settings == m.settings and back.source == m.source and back.model == m.model
    assert back.camera.eye == camera.eye and back.camera.fov_y_deg == camera.fov_y_deg
    assert load_fit(rewrite(tmp_path / "fit.npz", meta=lambda d: d.pop("camera"))).camera is None


def test_a_camera_along_x_keeps_its_axis(rng, tmp_path):
    camera = Camera(eye=(1, 2, 3), look_at=(0, 0, 0), fov_deg=70.0, width=1280, height=720, fov_axis="x")
    model(rng, camera=camera).save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    assert back.camera == camera and back.camera.sized(512, 512).fov_y_deg == pytest.approx(70.0, rel=1e-12)
    with np.load(tmp_path / "fit.npz", allow_pickle=False) as npz:
        record = json.loads(str(npz["meta"]))["camera"]
    assert record["fov_y_deg"] == camera.fov_y_deg and record["fov_axis"] == "x" and record["film"] == [1280, 720]
    bad = rewrite(tmp_path / "fit.npz", meta=lambda d: d["camera"].update(fov_axis="sideways"))
    refused(bad, "meta 'camera'", "fov axis must be one of")


def test_save_refuses_nan_in_meta_and_writes_nothing(rng, tmp_path):
    m = model(rng, info={"error": {"relative_rms": float("nan")}})
    with pytest.raises(ValueError):
        m.save(tmp_path / "fit.npz")
    assert list(tmp_path.iterdir()) == []


def _set(key, value):
    def edit(meta):
        meta[key] = value

    return edit


def _set_info(value):
    def edit(meta):
        meta["objects"][NAME] = value

    return edit


META_CASES = {
    "objects not a dict": (_set("objects", [NAME]), ["meta 'objects'", "a list"]),
    "objects missing": (lambda d: d.pop("objects"), ["meta 'objects'", "null"]),
    "info not a dict": (_set_info(3), [f"object {NAME!r}", "a number"]),
    "settings not a dict": (_set("settings", [1, 2]), ["meta 'settings'", "a list"]),
    "source not a string": (_set("source", 5), ["meta 'source'", "a number"]),
    "model not a string": (_set("model", None), ["meta 'model'", "null"]),
    "zero objects": (_set("objects", {}), ["meta 'objects' is empty"]),
    "lights miscounted": (_set_info({"lights": 3}), [f"object {NAME!r}", "3 lights", "hold 2"]),
    "bad camera": (_set("camera", {"eye": [0, 0, 0]}), ["meta 'camera'", "look_at"]),
    "wrong version": (_set("version", 11), ["version 11"]),
    "wrong format": (_set("format", "vlights.solution"), ["format 'vlights.solution'"]),
}


@pytest.mark.parametrize("case", sorted(META_CASES))
def test_bad_meta_is_refused(case, good_file):
    edit, words = META_CASES[case]
    refused(rewrite(good_file, meta=edit), *words)


V, K = 5, 2
ARRAY_CASES = {
    "strings": ("emitted", np.array([["a", "b", "c"]] * V), "dtype <U1"),
    "booleans": ("light_rgb", np.ones((K, 3), bool), "dtype bool"),
    "object array": ("specular", np.array([[1, 2, None]] * V, dtype=object), "cannot read"),
    "float faces": ("faces", np.array([[0.0, 1.0, 2.0]]), "expected integers"),
    "no faces": ("faces", np.zeros((0, 3), np.int32), "no faces"),
    "face index out of range": ("faces", np.array([[0, 1, V]], np.int32), f"outside [0, {V})"),
    "negative face index": ("faces", np.array([[0, -1, 2]], np.int32), "from -1"),
    "negative shininess": ("shininess", np.array([30.0, -1.0], np.float32), "negative exponent"),
    "NaN": ("emitted", np.full((V, 3), np.nan, np.float32), "NaN or infinite"),
    "infinity": ("light_rgb", np.array([[1, 1, np.inf], [1, 1, 1]], np.float32), "NaN or infinite"),
    "NaN light direction": ("light_pos", np.array([[0, 0, 1, 0], [0, np.nan, 1, 0]], np.float32), "NaN or infinite"),
    "w neither 0 nor 1": ("light_pos", np.array([[0, 0, 1, 0], [0, 0, 1, 0.5]], np.float32), "w = 0.5"),
    "negative coefficient": ("specular", -np.ones((V, 3), np.float32), "must not be negative"),
    "per-light coefficients of other lights": ("specular", np.ones((V, K + 1, 3), np.float32), "expected (5, 3) or (5, 2, 3)"),
    "wrong width": ("specular", np.ones((V, 2), np.float32), "expected (5, 3)"),
    "wrong vertex count": ("normals", np.ones((V + 1, 3), np.float32), "expected (5, 3)"),
    "too many exponents": ("shininess", np.ones(K + 1, np.float32), "expected (2"),
    "colours of other lights": ("light_rgb", np.ones((K + 1, 3), np.float32), "expected (2, 3)"),
    "exponents as a matrix": ("shininess", np.ones((K, 1), np.float32), "expected (2"),
    "positions flat": ("positions", np.ones(3 * V, np.float32), "expected (N, 3)"),
    "light directions not unit": ("light_pos", np.array([[0, 0, 2, 0], [0, 0, 1, 0]], np.float32), "unit vectors"),
}


@pytest.mark.parametrize("case", sorted(ARRAY_CASES))
def test_bad_arrays_are_refused(case, good_file):
    key, value, words = ARRAY_CASES[case]
    refused(rewrite(good_file, arrays={f"{NAME}/{key}": value}), f"'{NAME}/{key}'", words)


def test_a_missing_array_is_refused(good_file):
    refused(rewrite(good_file, drop=[f"{NAME}/normals"]), f"'{NAME}/normals'", "no")


def test_not_a_fit_file_is_refused(tmp_path):
    (tmp_path / "empty.npz").write_bytes(b"")
    refused(tmp_path / "empty.npz", "empty file")
    refused(tmp_path / "absent.npz", "not found")
    np.savez(tmp_path / "no_meta.npz", x=np.zeros(3))
    refused(tmp_path / "no_meta.npz", "no 'meta'")


# ---------------------------------------------------------------------------
# shade's shapes


@pytest.fixture
def hundred(rng):
    return model(rng, n_vertices=100, lights=3)


def unit(rng, *shape):
    w = rng.normal(size=shape + (3,))
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def test_shade_takes_one_or_m_directions_per_vertex(hundred, rng):
    w = unit(rng, 100, 4)
    many = shade(hundred, NAME, w)
    assert many.shape == (100, 4, 3) and many.dtype == np.float64
    for m in range(4):
        assert np.allclose(shade(hundred, NAME, w[:, m]), many[:, m], rtol=1e-15, atol=0)
    assert shade(hundred, NAME, w[:, 0]).shape == (100, 3)
    # a selection of vertices: the directions are per selected vertex
    picked = np.array([3, 50, 99])
    assert np.array_equal(shade(hundred, NAME, w[picked, 0], vertices=picked), shade(hundred, NAME, w[:, 0])[picked])
    mask = np.zeros(100, bool)
    mask[10:20] = True
    assert np.array_equal(shade(hundred, NAME, w[mask], vertices=mask), many[mask])
    assert np.array_equal(shade(hundred, NAME, w[:5, 1], vertices=slice(0, 5)), many[:5, 1])


@pytest.mark.parametrize("shape", [(2, 3), (3,), (100,), (100, 2), (100, 4, 2), (1, 100, 3), (100, 1, 1, 3), (99, 3)])
def test_shade_refuses_shapes_that_do_not_fit(hundred, shape):
    with pytest.raises(ValueError) as info:
        shade(hundred, NAME, np.ones(shape))
    message = str(info.value)
    assert "\n" not in message
    assert "(100, 3)" in message and "(100, M, 3)" in message and f"got shape {shape}" in message


def test_shade_refuses_a_single_vertex_index(hundred):
    with pytest.raises(ValueError, match="vertices"):
        shade(hundred, NAME, np.ones((1, 3)), vertices=3)


def test_a_fit_with_delta_parts_is_version_5_and_an_older_one_holding_them_is_refused(rng, tmp_path):
    """A point light's and a direction's highlights: the file is version 5 (the lowest
    that holds them), reads back shading the same; said to be version 4, refused."""
    import dataclasses

    from fitting.model import Highlight
    from radiosity.physics.emitters import EmitterPart, SpotProfile

    lamps = (EmitterPart("point", [[0.0, 3.0, 0.0]], 0.0, [5.0, 4.0, 3.0], "torch", SpotProfile([0, -1, 0], 40, 30)),
             EmitterPart("direction", [[0.2, -1.0, 0.1]], 0.0, [1.0, 1.0, 1.0], "sun"))
    m = model(rng)
    obj = m.object(NAME)
    highlight = Highlight(lamps, 8, np.array([0.4, 0.4, 0.4]), 20.0, np.ones((len(obj.positions), 2), np.float32))
    m = dataclasses.replace(m, objects=(dataclasses.replace(obj, highlight=highlight),), emitters=lamps)
    assert m.version == 5 and model(rng).version == 3
    m.save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    assert [p.to_dict() for p in back.emitters] == [p.to_dict() for p in lamps]
    n = obj.normals.astype(np.float64)
    toward = -lamps[1].points[0]
    w = 2 * (n @ toward)[:, None] * n - toward  # each vertex seen where it mirrors the sun
    assert np.array_equal(back.object(NAME).shade(w), m.object(NAME).shade(w))
    assert np.abs(back.object(NAME).shade(w, parts=("emitters",)) - back.object(NAME).shade(w, parts=())).max() > 0.1
    refused(rewrite(tmp_path / "fit.npz", meta=_set("version", 4)), "kind 'point' is not one of sphere, polygon")
