"""Light from outside the scene, from every direction: a constant radiance or a
latitude-longitude map (Mitsuba 3's ``constant`` and ``envmap`` emitters), as the
files carry it and as the kernels sample it.

    EnvironmentLight  the record: a constant RGB radiance or a latitude-longitude image,
                      times a scale, turned by a rotation (world from environment),
                      validated; ``radiance`` its numpy reference, which every display
                      is tested against; ``read_environment`` reads it from a solution
    Environment       the same with the kernels' sampling (``kernel_arrays``) and its
                      numpy references (``sample``, ``pdf``)
    EnvArrays         the same as the kernels read it (``env_lookup``, ``env_sample``,
                      ``env_pdf``)

The latitude-longitude convention is Mitsuba 3's (``src/emitters/envmap.cpp``, checked
against Mitsuba 3.9.1 itself by tests/radiosity/scene/test_environment.py). In the
environment's own frame a direction d = (x, y, z) (y up) has

    u = atan2(x, -z) / (2 pi)  (mod 1),    v = acos(y) / pi
    d = (sin(2 pi u) sin(pi v), cos(pi v), -cos(2 pi u) sin(pi v))

and a world direction w is d = rotation^T w. An H x W image is sampled bilinearly
with pixel column i at u = (i + 0.5) / W (wrapping around: the column after the last
is the first) and pixel row j at v = j / (H - 1): row 0 is the zenith (+y), row H - 1
the nadir. So the top row is the single value seen straight up, as in Mitsuba.

In the solution file (version 3): the array ``environment_image`` (H, W, 3) float32
(before ``scale``) and ``meta.environment`` = {"scale", "constant", "rotation": 3 x 3,
"source"} (``EnvironmentLight.meta``, ``read_environment``).

Sampling (``env_sample``, ``env_pdf``; ``Environment.sample`` and ``.pdf`` are their
numpy references): piecewise constant over the W x (H - 1) cells between pixel
centres, each cell's probability its mean corner luminance times its mean sin(theta),
so every direction where the bilinear radiance is not zero can be drawn; the density
in solid angle is p(u, v) / (2 pi^2 sin(theta)). A constant environment is drawn
through the same code as a CONSTANT_ROWS x CONSTANT_COLUMNS image of its radiance
(bilinear lookups of a constant are exact), whose cells then follow sin(theta): nearly
uniform on the sphere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.files.errors import InputError
from radiosity.files.images import HDR_EXTENSIONS, read_hdr_image, read_image
from radiosity.physics.cdf import search_cdf

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


LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709, as Mitsuba's ``luminance``


class EnvArrays(NamedTuple):
    """An environment as the transport kernels read it (``Environment.kernel_arrays``,
    or ``no_environment``).

    active      : bool             rays that leave the scene see ``pixels``
    pixels      : (H, W + 1, 3) float64  scaled radiance, the first column repeated last
    rotation    : (3, 3) float64   world from environment
    row_cdf     : (H - 1,) float64 cumulative probability of the rows of cells
    column_cdf  : (H - 1, W) float64 cumulative probability of the cells in each row
    cell_pdf    : (H - 1, W) float64 density in (u, v) of each cell (integrates to 1)
    center      : (3,) float64     the scene's bounding sphere, where photons come from
    radius      : float
    photon_share: float            probability that a photon is the environment's
    light_share : float            probability that a light sample (the path tracer's
                                   next-event estimate) picks the environment
    """

    active: bool
    pixels: np.ndarray
    rotation: np.ndarray
    row_cdf: np.ndarray
    column_cdf: np.ndarray
    cell_pdf: np.ndarray
    center: np.ndarray
    radius: float
    photon_share: float
    light_share: float


def no_environment():
    """``EnvArrays`` of a scene without an environment (black, never sampled)."""
    return EnvArrays(
        False, np.zeros((MIN_ROWS, MIN_COLUMNS + 1, 3)), np.eye(3), np.ones(MIN_ROWS - 1),
        np.ones((MIN_ROWS - 1, MIN_COLUMNS)), np.zeros((MIN_ROWS - 1, MIN_COLUMNS)), np.zeros(3), 0.0, 0.0, 0.0,
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class Environment(EnvironmentLight):
    """``radiosity.physics.environment.EnvironmentLight`` with what the transport
    kernels need: the sampling distribution (``kernel_arrays``) and its numpy
    references (``sample``, ``pdf``)."""

    def cell_weights(self):
        """(H - 1, W) float64: each cell's mean corner luminance times its mean sin(theta)."""
        pixels = self.padded_pixels()
        lum = pixels @ np.asarray(LUMINANCE)
        corners = 0.25 * (lum[:-1, :-1] + lum[:-1, 1:] + lum[1:, :-1] + lum[1:, 1:])
        rows = pixels.shape[0] - 1
        theta = np.linspace(0.0, np.pi, rows + 1)
        mean_sin = (np.cos(theta[:-1]) - np.cos(theta[1:])) / (np.pi / rows)
        return corners * mean_sin[:, None]

    def kernel_arrays(self, center, radius, other_power=0.0):
        """``EnvArrays`` for a scene whose bounding sphere is (center, radius) and
        whose emitting triangles send ``other_power`` (the sum of their RGB power):
        photons are shared by power, light samples half and half when both emit."""
        pixels = self.padded_pixels()
        weights = self.cell_weights()
        total = weights.sum()
        rows, columns = weights.shape
        if total > 0:
            row_sum = weights.sum(axis=1)
            row_cdf = np.cumsum(row_sum) / total
            row_cdf[-1] = 1.0
            with np.errstate(invalid="ignore", divide="ignore"):
                column_cdf = np.cumsum(weights, axis=1) / row_sum[:, None]
            column_cdf[row_sum <= 0] = 1.0
            column_cdf[:, -1] = 1.0
            cell_pdf = weights / total * (rows * columns)
            power = float(self.power(radius).sum())
            photon_share = power / (power + other_power) if power + other_power > 0 else 0.0
            light_share = 0.5 if other_power > 0 else 1.0
        else:
            row_cdf, column_cdf, cell_pdf = np.ones(rows), np.ones((rows, columns)), np.zeros((rows, columns))
            photon_share = light_share = 0.0
        return EnvArrays(
            True, pixels, self.rotation.copy(), row_cdf, np.ascontiguousarray(column_cdf), cell_pdf,
            np.asarray(center, dtype=np.float64), float(radius), float(photon_share), float(light_share),
        )  # fmt: skip

    def sample(self, samples, center=(0.0, 0.0, 0.0), radius=1.0):
        """Directions drawn from uniform ``samples`` (N, 2): (world directions (N, 3),
        their density in solid angle (N,)), as ``env_sample`` draws them."""
        env = self.kernel_arrays(center, radius)
        s = np.asarray(samples, dtype=np.float64)
        rows, columns = env.cell_pdf.shape
        j = np.minimum(np.searchsorted(env.row_cdf, s[:, 0], side="right"), rows - 1)
        below = np.where(j > 0, env.row_cdf[np.maximum(j - 1, 0)], 0.0)
        fy = np.clip((s[:, 0] - below) / np.maximum(env.row_cdf[j] - below, 1e-300), 0.0, 1.0)
        cdf = env.column_cdf[j]
        i = np.minimum((cdf <= s[:, 1:2]).sum(axis=1), columns - 1)
        left = np.where(i > 0, cdf[np.arange(len(i)), np.maximum(i - 1, 0)], 0.0)
        fx = np.clip((s[:, 1] - left) / np.maximum(cdf[np.arange(len(i)), i] - left, 1e-300), 0.0, 1.0)
        u = np.mod((i + 0.5 + fx) / columns, 1.0)
        v = (j + fy) / rows
        local = uv_to_direction(u, v)
        world = local @ self.rotation.T
        sin_theta = np.sin(np.pi * v)
        pdf = np.where(sin_theta > 0, env.cell_pdf[j, i] / (2 * np.pi**2 * np.maximum(sin_theta, 1e-300)), 0.0)
        return world, pdf

    def pdf(self, directions):
        """(N,) float64: the density in solid angle with which ``sample`` draws world ``directions``."""
        env = self.kernel_arrays((0.0, 0.0, 0.0), 1.0)
        local = np.asarray(directions, dtype=np.float64) @ self.rotation
        u, v = direction_to_uv(local)
        rows, columns = env.cell_pdf.shape
        i = np.mod(np.floor(u * columns - 0.5).astype(np.int64), columns)
        j = np.minimum(np.floor(v * rows).astype(np.int64), rows - 1)
        sin_theta = np.hypot(local[:, 0], local[:, 2])
        return np.where(sin_theta > 0, env.cell_pdf[j, i] / (2 * np.pi**2 * np.maximum(sin_theta, 1e-300)), 0.0)

