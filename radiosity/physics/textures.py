"""Diffuse textures: images read as linear RGB, looked up at texture coordinates, and a
textured object's diffuse term as the solution and fit files carry it.

A textured object's diffuse reflectance at a point x is

    kd(x) = kd * texture(uv(x))

with ``kd`` its material's diffuse colour and ``uv(x)`` its per-vertex texture
coordinates interpolated barycentrically. The conventions, one for every format
(each loader converts to them) and every stage:

    texture : (H, W, 3) float32, linear RGB in [0, 1], row 0 the image's top row
    uvs     : (V, 2) float64, u to the right, v up: (0, 0) is the image's bottom-left
              corner, (1, 1) its top-right (OBJ's and OpenGL's convention; glTF's v
              runs down, and trimesh flips it on reading)
    lookup  : texel (i, j) (row i from the top, column j) is centred on
              u = (j + 0.5) / W, v = 1 - (i + 0.5) / H; bilinear between the four
              nearest texel centres, repeating outside [0, 1) (Mitsuba's default)

``lookup`` is the numpy reference every consumer uses (the fit's shading, the
displays' tests); ``texel`` the same lookup for the kernels, which read every texture
of a scene from one flat atlas (``atlas``).

Wrap modes: every stage repeats. Mitsuba's other two (``mirror``: the image mirrored
at each edge; ``clamp``: the edge texels extended) are turned into repeating ones by
the loader (``as_repeating``: a texture and uvs that read, repeating, exactly what the
original reads in its mode), so the kernels, the files and the displays know one
mode; ``wrapped_lookup`` is the reference of the three.

In the files (``TexturedDiffuse``). A textured object's diffuse radiance
``kd(x) / pi * E(x)`` changes with the texture much faster than the solver's mesh can
follow, so the files keep its two factors apart and a display multiplies them per
pixel:

    diffuse(x) = kd * lookup(texture, uv(x)) / pi * E(x)

with ``uv(x)`` and the irradiance ``E(x)`` interpolated barycentrically from the
vertices. The object's stored radiance then holds everything else (emission, the
specular part). A material with Fresnel (``radiosity.physics.materials``) sends its
diffuse part out with a further factor b(cos_o) = 1 - (1 - cos_o)^5; the stored
radiance leaves out exactly what the solver added, but the term above is drawn
without that factor (1 at the normal, 0.94 at 65 degrees, 0.60 at 80 degrees): a
textured glossy Fresnel surface seen at grazing angles is drawn too bright.

Per textured object (solution version 3, fit version 4), all or none:
``<name>/uvs`` (V, 2) float32, ``<name>/irradiance`` (V, 3) float32 and
``<name>/texture`` (H, W, 3): uint8 holding the sRGB encoding when that gives back the
same float32 values (the 8-bit images texture files hold), float32 linear otherwise.
A textured object may also have an opacity mask (solution and fit version 9):
``<name>/opacity`` (H', W') read through the same uvs as the texture, uint8 holding
round(255 opacity) when that gives back the same float32 values (an 8-bit alpha
channel), float32 in [0, 1] otherwise; the surface is there only where the mask reads
at least ``OPACITY_CUTOFF`` (an alpha test, in every stage).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.files.errors import InputError
from radiosity.files.images import MAX_TEXTURE_PIXELS, picture_from_array, read_image
from radiosity.physics.materials import srgb_to_linear

KEYS = ("uvs", "irradiance", "texture")
OPACITY_CUTOFF = 0.5  # a mask reading below this is a hole, at and above it the surface (an alpha test)


def _coordinates(u, v, height, width):
    """The bilinear footprint of (u, v) on a height x width texture: the rows (i0,
    i1), columns (j0, j1) and weights (fy, fx) toward i1 and j1, repeating."""
    x = u * width - 0.5
    y = (1.0 - v) * height - 0.5
    j0 = np.floor(x)
    i0 = np.floor(y)
    fx, fy = x - j0, y - i0
    j0 = np.mod(j0, width).astype(np.int64)
    i0 = np.mod(i0, height).astype(np.int64)
    return i0, (i0 + 1) % height, j0, (j0 + 1) % width, fy, fx


def lookup(texture, uv):
    """The texture's bilinear, repeating value at texture coordinates uv (..., 2):
    (..., 3) float64. Coordinates that are not finite read at (0, 0), as the kernels'
    ``texel`` does."""
    uv = np.asarray(uv, dtype=np.float64)
    uv = np.where(np.isfinite(uv).all(axis=-1, keepdims=True), uv, 0.0)
    tex = np.asarray(texture, dtype=np.float64)
    i0, i1, j0, j1, fy, fx = _coordinates(uv[..., 0], uv[..., 1], *tex.shape[:2])
    fx, fy = fx[..., None], fy[..., None]
    top = tex[i0, j0] + fx * (tex[i0, j1] - tex[i0, j0])
    bottom = tex[i1, j0] + fx * (tex[i1, j1] - tex[i1, j0])
    return top + fy * (bottom - top)


def _srgb8_table():
    """float32 linear values of the 256 sRGB codes."""
    return srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def linear_to_srgb8(texture):
    """The uint8 sRGB codes whose decoding gives back ``texture`` (float32) exactly, or
    None if some value is not such a decoding (a float image, or one edited after
    decoding)."""
    table = _srgb8_table()
    t = np.asarray(texture, dtype=np.float32)
    codes = np.clip(np.searchsorted(table, t), 0, 255)
    below = np.clip(codes - 1, 0, 255)
    codes = np.where(np.abs(table[below] - t) < np.abs(table[codes] - t), below, codes).astype(np.uint8)
    return codes if np.array_equal(table[codes], t) else None


@dataclass(frozen=True, eq=False, repr=False)
class TexturedDiffuse:
    """A textured object's diffuse term, validated on construction (ValueError).

    uvs (V, 2) float32 finite; irradiance (V, 3) float32 finite, >= 0; texture (H, W,
    3) float32 linear in [0, 1]; kd: the material's diffuse colour (3,), the factor the
    texture multiplies; opacity (H', W') float32 in [0, 1] or None: the object's mask,
    read through the same uvs (a hole where it is below ``OPACITY_CUTOFF``)."""

    uvs: np.ndarray
    irradiance: np.ndarray
    texture: np.ndarray
    kd: tuple
    opacity: np.ndarray | None = None

    def __post_init__(self):
        put = object.__setattr__
        uvs = np.ascontiguousarray(self.uvs, dtype=np.float32)
        e = np.ascontiguousarray(self.irradiance, dtype=np.float32)
        tex = np.ascontiguousarray(self.texture, dtype=np.float32)
        kd = tuple(float(c) for c in np.asarray(self.kd, dtype=np.float64).reshape(-1))
        if uvs.ndim != 2 or uvs.shape[1] != 2:
            raise ValueError(f"'uvs' has shape {uvs.shape}, expected (V, 2)")
        if e.shape != (len(uvs), 3):
            raise ValueError(f"'irradiance' has shape {e.shape}, expected (V, 3) = ({len(uvs)}, 3)")
        if tex.ndim != 3 or tex.shape[2] != 3 or 0 in tex.shape:
            raise ValueError(f"'texture' has shape {tex.shape}, expected (H, W, 3)")
        if tex.shape[0] * tex.shape[1] > MAX_TEXTURE_PIXELS:
            raise ValueError(f"'texture' has {tex.shape[0]} x {tex.shape[1]} pixels, more than {MAX_TEXTURE_PIXELS:,}")
        if not np.isfinite(uvs).all():
            raise ValueError("'uvs' has NaN or infinite values")
        if not (np.isfinite(e).all() and (e >= 0).all()):
            raise ValueError("'irradiance' has NaN, infinite or negative values")
        if not (np.isfinite(tex).all() and tex.min() >= 0.0 and tex.max() <= 1.0):
            raise ValueError("'texture' has values outside [0, 1] (a reflectance)")
        if len(kd) != 3:
            raise ValueError(f"kd must be 3 numbers, got {len(kd)}")
        if self.opacity is not None:
            mask = np.ascontiguousarray(self.opacity, dtype=np.float32)
            if mask.ndim != 2 or 0 in mask.shape:
                raise ValueError(f"'opacity' has shape {mask.shape}, expected (H, W)")
            if mask.shape[0] * mask.shape[1] > MAX_TEXTURE_PIXELS:
                raise ValueError(f"'opacity' has {mask.shape[0]} x {mask.shape[1]} pixels, more than "
                                 f"{MAX_TEXTURE_PIXELS:,}")
            if not (np.isfinite(mask).all() and mask.min() >= 0.0 and mask.max() <= 1.0):
                raise ValueError("'opacity' has values outside [0, 1]")
            put(self, "opacity", mask)
        put(self, "uvs", uvs)
        put(self, "irradiance", e)
        put(self, "texture", tex)
        put(self, "kd", kd)

    def __repr__(self):
        return f"TexturedDiffuse(V={len(self.uvs)}, texture={self.texture.shape[1]}x{self.texture.shape[0]})"

    @property
    def n_vertices(self):
        return len(self.uvs)

    def radiance(self, vertices=slice(None), weights=None):
        """kd * texture(uv) / pi * E (..., 3) float64: at the vertices ``vertices``, or,
        with ``weights`` (..., 3), at points interpolated from the corners
        ``vertices`` (..., 3) (barycentric weights)."""
        uvs = self.uvs.astype(np.float64)[vertices]
        e = self.irradiance.astype(np.float64)[vertices]
        if weights is not None:
            weights = np.asarray(weights, dtype=np.float64)[..., None]
            uvs = np.sum(weights * uvs, axis=-2)
            e = np.sum(weights * e, axis=-2)
        return np.asarray(self.kd) / np.pi * lookup(self.texture, uvs) * e

    def arrays(self, name):
        """The file's members of object ``name``."""
        codes = linear_to_srgb8(self.texture)
        out = {
            f"{name}/uvs": self.uvs,
            f"{name}/irradiance": self.irradiance,
            f"{name}/texture": self.texture if codes is None else codes,
        }
        if self.opacity is not None:
            codes = np.round(self.opacity * 255.0).astype(np.uint8)
            exact = np.array_equal((codes / np.float32(255.0)).astype(np.float32), self.opacity)
            out[f"{name}/opacity"] = codes if exact else self.opacity
        return out

    def covered(self, uv):
        """Whether the surface is there at texture coordinates uv (..., 2): True
        everywhere without a mask, else where the mask reads at least OPACITY_CUTOFF."""
        uv = np.asarray(uv, dtype=np.float64)
        if self.opacity is None:
            return np.ones(uv.shape[:-1], bool)
        return lookup(self.opacity[..., None], uv)[..., 0] >= OPACITY_CUTOFF

    def nbytes(self):
        """The bytes its arrays take in memory."""
        return self.uvs.nbytes + self.irradiance.nbytes + self.texture.nbytes + (
            0 if self.opacity is None else self.opacity.nbytes)


