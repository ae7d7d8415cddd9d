"""A camera's field of view along its axis at any image size (Mitsuba 3's rule), and
the camera record that carries it: no Mitsuba needed.

tests/radiosity/scene/test_mitsuba_camera.py holds the same rule against Mitsuba 3
itself where it is installed; here the answers are closed forms and the numbers
Mitsuba 3.9.1 (scalar_rgb) gave for a sensor's rays."""

import json
import math

import numpy as np
import pytest

from radiosity.files.camera import FOV_AXES, Camera, camera_from_dict, fov_y_deg
from radiosity.files.errors import InputError

FILM = (1280, 720)
SIZES = {"film": FILM, "wider": (1920, 600), "taller": (600, 1000), "square": (1024, 1024), "tiny": (5, 2)}
EYE, LOOK_AT, UP = (0.3, 0.4, 5.0), (0.0, 0.1, 0.0), (0.15, 1.0, 0.0)


def extents(camera):
    """(tan of half the width, tan of half the height) of the image, as the path tracer's
    rays (``pixel_rays``) and the renderer's projection (``projection_matrix``) each
    see it; the two must agree."""
    right, up, forward = camera.basis
    rays = camera.pixel_rays()
    w, h = camera.width, camera.height
    corner = rays[0, -1]  # the top-right pixel's centre, (1 - 1/w, 1 - 1/h) of the half extents
    from_rays = (corner @ right / (corner @ forward) / (1 - 1 / w), corner @ up / (corner @ forward) / (1 - 1 / h))
    p = camera.projection_matrix(0.1, 10.0)
    np.testing.assert_allclose(from_rays, (1 / p[0, 0], 1 / p[1, 1]), rtol=1e-12)
    return from_rays


def spanned(axis, tan_x, tan_y):
    """The field of view (degrees) an image of half extents tan_x, tan_y spans along ``axis``."""
    half = {"x": tan_x, "y": tan_y, "diagonal": math.hypot(tan_x, tan_y), "smaller": min(tan_x, tan_y),
            "larger": max(tan_x, tan_y)}[axis]
    return math.degrees(2 * math.atan(half))


@pytest.mark.parametrize("size_name", list(SIZES))
@pytest.mark.parametrize("axis", FOV_AXES)
def test_the_fov_stays_along_its_axis_at_any_size(axis, size_name):
    camera = Camera(EYE, LOOK_AT, UP, 70.0, *FILM, axis).sized(*SIZES[size_name])
    assert (camera.fov_deg, camera.fov_axis) == (70.0, axis)
    tan_x, tan_y = extents(camera)
    assert tan_x / tan_y == pytest.approx(camera.width / camera.height, rel=1e-12)  # square pixels
    assert spanned(axis, tan_x, tan_y) == pytest.approx(70.0, rel=1e-12)
    assert camera.fov_y_deg == pytest.approx(spanned("y", tan_x, tan_y), rel=1e-12)


# Mitsuba 3.9.1, scalar_rgb: a perspective sensor of fov 70 along each axis, its film's size,
# and the angles (degrees) of the rays its sample_ray gives through the middles of the film's
# right and top edges: the horizontal and vertical fields of view
MITSUBA = [
    ("x", (64, 36), 69.99999, 42.99566), ("x", (36, 64), 69.99999, 102.44785), ("x", (32, 32), 69.99999, 70.0),
    ("y", (64, 36), 102.44785, 70.0), ("y", (36, 64), 42.99565, 70.0),
    ("diagonal", (64, 36), 62.79007, 37.89312), ("diagonal", (36, 64), 37.89311, 62.79007),
    ("diagonal", (32, 32), 52.68199, 52.68200),
    ("smaller", (64, 36), 102.44785, 70.0), ("smaller", (36, 64), 69.99999, 102.44785),
    ("larger", (64, 36), 69.99999, 42.99566), ("larger", (36, 64), 42.99565, 70.0),
]


@pytest.mark.parametrize("axis, size, fov_x, fov_y", MITSUBA)
def test_the_numbers_mitsuba_3_gives(axis, size, fov_x, fov_y):
    camera = Camera(EYE, LOOK_AT, UP, 70.0, 48, 27, axis).sized(*size)
    tan_x, tan_y = extents(camera)
    assert spanned("x", tan_x, tan_y) == pytest.approx(fov_x, abs=2e-5)  # Mitsuba's float32 rays
    assert camera.fov_y_deg == pytest.approx(fov_y, abs=2e-5)


