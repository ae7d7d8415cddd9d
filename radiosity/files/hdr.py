"""Reading an image of linear radiance: OpenEXR, Radiance HDR (RGBE), PFM or .npy ->
(H, W, 3) float32 RGB, row 0 at the top, checked (``read_hdr_image``). Used by
``vlights compare --reference`` (through ``display.images``) and by the scene loaders
(environment maps), so it lives in the shared core every stage may import.
"""

from __future__ import annotations

import contextlib
import math
import os
import warnings

import numpy as np

from radiosity.files.camera import MAX_IMAGE_SIDE
from radiosity.files.errors import InputError, SceneWarning

__all__ = ["HDR_EXTENSIONS", "read_hdr_image"]

HDR_EXTENSIONS = (".exr", ".hdr", ".pfm", ".npy")
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
    expected = [name for ext, magic, name in _MAGIC if ext == suffix]
    if not any(data.startswith(magic) for ext, magic, _ in _MAGIC if ext == suffix):
        actual = next((name for _, magic, name in _MAGIC if data.startswith(magic)), None)
        raise InputError(f"{what} {shown!r} is not {expected[0].replace('a colour ', 'a ')}" + (
            f": it is {actual} (its extension is wrong)" if actual else
            " (empty)" if not data else f" (it starts with {data[:8]!r})"))
    reader = {".exr": _read_exr, ".hdr": _read_rgbe, ".pfm": _read_pfm, ".npy": _read_npy}[suffix]
    try:
        image = reader(data, f"{what} {shown!r}") if reader is _read_exr else reader(data)
    except _Bad as exc:
        raise InputError(f"{what} {shown!r} {exc}") from None
    return _checked_radiance(image, f"{what} {shown!r}")


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
        raise InputError(f"{where} has {c} channels; a reference takes 1 (grey), 3 (RGB) or 4 (RGBA, alpha dropped)")
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
        raise _Bad(f"is {w}x{h} pixels; a reference is 1 to {MAX_IMAGE_SIDE} a side")
    _, _, channels = open_file(False)
    names = sorted(c for c in channels if "." not in c)  # the image's own channels
    layers = sorted({c.rsplit(".", 1)[0] for c in channels if "." in c})  # "layer.X": other images beside it (AOVs)
    if {"R", "G", "B"} <= set(names) and set(names) <= {"R", "G", "B", "A"}:
        order = ["R", "G", "B"]
    elif len(names) == 1:
        order = names
    else:
        raise _Bad(f"has {len(names)} channels ({', '.join(names)}); a reference takes R, G, B (and A, dropped) "
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
        raise _Bad(f"is {w}x{h} pixels; a reference is 1 to {MAX_IMAGE_SIDE} a side")
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
        raise _Bad(f"is {shape[1]}x{shape[0]} pixels; a reference is 1 to {MAX_IMAGE_SIDE} a side")
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
        raise _Bad(f"is {length}x{lines} pixels; a reference is 1 to {MAX_IMAGE_SIDE} a side")
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