def read_environment_image(path, where):
    """(H, W, 3) float32 linear radiance of an environment map file: OpenEXR, Radiance
    HDR, PFM or .npy checked as radiance (``read_hdr_image``: no NaN, infinite or
    negative values); an 8- or 16-bit image (PNG, JPEG, ...) sRGB-decoded to [0, 1]
    (``read_image``). InputError naming ``where`` and the file."""
    if str(path).lower().endswith(HDR_EXTENSIONS):
        return read_hdr_image(path, f"{where}: environment map")
    try:
        return read_image(path, "environment map").rgb.astype(np.float32)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


# -- numba ------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _local_uv(rotation, dx, dy, dz):
    """(u, v, sin theta) of world direction (dx, dy, dz) in the environment's frame."""
    x = rotation[0, 0] * dx + rotation[1, 0] * dy + rotation[2, 0] * dz
    y = rotation[0, 1] * dx + rotation[1, 1] * dy + rotation[2, 1] * dz
    z = rotation[0, 2] * dx + rotation[1, 2] * dy + rotation[2, 2] * dz
    u = math.atan2(x, -z) / (2.0 * math.pi)
    if u < 0.0:
        u += 1.0
    if u >= 1.0:
        u -= 1.0
    v = math.acos(min(max(y, -1.0), 1.0)) / math.pi
    return u, v, math.sqrt(x * x + z * z)


