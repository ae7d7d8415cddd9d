"""Diffuse textures: images read as linear RGB, looked up at texture coordinates.

A textured object's diffuse reflectance at a point x is

    kd(x) = kd * texture(uv(x))

with ``kd`` its material's diffuse colour and ``uv(x)`` its per-vertex texture
coordinates interpolated barycentrically. The conventions, one for every format
(each loader converts to them):

    texture : (H, W, 3) float32, linear RGB in [0, 1], row 0 the image's top row
    uvs     : (V, 2) float64, u to the right, v up: (0, 0) is the image's bottom-left
              corner, (1, 1) its top-right (OBJ's and OpenGL's convention; glTF's v
              runs down, and trimesh flips it on reading)
    lookup  : texel (i, j) (row i from the top, column j) is centred on
              u = (j + 0.5) / W, v = 1 - (i + 0.5) / H; bilinear between the four
              nearest texel centres, repeating outside [0, 1) (Mitsuba's default)

``lookup`` (``radiosity.formats.texture``, where the files' readers reach it) is the
numpy reference; ``texel`` the same lookup for the kernels, which read every texture
of a scene from one flat atlas (``atlas``).

Wrap modes: every stage repeats. Mitsuba's other two (``mirror``: the image mirrored
at each edge; ``clamp``: the edge texels extended) are turned into repeating ones by
the loader (``as_repeating``: a texture and uvs that read, repeating, exactly what the
original reads in its mode), so the kernels, the files and the displays know one
mode; ``wrapped_lookup`` is the reference of the three.
"""

from __future__ import annotations

import io
import math
from typing import NamedTuple

import numba
import numpy as np
from PIL import Image

from radiosity.formats.errors import InputError
from radiosity.formats.inputs import read_input_bytes
from radiosity.formats.material import srgb_to_linear
from radiosity.formats.texture import MAX_TEXTURE_PIXELS, OPACITY_CUTOFF, lookup

__all__ = ["WRAP_MODES", "as_repeating", "atlas", "lookup", "read_texture", "srgb_to_linear", "texel", "texture_from_image", "wrap_index", "wrapped_lookup"]

TEXTURE_BYTES = 1 << 30  # an image file larger is refused before it is decoded


def texture_from_image(image, where):
    """A PIL image (8 bits per channel, sRGB-encoded, as PNG and JPEG files hold them)
    as a texture: (H, W, 3) float32 linear RGB, row 0 the top. Alpha is dropped; a
    grey image is repeated into the three channels."""
    width, height = image.size
    if width < 1 or height < 1:
        raise InputError(f"{where}: the texture is empty ({width} x {height} pixels)")
    if width * height > MAX_TEXTURE_PIXELS:
        raise InputError(
            f"{where}: the texture is {width} x {height} pixels, more than the {MAX_TEXTURE_PIXELS:,} allowed"
        )
    if image.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        raise InputError(f"{where}: the texture has {image.mode} pixels; give an 8-bit RGB or grey image")
    rgb = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
    return srgb_to_linear(rgb).astype(np.float32)


def read_texture(path, where):
    """A texture from an image file (PNG, JPEG, ... through pillow): (H, W, 3) float32
    linear RGB (``texture_from_image``). InputError naming ``where`` and the file if
    it is missing, not an image, or too large."""
    try:
        data = read_input_bytes(path, "texture", TEXTURE_BYTES)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    try:
        with Image.open(io.BytesIO(data)) as image:
            image.load()
            return texture_from_image(image, f"{where}: texture {str(path)!r}")
    except InputError:
        raise
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise InputError(f"{where}: cannot read the texture {str(path)!r}: {exc}") from None


