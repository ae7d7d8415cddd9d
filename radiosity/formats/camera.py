"""The one camera type (Contract 3): a pinhole with ``eye``, ``look_at``, ``up``,
``fov_y_deg`` (vertical field of view) and an image of ``width`` x ``height``
pixels, pixel centres at half-integers, right-handed world, the image's right being
cross(forward, up), row 0 at the top.

A scene file's ``[camera]``, a views file's entries, the camera flags of the
display commands and a solution's ``meta.camera`` all become a ``Camera``; it
validates itself on construction, so every source refuses the same mistakes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace

import numpy as np

from radiosity.formats.errors import InputError
from radiosity.formats.inputs import TEXT_BYTES, loads_json, read_input_bytes

__all__ = [
    "DEFAULT_FOV_Y_DEG", "FOV_AXES", "MAX_IMAGE_SIDE", "Camera", "camera_from_dict", "camera_from_meta", "fov_y_deg",
    "load_views", "pose_from_matrix",
]

DEFAULT_FOV_Y_DEG = 39.3
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
    fov_y_deg        : vertical field of view, in (0, 180) degrees
    width, height    : image size in pixels, 1 to ``MAX_IMAGE_SIDE``
    """

    eye: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y_deg: float = DEFAULT_FOV_Y_DEG
    width: int = 512
    height: int = 512

    def __post_init__(self):
        for name in ("eye", "look_at", "up"):
            object.__setattr__(self, name, _vec3(getattr(self, name), name.replace("_", "-")))
        try:
            fov = float(self.fov_y_deg)
        except (TypeError, ValueError):
            raise InputError(f"camera: the field of view must be a number, got {self.fov_y_deg!r}") from None
        object.__setattr__(self, "fov_y_deg", fov)
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

    def sized(self, width, height):
        """The same camera with another image size."""
        return replace(self, width=width, height=height)

    def to_dict(self):
        """The pose as JSON-ready lists (the image size is not part of it)."""
        return {"eye": list(self.eye), "look_at": list(self.look_at), "up": list(self.up), "fov_y_deg": self.fov_y_deg}

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


def camera_from_dict(data, width=512, height=512, where="camera"):
    """A Camera from ``{"eye" (or "position"), "look_at", "up"?, "fov_y_deg"?}``;
    ``where`` prefixes any error (a file and a table, say)."""
    if not isinstance(data, dict):
        raise InputError(f"{where}: must be a table of eye, look_at, up, fov_y_deg")
    if "position" in data and "eye" in data:
        raise InputError(f"{where}: give 'position' or 'eye', not both")
    eye = data.get("eye", data.get("position"))
    if eye is None or "look_at" not in data:
        raise InputError(f"{where}: needs 'eye' (or 'position') and 'look_at'")
    try:
        return Camera(eye, data["look_at"], data.get("up", (0.0, 1.0, 0.0)),
                      data.get("fov_y_deg", DEFAULT_FOV_Y_DEG), width, height)
    except InputError as exc:
        raise InputError(f"{where}: {str(exc).removeprefix('camera: ')}") from None


FOV_AXES = ("x", "y", "diagonal", "smaller", "larger")


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
    ratio = {"x": height / width, "y": 1.0, "diagonal": height / math.hypot(width, height)}[axis]
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
    return tuple(eye), tuple(look_at), tuple(up), bool(np.linalg.det(linear) < 0)


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
    """Named views from a JSON file: {"name": {"eye": [...], "look_at": [...], "up": [...], "fov_y_deg": d}}.
    Returns {name: dict}; ``camera_from_dict`` makes each a Camera."""
    where = f"views file {str(path)!r}"
    try:
        data = loads_json(read_input_bytes(path, "views file", TEXT_BYTES).decode("utf-8"), where)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"views file {str(path)!r} is not JSON: {' '.join(str(exc).split())}") from None
    if not isinstance(data, dict) or not data:
        raise InputError(f"views file {str(path)!r} must map view names to cameras")
    return data