@numba.njit(cache=True, nogil=True, inline="always")
def env_lookup(pixels, rotation, dx, dy, dz):
    """The radiance (3-tuple) arriving from world direction (dx, dy, dz) (unit), bilinear
    in ``pixels`` (H, W + 1, 3) (``EnvArrays``)."""
    u, v, _ = _local_uv(rotation, dx, dy, dz)
    rows, width = pixels.shape[0], pixels.shape[1] - 1
    x = u - 0.5 / width
    if x < 0.0:
        x += 1.0
    x *= width
    y = v * (rows - 1)
    i = min(int(x), width - 1)
    j = min(int(y), rows - 2)
    fx, fy = x - i, y - j
    out0 = (1.0 - fy) * ((1.0 - fx) * pixels[j, i, 0] + fx * pixels[j, i + 1, 0]) + fy * (
        (1.0 - fx) * pixels[j + 1, i, 0] + fx * pixels[j + 1, i + 1, 0])
    out1 = (1.0 - fy) * ((1.0 - fx) * pixels[j, i, 1] + fx * pixels[j, i + 1, 1]) + fy * (
        (1.0 - fx) * pixels[j + 1, i, 1] + fx * pixels[j + 1, i + 1, 1])
    out2 = (1.0 - fy) * ((1.0 - fx) * pixels[j, i, 2] + fx * pixels[j, i + 1, 2]) + fy * (
        (1.0 - fx) * pixels[j + 1, i, 2] + fx * pixels[j + 1, i + 1, 2])
    return out0, out1, out2


@numba.njit(cache=True, nogil=True, inline="always")
def env_pdf(rotation, cell_pdf, dx, dy, dz):
    """The density in solid angle with which ``env_sample`` draws world direction (dx, dy, dz)."""
    u, v, sin_theta = _local_uv(rotation, dx, dy, dz)
    if sin_theta <= 0.0:
        return 0.0
    rows, columns = cell_pdf.shape
    i = int(math.floor(u * columns - 0.5))
    if i < 0:
        i += columns
    i = min(i, columns - 1)
    j = min(int(v * rows), rows - 1)
    return cell_pdf[j, i] / (2.0 * math.pi * math.pi * sin_theta)


@numba.njit(cache=True, nogil=True, inline="always")
def _pick(cdf, u):
    """(slot of ``cdf`` holding u, u's fraction across that slot)."""
    k = min(search_cdf(cdf, u), len(cdf) - 1)
    below = cdf[k - 1] if k > 0 else 0.0
    width = cdf[k] - below
    f = (u - below) / width if width > 0.0 else 0.5
    return k, min(max(f, 0.0), 1.0)


@numba.njit(cache=True, nogil=True, inline="always")
def env_sample(rotation, row_cdf, column_cdf, cell_pdf, u1, u2):
    """A world direction toward the environment drawn from the uniform numbers (u1,
    u2): (direction 3-tuple, its density in solid angle; 0: unusable)."""
    rows, columns = cell_pdf.shape
    j, fy = _pick(row_cdf, u1)
    i, fx = _pick(column_cdf[j], u2)
    u = (i + 0.5 + fx) / columns
    if u >= 1.0:
        u -= 1.0
    v = (j + fy) / rows
    theta, phi = math.pi * v, 2.0 * math.pi * u
    sin_theta = math.sin(theta)
    x, y, z = math.sin(phi) * sin_theta, math.cos(theta), -math.cos(phi) * sin_theta
    wx = rotation[0, 0] * x + rotation[0, 1] * y + rotation[0, 2] * z
    wy = rotation[1, 0] * x + rotation[1, 1] * y + rotation[1, 2] * z
    wz = rotation[2, 0] * x + rotation[2, 1] * y + rotation[2, 2] * z
    if sin_theta <= 0.0:
        return (wx, wy, wz), 0.0
    return (wx, wy, wz), cell_pdf[j, i] / (2.0 * math.pi * math.pi * sin_theta)
