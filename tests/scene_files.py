"""Scenes for tests, written and read back: the helpers every stage's tests share."""

import json
import textwrap
import warnings

import numpy as np

from radiosity.files.errors import SceneWarning
from radiosity.scene.loaders import load_scene


def scene_from(tmp_path, text, name="scene.toml"):
    """The scene of ``text`` (a TOML scene, dedented), written to ``tmp_path / name``."""
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return load_scene(path)


def load_warned(path, load=load_scene):
    """(the scene ``load(path)`` reads, the messages of the SceneWarnings it gave)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load(path)
    return scene, [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def gltf_square(tmp_path, material, name="m.gltf", copies=1):
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
