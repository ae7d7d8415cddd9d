"""Hostile Mitsuba XML documents, held out by an adversarial sweep: each is refused in one
line naming the file, the line and the problem (an InputError), quickly, with no traceback
and no hang: cycles of references and instances, ids given twice, includes and instances
that multiply, a film of no pixels, files that are directories, devices or FIFOs."""

import os

import pytest
from refusals import input_error

from radiosity.scene.loaders import load_scene

LAMP = '''<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>'''


def write(tmp_path, body, name="scene.xml"):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<scene version="3.0.0">\n{body}\n</scene>\n')
    return path


def refused(path, *fragments, within=10.0):
    """The one-line InputError of loading ``path``, which names an XML file of the scene and
    each fragment, in less than ``within`` seconds."""
    return input_error(lambda: load_scene(path), *fragments, names=".xml:", within=within)


@pytest.mark.parametrize("body, where", [
    ('<bsdf type="twosided" id="a"><ref id="a"/></bsdf><shape type="rectangle"><ref id="a"/></shape>', ":3:"),
    ('<bsdf type="twosided" id="a"><ref id="b"/></bsdf><bsdf type="twosided" id="b"><ref id="a"/></bsdf>'
     '<shape type="rectangle"><ref id="a"/></shape>', ":3:"),
])
def test_a_cycle_of_bsdfs_is_refused(tmp_path, body, where):
    refused(write(tmp_path, body + LAMP), "refers to itself (a cycle of bsdfs through <ref>)", where)


def test_a_shapegroup_instancing_itself_is_refused(tmp_path):
    body = ('<shape type="shapegroup" id="g"><shape type="instance"><ref id="g"/></shape>'
            '<shape type="rectangle"/></shape><shape type="instance"><ref id="g"/></shape>')
    refused(write(tmp_path, body + LAMP), "instances the shapegroup it is in (a cycle of instances)")


def test_an_id_given_twice_is_refused_as_mitsuba_refuses_it(tmp_path):
    body = '<bsdf type="diffuse" id="a"/>\n<bsdf type="conductor" id="a"/><shape type="rectangle"><ref id="a"/></shape>'
    refused(write(tmp_path, body + LAMP), "id 'a' is given twice (first at", ":4:")


def test_nested_instances_that_multiply_are_refused_quickly(tmp_path):
    """Six groups, each instancing the next ten times: 10^6 rectangles in a file of 2 KB."""
    groups = ['<shape type="shapegroup" id="g6"><shape type="rectangle"/></shape>']
    for level in range(5, 0, -1):
        inner = "".join(f'<shape type="instance"><ref id="g{level + 1}"/></shape>' for _ in range(10))
        groups.append(f'<shape type="shapegroup" id="g{level}">{inner}</shape>')
    body = "".join(groups) + "".join('<shape type="instance"><ref id="g1"/></shape>' for _ in range(10))
    refused(write(tmp_path, body + LAMP), "more than 20,000 shapes in all")


def test_includes_that_multiply_are_refused_quickly(tmp_path):
    """Eight files, each including the next ten times: 10^8 includes."""
    for level in range(8, 0, -1):
        inner = LAMP if level == 8 else "".join(f'<include filename="f{level + 1}.xml"/>' for _ in range(10))
        write(tmp_path, inner, f"f{level}.xml")
    refused(write(tmp_path, '<include filename="f1.xml"/>'), "more than 256 <include>s in all", "f7.xml:3:")


def test_a_film_of_no_pixels_is_refused(tmp_path):
    body = ('<sensor type="perspective"><float name="fov" value="40"/><film type="hdrfilm">'
            '<integer name="width" value="0"/><integer name="height" value="0"/></film></sensor>')
    refused(write(tmp_path, body + LAMP), "a film of 0 x 0 pixels")


@pytest.mark.parametrize("kind, words", [("directory", "is a directory"), ("fifo", "is a named pipe (FIFO)"),
                                         ("device", "is a character device")])
@pytest.mark.parametrize("element", ["include", "envmap"])
def test_a_named_file_that_is_not_a_regular_file_says_so(tmp_path, kind, words, element):
    """Not "not found": the input check's own words (a FIFO is not waited for)."""
    name = "thing.xml" if element == "include" else "sky.exr"
    if kind == "directory":
        (tmp_path / name).mkdir()
    elif kind == "fifo":
        os.mkfifo(tmp_path / name)
    else:
        (tmp_path / name).symlink_to("/dev/zero")
    body = (f'<include filename="{name}"/>' if element == "include"
            else f'<emitter type="envmap"><string name="filename" value="{name}"/></emitter>')
    message = refused(write(tmp_path, body + LAMP), name, words)
    assert "not found" not in message


@pytest.mark.parametrize("emitter, words", [
    ('<emitter type="point"><point name="position" x="0" y="0" z="1"/><rgb name="intensity" value="-5, 1, 1"/>'
     "</emitter>", "the intensity must not be negative, got (-5.0, 1.0, 1.0)"),
    ('<shape type="sphere"><emitter type="area"><rgb name="radiance" value="-4770.82, 1, 1"/></emitter></shape>',
     "the radiance must not be negative, got (-4770.82, 1.0, 1.0)"),
])
def test_a_negative_light_names_its_element_and_the_value_written(tmp_path, emitter, words):
    """A held-out input was refused as "material 'point_light_2': emission red = -4770.82
    is negative": naming neither the line, what the file calls it, nor the value written."""
    refused(write(tmp_path, '<shape type="rectangle"/>\n' + emitter), ":4: <emitter", words)


@pytest.mark.parametrize("side", [9000, 20000])
def test_a_huge_picture_is_refused_from_its_header_before_it_is_decoded(tmp_path, side):
    """A PNG of a few hundred bytes claiming side x side pixels, as a texture and as a
    mask: refused in one line at once (it was decoded first: 1.2 GB for 20000 x 20000)."""
    import struct
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    (tmp_path / "big.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 6, 0, 0, 0))
                                       + chunk(b"IEND", b""))
    texture = '<texture type="bitmap" name="reflectance"><string name="filename" value="big.png"/></texture>'
    body = f'<shape type="rectangle"><bsdf type="diffuse">{texture}</bsdf></shape>'
    refused(write(tmp_path, body + LAMP), "big.png", "more than the 67,108,864 allowed", within=2.0)
    mask = f'<bsdf type="mask">{texture.replace("reflectance", "opacity")}<bsdf type="diffuse"/></bsdf>'
    refused(write(tmp_path, f'<shape type="rectangle">{mask}</shape>' + LAMP), "big.png", "more than the 67,108,864",
            within=2.0)
