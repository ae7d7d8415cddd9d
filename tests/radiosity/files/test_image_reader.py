"""The one image reader (radiosity.files.images): every scene kind reads every format it
reads the same way: a 16-bit PNG, an OpenEXR texture, an alpha channel, a raw image;
a picture too large is refused from its header; a named image that is a directory is
said to be one."""

import io

import numpy as np
import pytest
from PIL import Image

from radiosity.files.errors import InputError
from radiosity.files.images import MAX_TEXTURE_PIXELS, picture_from_array, read_image
from radiosity.physics.materials import srgb_to_linear
from radiosity.physics.textures import read_texture, texture_from_image
from radiosity.scene.loaders import load_scene

RNG = np.random.default_rng(7)
SIXTEEN = RNG.integers(0, 65536, size=(4, 5, 3), dtype=np.uint16)  # every texel its own colour, 16 bits a channel
LINEAR = RNG.random((4, 5, 3)).astype(np.float32) * 0.9


def _png16(path, pixels=SIXTEEN):
    """A PNG of 16 bits a channel (grey, grey and alpha, RGB, RGBA), written here: pillow
    writes 16 bits of grey alone."""
    import struct
    import zlib

    pixels = np.asarray(pixels, np.uint16)
    pixels = pixels[..., None] if pixels.ndim == 2 else pixels
    height, width, channels = pixels.shape
    rows = b"".join(b"\0" + pixels[i].astype(">u2").tobytes() for i in range(height))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    colour = {1: 0, 2: 4, 3: 2, 4: 6}[channels]
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 16, colour, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    return path


def _exr(path, image=LINEAR):
    import OpenEXR

    channels = {name: np.ascontiguousarray(image[..., i], dtype=np.float32) for i, name in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(str(path))
    return path


def test_a_16_bit_png_keeps_its_16_bits_srgb_decoded(tmp_path):
    picture = read_image(_png16(tmp_path / "t.png"), "texture")
    assert picture.alpha is None and picture.rgb.shape == (4, 5, 3)
    assert np.allclose(picture.rgb, srgb_to_linear(SIXTEEN / 65535.0), rtol=0, atol=1e-12)
    raw = read_image(tmp_path / "t.png", "texture", raw=True)
    assert np.allclose(raw.rgb, SIXTEEN / 65535.0, rtol=0, atol=1e-12)


def test_an_alpha_channel_is_kept_linear_and_grey_is_copied(tmp_path):
    rgba = np.dstack([SIXTEEN, np.full((4, 5, 1), 32768, np.uint16)])
    picture = read_image(_png16(tmp_path / "a.png", rgba), "mask")
    assert np.allclose(picture.alpha, 32768 / 65535.0)
    grey = read_image(_png16(tmp_path / "g.png", SIXTEEN[..., 0]), "texture", raw=True)
    assert np.allclose(grey.rgb, (SIXTEEN[..., 0] / 65535.0)[..., None].repeat(3, axis=2))


def test_an_exr_is_read_as_the_linear_values_it_holds(tmp_path):
    picture = read_image(_exr(tmp_path / "t.exr"), "texture")
    assert np.array_equal(picture.rgb, LINEAR.astype(np.float64)) and picture.alpha is None
    bad = LINEAR.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(InputError, match=r"^texture '.*n.exr' holds NaN or infinite values$"):
        read_image(_exr(tmp_path / "n.exr", bad), "texture")


def _toml_scene(tmp_path, texture):
    (tmp_path / "s.toml").write_text(f"""
[materials.picture]
diffuse = 1.0
diffuse_texture = "{texture}"
[materials.lamp]
diffuse = 0.0
emission = 1.0
[[objects]]
name = "quad"
builtin = "quad"
material = "picture"
[[objects]]
name = "lamp"
builtin = "quad"
material = "lamp"
translate = [0, 0, 2]
""")
    return tmp_path / "s.toml"


def _xml_scene(tmp_path, texture):
    (tmp_path / "s.xml").write_text(f"""<scene version="3.0.0">
<shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">
<string name="filename" value="{texture}"/></texture></bsdf></shape>
<shape type="rectangle"><transform name="to_world"><translate z="2"/></transform>
<emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
</scene>""")
    return tmp_path / "s.xml"


@pytest.mark.parametrize("write, name", [(_png16, "t.png"), (_exr, "t.exr")])
def test_toml_and_xml_read_the_same_texture_from_a_16_bit_png_or_an_exr(tmp_path, write, name):
    """Refused from TOML before (pillow's 8-bit reader), read from XML: now one reader."""
    write(tmp_path / name)
    toml = load_scene(_toml_scene(tmp_path, name)).object("quad").texture
    xml = next(o for o in load_scene(_xml_scene(tmp_path, name)).objects if o.texture is not None).texture
    assert toml.dtype == np.float32 and toml.shape == (4, 5, 3)
    assert np.array_equal(toml, xml)
    assert np.array_equal(toml, read_texture(tmp_path / name, "here"))


def test_a_mesh_file_s_16_bit_image_decodes_as_the_file_reader_does(tmp_path):
    """trimesh hands a mesh file's images over as pillow images: a 16-bit grey one
    ("I;16" or "I") decodes as read_image decodes the file."""
    grey = SIXTEEN[..., 0]
    path = _png16(tmp_path / "g.png", grey)
    with Image.open(path) as image:
        image.load()
        assert image.mode.startswith("I")
        texture = texture_from_image(image, "here")
    assert np.array_equal(texture, read_texture(path, "here"))


def test_a_picture_too_large_is_refused_from_its_header_before_it_is_decoded(tmp_path):
    import struct
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 9000, 9000, 16, 2, 0, 0, 0)) + chunk(b"IEND", b"")
    (tmp_path / "big.png").write_bytes(header)
    with pytest.raises(InputError, match=f"texture '.*big.png' is 9000 x 9000 pixels, more than the {MAX_TEXTURE_PIXELS:,}"):
        read_image(tmp_path / "big.png", "texture")


