"""The one camera type (docs/formats.md, "Cameras and views"): a pinhole with ``eye``, ``look_at``, ``up``, a
field of view ``fov_deg`` along ``fov_axis`` and an image of ``width`` x ``height``
pixels, pixel centres at half-integers, right-handed world, the image's right being
cross(forward, up), row 0 at the top.

The field of view is kept along its axis, as Mitsuba 3 keeps a sensor's ``fov`` along
its ``fov_axis``: the vertical one (``fov_y_deg``, what every renderer draws with)
follows from the image's size, so the same camera drawn at another size or aspect sees
as far along that axis. The default axis is y: ``fov_deg`` is then the vertical field
of view at every size.

A scene file's ``[camera]``, a views file's entries, the camera flags of the
display commands and a solution's ``meta.camera`` all become a ``Camera``; it
validates itself on construction, so every source refuses the same mistakes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace

import numpy as np

from radiosity.files.errors import InputError
from radiosity.files.inputs import TEXT_BYTES, loads_json, read_input_bytes

__all__ = [
    "DEFAULT_FOV_Y_DEG", "FOV_AGREEMENT_DEG", "FOV_AXES", "MAX_IMAGE_SIDE", "Camera", "camera_from_dict",
    "camera_from_meta", "fov_y_deg", "load_views", "pose_from_matrix",
]

DEFAULT_FOV_Y_DEG = 39.3
FOV_AXES = ("x", "y", "diagonal", "smaller", "larger")  # Mitsuba's fov_axis: which extent the fov spans
MAX_IMAGE_SIDE = 16384


def _vec3(value, what):
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise InputError(f"camera: {what} must be 3 numbers, got {value!r}") from None
    if len(v) != 3:
        raise InputError(f"camera: {what} must be 3 numbers, got {len(v)}")
    return v


@dataclass(frozen=True)
class Camera:
    """A pinhole camera; raises ``InputError`` naming the problem if it cannot be one.

    eye, look_at, up : 3 floats each, world space
    fov_deg          : field of view along ``fov_axis``, in (0, 180) degrees
    width, height    : image size in pixels, 1 to ``MAX_IMAGE_SIDE``
    fov_axis         : the extent of the image ``fov_deg`` spans, one of FOV_AXES (Mitsuba's
                       ``fov_axis``): "y" its height (the default: ``fov_deg`` is the vertical
                       field of view), "x" its width, "diagonal", "smaller" or "larger" side
    fov_y_deg        : (derived) the vertical field of view at this camera's size, degrees
    """

    eye: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_deg: float = DEFAULT_FOV_Y_DEG
    width: int = 512
    height: int = 512
    fov_axis: str = "y"

    def __post_init__(self):
        for name in ("eye", "look_at", "up"):
            object.__setattr__(self, name, _vec3(getattr(self, name), name.replace("_", "-")))
        try:
            fov = float(self.fov_deg)
        except (TypeError, ValueError):
            raise InputError(f"camera: the field of view must be a number, got {self.fov_deg!r}") from None
        object.__setattr__(self, "fov_deg", fov)
        if not isinstance(self.fov_axis, str) or self.fov_axis not in FOV_AXES:
            raise InputError(f"camera: the fov axis must be one of {', '.join(FOV_AXES)}, got {self.fov_axis!r}")
        values = np.concatenate([self.eye, self.look_at, self.up])
        if not np.isfinite(values).all() or np.abs(values).max() > 3.4e38:
            raise InputError("camera: eye, look-at and up must be finite")
        forward = np.subtract(self.look_at, self.eye)
        if np.linalg.norm(forward) == 0:
            raise InputError("camera: look-at equals the eye")
        if np.linalg.norm(np.cross(forward, self.up)) <= 1e-9 * np.linalg.norm(forward) * np.linalg.norm(self.up):
            raise InputError("camera: up is zero or parallel to the viewing direction")
        if not (math.isfinite(fov) and 0 < fov < 180):
            raise InputError(f"camera: the field of view must be between 0 and 180 degrees, got {fov:g}")
        ok = all(isinstance(s, int | np.integer) and 1 <= s <= MAX_IMAGE_SIDE for s in (self.width, self.height))
        if not ok:
            raise InputError(
                f"camera: image size must be 1 to {MAX_IMAGE_SIDE} pixels a side, got {self.width}x{self.height}"
            )
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))

    @property
    def fov_y_deg(self):
        """The vertical field of view at this camera's size, degrees: ``fov_deg`` itself
        when the axis is y."""
        return fov_y_deg(self.fov_deg, self.fov_axis, self.width, self.height)

    def sized(self, width, height):
        """The same camera with another image size: its field of view kept along its
        axis (the vertical one follows the new aspect, as Mitsuba 3's)."""
        return replace(self, width=width, height=height)

    def to_dict(self):
        """The pose and field of view as JSON-ready values (the files' ``camera`` record):
        ``eye``, ``look_at``, ``up`` and ``fov_y_deg``, the vertical field of view at this
        camera's size. A camera whose axis is not y adds ``fov_deg``, ``fov_axis`` and
        ``film`` ([width, height], the size ``fov_y_deg`` is for): a reader that knows
        them keeps the field of view along its axis at any size; one that does not reads
        ``fov_y_deg`` as before."""
        out = {"eye": list(self.eye), "look_at": list(self.look_at), "up": list(self.up), "fov_y_deg": self.fov_y_deg}
        if self.fov_axis != "y":
            out |= {"fov_deg": self.fov_deg, "fov_axis": self.fov_axis, "film": [self.width, self.height]}
        return out

    @property
    def basis(self):
        """(right, up, forward) unit vectors, right = cross(forward, up)."""
        forward = np.subtract(self.look_at, self.eye).astype(np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward), forward

    def view_matrix(self):
        """4x4 world -> camera (OpenGL: camera looks down -z)."""
        right, up, forward = self.basis
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = right, up, -forward
        m[:3, 3] = -m[:3, :3] @ np.asarray(self.eye, np.float64)
        return m

    def projection_matrix(self, near, far):
        f = 1.0 / np.tan(np.radians(self.fov_y_deg) / 2)
        aspect = self.width / self.height
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = f / aspect, f
        m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
        m[3, 2] = -1.0
        return m

    def pixel_rays(self):
        """Unit world directions (H, W, 3) through the pixel centres, row 0 at the top."""
        right, up, forward = self.basis
        t = np.tan(np.radians(self.fov_y_deg) / 2)
        x = (2 * (np.arange(self.width) + 0.5) / self.width - 1) * t * self.width / self.height
        y = (1 - 2 * (np.arange(self.height) + 0.5) / self.height) * t
        d = forward + x[None, :, None] * right + y[:, None, None] * up
        return d / np.linalg.norm(d, axis=2, keepdims=True)


def _film(value, where):
    """(width, height) of a camera record's ``film``: two whole numbers, 1 to MAX_IMAGE_SIDE."""
    ok = (isinstance(value, list | tuple) and len(value) == 2
          and all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_IMAGE_SIDE for v in value))
    if not ok:
        raise InputError(f"{where}: 'film' must be [width, height], whole numbers from 1 to {MAX_IMAGE_SIDE}, "
                         f"got {value!r}")
    return int(value[0]), int(value[1])


