"""The readers of linear HDR images (``display.images.read_hdr_image``, what
``compare --reference`` reads): each format round-trips known pixel values, row 0 at
the top, written by a library where one writes it (OpenEXR, NumPy, Pillow's grey PFM)
and byte by byte where none does (colour PFM, Radiance RGBE, both run-length schemes);
bad files are refused in one line naming the file."""

import struct

import numpy as np
import pytest
from refusals import input_error

from display.images import read_hdr_image
from radiosity.files.errors import SceneWarning

OpenEXR = pytest.importorskip("OpenEXR")

# (H, W, 3): every pixel and channel different, row 0 distinguishable from the last
KNOWN = (np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3) / 8 + np.float32(0.125))


def write_exr(path, channels, compression=None):
    header = {} if compression is None else {"compression": compression}
    # the bindings write an array's buffer as it lies in memory, strides ignored: a slice must be copied
    channels = {name: np.ascontiguousarray(pixels) for name, pixels in channels.items()}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))
    return path


def refused(path, *fragments):
    """The InputError of reading ``path``: one line naming the file and every fragment."""
    return input_error(lambda: read_hdr_image(path), *fragments, names=str(path))


# --- OpenEXR ---------------------------------------------------------------------------

@pytest.mark.parametrize("compression", ["NO_COMPRESSION", "ZIP_COMPRESSION", "PIZ_COMPRESSION"])
def test_exr_rgb_round_trips(tmp_path, compression):
    path = write_exr(tmp_path / "a.exr", {"RGB": KNOWN}, getattr(OpenEXR, compression))
    image = read_hdr_image(path)
    assert image.dtype == np.float32 and image.shape == (4, 5, 3)
    np.testing.assert_array_equal(image, KNOWN)


def test_exr_separate_channels_half_and_alpha(tmp_path):
    # Mitsuba writes R, G, B (and A) as channels of their own, often half floats
    half = KNOWN.astype(np.float16)
    path = write_exr(tmp_path / "m.exr", {"R": half[..., 0], "G": half[..., 1], "B": half[..., 2],
                                          "A": np.full((4, 5), 0.25, np.float16)})
    np.testing.assert_array_equal(read_hdr_image(path), half.astype(np.float32))


def test_exr_of_an_aov_integrator_is_its_r_g_b_and_its_layers_are_left_with_a_warning(tmp_path):
    # Mitsuba's aov integrator writes the render as R, G, B (and A) and each AOV as a layer: "nn.X", "dd.y", ...
    layers = {"nn.X": KNOWN[..., 0], "nn.Y": KNOWN[..., 1], "nn.Z": KNOWN[..., 2], "dd.y": KNOWN[..., 0],
              "_arg_0.R": KNOWN[..., 1]}
    path = write_exr(tmp_path / "aov.exr", {"R": KNOWN[..., 0], "G": KNOWN[..., 1], "B": KNOWN[..., 2],
                                            "A": np.ones((4, 5), np.float32), **layers})
    with pytest.warns(SceneWarning) as caught:
        image = read_hdr_image(path)
    np.testing.assert_array_equal(image, KNOWN)
    (message,) = [str(w.message) for w in caught]
    assert message == (f"--reference {str(path)!r}: its 3 other layer(s) (_arg_0, dd, nn) are not read: the image is "
                       "its R, G, B")
    write_exr(tmp_path / "layers.exr", layers)  # layers alone: no image
    refused(tmp_path / "layers.exr", "has 0 channels", "beside layers (_arg_0, dd, nn)")


def test_exr_single_channel_is_grey(tmp_path):
    path = write_exr(tmp_path / "y.exr", {"Y": KNOWN[..., 1]})
    image = read_hdr_image(path)
    for c in range(3):
        np.testing.assert_array_equal(image[..., c], KNOWN[..., 1])


