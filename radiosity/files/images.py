"""The one image reader: every image any stage reads goes through here.

- ``read_image(path, what)``: a texture, a mask or an environment map, from any scene
  kind (TOML, Mitsuba XML, the images an MTL or glTF names): 8- and 16-bit images
  (PNG, JPEG, ... through imageio, their size checked from the header before they are
  decoded) sRGB-decoded unless ``raw``, their alpha kept; OpenEXR, Radiance HDR, PFM
  and .npy as the linear values they hold. -> ``Picture`` (linear RGB, alpha or None).
- ``picture_from_array``: the same decoding of pixels another library has read (the
  images trimesh decodes for a mesh file).
- ``read_hdr_image(path, what)``: a linear HDR image alone, checked as radiance (no NaN,
  infinite or negative values): ``vlights compare --reference``'s image.

OpenEXR is read by the OpenEXR library; RGBE, PFM and NPY by the few lines below.
Everything lives in the shared core, since every stage reads images.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import warnings
from typing import NamedTuple

import numpy as np

from radiosity.files.camera import MAX_IMAGE_SIDE
from radiosity.files.errors import InputError, SceneWarning

__all__ = ["HDR_EXTENSIONS", "MAX_TEXTURE_PIXELS", "TEXTURE_BYTES", "Picture", "picture_from_array", "read_hdr_image",
           "read_image"]

HDR_EXTENSIONS = (".exr", ".hdr", ".pfm", ".npy")
TEXTURE_BYTES = 1 << 30  # an image file of a scene larger is refused before it is decoded
MAX_TEXTURE_PIXELS = 1 << 26  # 64 Mpixels: a scene's image larger is refused
HDR_IMAGE_BYTES = 4 * 2**30  # a 16384 x 16384 RGB float32 image is 3 GiB; nothing larger could be drawn
_LDR_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".gif", ".webp")
_MAGIC = (  # (extension, first bytes, name): how a file says what it is
    (".exr", b"\x76\x2f\x31\x01", "an OpenEXR image"),
    (".hdr", b"#?", "a Radiance HDR (RGBE) image"),
    (".pfm", b"PF", "a colour PFM image"),
    (".pfm", b"Pf", "a grey PFM image"),
    (".npy", b"\x93NUMPY", "a NumPy .npy array"),
    (".png", b"\x89PNG", "a PNG image"),
    (".jpg", b"\xff\xd8\xff", "a JPEG image"),
    (".tif", b"II*\x00", "a TIFF image"),
    (".tif", b"MM\x00*", "a TIFF image"),
)


class _Bad(Exception):
    """A reader's complaint about the file's contents, worded after its name by ``read_hdr_image``."""


def read_hdr_image(path, what="--reference"):
    """A linear HDR image as (H, W, 3) float32 RGB, row 0 at the top, from an OpenEXR
    (.exr), Radiance HDR (.hdr, RGBE), PFM (.pfm) or NumPy (.npy) file, chosen by the
    extension and checked against the file's first bytes.

    Channels: RGB; RGBA (alpha dropped); one channel (grey, copied to R, G and B); an
    OpenEXR file's layers beside them (channels "layer.X") left, with a warning.
    Refused with InputError, one line naming ``what``, the file and the problem: another
    extension, a file that is not what its extension says, a truncated or corrupt file,
    an empty image, one wider or taller than ``MAX_IMAGE_SIDE``, another channel count,
    and NaN, infinite or negative values (with their counts).

    EXR is read by the OpenEXR library (half, float; scanline or tiled; the data window
    must be the display window); RGBE, PFM and NPY by the few lines below (no library
    here reads RGBE or colour PFM): RGBE as Radiance itself decodes it ((byte + 0.5) *
    2^(exponent - 136), both run-length schemes and all eight orientations, divided by
    the header's EXPOSURE and COLORCORR as its specification says); PFM's scale only
    gives the byte order, as every reader takes it.
    """
    from radiosity.files.inputs import read_input_bytes

    shown = str(path)
    suffix = os.path.splitext(shown)[1].lower()
    if suffix not in HDR_EXTENSIONS:
        why = " (8-bit and tone-mapped, not linear radiance)" if suffix in _LDR_EXTENSIONS else ""
        raise InputError(f"{what} {shown!r}: {suffix or 'no extension'}{why} is not a linear HDR image; give "
                         f"{', '.join(HDR_EXTENSIONS[:-1])} or {HDR_EXTENSIONS[-1]}")
    data = read_input_bytes(path, what, HDR_IMAGE_BYTES)
    return _checked_radiance(_hdr_pixels(data, suffix, f"{what} {shown!r}"), f"{what} {shown!r}")


def _hdr_pixels(data, suffix, where):
    """The pixels of an HDR file's bytes (its kind by ``suffix``, checked against its first
    bytes), as its reader gives them; InputError naming ``where``."""
    expected = [name for ext, magic, name in _MAGIC if ext == suffix]
    if not any(data.startswith(magic) for ext, magic, _ in _MAGIC if ext == suffix):
        actual = next((name for _, magic, name in _MAGIC if data.startswith(magic)), None)
        raise InputError(f"{where} is not {expected[0].replace('a colour ', 'a ')}" + (
            f": it is {actual} (its extension is wrong)" if actual else
            " (empty)" if not data else f" (it starts with {data[:8]!r})"))
    reader = {".exr": _read_exr, ".hdr": _read_rgbe, ".pfm": _read_pfm, ".npy": _read_npy}[suffix]
    try:
        return reader(data, where) if reader is _read_exr else reader(data)
    except _Bad as exc:
        raise InputError(f"{where} {exc}") from None


class Picture(NamedTuple):
    """An image as the scene loaders keep it: ``rgb`` (H, W, 3) float64 linear (an 8- or
    16-bit file's values sRGB-decoded unless read raw), ``alpha`` (H, W) float64 in
    [0, 1] or None (a float image's alpha is not read)."""

    rgb: np.ndarray
    alpha: np.ndarray | None


def read_image(path, what="image", raw=False):
    """The ``Picture`` of an image file of a scene: OpenEXR, Radiance HDR, PFM or .npy
    (by the extension) as the linear values it holds; any other (PNG, JPEG, BMP, TGA,
    TIFF, ... through imageio, 8 or 16 bits a channel) sRGB-decoded unless ``raw``, its
    alpha (linear, as PNG stores it) kept; one channel copied to three. InputError in
    one line naming ``what`` and the file: missing, not a regular file, larger than
    TEXTURE_BYTES, of more than MAX_TEXTURE_PIXELS pixels (checked from the header before
    it is decoded), not an image this reads, or holding NaN or infinite values."""
    from radiosity.files.inputs import read_input_bytes

    shown = f"{what} {str(path)!r}"
    data = read_input_bytes(path, what, TEXTURE_BYTES)
    if not data:
        raise InputError(f"{shown} is empty")
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix in HDR_EXTENSIONS:
        return picture_from_array(_hdr_pixels(data, suffix, shown), shown, raw=True, alpha=False)
    _check_picture_size(data, shown)
    if data.startswith(b"\x89PNG\r\n\x1a\n") and data[24:26] in (b"\x10\x02", b"\x10\x06"):
        return picture_from_array(_rgb16_png(path, data[25] == 6, shown), shown, raw=raw)
    import imageio.v3 as iio

    try:
        pixels = np.asarray(iio.imread(data, extension=suffix or None))
    except Exception as exc:  # imageio raises many types for a bad or unknown file
        raise InputError(f"cannot read {shown}: {' '.join(str(exc).split())}") from None
    return picture_from_array(pixels, shown, raw=raw)


def _rgb16_png(path, alpha, shown):
    """A PNG of 16-bit RGB or RGBA (its IHDR's bit depth 16, colour type 2 or 6) as
    (H, W, 3 or 4) uint16: pillow (imageio's PNG reader) keeps only the top 8 bits of
    these, ffmpeg (imageio-ffmpeg's) all 16."""
    import imageio_ffmpeg

    frames = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgba64le", bits_per_pixel=64)
    try:
        width, height = next(frames)["size"]
        pixels = np.frombuffer(next(frames), "<u2").reshape(height, width, 4)
    except (StopIteration, RuntimeError, OSError, ValueError):  # ffmpeg's whole log: not one line
        raise InputError(f"cannot read {shown}: a 16-bit PNG that is truncated or corrupt (ffmpeg decodes none of "
                         "it)") from None
    finally:
        frames.close()
    return pixels if alpha else pixels[..., :3]


def _check_picture_size(data, shown):
    """Refuse a picture of more than MAX_TEXTURE_PIXELS from its header, before it is
    decoded (a PNG of a few hundred bytes may claim 20000 x 20000 pixels): where pillow
    reads the header; a file it does not read is left to the decoder."""
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as image:
            width, height = image.size
    except Image.DecompressionBombError:
        width = height = None
    except Exception:  # not for pillow, or damaged: the decoder says which
        return
    if width is None or width * height > MAX_TEXTURE_PIXELS:
        size = "more pixels than pillow opens" if width is None else f"{width} x {height} pixels"
        raise InputError(f"{shown} is {size}, more than the {MAX_TEXTURE_PIXELS:,} allowed")


def picture_from_array(pixels, shown, raw=False, alpha=True):
    """The ``Picture`` of decoded pixels (H, W), (H, W, C) with C in 1-4: integers (8 or 16
    bits) scaled to [0, 1] and sRGB-decoded unless ``raw``, floats as they are; C 2 or 4
    holds alpha (kept where ``alpha``). InputError naming ``shown`` for another shape, an
    empty or too large image, or NaN or infinite values."""
    from radiosity.physics.materials import srgb_to_linear

    image = np.asarray(pixels)
    if image.ndim == 2:
        image = image[..., None]
    if image.ndim != 3 or image.shape[2] not in (1, 2, 3, 4) or image.size == 0:
        raise InputError(f"{shown} is not an RGB image (shape {image.shape})")
    if image.shape[0] * image.shape[1] > MAX_TEXTURE_PIXELS:
        raise InputError(f"{shown} is {image.shape[1]} x {image.shape[0]} pixels, more than the "
                         f"{MAX_TEXTURE_PIXELS:,} allowed")
    kept = image[..., -1] if alpha and image.shape[2] in (2, 4) else None
    rgb = image[..., :1].repeat(3, axis=2) if image.shape[2] <= 2 else image[..., :3]
    if image.dtype.kind in "ub":
        top = 1 if image.dtype.kind == "b" else np.iinfo(image.dtype).max
        encoded = rgb.astype(np.float64) / top
        return Picture(encoded if raw else srgb_to_linear(encoded), None if kept is None else kept / top)
    if image.dtype.kind != "f":
        raise InputError(f"{shown} holds {image.dtype} values, not an image's")
    rgb = rgb.astype(np.float64)
    if not np.isfinite(rgb).all():
        raise InputError(f"{shown} holds NaN or infinite values")
    return Picture(rgb, None if kept is None else np.clip(kept.astype(np.float64), 0.0, 1.0))


def _checked_radiance(image, where):
    """(H, W, C) or (H, W) numbers -> (H, W, 3) float32 RGB, refusing what is not an image of radiance."""
    if image.ndim == 2:
        image = image[:, :, None]
    if image.ndim != 3:
        raise InputError(f"{where} is an array of shape {image.shape}, not an image (height, width, channels)")
    h, w, c = image.shape
    if h == 0 or w == 0:
        raise InputError(f"{where} is empty ({w}x{h} pixels)")
    if max(h, w) > MAX_IMAGE_SIDE:
        raise InputError(f"{where} is {w}x{h} pixels; at most {MAX_IMAGE_SIDE} a side can be drawn")
    if c not in (1, 3, 4):
        raise InputError(f"{where} has {c} channels; an image takes 1 (grey), 3 (RGB) or 4 (RGBA, alpha dropped)")
    if image.dtype.kind != "f":
        raise InputError(f"{where} holds {image.dtype} values, not floating-point linear radiance")
    rgb = image[:, :, :3] if c >= 3 else np.repeat(image, 3, axis=2)
    with np.errstate(over="ignore"):
        rgb = np.ascontiguousarray(rgb, np.float32)
    nan, inf = int(np.isnan(rgb).sum()), int(np.isinf(rgb).sum())
    if nan or inf:
        raise InputError(f"{where} has {nan} NaN and {inf} infinite values (of {rgb.size}; beyond float32 counts "
                         "as infinite); radiance must be finite")
    negative = int((rgb < 0).sum())
    if negative:
        raise InputError(f"{where} has {negative} negative values (of {rgb.size}, the lowest {rgb.min():.3g}); "
                         "radiance is not negative (a reconstruction filter with negative lobes, Mitchell or "
                         "Lanczos, makes them: render the reference with a box or Gaussian filter)")
    return rgb


@contextlib.contextmanager
def _quiet_output():
    """Silence standard output and error, both Python's streams and file descriptors
    1 and 2 (the OpenEXR library prints its own reasons, through either, beside the
    exception it raises); yields a list that receives what was printed, as one line."""
    import ctypes
    import io
    import sys
    import tempfile

    said = []
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    saved = [os.dup(1), os.dup(2)]
    text = io.StringIO()
    with tempfile.TemporaryFile() as sink, contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield said
        finally:
            with contextlib.suppress(Exception):
                ctypes.CDLL(None).fflush(None)  # C stdio's buffers into the sink, not after it
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            printed = sink.read(4096).decode("utf-8", "replace") + " " + text.getvalue()[:4096]
            said.append(" ".join(printed.split()))


def _read_exr(data, where="the image"):
    """OpenEXR bytes -> (H, W, C) float: R, G, B (and A), or a single channel; layers
    beside them (a Mitsuba aov integrator's depth, normals, ...: channels named
    "layer.X") are left, with a warning naming ``where``."""
    import io

    import OpenEXR

    def open_file(header_only):
        with _quiet_output() as said:
            try:
                with OpenEXR.File(io.BytesIO(data), separate_channels=True, header_only=header_only) as f:
                    channels = None if header_only else {k: np.array(v.pixels) for k, v in f.channels().items()}
                    return list(f.parts), dict(f.header()), channels
            except Exception as exc:  # the bindings raise RuntimeError, ValueError, ... for a bad file
                failure = " ".join(str(exc).split())
        reason = said[0].replace("<python_buffer>: ", "") if said and said[0] else failure
        raise _Bad(f"cannot be read by the OpenEXR library (truncated or corrupt?): {reason}")

    parts, header, _ = open_file(True)
    if len(parts) != 1:
        raise _Bad(f"is a multi-part OpenEXR file ({len(parts)} parts); give a single-part image")
    data_window, display_window = (np.asarray(header[k]).reshape(2, 2) for k in ("dataWindow", "displayWindow"))
    if not np.array_equal(data_window, display_window):
        raise _Bad(f"has a data window {data_window.tolist()} other than its display window {display_window.tolist()}; "
                   "give an image whose pixels cover the whole frame")
    w, h = (display_window[1] - display_window[0] + 1).tolist()
    if max(w, h) > MAX_IMAGE_SIDE or min(w, h) <= 0:
        raise _Bad(f"is {w}x{h} pixels; an image is 1 to {MAX_IMAGE_SIDE} a side")
    _, _, channels = open_file(False)
    names = sorted(c for c in channels if "." not in c)  # the image's own channels
    layers = sorted({c.rsplit(".", 1)[0] for c in channels if "." in c})  # "layer.X": other images beside it (AOVs)
    if {"R", "G", "B"} <= set(names) and set(names) <= {"R", "G", "B", "A"}:
        order = ["R", "G", "B"]
    elif len(names) == 1:
        order = names
    else:
        raise _Bad(f"has {len(names)} channels ({', '.join(names)}); an image takes R, G, B (and A, dropped) "
                   "or a single channel" + (f", beside layers ({', '.join(layers)}) it leaves" if layers else ""))
    if layers:  # a Mitsuba aov integrator's file: the render is R, G, B; depth, normals, ... are layers
        warnings.warn(f"{where}: its {len(layers)} other layer(s) ({', '.join(layers)}) are not read: the image is "
                      f"its {', '.join(order)}", SceneWarning, stacklevel=2)
    planes = [channels[name] for name in order]
    if any(p.dtype.kind != "f" for p in planes):
        raise _Bad(f"has channels of {planes[0].dtype} values (an ID or mask image), not radiance")
    return np.stack(planes, axis=2)


def _read_pfm(data):
    """PFM bytes ("PF" colour, "Pf" grey; width, height, scale whose sign is the byte
    order: negative little-endian; rows bottom to top) -> (H, W, C) float32."""
    tokens, pos = [], 0
    while len(tokens) < 4:  # magic, width, height, scale: ASCII separated by whitespace
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        start = pos
        while pos < len(data) and not data[pos:pos + 1].isspace():
            pos += 1
        if pos == start or pos - start > 32:
            raise _Bad("has a PFM header (PF or Pf, width, height, scale) cut short or malformed")
        tokens.append(data[start:pos])
    pos += 1  # the single whitespace character before the pixels
    try:
        w, h, scale = int(tokens[1]), int(tokens[2]), float(tokens[3])
    except ValueError:
        raise _Bad(f"has {b' '.join(tokens[1:]).decode('ascii', 'replace')!r} in its PFM header where width, "
                   "height and scale belong") from None
    if w < 0 or h < 0 or scale == 0 or not np.isfinite(scale):
        raise _Bad(f"has a PFM header of {w}x{h} pixels with scale {scale:g}; sizes are not negative and the "
                   "scale not zero")
    if max(w, h) > MAX_IMAGE_SIDE:
        raise _Bad(f"is {w}x{h} pixels; an image is 1 to {MAX_IMAGE_SIDE} a side")
    c = 3 if tokens[0] == b"PF" else 1
    need = w * h * c * 4
    if len(data) - pos < need:
        raise _Bad(f"is truncated: {w}x{h}x{c} floats need {need} bytes after the header, it has {len(data) - pos}")
    pixels = np.frombuffer(data, "<f4" if scale < 0 else ">f4", w * h * c, pos).reshape(h, w, c)
    return pixels[::-1].astype(np.float32)


def _read_npy(data):
    """.npy bytes -> the array (no pickles), its header checked before the data is read."""
    import io

    stream = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(stream)
        read_header = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
        if version not in read_header:
            raise ValueError(f".npy version {version[0]}.{version[1]} (structured arrays) is not an image")
        shape, fortran, dtype = read_header[version](stream)
    except (ValueError, SyntaxError, TypeError) as exc:
        raise _Bad(f"has an .npy header that cannot be read: {' '.join(str(exc).split())}") from None
    if dtype.hasobject:
        raise _Bad("holds Python objects, not numbers (refused: reading them would run code)")
    if len(shape) in (2, 3) and max(shape[:2]) > MAX_IMAGE_SIDE:
        raise _Bad(f"is {shape[1]}x{shape[0]} pixels; an image is 1 to {MAX_IMAGE_SIDE} a side")
    count = math.prod(int(n) for n in shape)  # Python's integers: a header's shape may overflow int64
    need = count * dtype.itemsize
    if len(data) - stream.tell() < need:
        raise _Bad(f"is truncated: an array of shape {shape} needs {need} bytes of data, it has "
                   f"{len(data) - stream.tell()}")
    array = np.frombuffer(data, dtype, count, stream.tell())
    return array.reshape(shape, order="F" if fortran else "C")


def _read_rgbe(data):
    """Radiance HDR bytes -> (H, W, 3) float32 (see ``read_hdr_image``)."""
    end = data.find(b"\n\n")
    if end < 0:
        raise _Bad("has a Radiance header with no end (no blank line before the resolution)")
    exposure, correction = 1.0, np.ones(3)
    for line in data[:end].decode("latin-1").splitlines()[1:]:
        key, _, value = line.partition("=")
        try:
            if key == "FORMAT" and value.strip() != "32-bit_rle_rgbe":
                raise _Bad(f"is in FORMAT={value.strip()}; only 32-bit_rle_rgbe (RGB) is read")
            if key == "EXPOSURE":
                exposure *= float(value)
            elif key == "COLORCORR":
                correction *= np.array([float(v) for v in value.split()[:3]])
        except ValueError:
            raise _Bad(f"has a header line {line!r} whose value is not a number") from None
    if not (exposure > 0 and np.all(correction > 0)):
        raise _Bad(f"has a header EXPOSURE {exposure:g} or COLORCORR {correction.tolist()} that is not positive")
    line_end = data.find(b"\n", end + 2)
    words = data[end + 2:line_end if line_end >= 0 else len(data)].decode("latin-1").split()
    axes = (words[0], words[2]) if len(words) == 4 else ()
    if sorted(a[-1:] for a in axes) != ["X", "Y"] or not all(a[:1] in "+-" and len(a) == 2 for a in axes) or not (
            words[1].isdigit() and words[3].isdigit()):
        raise _Bad(f"has a resolution line {' '.join(words)!r} unlike '-Y height +X width'")
    lines, length = int(words[1]), int(words[3])
    if max(lines, length) > MAX_IMAGE_SIDE or min(lines, length) == 0:
        raise _Bad(f"is {length}x{lines} pixels; an image is 1 to {MAX_IMAGE_SIDE} a side")
    pixels = _rgbe_scanlines(memoryview(data)[line_end + 1:], lines, length)
    scale = np.ldexp(1.0, pixels[..., 3].astype(np.int32) - 136)
    rgb = np.where(pixels[..., 3:] > 0, (pixels[..., :3] + 0.5) * scale[..., None], 0.0) / (exposure * correction)
    if axes[0][1] == "X":  # scanlines are columns
        rgb = rgb.transpose(1, 0, 2)
    y, x = (axes if axes[0][1] == "Y" else axes[::-1])
    return np.ascontiguousarray(rgb[:: -1 if y[0] == "+" else 1, :: -1 if x[0] == "-" else 1], np.float32)


def _rgbe_scanlines(data, lines, length):
    """(lines, length, 4) uint8 RGBE from the pixel bytes: each scanline flat, in the old
    run-length scheme ((1, 1, 1, n): the previous pixel again), or in the new one (2, 2,
    length; then each component as runs: a count above 128 repeats the next byte count -
    128 times, a count up to 128 is followed by that many bytes)."""
    out = np.empty((lines, length, 4), np.uint8)
    buf = np.frombuffer(data, np.uint8)
    pos, size = 0, len(buf)

    def cut():
        raise _Bad(f"is truncated or corrupt: its pixel data ends inside scanline {row + 1} of {lines}")

    for row in range(lines):
        if pos + 4 > size:
            cut()
        head = buf[pos:pos + 4]
        if 8 <= length < 32768 and head[0] == 2 and head[1] == 2 and not head[2] & 0x80:
            if (int(head[2]) << 8 | int(head[3])) != length:
                raise _Bad(f"is corrupt: scanline {row + 1} says it is {int(head[2]) << 8 | int(head[3])} pixels "
                           f"long, the image {length}")
            pos += 4
            for component in range(4):
                x = 0
                while x < length:
                    if pos >= size:
                        cut()
                    count = int(buf[pos])
                    run = count > 128
                    count -= 128 if run else 0
                    take = 1 if run else count
                    if pos + 1 + take > size:
                        cut()
                    if count == 0 or x + count > length:
                        raise _Bad(f"is corrupt: a run of {count} bytes in scanline {row + 1} (of {length} pixels)")
                    out[row, x:x + count, component] = buf[pos + 1:pos + 1 + take]
                    pos += 1 + take
                    x += count
            continue
        x, shift = 0, 0
        while x < length:  # flat pixels, maybe with old-style runs
            if pos + 4 > size:
                cut()
            pixel = buf[pos:pos + 4]
            pos += 4
            if pixel[0] == 1 and pixel[1] == 1 and pixel[2] == 1 and x > 0:
                count = int(pixel[3]) << shift
                if x + count > length:
                    raise _Bad(f"is corrupt: a run of {count} pixels overruns scanline {row + 1}")
                out[row, x:x + count] = out[row, x - 1]
                x += count
                shift += 8
            else:
                out[row, x] = pixel
                x += 1
                shift = 0
    return out