def _linear_texture(archive, key):
    """Texture ``key`` of an open archive as float32 linear reflectance."""
    texture = archive.array(key, "fiu", (None, None, 3))
    if texture.dtype == np.uint8:
        return _srgb8_table()[texture]
    if texture.dtype.kind != "f":
        raise archive.fail(f"'{key}' has dtype {texture.dtype}, expected uint8 (sRGB) or float32 (linear)")
    return np.ascontiguousarray(texture, dtype=np.float32)


def _opacity(archive, key):
    """Mask ``key`` of an open archive as float32 opacity."""
    mask = archive.array(key, "fiu", (None, None))
    if mask.dtype == np.uint8:
        return (mask / np.float32(255.0)).astype(np.float32)
    if mask.dtype.kind != "f":
        raise archive.fail(f"'{key}' has dtype {mask.dtype}, expected uint8 (opacity x 255) or float32")
    return np.ascontiguousarray(mask, dtype=np.float32)


def read_textured(archive, name, n_vertices, kd, masks=False):
    """Object ``name``'s ``TexturedDiffuse`` from an open archive
    (``radiosity.files.npz``), or None if it has none; the archive's one-line
    InputError if only some of its members are there or one is malformed. ``masks``:
    the file's version may hold an opacity mask (``<name>/opacity``), else one is
    passed over."""
    present = [k for k in KEYS if f"{name}/{k}" in archive.keys]
    if not present:
        return None
    if len(present) != len(KEYS):
        missing = next(k for k in KEYS if k not in present)
        raise archive.fail(f"object {name!r} has '{name}/{present[0]}' but no '{name}/{missing}': a textured object has all of {', '.join(KEYS)}")
    uvs = archive.array(f"{name}/uvs", "fiu", (n_vertices, 2))
    irradiance = archive.array(f"{name}/irradiance", "fiu", (n_vertices, 3))
    texture = archive.shared(f"{name}/texture", lambda key: _linear_texture(archive, key))
    opacity = None
    if masks and f"{name}/opacity" in archive.keys:
        opacity = archive.shared(f"{name}/opacity", lambda key: _opacity(archive, key))
    try:
        return TexturedDiffuse(uvs=uvs, irradiance=irradiance, texture=texture, kd=kd, opacity=opacity)
    except ValueError as exc:
        raise archive.fail(f"object {name!r}: {exc}") from None