def test_exr_refusals(tmp_path, capfd):
    good = write_exr(tmp_path / "good.exr", {"RGB": KNOWN}, OpenEXR.ZIP_COMPRESSION).read_bytes()
    (tmp_path / "cut.exr").write_bytes(good[:-12])
    refused(tmp_path / "cut.exr", "OpenEXR", "truncated or corrupt")
    (tmp_path / "head.exr").write_bytes(good[:40])
    refused(tmp_path / "head.exr", "OpenEXR")
    assert capfd.readouterr() == ("", "")  # the library's own messages are in the line, not on the terminal
    write_exr(tmp_path / "two.exr", {"R": KNOWN[..., 0], "G": KNOWN[..., 1]})
    refused(tmp_path / "two.exr", "2 channels (G, R)")
    write_exr(tmp_path / "five.exr", {"R": KNOWN[..., 0], "G": KNOWN[..., 1], "B": KNOWN[..., 2], "A": KNOWN[..., 0],
                                      "Z": KNOWN[..., 0]})
    refused(tmp_path / "five.exr", "5 channels")
    write_exr(tmp_path / "ids.exr", {"Y": np.arange(20, dtype=np.uint32).reshape(4, 5)})
    refused(tmp_path / "ids.exr", "uint32")
    bad = KNOWN.copy()
    bad[0, 0, 0], bad[1, 1, 1], bad[2, 2, 2] = np.nan, np.inf, -0.5
    write_exr(tmp_path / "nan.exr", {"RGB": bad})
    refused(tmp_path / "nan.exr", "1 NaN and 1 infinite values")
    bad[0, 0, 0] = bad[1, 1, 1] = 1.0
    write_exr(tmp_path / "neg.exr", {"RGB": bad})
    refused(tmp_path / "neg.exr", "1 negative values", "-0.5")


# --- NumPy ------------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64])
def test_npy_round_trips(tmp_path, dtype):
    np.save(tmp_path / "a.npy", KNOWN.astype(dtype))
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "a.npy"), KNOWN.astype(dtype).astype(np.float32))


def test_npy_rgba_drops_alpha_and_grey_is_copied(tmp_path):
    np.save(tmp_path / "rgba.npy", np.concatenate([KNOWN, np.full((4, 5, 1), 7.0, np.float32)], axis=2))
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "rgba.npy"), KNOWN)
    np.save(tmp_path / "grey.npy", KNOWN[..., 2])
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "grey.npy"), np.repeat(KNOWN[..., 2:], 3, axis=2))
    np.save(tmp_path / "grey1.npy", KNOWN[..., :1])
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "grey1.npy"), np.repeat(KNOWN[..., :1], 3, axis=2))


def test_npy_refusals(tmp_path):
    np.save(tmp_path / "two.npy", np.ones((4, 5, 2), np.float32))
    refused(tmp_path / "two.npy", "has 2 channels", "1 (grey), 3 (RGB) or 4")
    np.save(tmp_path / "empty.npy", np.ones((0, 5, 3), np.float32))
    refused(tmp_path / "empty.npy", "is empty (5x0 pixels)")
    np.save(tmp_path / "ints.npy", np.ones((4, 5, 3), np.uint8))
    refused(tmp_path / "ints.npy", "uint8", "not floating-point")
    np.save(tmp_path / "line.npy", np.ones(12, np.float32))
    refused(tmp_path / "line.npy", "shape (12,)")
    np.save(tmp_path / "objects.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    refused(tmp_path / "objects.npy", "Python objects")
    np.save(tmp_path / "big.npy", np.full((4, 5, 3), 1e300))
    refused(tmp_path / "big.npy", "0 NaN and 60 infinite values", "beyond float32")
    whole = (tmp_path / "big.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(whole[:-8])
    refused(tmp_path / "cut.npy", "truncated")
    (tmp_path / "header.npy").write_bytes(whole[:20])
    refused(tmp_path / "header.npy", ".npy header")
    # a header whose shape's product overflows int64 (a held-out input: numpy's reshape raised)
    header = "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 4, 1099511627776, 1099511627776), }"
    header += " " * (118 - len(header)) + "\n"
    (tmp_path / "overflow.npy").write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode()
                                            + bytes(64))
    refused(tmp_path / "overflow.npy", "truncated", "77371252455336267181195264 bytes")


# --- PFM --------------------------------------------------------------------------------

def pfm_bytes(image, little=True, scale=1.0):
    """A PFM file by its specification: header, then rows bottom to top."""
    magic = b"PF" if image.ndim == 3 else b"Pf"
    h, w = image.shape[:2]
    header = b"%s\n%d %d\n%s\n" % (magic, w, h, repr(-scale if little else scale).encode())
    return header + np.ascontiguousarray(image[::-1]).astype("<f4" if little else ">f4").tobytes()


@pytest.mark.parametrize("little", [True, False])
def test_pfm_colour_round_trips_in_either_byte_order(tmp_path, little):
    (tmp_path / "a.pfm").write_bytes(pfm_bytes(KNOWN, little, scale=2.0))
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "a.pfm"), KNOWN)  # the scale's size is ignored


def test_pfm_grey_written_by_pillow(tmp_path):
    from PIL import Image

    grey = KNOWN[..., 0]
    Image.fromarray(grey, mode="F").save(tmp_path / "g.pfm")
    np.testing.assert_array_equal(read_hdr_image(tmp_path / "g.pfm"), np.repeat(grey[..., None], 3, axis=2))


