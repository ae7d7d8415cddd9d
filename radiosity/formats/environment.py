"""Light from outside the scene, as the files carry it: a constant radiance or a
latitude-longitude map (Mitsuba 3's ``constant`` and ``envmap`` emitters).

The latitude-longitude convention is Mitsuba 3's (``src/emitters/envmap.cpp``, checked
against Mitsuba 3.9.1 itself by tests/radiosity/scene/test_environment.py). In the
environment's own frame a direction d = (x, y, z) (y up) has

    u = atan2(x, -z) / (2 pi)  (mod 1),    v = acos(y) / pi
    d = (sin(2 pi u) sin(pi v), cos(pi v), -cos(2 pi u) sin(pi v))

and a world direction w is d = rotation^T w. An H x W image is sampled bilinearly
with pixel column i at u = (i + 0.5) / W (wrapping around) and pixel row j at v = j /
(H - 1): row 0 is the zenith (+y), row H - 1 the nadir.

``EnvironmentLight`` is the record (validated; ``radiance`` its numpy reference, which
every display is tested against); ``radiosity.scene.environment.Environment`` adds the
kernels' sampling. In the solution file (version 3): the array ``environment_image``
(H, W, 3) float32 (before ``scale``) and ``meta.environment`` = {"scale", "constant",
"rotation": 3 x 3, "source"} (``EnvironmentLight.meta``, ``read_environment``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from radiosity.formats.errors import InputError

__all__ = ["IMAGE_KEY", "EnvironmentLight", "direction_to_uv", "read_environment", "uv_to_direction"]

CONSTANT_ROWS, CONSTANT_COLUMNS = 33, 64  # the image a constant environment is sampled as
MIN_ROWS, MIN_COLUMNS = 3, 2  # Mitsuba's smallest environment map
ORTHONORMAL_TOLERANCE = 1e-5
IMAGE_KEY = "environment_image"  # its array in the solution file (no '/': never an object's key)


def _rotation(rotation, where):
    r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    if r.shape != (3, 3) or not np.isfinite(r).all():
        raise InputError(f"{where}: the rotation must be a 3 x 3 matrix of finite numbers")
    if np.abs(r.T @ r - np.eye(3)).max() > ORTHONORMAL_TOLERANCE:
        raise InputError(f"{where}: the rotation is not orthonormal (a rotation, maybe mirrored; no scale or shear)")
    return r


@dataclass(frozen=True, eq=False)
class EnvironmentLight:
    """Light from outside the scene.

    image    : (H, W, 3) float32 linear radiance before ``scale``, row 0 the zenith
               (see the module docstring); a constant environment: (1, 1, 3)
    scale    : float >= 0, multiplies the image
    rotation : (3, 3) float64, world from environment (orthonormal)
    constant : bool, the image is one radiance in every direction
    source   : where it was given (for messages)
    """

    image: np.ndarray
    scale: float = 1.0
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    constant: bool = False
    source: str = ""

    def __post_init__(self):
        where = self.source or "environment"
        image = np.asarray(self.image, dtype=np.float32)
        if image.ndim != 3 or image.shape[2] != 3:
            raise InputError(f"{where}: the environment image must be H x W x 3 (RGB), got shape {image.shape}")
        if self.constant and image.shape[:2] != (1, 1):
            raise InputError(f"{where}: a constant environment is one RGB radiance")
        if not self.constant and (image.shape[0] < MIN_ROWS or image.shape[1] < MIN_COLUMNS):
            raise InputError(f"{where}: an environment map needs at least {MIN_COLUMNS} x {MIN_ROWS} pixels "
                             f"(width x height), got {image.shape[1]} x {image.shape[0]}")
        if not np.isfinite(image).all() or (image < 0).any():
            raise InputError(f"{where}: the environment's radiance must be finite and >= 0")
        scale = float(self.scale)
        if not (math.isfinite(scale) and scale >= 0):
            raise InputError(f"{where}: the environment's scale must be a finite number >= 0, got {self.scale}")
        object.__setattr__(self, "image", image)
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "rotation", _rotation(self.rotation, where))

    @classmethod
    def uniform(cls, radiance, scale=1.0, rotation=None, source=""):
        """A constant environment of RGB ``radiance`` (a number or 3 numbers)."""
        rgb = np.broadcast_to(np.asarray(radiance, dtype=np.float64), (3,))
        return cls(rgb.reshape(1, 1, 3), scale, rotation, True, source)

    @classmethod
    def from_image(cls, image, scale=1.0, rotation=None, source=""):
        """A latitude-longitude environment map ((H, W, 3) linear radiance)."""
        return cls(image, scale, rotation, False, source)

    # -- storage (the solution file) --------------------------------------------------

    def to_arrays(self):
        """Plain numpy arrays that ``from_arrays`` makes this environment from again:
        image (H, W, 3) float32, rotation (3, 3) float64, scale () float64, constant
        () bool. No objects, so an ``.npz`` holds them with allow_pickle=False."""
        return {
            "image": self.image.copy(),
            "rotation": self.rotation.copy(),
            "scale": np.float64(self.scale),
            "constant": np.bool_(self.constant),
        }

    @classmethod
    def from_arrays(cls, arrays, source=""):
        """The ``Environment`` of ``to_arrays``'s dict (InputError if one is missing or wrong)."""
        missing = [k for k in ("image", "rotation", "scale", "constant") if k not in arrays]
        if missing:
            raise InputError(f"{source or 'environment'}: missing {', '.join(missing)}")
        return cls(np.asarray(arrays["image"]), float(np.asarray(arrays["scale"])), np.asarray(arrays["rotation"]),
                   bool(np.asarray(arrays["constant"])), source)

    def meta(self):
        """Its entry of the solution's meta (the image is the array ``IMAGE_KEY``)."""
        return {"scale": self.scale, "constant": self.constant, "rotation": self.rotation.tolist(), "source": self.source}

    def info(self):
        """A JSON-ready description: kind, resolution, scale, mean radiance."""
        return {
            "kind": "constant" if self.constant else "envmap",
            "width": int(self.image.shape[1]),
            "height": int(self.image.shape[0]),
            "scale": self.scale,
            "rotation": self.rotation.tolist(),
            "mean_radiance": (self.integral() / (4 * np.pi)).tolist(),  # over the sphere
            "source": self.source,
        }

    def padded_pixels(self):
        """(H, W + 1, 3) float64: the scaled image with its first column repeated
        last (a constant: CONSTANT_ROWS x CONSTANT_COLUMNS of it)."""
        image = self.image.astype(np.float64) * self.scale
        if self.constant:
            image = np.broadcast_to(image, (CONSTANT_ROWS, CONSTANT_COLUMNS, 3))
        return np.ascontiguousarray(np.concatenate([image, image[:, :1]], axis=1))

    def integral(self):
        """(3,) float64: the integral of the radiance over the sphere (exact for the
        bilinear image: piecewise linear in theta and phi)."""
        pixels = self.padded_pixels()[:, :-1]
        row_mean = pixels.mean(axis=1)  # the periodic linear interpolant's mean over phi
        rows = len(row_mean) - 1
        theta = np.linspace(0.0, np.pi, rows + 1)
        a, b = theta[:-1], theta[1:]
        s = np.cos(a) - np.cos(b)
        t = (np.sin(b) - b * np.cos(b)) - (np.sin(a) - a * np.cos(a))
        i0, i1 = (b * s - t) / (b - a), (t - a * s) / (b - a)
        return 2 * np.pi * (i0[:, None] * row_mean[:-1] + i1[:, None] * row_mean[1:]).sum(axis=0)

    def power(self, radius):
        """(3,) float64: the power the environment sends through a disk of ``radius``
        facing each direction (pi radius^2 times the radiance's integral): what enters
        the bounding sphere of that radius."""
        return np.pi * radius * radius * self.integral()

    # -- numpy references ----------------------------------------------------------------

    def radiance(self, directions):
        """(N, 3) float64: the radiance arriving from world ``directions`` (N, 3) (unit)."""
        pixels = self.padded_pixels()
        local = np.asarray(directions, dtype=np.float64) @ self.rotation
        u, v = direction_to_uv(local)
        return _bilinear(pixels, u, v)