def check_texture(texture, uvs, n_vertices, where):
    """``texture`` and ``uvs`` as an object keeps them, checked: (float32 (H, W, 3)
    finite in [0, 1], float64 (V, 2) finite), or (None, uvs) for an untextured
    object (which may still carry uvs). InputError naming ``where``."""
    if uvs is not None:
        uvs = np.asarray(uvs, dtype=np.float64)
        if uvs.shape != (n_vertices, 2):
            raise InputError(f"{where}: texture coordinates must be (V, 2) for its {n_vertices} vertices, got {uvs.shape}")
        if not np.isfinite(uvs).all():
            raise InputError(f"{where}: texture coordinates must be finite")
        if len(uvs) and np.abs(uvs).max() > MAX_UV:
            raise InputError(f"{where}: texture coordinates reach {np.abs(uvs).max():.3g}, beyond the +-{MAX_UV:g} "
                             "a texture repeats to in single precision")
    if texture is None:
        return None, uvs
    if uvs is None:
        raise InputError(f"{where}: has a texture but no texture coordinates")
    texture = np.asarray(texture, dtype=np.float32)
    if texture.ndim != 3 or texture.shape[2] != 3 or 0 in texture.shape:
        raise InputError(f"{where}: a texture must be (H, W, 3), got {texture.shape}")
    if not (np.isfinite(texture).all() and texture.min() >= 0.0 and texture.max() <= 1.0):
        raise InputError(f"{where}: texture values must lie in [0, 1] (a reflectance)")
    return texture, uvs


MAX_UV = 1e6  # texture coordinates beyond this are refused: float32 keeps 1/16 of a repeat there, no texel
CUTOFF = OPACITY_CUTOFF  # a mask's opacity below this is a hole, at and above it the surface (an alpha test)


def check_opacity(opacity, uvs, where):
    """A mask's ``opacity`` as an object keeps it, checked: float32 (H, W) finite in
    [0, 1], read at the object's ``uvs`` as a texture is (``lookup``; the kernels read
    it from a three-channel atlas, ``cutout_atlas``). Where it is below ``CUTOFF`` the
    surface is not there: rays pass through, the displays discard the fragment. None
    stays None. InputError naming ``where``."""
    if opacity is None:
        return None
    if uvs is None:
        raise InputError(f"{where}: has an opacity mask but no texture coordinates")
    opacity = np.asarray(opacity, dtype=np.float32)
    if opacity.ndim != 2 or 0 in opacity.shape:
        raise InputError(f"{where}: an opacity mask must be (H, W), got {opacity.shape}")
    if not (np.isfinite(opacity).all() and opacity.min() >= 0.0 and opacity.max() <= 1.0):
        raise InputError(f"{where}: opacity values must lie in [0, 1]")
    return opacity


WRAP_MODES = ("repeat", "mirror", "clamp")


def wrap_index(i, n, wrap="repeat"):
    """Texel indices i (any integers) on an axis of n texels: repeating (i mod n),
    mirrored (period 2n, the second half reversed) or clamped to [0, n - 1], as
    Mitsuba 3's bitmap wraps each of the four texels of a bilinear lookup."""
    i = np.asarray(i, dtype=np.int64)
    if wrap == "repeat":
        return np.mod(i, n)
    if wrap == "mirror":
        i = np.mod(i, 2 * n)
        return np.where(i >= n, 2 * n - 1 - i, i)
    if wrap == "clamp":
        return np.clip(i, 0, n - 1)
    raise ValueError(f"wrap mode {wrap!r} is not one of {', '.join(WRAP_MODES)}")


