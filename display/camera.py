"""Cameras (shared/DESIGN.md, "Contract 3"): a pinhole with ``eye``, ``look_at``, ``up``,
``fov_y_deg`` (vertical field of view) and an image of ``width`` x ``height`` pixels,
pixel centres at half-integers, right-handed world, the image's right being
cross(forward, up), row 0 at the top.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from radiosity.errors import InputError


@dataclass(frozen=True)
class View:
    eye: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y_deg: float = 39.3
    width: int = 512
    height: int = 512

    def __post_init__(self):
        forward = np.subtract(self.look_at, self.eye)
        if not np.isfinite(np.concatenate([self.eye, self.look_at, self.up])).all():
            raise InputError("camera: eye, look-at and up must be finite")
        if np.linalg.norm(forward) == 0:
            raise InputError("camera: look-at equals the eye")
        if np.linalg.norm(np.cross(forward, self.up)) <= 1e-9 * np.linalg.norm(forward) * np.linalg.norm(self.up):
            raise InputError("camera: up is zero or parallel to the viewing direction")
        if not 0 < self.fov_y_deg < 180:
            raise InputError(f"camera: the field of view must be between 0 and 180 degrees, got {self.fov_y_deg:g}")
        if not (isinstance(self.width, int) and isinstance(self.height, int) and 1 <= self.width <= 16384 and 1 <= self.height <= 16384):
            raise InputError(f"camera: image size must be 1 to 16384 pixels a side, got {self.width}x{self.height}")

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


def view_from_camera(camera, width, height):
    """A View from a ``radiosity.scene.Camera`` (or any object with its fields)."""
    return View(tuple(camera.eye), tuple(camera.look_at), tuple(camera.up), float(camera.fov_y_deg), width, height)


def framing_view(lo, hi, width, height, fov_y_deg=39.3):
    """A view of the box [lo, hi] from its -z side, the whole box in frame."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * np.linalg.norm(hi - lo), 1e-9)
    distance = radius / np.sin(np.radians(fov_y_deg) / 2) * 1.05
    eye = centre - np.array([0.0, 0.0, distance])
    return View(tuple(eye), tuple(centre), (0.0, 1.0, 0.0), fov_y_deg, width, height)


def load_views(path):
    """Named views from a JSON file: {"name": {"eye": [...], "look_at": [...], "up": [...], "fov_y_deg": d}}."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InputError(f"views file {str(path)!r} not found") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"views file {str(path)!r} is not JSON: {' '.join(str(exc).split())}") from None
    if not isinstance(data, dict) or not data:
        raise InputError(f"views file {str(path)!r} must map view names to cameras")
    return data