def test_pfm_refusals(tmp_path):
    whole = pfm_bytes(KNOWN)
    (tmp_path / "cut.pfm").write_bytes(whole[:-4])
    refused(tmp_path / "cut.pfm", "truncated", "240 bytes")
    (tmp_path / "p6.pfm").write_bytes(b"P6\n1 1\n255\n\0\0\0")
    refused(tmp_path / "p6.pfm", "is not a PFM image")
    (tmp_path / "words.pfm").write_bytes(b"PF\nfive 4\n-1.0\n" + bytes(240))
    refused(tmp_path / "words.pfm", "width, height and scale")
    (tmp_path / "short.pfm").write_bytes(b"PF\n5 4")
    refused(tmp_path / "short.pfm", "PFM header")
    bad = KNOWN.copy()
    bad[3, 4, 2] = -1.0
    (tmp_path / "neg.pfm").write_bytes(pfm_bytes(bad))
    refused(tmp_path / "neg.pfm", "1 negative values")


# --- Radiance RGBE ----------------------------------------------------------------------

def rgbe_value(r, g, b, e):
    """What Radiance decodes an RGBE pixel to: (byte + 0.5) * 2^(e - 136), 0 for e = 0."""
    r, g, b, e = (int(v) for v in (r, g, b, e))
    return np.array([0.0, 0.0, 0.0] if e == 0 else [(c + 0.5) * 2.0 ** (e - 136) for c in (r, g, b)], np.float32)


def rle_component(values):
    """One component of a new-style scanline: a run where a value repeats 3 or more
    times, literal bytes otherwise."""
    out, i = bytearray(), 0
    while i < len(values):
        j = i
        while j < len(values) and values[j] == values[i] and j - i < 127:
            j += 1
        if j - i >= 3:
            out += bytes([128 + j - i, values[i]])
            i = j
            continue
        j = i
        while j < len(values) and j - i < 128 and not (j + 2 < len(values) and values[j] == values[j + 1] == values[j + 2]):
            j += 1
        out += bytes([j - i]) + bytes(values[i:j])
        i = j
    return bytes(out)


def hdr_file(pixels, resolution=None, header=b"", rle=True):
    """A Radiance file of ``pixels`` ((lines, length, 4) uint8 RGBE in file order)."""
    lines, length = pixels.shape[:2]
    body = bytearray()
    for row in pixels:
        if rle:
            body += bytes([2, 2, length >> 8, length & 255])
            for c in range(4):
                body += rle_component(list(row[:, c]))
        else:
            body += row.tobytes()
    resolution = resolution or b"-Y %d +X %d" % (lines, length)
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n" + header + b"\n" + resolution + b"\n" + bytes(body)


def decoded(pixels):
    return np.stack([np.stack([rgbe_value(*p) for p in row]) for row in pixels])


@pytest.fixture
def rgbe_pixels():
    """(3, 10, 4) RGBE bytes with runs (the first six pixels alike), literals, a zero pixel."""
    rng = np.random.default_rng(5)
    pixels = rng.integers(1, 256, (3, 10, 4)).astype(np.uint8)
    pixels[..., 3] = rng.integers(120, 140, (3, 10))
    pixels[0, :6] = (200, 100, 50, 130)
    pixels[2, 9] = (0, 0, 0, 0)
    return pixels


def test_rgbe_new_run_length_scheme(tmp_path, rgbe_pixels):
    (tmp_path / "a.hdr").write_bytes(hdr_file(rgbe_pixels))
    image = read_hdr_image(tmp_path / "a.hdr")
    np.testing.assert_allclose(image, decoded(rgbe_pixels), rtol=1e-6)
    assert image[0, 0] == pytest.approx([200.5 / 64, 100.5 / 64, 50.5 / 64])  # 2^(130 - 136)
    assert (image[2, 9] == 0).all()