def wrapped_lookup(texture, uv, wrap="repeat"):
    """``lookup`` with the texels wrapped by ``wrap`` (``wrap_index``): (..., 3)
    float64, Mitsuba 3's bilinear bitmap lookup in each of its wrap modes; the
    reference ``as_repeating`` is tested against."""
    uv = np.asarray(uv, dtype=np.float64)
    tex = np.asarray(texture, dtype=np.float64)
    height, width = tex.shape[:2]
    x = uv[..., 0] * width - 0.5
    y = (1.0 - uv[..., 1]) * height - 0.5
    j0, i0 = np.floor(x), np.floor(y)
    fx, fy = (x - j0)[..., None], (y - i0)[..., None]
    j0, i0 = j0.astype(np.int64), i0.astype(np.int64)
    i0, i1 = wrap_index(i0, height, wrap), wrap_index(i0 + 1, height, wrap)
    j0, j1 = wrap_index(j0, width, wrap), wrap_index(j0 + 1, width, wrap)
    top = tex[i0, j0] + fx * (tex[i0, j1] - tex[i0, j0])
    bottom = tex[i1, j0] + fx * (tex[i1, j1] - tex[i1, j0])
    return top + fy * (bottom - top)


def _repeating_axis(coordinate, n, wrap, limit):
    """One axis of ``as_repeating``: (source texel of each new texel (n',) int64,
    scale, offset) with the new coordinate = scale * coordinate + offset (coordinate
    running along the texel order: u, or 1 - v), or None past ``limit`` texels."""
    x = coordinate * n - 0.5
    first, last = int(np.floor(x.min())), int(np.floor(x.max())) + 1  # every texel a lookup may touch
    span = last - first + 1
    if wrap == "mirror" and span > 2 * n:  # one mirrored pair of periods, repeating: exact for any range
        return wrap_index(np.arange(2 * n), n, "mirror"), 0.5, 0.0
    if span > limit:
        return None
    # texel k of the new axis is texel first + k of the old: x' = x - first, so c' = (c n - first) / span
    return wrap_index(np.arange(first, last + 1), n, wrap), n / span, -first / span


def as_repeating(texture, uvs, wrap, limit=MAX_TEXTURE_PIXELS):
    """A texture read in Mitsuba's ``wrap`` mode as one read repeating: (texture',
    uvs') with ``lookup(texture', uv')`` equal to ``wrapped_lookup(texture, uv,
    wrap)`` at every point of every triangle (the uvs' map is affine, so it commutes
    with the barycentric interpolation; equal up to rounding).

    repeat: unchanged. clamp, and mirror over at most two periods: the texels the
    uvs reach, laid out once (the image and a texel's margin where the uvs stay in
    [0, 1]); mirror over more: the image beside its mirror images (2H x 2W), uvs
    halved. None where the new texture would pass ``limit`` pixels (clamp over a
    range of uvs many images wide).
    """
    if wrap == "repeat":
        return texture, uvs
    uvs = np.asarray(uvs, dtype=np.float64)
    height, width = texture.shape[:2]
    columns = _repeating_axis(uvs[:, 0], width, wrap, limit)
    rows = _repeating_axis(1.0 - uvs[:, 1], height, wrap, limit)
    if columns is None or rows is None or len(columns[0]) * len(rows[0]) > limit:
        return None
    out = np.ascontiguousarray(texture[rows[0]][:, columns[0]])
    u = columns[1] * uvs[:, 0] + columns[2]
    v = 1.0 - (rows[1] * (1.0 - uvs[:, 1]) + rows[2])
    return out, np.stack([u, v], axis=1)


def atlas(textures):
    """Every texture of a scene in one flat array, as the kernels read them.

    textures : sequence of (H_k, W_k, 3) float32
    Returns (pixels (sum H_k W_k 3,) float32, offsets (K,) int64 where texture k
    starts, sizes (K, 2) int64 its (H_k, W_k)). With no texture the pixels are one
    texel of zeros (a kernel's arrays are never empty) and offsets, sizes empty.
    """
    if not textures:
        return np.zeros(3, np.float32), np.zeros(0, np.int64), np.zeros((0, 2), np.int64)
    sizes = np.array([t.shape[:2] for t in textures], dtype=np.int64)
    lengths = 3 * sizes[:, 0] * sizes[:, 1]
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    pixels = np.concatenate([np.ascontiguousarray(t, dtype=np.float32).ravel() for t in textures])
    return pixels, offsets, sizes


