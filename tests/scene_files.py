"""Scenes for tests, written and read back: the helpers every stage's tests share."""

import textwrap
import warnings

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