def direction_to_uv(local):
    """(u, v) in [0, 1) x [0, 1] of unit directions ``local`` (N, 3) in the environment's frame."""
    local = np.asarray(local, dtype=np.float64)
    u = np.mod(np.arctan2(local[:, 0], -local[:, 2]) / (2 * np.pi), 1.0)
    v = np.arccos(np.clip(local[:, 1], -1.0, 1.0)) / np.pi
    return u, v


def uv_to_direction(u, v):
    """(N, 3) unit directions in the environment's frame of (u, v) (``direction_to_uv``'s inverse)."""
    theta, phi = np.pi * np.asarray(v, dtype=np.float64), 2 * np.pi * np.asarray(u, dtype=np.float64)
    return np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], axis=-1)


def _bilinear(pixels, u, v):
    rows, width = pixels.shape[0], pixels.shape[1] - 1
    x = np.mod(u - 0.5 / width, 1.0) * width
    y = v * (rows - 1)
    i = np.minimum(x.astype(np.int64), width - 1)
    j = np.minimum(y.astype(np.int64), rows - 2)
    fx, fy = (x - i)[:, None], (y - j)[:, None]
    top = (1 - fx) * pixels[j, i] + fx * pixels[j, i + 1]
    bottom = (1 - fx) * pixels[j + 1, i] + fx * pixels[j + 1, i + 1]
    return (1 - fy) * top + fy * bottom


def read_environment(archive, meta):
    """The ``EnvironmentLight`` of an open solution archive whose ``meta`` has an
    "environment", or None; the archive's one-line InputError if it is malformed."""
    info = meta.get("environment")
    if info is None:
        return None
    if not isinstance(info, dict) or IMAGE_KEY not in archive.keys:
        raise archive.fail(f"meta 'environment' needs a JSON object and the array '{IMAGE_KEY}'")
    image = archive.array(IMAGE_KEY, "fiu", (None, None, 3))
    try:
        return EnvironmentLight(image, float(info.get("scale", 1.0)), np.asarray(info.get("rotation", np.eye(3)), float),
                                bool(info.get("constant", False)), str(info.get("source", "")))
    except (InputError, TypeError, ValueError) as exc:
        raise archive.fail(f"the environment: {exc}") from None
