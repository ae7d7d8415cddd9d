"""A textured object's diffuse term, as the solution and fit files carry it.

A textured object (``radiosity.scene.textures``) reflects diffusely with
``kd(x) = kd * texture(uv(x))``. Its diffuse radiance ``kd(x) / pi * E(x)`` changes
with the texture much faster than the solver's mesh can follow, so the files keep its
two factors apart and a display multiplies them per pixel:

    diffuse(x) = kd * lookup(texture, uv(x)) / pi * E(x)

with ``uv(x)`` and the irradiance ``E(x)`` interpolated barycentrically from the
vertices. The object's stored radiance then holds everything else (emission, the
specular part). A material with Fresnel (``radiosity.formats.material``) sends its
diffuse part out with a further factor b(cos_o) = 1 - (1 - cos_o)^5; the stored
radiance leaves out exactly what the solver added, but the term above is drawn
without that factor (1 at the normal, 0.94 at 65 degrees, 0.60 at 80 degrees): a
textured glossy Fresnel surface seen at grazing angles is drawn too bright. The conventions (also ``radiosity.scene.textures``'s):

    texture : (H, W, 3) linear RGB in [0, 1], row 0 the image's top row
    uvs     : (V, 2), u to the right, v up: (0, 0) the image's bottom-left corner
    lookup  : texel (i, j) centred on u = (j + 0.5) / W, v = 1 - (i + 0.5) / H;
              bilinear between the four nearest texel centres, repeating

In a file (solution version 3, fit version 4), per textured object, all or none:
``<name>/uvs`` (V, 2) float32, ``<name>/irradiance`` (V, 3) float32 and
``<name>/texture`` (H, W, 3): uint8 holding the sRGB encoding when that gives back the
same float32 values (the 8-bit images texture files hold), float32 linear otherwise.
A textured object may also have an opacity mask (solution and fit version 9):
``<name>/opacity`` (H', W') read through the same uvs as the texture, uint8 holding
round(255 opacity) when that gives back the same float32 values (an 8-bit alpha
channel), float32 in [0, 1] otherwise; the surface is there only where the mask reads
at least ``OPACITY_CUTOFF`` (an alpha test, in every stage).

``lookup`` is the numpy reference every consumer (the fit's shading, the display's
tests) uses; ``radiosity.scene.textures.texel`` is the kernels' copy of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from radiosity.formats.material import srgb_to_linear

__all__ = ["KEYS", "MAX_TEXTURE_PIXELS", "OPACITY_CUTOFF", "TexturedDiffuse", "linear_to_srgb8", "lookup", "read_textured"]

KEYS = ("uvs", "irradiance", "texture")
MAX_TEXTURE_PIXELS = 1 << 26  # 64 Mpixels: a texture larger is refused
OPACITY_CUTOFF = 0.5  # a mask reading below this is a hole (``radiosity.scene.textures.CUTOFF`` is this)


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
    (``radiosity.formats.npz``), or None if it has none; the archive's one-line
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