class Cutout(NamedTuple):
    """The opacity masks of a merged mesh's triangles (what the ray tracer filters by).

    image      : (T,) int64      each triangle's mask in the atlas, -1 where it has none
    corner_uvs : (T, 6) float32  its corners' texture coordinates (u0, v0, u1, v1, u2, v2)
    pixels, offsets, sizes : the masks' atlas (``cutout_atlas``)
    """

    image: np.ndarray
    corner_uvs: np.ndarray
    pixels: np.ndarray
    offsets: np.ndarray
    sizes: np.ndarray


def cutout_of(objects, triangle_object, faces, uvs):
    """The ``Cutout`` of a merged mesh (``faces`` (T, 3) into the objects' concatenated
    ``uvs`` (N, 2), ``triangle_object`` (T,)), each mask once however many objects
    share it; None where no object has one."""
    masks, index = [], {}
    object_mask = np.full(len(objects), -1, np.int64)
    for i, o in enumerate(objects):
        if o.opacity is not None:
            object_mask[i] = index.setdefault(id(o.opacity), len(masks))
            if object_mask[i] == len(masks):
                masks.append(o.opacity)
    if not masks:
        return None
    image = object_mask[triangle_object]
    corner_uvs = np.where((image >= 0)[:, None], np.asarray(uvs, np.float32)[faces].reshape(-1, 6), np.float32(0.0))
    return Cutout(image, np.ascontiguousarray(corner_uvs, np.float32), *cutout_atlas(masks))


def cutout_atlas(opacities):
    """The atlas (``atlas``) of a scene's opacity masks, each (H, W) copied to three
    channels so that ``texel`` reads it as it reads a texture."""
    return atlas([np.repeat(np.asarray(o, np.float32)[..., None], 3, axis=2) for o in opacities])


@numba.njit(cache=True, nogil=True, inline="always")
def _wrap(i, n):
    i = i % n
    return i + n if i < 0 else i


@numba.njit(cache=True, nogil=True, inline="always")
def texel(pixels, offsets, sizes, k, u, v):
    """Texture k of an atlas (``atlas``) at texture coordinates (u, v): bilinear,
    repeating, as an RGB 3-tuple of float64 (``lookup``, one point). Coordinates that
    are not finite read the texel at (0, 0)."""
    if not (math.isfinite(u) and math.isfinite(v)):
        u, v = 0.0, 0.0
    height, width = sizes[k, 0], sizes[k, 1]
    base = offsets[k]
    x = u * width - 0.5
    y = (1.0 - v) * height - 0.5
    xf = math.floor(x)
    yf = math.floor(y)
    fx, fy = x - xf, y - yf
    j0 = _wrap(np.int64(xf), width)
    i0 = _wrap(np.int64(yf), height)
    j1 = j0 + 1 if j0 + 1 < width else 0
    i1 = i0 + 1 if i0 + 1 < height else 0
    a = base + 3 * (i0 * width + j0)
    b = base + 3 * (i0 * width + j1)
    c = base + 3 * (i1 * width + j0)
    d = base + 3 * (i1 * width + j1)
    out0 = _bilinear(pixels, a, b, c, d, fx, fy, 0)
    out1 = _bilinear(pixels, a, b, c, d, fx, fy, 1)
    out2 = _bilinear(pixels, a, b, c, d, fx, fy, 2)
    return out0, out1, out2


@numba.njit(cache=True, nogil=True, inline="always")
def _bilinear(pixels, a, b, c, d, fx, fy, ch):
    """Channel ch between four texels at flat indices a (top left), b (top right), c
    (bottom left), d (bottom right), as ``lookup`` computes it (the same rounding)."""
    ta, tb = np.float64(pixels[a + ch]), np.float64(pixels[b + ch])
    tc, td = np.float64(pixels[c + ch]), np.float64(pixels[d + ch])
    top = ta + fx * (tb - ta)
    bottom = tc + fx * (td - tc)
    return top + fy * (bottom - top)