def test_a_16_9_film_with_its_fov_along_x_drawn_square():
    # a 1280 x 720 film with fov 70 along x (Mitsuba's default axis) drawn 1024 x 1024: 70 both ways
    film = Camera(EYE, LOOK_AT, UP, 70.0, 1280, 720, "x")
    assert film.fov_y_deg == pytest.approx(42.99566, abs=1e-5)
    assert film.sized(1024, 1024).fov_y_deg == pytest.approx(70.0, rel=1e-12)
    assert film.sized(1280, 720) == film


def test_fov_y_deg_is_the_function_of_the_axis_and_size():
    for axis in FOV_AXES:
        for size in SIZES.values():
            assert Camera(EYE, LOOK_AT, UP, 33.0, *size, axis).fov_y_deg == fov_y_deg(33.0, axis, *size)
    for fov in (33.0, 39.3, 60.0, 0.001, 179.9):  # the default axis, y: the vertical fov itself, to the bit
        assert Camera(EYE, LOOK_AT, UP, fov, 10, 1000).fov_y_deg == fov
        assert Camera(EYE, LOOK_AT, UP, fov, 1000, 10, "smaller").fov_y_deg == fov


# -- the camera record ------------------------------------------------------------------------


def test_a_y_axis_record_is_the_one_of_before():
    camera = Camera(EYE, LOOK_AT, UP, 45.0, 64, 32)
    assert camera.to_dict() == {"eye": list(EYE), "look_at": list(LOOK_AT), "up": list(UP), "fov_y_deg": 45.0}
    assert camera_from_dict(camera.to_dict(), 64, 32) == camera


@pytest.mark.parametrize("axis", [a for a in FOV_AXES if a != "y"])
def test_a_record_along_another_axis_round_trips_and_older_readers_read_the_film_s_vertical(axis):
    camera = Camera(EYE, LOOK_AT, UP, 70.0, *FILM, axis)
    record = json.loads(json.dumps(camera.to_dict()))  # as a file holds it
    assert record["fov_deg"] == 70.0 and record["fov_axis"] == axis and record["film"] == list(FILM)
    assert record["fov_y_deg"] == camera.fov_y_deg == fov_y_deg(70.0, axis, *FILM)
    back = camera_from_dict(record)  # at the film's size, whatever size is asked
    assert back == camera and camera_from_dict(record, 8, 8) == camera
    assert back.sized(1024, 1024).fov_y_deg == fov_y_deg(70.0, axis, 1024, 1024)
    # a reader that knows only eye, look_at, up and fov_y_deg draws the film's view as before
    old = camera_from_dict({k: record[k] for k in ("eye", "look_at", "up", "fov_y_deg")}, *FILM)
    assert old.fov_y_deg == camera.fov_y_deg
    # a views file may give the fov along an axis without the rest
    view = camera_from_dict({"eye": EYE, "look_at": LOOK_AT, "fov_deg": 70, "fov_axis": axis}, 300, 200)
    assert (view.fov_deg, view.fov_axis, view.width, view.height) == (70.0, axis, 300, 200)


RECORD = {"eye": list(EYE), "look_at": list(LOOK_AT), "fov_deg": 70.0, "fov_axis": "x", "film": [1280, 720],
          "fov_y_deg": fov_y_deg(70.0, "x", 1280, 720)}


@pytest.mark.parametrize("change, says", [
    ({"fov_y_deg": 43.5}, "'fov_y_deg' 43.5 is not the vertical field of view of 'fov_deg' 70 along x at the film "
                          "1280x720 (42.9956614)"),
    ({"fov_y_deg": "wide"}, "is not the vertical field of view"),
    ({"film": None}, "not both, unless 'film' gives the size at which they agree"),
    ({"fov_axis": "z"}, "the fov axis must be one of x, y, diagonal, smaller, larger, got 'z'"),
    ({"fov_axis": 1}, "the fov axis must be one of"),
    ({"fov_deg": 180}, "between 0 and 180 degrees"),
    ({"film": [1280]}, "'film' must be [width, height], whole numbers from 1 to 16384"),
    ({"film": [1280.0, 720]}, "'film' must be"),
    ({"film": [True, 720]}, "'film' must be"),
    ({"film": [0, 720]}, "'film' must be"),
])
def test_a_record_that_contradicts_itself_is_one_line(change, says):
    record = {k: v for k, v in (RECORD | change).items() if v is not None}
    with pytest.raises(InputError) as info:
        camera_from_dict(record, where="meta 'camera'")
    message = str(info.value)
    assert "\n" not in message and message.startswith("meta 'camera': ") and says in message, message


def test_a_camera_refuses_an_axis_that_is_none():
    with pytest.raises(InputError, match="fov axis must be one of"):
        Camera(EYE, LOOK_AT, UP, 40.0, 8, 8, "vertical")