def test_rgbe_flat_and_old_runs(tmp_path):
    # 4 pixels a line (too short for the new scheme): flat, with an old-style run (1, 1, 1, n) repeating
    pixels = np.array([[[128, 64, 32, 129], [1, 1, 1, 2], [10, 20, 30, 140]],
                       [[0, 0, 0, 0], [255, 255, 255, 128], [2, 3, 4, 136]]], np.uint8)
    body = pixels[0].tobytes() + pixels[1].tobytes() + bytes([7, 7, 7, 136])
    data = b"#?RGBE\n\n-Y 2 +X 4\n" + body
    (tmp_path / "a.hdr").write_bytes(data)
    image = read_hdr_image(tmp_path / "a.hdr")
    first = rgbe_value(128, 64, 32, 129)
    np.testing.assert_allclose(image[0], [first, first, first, rgbe_value(10, 20, 30, 140)], rtol=1e-6)
    np.testing.assert_allclose(image[1], [[0, 0, 0], rgbe_value(255, 255, 255, 128), rgbe_value(2, 3, 4, 136),
                                          rgbe_value(7, 7, 7, 136)], rtol=1e-6)
    assert first[0] == pytest.approx(128.5 / 128)


@pytest.mark.parametrize("resolution, orient", [
    (b"+Y 3 +X 10", lambda a: a[::-1]),        # rows bottom to top
    (b"-Y 3 -X 10", lambda a: a[:, ::-1]),     # right to left
    (b"+X 3 -Y 10", lambda a: a.transpose(1, 0, 2)),  # scanlines are columns, top to bottom
])
def test_rgbe_orientations(tmp_path, rgbe_pixels, resolution, orient):
    (tmp_path / "o.hdr").write_bytes(hdr_file(rgbe_pixels, resolution))
    np.testing.assert_allclose(read_hdr_image(tmp_path / "o.hdr"), orient(decoded(rgbe_pixels)), rtol=1e-6)


def test_rgbe_exposure_divides(tmp_path, rgbe_pixels):
    (tmp_path / "e.hdr").write_bytes(hdr_file(rgbe_pixels, header=b"EXPOSURE=2\nEXPOSURE=1.5\n"))
    np.testing.assert_allclose(read_hdr_image(tmp_path / "e.hdr"), decoded(rgbe_pixels) / 3, rtol=1e-6)


def test_rgbe_refusals(tmp_path, rgbe_pixels):
    whole = hdr_file(rgbe_pixels)
    (tmp_path / "cut.hdr").write_bytes(whole[:-5])
    refused(tmp_path / "cut.hdr", "truncated or corrupt", "scanline 3 of 3")
    (tmp_path / "xyz.hdr").write_bytes(whole.replace(b"rle_rgbe", b"rle_xyze"))
    refused(tmp_path / "xyz.hdr", "32-bit_rle_xyze")
    (tmp_path / "res.hdr").write_bytes(hdr_file(rgbe_pixels, b"Y 3 X 10"))
    refused(tmp_path / "res.hdr", "resolution line")
    (tmp_path / "nohead.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n")
    refused(tmp_path / "nohead.hdr", "no end")
    long_line = bytearray(whole)
    long_line[long_line.index(b"\n-Y") + len(b"\n-Y 3 +X 10\n") + 3] = 11  # the first line says 11 pixels, not 10
    (tmp_path / "len.hdr").write_bytes(bytes(long_line))
    refused(tmp_path / "len.hdr", "says it is 11 pixels long")
    (tmp_path / "exr.hdr").write_bytes(b"\x76\x2f\x31\x01" + bytes(40))
    refused(tmp_path / "exr.hdr", "is not a Radiance HDR", "it is an OpenEXR image (its extension is wrong)")


# --- any format -------------------------------------------------------------------------

def test_names_and_magic_numbers(tmp_path):
    (tmp_path / "a.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(20))
    refused(tmp_path / "a.png", ".png (8-bit and tone-mapped", "give .exr, .hdr, .pfm or .npy")
    (tmp_path / "a.tga").write_bytes(bytes(20))
    refused(tmp_path / "a.tga", ".tga is not a linear HDR image")
    (tmp_path / "png.exr").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(20))
    refused(tmp_path / "png.exr", "is not an OpenEXR image: it is a PNG image")
    np.save(tmp_path / "array.npy", KNOWN)
    (tmp_path / "array.exr").write_bytes((tmp_path / "array.npy").read_bytes())
    refused(tmp_path / "array.exr", "it is a NumPy .npy array")
    (tmp_path / "empty.hdr").write_bytes(b"")
    refused(tmp_path / "empty.hdr", "(empty)")
    refused(tmp_path / "missing.exr", "not found")
    (tmp_path / "dir.exr").mkdir()
    refused(tmp_path / "dir.exr", "is a directory")


def test_an_image_wider_than_any_camera_is_refused_before_its_pixels(tmp_path):
    header = b"PF\n20000 1\n-1.0\n"
    (tmp_path / "wide.pfm").write_bytes(header + struct.pack("<3f", 1, 1, 1))
    refused(tmp_path / "wide.pfm", "20000x1 pixels", "16384")