def camera_from_dict(data, width=512, height=512, where="camera"):
    """A Camera from ``{"eye" (or "position"), "look_at", "up"?, a field of view,
    "film"?}``; ``where`` prefixes any error (a file and a table, say).

    The field of view is ``fov_y_deg`` (vertical), or ``fov_deg`` along ``fov_axis``
    (FOV_AXES, default y); both only with ``film``, [width, height], the size at which
    ``fov_y_deg`` is the vertical field of view of ``fov_deg`` along ``fov_axis``
    (the files' camera record, ``Camera.to_dict``), and they must agree there. The camera's
    size is ``film`` if given, else ``width`` x ``height``."""
    if not isinstance(data, dict):
        raise InputError(f"{where}: must be a table of eye, look_at, up, fov_y_deg")
    if "position" in data and "eye" in data:
        raise InputError(f"{where}: give 'position' or 'eye', not both")
    eye = data.get("eye", data.get("position"))
    if eye is None or "look_at" not in data:
        raise InputError(f"{where}: needs 'eye' (or 'position') and 'look_at'")
    if "film" in data:
        width, height = _film(data["film"], where)
    along = "fov_deg" in data or "fov_axis" in data
    if along and "fov_y_deg" in data and "film" not in data:
        raise InputError(f"{where}: give 'fov_y_deg' or 'fov_deg' (with 'fov_axis'), not both, unless 'film' "
                         "gives the size at which they agree")
    fov = data.get("fov_deg", DEFAULT_FOV_Y_DEG) if along else data.get("fov_y_deg", DEFAULT_FOV_Y_DEG)
    try:
        camera = Camera(eye, data["look_at"], data.get("up", (0.0, 1.0, 0.0)), fov, width, height,
                        data.get("fov_axis", "y"))
    except InputError as exc:
        raise InputError(f"{where}: {str(exc).removeprefix('camera: ')}") from None
    if along and "fov_y_deg" in data:
        given = data["fov_y_deg"]
        if not (isinstance(given, int | float) and not isinstance(given, bool)
                and abs(given - camera.fov_y_deg) <= FOV_AGREEMENT_DEG):
            raise InputError(f"{where}: 'fov_y_deg' {given!r} is not the vertical field of view of 'fov_deg' "
                             f"{camera.fov_deg:g} along {camera.fov_axis} at the film {width}x{height} "
                             f"({camera.fov_y_deg:.9g})")
    return camera


