"""What TOML scenes gained with the Mitsuba reader: a 4x4 transform, two-sided
surfaces, disks and cylinders, a camera as a matrix with a fov axis and a film."""

import math

import numpy as np
import pytest

from radiosity.files.camera import fov_y_deg, pose_from_matrix
from radiosity.files.errors import InputError
from radiosity.scene import builtins
from radiosity.scene.loaders import load_scene
from radiosity.scene.model import BACK_OFFSET, is_closed

HEAD = """
[materials.white]
diffuse = 0.7
"""


def scene(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(HEAD + text)
    return load_scene(path)


def test_transform_is_applied_after_scale_rotate_translate(tmp_path):
    s = scene(tmp_path, """
[[objects]]
name = "q"
builtin = "quad"
material = "white"
scale = 2
transform = [1, 0, 0, 5,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]
""")
    q = s.objects[0]
    assert np.allclose(q.positions.min(axis=0), [4, 0, -1]) and np.allclose(q.positions.max(axis=0), [6, 0, 1])


def test_a_mirroring_transform_keeps_the_front_where_the_normals_go(tmp_path):
    s = scene(tmp_path, """
[[objects]]
name = "q"
builtin = "quad"
material = "white"
transform = [[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
""")
    q = s.objects[0]
    a, b, c = q.positions[q.faces[0]]
    assert np.cross(b - a, c - a)[1] < 0 and q.normals[0][1] < 0  # the quad faced +y; mirrored in y it faces -y


@pytest.mark.parametrize("bad, match", [
    ("[1, 2, 3]", "4 rows of 4"),
    ("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]]", "affine"),
    ("[[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]", "singular"),
])
def test_bad_transforms_are_refused(tmp_path, bad, match):
    with pytest.raises(InputError, match=match):
        scene(tmp_path, f'[[objects]]\nname = "q"\nbuiltin = "quad"\nmaterial = "white"\ntransform = {bad}\n')


def test_two_sided_open_surfaces_get_a_back_and_closed_ones_do_not(tmp_path):
    s = scene(tmp_path, """
[[objects]]
name = "q"
builtin = "quad"
material = "white"
twosided = true
[[objects]]
name = "box"
builtin = "cube"
material = "white"
twosided = true
translate = [0, 2, 0]
""")
    names = [o.name for o in s.objects]
    assert names == ["q", "q (back)", "box"]
    front, back = s.objects[0], s.objects[1]
    diagonal = np.linalg.norm(np.ptp(np.concatenate([front.positions, s.objects[2].positions]), axis=0))
    assert np.allclose(back.positions, front.positions - BACK_OFFSET * diagonal * front.normals)
    assert np.allclose(back.normals, -front.normals)
    a, b, c = back.positions[back.faces[0]]
    assert np.cross(b - a, c - a) @ back.normals[0] > 0  # its winding agrees with its normals: it faces the back
    assert is_closed(s.objects[2]) and not is_closed(front)
    with pytest.raises(InputError, match="'twosided' must be true or false"):
        scene(tmp_path, '[[objects]]\nname = "q"\nbuiltin = "quad"\nmaterial = "white"\ntwosided = 1\n')


@pytest.mark.parametrize("segments", [3, 16, 256])
def test_disk_and_cylinder_areas_converge_to_the_circle(segments):
    for spec, exact in (("disk", math.pi), ("cylinder", 2 * math.pi)):
        positions, faces = builtins.mesh(spec, segments=segments)
        e1, e2 = positions[faces[:, 1]] - positions[faces[:, 0]], positions[faces[:, 2]] - positions[faces[:, 0]]
        cross = np.cross(e1, e2)
        area = 0.5 * np.linalg.norm(cross, axis=1).sum()
        inscribed = segments / 2 * math.sin(2 * math.pi / segments) * (1 if spec == "disk" else 0)
        if spec == "disk":
            assert area == pytest.approx(inscribed)
            assert (cross[:, 2] > 0).all()  # facing +z
        else:
            assert area == pytest.approx(segments * 2 * math.sin(math.pi / segments))
            centres = positions[faces].mean(axis=1)
            assert (np.einsum("ij,ij->i", cross[:, :2], centres[:, :2]) > 0).all()  # facing out
        assert area < exact


def test_segments_apply_to_disks_and_cylinders_only(tmp_path):
    with pytest.raises(InputError, match="'segments' applies"):
        builtins.mesh("sphere", segments=8)
    with pytest.raises(InputError, match="segments must be"):
        builtins.mesh("disk", segments=2)


@pytest.mark.parametrize("axis, width, height, expected", [
    ("y", 64, 48, 45.0),
    ("x", 64, 48, math.degrees(2 * math.atan(math.tan(math.radians(22.5)) * 48 / 64))),
    ("diagonal", 64, 48, math.degrees(2 * math.atan(math.tan(math.radians(22.5)) * 48 / 80))),
    ("smaller", 64, 48, 45.0),
    ("larger", 64, 48, math.degrees(2 * math.atan(math.tan(math.radians(22.5)) * 48 / 64))),
    ("smaller", 48, 64, math.degrees(2 * math.atan(math.tan(math.radians(22.5)) * 64 / 48))),
])
def test_fov_axes(axis, width, height, expected):
    assert fov_y_deg(45.0, axis, width, height) == pytest.approx(expected)


def test_camera_as_a_matrix_with_a_fov_axis_and_a_film(tmp_path):
    s = scene(tmp_path, """
[camera]
matrix = [[-1, 0, 0, 0], [0, 1, 0, 1], [0, 0, -1, 3.8], [0, 0, 0, 1]]
fov_deg = 45
fov_axis = "x"
width = 64
height = 48
[[objects]]
name = "q"
builtin = "quad"
material = "white"
""")
    cam = s.camera
    assert cam.eye == (0, 1, 3.8) and cam.look_at == (0, 1, 2.8) and cam.up == (0, 1, 0)
    assert cam.fov_y_deg == pytest.approx(fov_y_deg(45, "x", 64, 48)) and s.film == (64, 48)
    right, up, forward = cam.basis
    assert np.allclose(right, [1, 0, 0])  # Mitsuba's camera x points left: the image's right is -x of the frame


def test_camera_matrix_conflicts_and_mirrors(tmp_path):
    quad = '[[objects]]\nname = "q"\nbuiltin = "quad"\nmaterial = "white"\n'
    with pytest.raises(InputError, match="not both"):
        scene(tmp_path, "[camera]\nmatrix = [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\neye = [0, 0, 0]\n" + quad)
    with pytest.raises(InputError, match="fov axis must be one of"):
        scene(tmp_path, '[camera]\neye = [0, 0, -3]\nlook_at = [0, 0, 0]\nfov_deg = 40\nfov_axis = "z"\n' + quad)
    with pytest.raises(InputError, match="'width' and 'height'"):
        scene(tmp_path, "[camera]\neye = [0, 0, -3]\nlook_at = [0, 0, 0]\nwidth = 0\nheight = 4\n" + quad)
    assert pose_from_matrix(np.diag([-1.0, 1, 1, 1]))[3] and not pose_from_matrix(np.eye(4))[3]
    with pytest.warns(match="mirrors the image"):
        scene(tmp_path, "[camera]\nmatrix = [-1,0,0,0, 0,1,0,0, 0,0,1,-3, 0,0,0,1]\n" + quad)
