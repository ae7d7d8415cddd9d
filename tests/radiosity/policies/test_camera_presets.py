"""The one camera type and the one preset table."""

import dataclasses

import numpy as np
import pytest

from radiosity.files.camera import Camera, camera_from_dict
from radiosity.files.errors import InputError
from radiosity.physics.directions import QUALITY_FACTORS, grid_size
from radiosity.policies import presets


def test_camera_validates_once_for_every_source():
    cam = Camera((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, 64, 32)
    right, up, forward = cam.basis
    np.testing.assert_allclose(forward, [0, 0, -1])
    np.testing.assert_allclose(right, [1, 0, 0])  # cross(forward, up)
    assert cam.sized(10, 20).width == 10 and cam.to_dict()["fov_y_deg"] == 45.0
    bad = [
        dict(eye=(0, 0, 0), look_at=(0, 0, 0)),
        dict(eye=(0, 0, 1), look_at=(0, 0, 0), up=(0, 0, 1)),
        dict(eye=(0, 0, 1), look_at=(0, 0, 0), fov_deg=180),
        dict(eye=(0, 0, float("nan")), look_at=(0, 0, 0)),
        dict(eye=(0, 0, 1e300), look_at=(0, 0, 0)),
        dict(eye=(0, 0, 1), look_at=(0, 0, 0), width=0),
        dict(eye=(0, 0), look_at=(0, 0, 0)),
    ]
    for kwargs in bad:
        with pytest.raises(InputError):
            Camera(**kwargs)


def test_camera_from_a_table_names_where():
    cam = camera_from_dict({"position": [1, 2, 3], "look_at": [0, 0, 0]}, 8, 8)
    assert cam.eye == (1.0, 2.0, 3.0) and cam.fov_y_deg == 39.3
    with pytest.raises(InputError, match=r"^scene.toml: \[camera\]: look-at equals the eye$"):
        camera_from_dict({"eye": [0, 0, 0], "look_at": [0, 0, 0]}, where="scene.toml: [camera]")
    with pytest.raises(InputError, match="needs 'eye'"):
        camera_from_dict({"look_at": [0, 0, 0]})


def test_every_quality_has_every_knob_and_they_grow():
    assert presets.QUALITIES == ("draft", "medium", "high")
    draft, medium, high = (presets.PRESETS[q] for q in presets.QUALITIES)
    for field in ("photons", "gather_samples", "light_samples", "max_edge_divisor", "grid_factor", "fit_iterations"):
        assert getattr(draft, field) < getattr(medium, field) < getattr(high, field), field
    assert QUALITY_FACTORS == {q: p.grid_factor for q, p in presets.PRESETS.items()}
    assert grid_size(120, "draft") < grid_size(120, "high")
    assert "fit_iterations" in presets.preset_table()
    with pytest.raises(InputError, match="unknown quality 'best'"):
        presets.preset("best")


def test_the_solver_reads_the_table(monkeypatch):
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions

    scene = load_scene("cornell")
    monkeypatch.setitem(presets.PRESETS, "draft", dataclasses.replace(presets.PRESETS["draft"], photons=1234, max_edge_divisor=10))
    settings = SolveOptions(quality="draft").resolved(scene)
    assert settings.photons == 1234 and settings.max_edge == pytest.approx(scene.diagonal / 10)
    assert SolveOptions(quality="draft", photons=99).resolved(scene).photons == 99