FOV_AGREEMENT_DEG = 1e-6  # a record's fov_y_deg against its fov_deg along fov_axis at its film, degrees


def fov_y_deg(fov_deg, axis, width, height):
    """The vertical field of view of an image ``width`` x ``height`` whose field of
    view along ``axis`` (FOV_AXES: the image's width, height, diagonal, or its smaller
    or larger side, as Mitsuba's ``fov_axis``) is ``fov_deg``."""
    if axis not in FOV_AXES:
        raise InputError(f"camera: the fov axis must be one of {', '.join(FOV_AXES)}, got {axis!r}")
    if not (isinstance(fov_deg, int | float) and math.isfinite(fov_deg) and 0 < fov_deg < 180):
        raise InputError(f"camera: the field of view must be between 0 and 180 degrees, got {fov_deg!r}")
    if axis == "smaller":
        axis = "x" if width < height else "y"
    elif axis == "larger":
        axis = "x" if width > height else "y"
    if axis == "y":
        return float(fov_deg)  # itself, not itself through tan and atan (one rounding off)
    ratio = {"x": height / width, "diagonal": height / math.hypot(width, height)}[axis]
    return math.degrees(2 * math.atan(math.tan(math.radians(fov_deg) / 2) * ratio))


def pose_from_matrix(matrix):
    """(eye, look_at, up) of a camera-to-world 4x4 matrix in Mitsuba's convention: the
    camera at the origin of its frame, looking along +z, +y up (and +x to the left);
    and whether the matrix mirrors the image (a negative determinant), which a
    ``Camera`` cannot: the caller says so."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"camera: the matrix must be 4x4 finite numbers, got shape {m.shape}")
    linear = m[:3, :3]
    eye, forward, up = m[:3, 3], linear @ [0.0, 0.0, 1.0], linear @ [0.0, 1.0, 0.0]
    if np.linalg.norm(forward) == 0:
        raise InputError("camera: the matrix maps the viewing direction to zero")
    look_at = eye + forward / np.linalg.norm(forward)
    return tuple(eye), tuple(look_at), tuple(up), bool(np.linalg.slogdet(linear)[0] < 0)


def camera_from_meta(meta, fail):
    """The optional ``camera`` of a file's meta, or None; ``fail(problem)`` makes the
    error naming the file."""
    if meta.get("camera") is None:
        return None
    try:
        return camera_from_dict(meta["camera"], where="meta 'camera'")
    except InputError as exc:
        raise fail(str(exc)) from None


def load_views(path):
    """Named views from a JSON file: {"name": {"eye": [...], "look_at": [...], "up": [...], "fov_y_deg": d}}
    (or "fov_deg": d, "fov_axis": "x", ...: ``camera_from_dict``). Returns {name: dict};
    ``camera_from_dict`` makes each a Camera."""
    where = f"views file {str(path)!r}"
    try:
        data = loads_json(read_input_bytes(path, "views file", TEXT_BYTES).decode("utf-8"), where)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"views file {str(path)!r} is not JSON: {' '.join(str(exc).split())}") from None
    if not isinstance(data, dict) or not data:
        raise InputError(f"views file {str(path)!r} must map view names to cameras")
    return data