@pytest.mark.parametrize("content", [b"", b"hello, I am text", b"\x89PNG\r\n\x1a\n" + b"\0" * 20])
def test_a_file_that_is_no_image_is_refused_in_one_line(tmp_path, content):
    (tmp_path / "t.png").write_bytes(content)
    with pytest.raises(InputError) as info:
        read_image(tmp_path / "t.png", "texture")
    assert "\n" not in str(info.value) and "t.png" in str(info.value)


def test_a_texture_or_environment_map_that_is_a_directory_is_said_to_be_one(tmp_path):
    (tmp_path / "t.png").mkdir()
    with pytest.raises(InputError, match="is a directory"):
        load_scene(_toml_scene(tmp_path, "t.png"))
    (tmp_path / "e.toml").write_text('[environment]\nimage = "t.png"\n[materials.m]\ndiffuse = 0.5\n'
                                     '[[objects]]\nname = "q"\nbuiltin = "quad"\nmaterial = "m"\n')
    with pytest.raises(InputError, match="is a directory"):
        load_scene(tmp_path / "e.toml")


@pytest.mark.parametrize("pixels, why", [(np.zeros((0, 3, 3), np.uint8), "not an RGB image"),
                                         (np.zeros((2, 2, 5), np.uint8), "not an RGB image"),
                                         (np.zeros((2, 2, 3), np.int32), "int32 values"),
                                         (np.full((2, 2, 3), np.inf, np.float32), "NaN or infinite")])
def test_pixels_that_are_no_image_are_refused(pixels, why):
    with pytest.raises(InputError, match=why):
        picture_from_array(pixels, "texture 'x'")


def test_eight_bits_decode_as_before(tmp_path):
    rgb8 = RNG.integers(0, 256, size=(3, 4, 3), dtype=np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(rgb8, "RGB").save(buffer, format="PNG")
    (tmp_path / "t.png").write_bytes(buffer.getvalue())
    assert np.array_equal(read_texture(tmp_path / "t.png", "here"), srgb_to_linear(rgb8 / 255.0).astype(np.float32))


@pytest.mark.parametrize("cut", [0.5, 0.9])
def test_a_truncated_16_bit_png_is_refused_in_one_line(tmp_path, cut):
    data = _png16(tmp_path / "t.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[:int(len(data) * cut)] if cut < 0.9 else data[:33] + b"\0" * 40)
    with pytest.raises(InputError, match=r"^cannot read texture '.*t.png': a 16-bit PNG that is truncated or corrupt") as info:
        read_image(tmp_path / "t.png", "texture")
    assert len(str(info.value)) < 200
