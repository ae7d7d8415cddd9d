"""An adversarial sweep of the Mitsuba XML reader after it was split by job: references,
includes, defaults, transforms and values. Every hostile document is refused in one line
naming the file, the line and the problem, or read as Mitsuba reads it; the cases that
were read in silence before (a reference to the wrong kind of element, a projective
matrix, a blend weight outside [0, 1], a reference with no id, a huge scale's overflow
warning) are among them."""

import warnings

import pytest
from refusals import input_error

from radiosity.scene.loaders import load_scene

LAMP = '<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>'
CUBE = '<shape type="cube">{}</shape>'


def write(tmp_path, body, name="scene.xml", head='<scene version="3.0.0">'):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n{head}\n{body}\n{LAMP}\n</scene>\n')
    return path


def refused(path, *fragments):
    return input_error(lambda: load_scene(path), *fragments, names=".xml:", within=10.0)


def cube_with(transform):
    return CUBE.format(f'<transform name="to_world">{transform}</transform>')


@pytest.mark.parametrize("body, fragments", [
    # references
    ('<texture type="checkerboard" id="t"/>' + CUBE.format('<ref id="t"/>'),
     (":3: <ref>", "id 't' is a <texture type='checkerboard'>, where a <shape> takes a <bsdf>, an <emitter> or a <medium>")),
    ('<shape type="sphere" id="s"/>' + CUBE.format('<ref id="s"/>'), ("id 's' is a <shape type='sphere'>",)),
    ('<shape type="shapegroup" id="g"><shape type="sphere"/></shape>' + CUBE.format('<ref id="g"/>'),
     ("id 'g' is a <shape type='shapegroup'>, where a <shape> takes",)),
    ('<emitter type="point" id="e"/><bsdf type="twosided" id="b"><ref id="e"/></bsdf>' + CUBE.format('<ref id="b"/>'),
     ("id 'e' is an <emitter type='point'>, where a <bsdf> takes a <bsdf>",)),
    ('<bsdf type="diffuse" id="b"/><shape type="instance"><ref id="b"/></shape>',
     ("id 'b' is a <bsdf type='diffuse'>, where a <shape> takes a <shape type='shapegroup'>",)),
    (CUBE.format('<ref/>'), ("<ref>: needs an 'id' (the element it refers to)",)),
    (CUBE.format('<ref id="ghost"/>'), ("<ref>: no element has id 'ghost'",)),
    # includes and defaults
    ('<include filename="scene.xml"/>', ("includes nested more than 16 deep",)),
    ('<include/>', ("<include>: needs a 'filename'",)),
    ('<include filename="../"/>', ("is a directory, not a file",)),
    ('<include filename="$f"/>', ("unknown parameter $f (no <default name='f'>)",)),
    ('<shape type="sphere"><float name="radius" value="$nope"/></shape>', ("unknown parameter $nope",)),
    # transforms
    (cube_with('<matrix value="1 0 0 0 0 1 0 0 0 0 1 0 1 1 1 0"/>'),
     ("<matrix>: the last row must be 0 0 0 1, got 1 1 1 0 (a projective transform is not read)",)),
    (cube_with('<matrix value="1 2 3"/>'), ("<matrix>: expected 16 or 9 numbers, got 3",)),
    (cube_with('<scale value="0"/>'), ("the transform is singular or not finite",)),
    (cube_with('<scale value="1e-300"/>'), ("the transform is singular or not finite",)),
    (cube_with('<scale value="nan"/>'), ("<scale>: expected finite numbers, got 'nan'",)),
    (cube_with('<rotate angle="30"/>'), ("<rotate>: needs a non-zero axis",)),
    # values
    (CUBE.format('<bsdf type="blendbsdf"><float name="weight" value="2"/><bsdf type="diffuse"/>'
                 '<bsdf type="conductor"/></bsdf>'), ("<bsdf type='blendbsdf'>: the blend's weight must be between 0 and 1, got 2",)),
    (CUBE.format('<bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2"/></bsdf>'), ("expected 1 or 3 numbers, got 2",)),
    (CUBE.format('<bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf>'),
     ("unknown index of refraction 'unobtainium'",)),
    ('<shape type="sphere"><float name="radius" value="0x10"/></shape>', ("expected numbers, got '0x10'",)),
    ('<emitter type="directional"><vector name="direction" value="0,0,0"/></emitter>', ("the direction must not be zero",)),
    ('<emitter type="spot"><float name="cutoff_angle" value="200"/></emitter>', ("the cutoff angle must be in (0, 180]",)),
], ids=lambda case: case if isinstance(case, str) and len(case) < 4 else None)
def test_a_hostile_document_is_refused_in_one_line(tmp_path, body, fragments):
    refused(write(tmp_path, body), *fragments)


def test_a_huge_scale_is_refused_by_size_without_an_overflow_warning(tmp_path):
    """Before, the transform's determinant overflowed: numpy's warning came first."""
    path = write(tmp_path, cube_with('<scale value="1e308"/>'))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        refused(path, "coordinates reach 1e+308, beyond the +-1e+10")


def test_a_reference_to_a_bsdf_an_emitter_or_a_shapegroup_is_still_read(tmp_path):
    """The check refuses only the wrong kinds: what Bitterli's scenes use is read."""
    body = ('<bsdf type="diffuse" id="b"><rgb name="reflectance" value="0.25"/></bsdf>'
            '<shape type="shapegroup" id="g"><shape type="sphere"><ref id="b"/></shape></shape>'
            + CUBE.format('<ref id="b"/>') + '<shape type="instance"><ref id="g"/></shape>')
    scene = load_scene(write(tmp_path, body))
    assert len(scene.objects) == 3
    assert sum(o.material.diffuse[0] == 0.25 for o in scene.objects) == 2
