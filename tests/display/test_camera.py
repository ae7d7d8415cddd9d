"""The display's cameras keep a scene camera's field of view along its axis: the camera
the flags ask for at any --size, a named view, the orbits of figure 5 and the video's
path. No OpenGL."""

import argparse
import json

import pytest

from display.camera import resolve_camera
from display.commands.common import add_camera_flags
from display.compare import orbit
from display.video import walkthrough_path
from radiosity.files.camera import Camera, fov_y_deg
from radiosity.files.errors import InputError

SCENE = Camera((6.9, 1.65, 2.55), (6.0, 1.65, 2.12), (0.0, 1.0, 0.0), 70.0, 1280, 720, "x")  # fov 70 along x
BOUNDS = [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]


def flags(*argv):
    parser = argparse.ArgumentParser()
    add_camera_flags(parser, (512, 512))
    return parser.parse_args([str(a) for a in argv])


@pytest.mark.parametrize("size", [(1280, 720), (1024, 1024), (1920, 600), (600, 1000)])
def test_the_scene_camera_at_any_size_keeps_its_fov_along_x(size):
    camera = resolve_camera(flags("--size", f"{size[0]}x{size[1]}"), BOUNDS, SCENE)
    assert (camera.width, camera.height, camera.fov_deg, camera.fov_axis) == (*size, 70.0, "x")
    assert camera.fov_y_deg == pytest.approx(fov_y_deg(70.0, "x", *size), rel=1e-15)
    moved = resolve_camera(flags("--size", f"{size[0]}x{size[1]}", "--eye", 0, 0, 5), BOUNDS, SCENE)
    assert moved.eye == (0.0, 0.0, 5.0) and moved.fov_axis == "x"  # another pose, the scene's fov


def test_fov_is_vertical_unless_fov_axis_says():
    vertical = resolve_camera(flags("--size", "400x200", "--fov", 50), BOUNDS, SCENE)
    assert vertical.fov_axis == "y" and vertical.fov_y_deg == 50.0
    across = resolve_camera(flags("--size", "400x200", "--fov", 50, "--fov-axis", "x"), BOUNDS, SCENE)
    assert across.fov_axis == "x" and across.fov_y_deg == pytest.approx(fov_y_deg(50.0, "x", 400, 200))
    with pytest.raises(InputError, match="--fov-axis x says which extent of the image --fov spans; give --fov DEG"):
        resolve_camera(flags("--fov-axis", "x"), BOUNDS, SCENE)


def test_a_named_view_may_give_its_fov_along_an_axis(tmp_path):
    views = tmp_path / "views.json"
    views.write_text(json.dumps({"wide": {"eye": [0, 0, -5], "look_at": [0, 0, 0], "fov_deg": 80, "fov_axis": "x"}}))
    camera = resolve_camera(flags("--size", "300x500", "--view", "wide", "--views", views), BOUNDS)
    assert (camera.fov_deg, camera.fov_axis, camera.width, camera.height) == (80.0, "x", 300, 500)


def test_orbits_and_the_video_path_keep_the_fov_and_its_axis():
    view = SCENE.sized(64, 64)
    for other in (orbit(view, 35.0), *walkthrough_path(view, 5)):
        assert (other.fov_deg, other.fov_axis, other.width, other.height) == (70.0, "x", 64, 64)
    assert orbit(view, 35.0).eye != view.eye