def texture_from_image(image, where):
    """A PIL image (as trimesh decodes a mesh file's images) as a texture: (H, W, 3)
    float32 linear RGB, row 0 the top, through the one image reader's decoding
    (``radiosity.files.images.picture_from_array``: 8- and 16-bit sRGB-decoded, float
    linear). Alpha is dropped; a grey image is repeated into the three channels; its
    size is checked before its pixels are read."""
    width, height = image.size
    if width < 1 or height < 1:
        raise InputError(f"{where}: the texture is empty ({width} x {height} pixels)")
    if width * height > MAX_TEXTURE_PIXELS:
        raise InputError(
            f"{where}: the texture is {width} x {height} pixels, more than the {MAX_TEXTURE_PIXELS:,} allowed"
        )
    if image.mode.startswith("I"):  # 16 bits a channel (pillow's "I;16", or "I" holding them)
        pixels = np.clip(np.asarray(image), 0, 65535).astype(np.uint16)
    elif image.mode == "F":
        pixels = np.asarray(image, dtype=np.float32)
    else:
        pixels = np.asarray(image.convert("RGB"))
    return picture_from_array(pixels, f"{where}: texture", alpha=False).rgb.astype(np.float32)


def read_texture(path, where):
    """A texture from an image file (``radiosity.files.images.read_image``: 8- and 16-bit
    images sRGB-decoded, OpenEXR, HDR, PFM as they are): (H, W, 3) float32 linear RGB.
    InputError naming ``where`` and the file if it is missing, not an image, or too large."""
    try:
        return read_image(path, "texture").rgb.astype(np.float32)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


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


def check_opacity(opacity, uvs, where):
    """A mask's ``opacity`` as an object keeps it, checked: float32 (H, W) finite in
    [0, 1], read at the object's ``uvs`` as a texture is (``lookup``; the kernels read
    it from a three-channel atlas, ``cutout_atlas``). Where it is below ``OPACITY_CUTOFF`` the
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
