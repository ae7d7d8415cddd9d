"""radiosity.scene.mitsuba: Mitsuba XML scenes against answers known beforehand.

The small scenes are in tests/data/mitsuba (one per element kind, and the failures:
``bad_*.xml``); variations on them (transform steps, fields of view, roughness sweeps,
``.serialized`` files) are written here into a temporary directory. Where Mitsuba's own
behaviour is the answer (a mirrored mesh's facing, the focal length's field of view), the
comment says how Mitsuba 3 was seen to behave.
"""

import math
import struct
import time
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from scene_files import load_warned

from radiosity.files.errors import InputError, SceneWarning
from radiosity.scene import geometry, microfacet
from radiosity.scene.loaders import load_scene
from radiosity.scene.material_kernels import albedo
from radiosity.scene.mitsuba import Tessellation, load_mitsuba, read_serialized
from radiosity.scene.model import BACK_OFFSET

DATA = Path(__file__).resolve().parents[2] / "data" / "mitsuba"
RECTANGLE = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])


def write_scene(tmp_path, body, version="3.0.0", name="scene.xml"):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<scene version="{version}">\n{body}\n</scene>\n')
    return path


def load_quietly(path, tessellation=None):
    """The scene, failing on any SceneWarning (the test expects none)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        return load_mitsuba(path, tessellation)


def refusal(path):
    """The InputError's message of loading ``path``: one line."""
    with pytest.raises(InputError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message, message
    return message


def assert_same_points(actual, expected, tol=1e-9):
    """The two point sets are equal (in any order)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape, (actual, expected)
    distance = np.linalg.norm(actual[:, None, :] - expected[None, :, :], axis=2)
    assert distance.min(axis=0).max() < tol and distance.min(axis=1).max() < tol, (actual, expected)


def face_normals(obj):
    return geometry.face_normals(obj.positions, obj.faces)[0]


def centroids(obj):
    return obj.positions[obj.faces].mean(axis=1)


# -- transforms --------------------------------------------------------------------------


def affine(linear=None, offset=(0.0, 0.0, 0.0)):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = np.eye(3) if linear is None else linear, offset
    return m


RZ90 = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # (x, y) -> (-y, x)
RX90 = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # y -> z, z -> -y
RY90 = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # z -> x, x -> -z
CYCLE = np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]])  # x -> y -> z -> x: 120 degrees about (1, 1, 1)

TRANSFORMS = {
    "translate xyz": ('<translate x="1" y="2" z="3"/>', affine(offset=(1, 2, 3))),
    "translate value": ('<translate value="1, 2, 3"/>', affine(offset=(1, 2, 3))),
    "translate one axis": ('<translate y="-2"/>', affine(offset=(0, -2, 0))),
    "scale xy": ('<scale x="2" y="3"/>', affine(np.diag([2.0, 3, 1]))),
    "scale uniform": ('<scale value="2"/>', affine(np.diag([2.0, 2, 2]))),
    "scale value 3": ('<scale value="2 3 4"/>', affine(np.diag([2.0, 3, 4]))),
    "rotate z": ('<rotate z="1" angle="90"/>', affine(RZ90)),
    "rotate x": ('<rotate x="1" angle="90"/>', affine(RX90)),
    "rotate y": ('<rotate y="1" angle="90"/>', affine(RY90)),
    "rotate value": ('<rotate value="0, 0, 1" angle="-90"/>', affine(RZ90.T)),
    "rotate diagonal": (f'<rotate x="{3 ** -0.5!r}" y="{3 ** -0.5!r}" z="{3 ** -0.5!r}" angle="120"/>', affine(CYCLE)),
    "matrix 16": ('<matrix value="0 0 1 5  1 0 0 6  0 1 0 7  0 0 0 1"/>', affine(CYCLE, (5, 6, 7))),
    "matrix 9": ('<matrix value="2 0 0  0 0 -1  0 1 0"/>', affine(np.diag([2.0, 1, 1]) @ RX90)),
    # forward +x; left = up x forward = -z; up' = forward x left = +y
    "lookat": ('<lookat origin="1, 2, 3" target="4, 2, 3" up="0, 1, 0"/>',
               affine(np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]), (1, 2, 3))),
    "rotate then translate": ('<rotate z="1" angle="90"/><translate x="1"/>',
                              affine(offset=(1, 0, 0)) @ affine(RZ90)),
    "translate then rotate": ('<translate x="1"/><rotate z="1" angle="90"/>',
                              affine(RZ90) @ affine(offset=(1, 0, 0))),
    "three steps": ('<scale x="2"/><rotate x="1" angle="90"/><translate z="1"/>',
                    affine(offset=(0, 0, 1)) @ affine(RX90) @ affine(np.diag([2.0, 1, 1]))),
}


def transformed_rectangle(tmp_path, steps):
    path = write_scene(tmp_path, f'<shape type="rectangle"><transform name="to_world">{steps}</transform></shape>')
    (obj,) = load_quietly(path).objects
    return obj


@pytest.mark.parametrize("case", TRANSFORMS, ids=list(TRANSFORMS))
def test_each_transform_step_against_its_matrix(tmp_path, case):
    steps, matrix = TRANSFORMS[case]
    obj = transformed_rectangle(tmp_path, steps)
    assert_same_points(obj.positions, RECTANGLE @ matrix[:3, :3].T + matrix[:3, 3])
    facing = np.linalg.inv(matrix[:3, :3]).T @ [0.0, 0, 1]  # a normal goes by the inverse transpose
    facing /= np.linalg.norm(facing)
    np.testing.assert_allclose(obj.normals, np.tile(facing, (len(obj.normals), 1)), atol=1e-12)
    np.testing.assert_allclose(face_normals(obj), np.tile(facing, (2, 1)), atol=1e-12)


# Mitsuba 3.9.1's ScalarTransform4f.rotate([1, 2, 0.5], 35): the axis as written, not normalised
MITSUBA3_ROTATE = np.array([[1.0, 0.07490766, 1.2375768], [0.6484841, 1.5425439, -0.3927285],
                            [-1.056729, 0.7544244, 0.864364]])


@pytest.mark.parametrize("version", ["3.0.0", "2.0.0", "0.6.0"])
def test_a_longer_rotation_axis_as_each_mitsuba_reads_it(tmp_path, version):
    """Mitsuba 2 and 3 take a rotation's axis as written (a longer axis scales too);
    Mitsuba 0.x normalises it."""
    step = '<rotate x="1" y="2" z="0.5" angle="35"/>'
    path = write_scene(tmp_path, f'<shape type="rectangle"><transform name="to_world">{step}</transform></shape>',
                       version=version)
    (obj,) = load_quietly(path).objects
    if version.startswith("0."):
        axis = np.array([1, 2, 0.5]) / np.linalg.norm([1, 2, 0.5])
        c, s = np.cos(np.radians(35)), np.sin(np.radians(35))
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        matrix = c * np.eye(3) + s * k + (1 - c) * np.outer(axis, axis)
    else:
        matrix = MITSUBA3_ROTATE
    assert_same_points(obj.positions, RECTANGLE @ matrix.T, tol=1e-6)


def test_the_order_of_steps_matters(tmp_path):
    first = transformed_rectangle(tmp_path, TRANSFORMS["rotate then translate"][0]).positions
    second = transformed_rectangle(tmp_path, TRANSFORMS["translate then rotate"][0]).positions
    assert np.ptp(first, axis=0)[:2].tolist() == np.ptp(second, axis=0)[:2].tolist() == [2, 2]
    assert first[:, 0].min() == pytest.approx(0) and first[:, 1].min() == pytest.approx(-1)
    assert second[:, 0].min() == pytest.approx(-1) and second[:, 1].min() == pytest.approx(0)


@pytest.mark.parametrize("mirror, facing", [("x", +1), ("y", +1), ("z", -1)])
def test_a_mirrored_rectangle_faces_where_mitsubas_does(tmp_path, mirror, facing):
    # Mitsuba 3: the rectangle's normal is to_world's inverse transpose times +z, so a
    # mirror in x or y keeps it facing +z; the reversed winding keeps the triangles so
    obj = transformed_rectangle(tmp_path, f'<scale {mirror}="-1"/>')
    assert_same_points(obj.positions, RECTANGLE)
    np.testing.assert_allclose(face_normals(obj)[:, 2], facing)
    np.testing.assert_allclose(obj.normals[:, 2], facing)


def test_a_mirrored_closed_shape_still_faces_outwards(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="cube"><transform name="to_world"><scale x="-1"/></transform></shape>
        <shape type="sphere"><transform name="to_world"><scale value="1, -1, 1"/><translate x="3"/></transform></shape>
        <shape type="cylinder"><transform name="to_world"><scale z="-1"/><translate x="-3"/></transform></shape>
    """)
    cube, ball, tube = load_quietly(path, Tessellation(segments=16, sphere_levels=1)).objects
    for obj, centre in ((cube, (0, 0, 0)), (ball, (3, 0, 0))):
        assert (np.einsum("ij,ij->i", face_normals(obj), centroids(obj) - centre) > 0).all()
    outwards = centroids(tube) - [-3, 0, 0]
    outwards[:, 2] = 0
    assert (np.einsum("ij,ij->i", face_normals(tube), outwards) > 0).all()


def test_a_mirrored_mesh_faces_as_its_normals_say_or_else_as_its_winding(tmp_path):
    # Mitsuba 3 (seen with mitsuba 3.x, scalar_rgb, by ray casts from +z): a mirrored mesh
    # keeps its triangles' order; with the file's vertex normals (turned by the inverse
    # transpose) it is lit from +z as before, without them (face_normals, or none in the
    # file) its facing flips to -z with its winding.
    (tmp_path / "meshes").mkdir()
    for name in ("patch.obj", "patch.ply"):
        (tmp_path / "meshes" / name).write_bytes((DATA / "meshes" / name).read_bytes())
    path = write_scene(tmp_path, """
        <shape type="obj" id="smooth">
            <string name="filename" value="meshes/patch.obj"/>
            <transform name="to_world"><scale x="-1"/></transform>
        </shape>
        <shape type="obj" id="faceted">
            <string name="filename" value="meshes/patch.obj"/>
            <boolean name="face_normals" value="true"/>
            <transform name="to_world"><scale x="-1"/><translate z="1"/></transform>
        </shape>
    """)
    smooth, faceted = load_quietly(path).objects
    assert (face_normals(smooth)[:, 2] > 0).all() and (smooth.normals[:, 2] > 0).all()
    # the file's normals lean outwards from the square's middle: mirrored, they still do
    middle = smooth.positions.mean(axis=0)
    assert (np.einsum("ij,ij->i", smooth.normals[:, :2], smooth.positions[:, :2] - middle[:2]) > 0).all()
    assert (face_normals(faceted)[:, 2] < 0).all() and (faceted.normals[:, 2] < 0).all()


@pytest.mark.parametrize("steps, problem", [
    ('<rotate angle="90"/>', "non-zero axis"),
    ('<scale x="0"/>', "singular"),
    ('<matrix value="1 2 3"/>', "16 or 9 numbers"),
    ('<lookat origin="0, 0, 1" target="0, 0, 1"/>', "target equals origin"),
    ('<lookat origin="0, 0, 1" target="0, 0, 0" up="0, 0, 1"/>', "parallel"),
    ('<translate x="nan"/>', "finite"),
    ('<shear x="1"/>', "not a transform step"),
])
def test_a_bad_transform_step_is_refused_with_its_line(tmp_path, steps, problem):
    path = write_scene(tmp_path, f'<shape type="rectangle">\n<transform name="to_world">\n{steps}\n</transform>'
                                 '</shape>')
    message = refusal(path)
    assert problem in message and str(path) in message
    assert f"{path}:5:" in message or f"{path}:4:" in message  # the step's line, or the transform's


# -- shapes ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def shapes():
    return {o.name: o for o in load_quietly(DATA / "shapes.xml").objects}


def polygon_area_ratio(n):
    """A regular n-gon's area over its circumscribed circle's."""
    return math.sin(2 * math.pi / n) / (2 * math.pi / n)


def polygon_perimeter_ratio(n):
    return math.sin(math.pi / n) / (math.pi / n)


def test_shape_bounds(shapes):
    expected = {
        "rect": [[-2, -0.5, 1], [2, 0.5, 1]],
        "rect_flipped": [[-2, -0.5, 2], [2, 0.5, 2]],
        "disk": [[-0.5, -0.5, 3], [0.5, 0.5, 3]],  # 64 segments: the four axis points are vertices
        "cube": [[-0.5, 2.5, -0.5], [0.5, 3.5, 0.5]],
        "tube": [[-3.25, -0.25, -1], [-2.75, 0.25, 1]],
    }
    for name, bounds in expected.items():
        p = shapes[name].positions
        np.testing.assert_allclose([p.min(axis=0), p.max(axis=0)], bounds, atol=1e-12, err_msg=name)
    ball = shapes["ball"].positions
    np.testing.assert_allclose(np.linalg.norm(ball - [3, 0, 0], axis=1), 0.5)  # vertices on the sphere
    assert np.ptp(ball, axis=0).min() > 0.98  # and all around it


def test_shape_areas_within_the_tessellations_error(shapes):
    exact = {"rect": 4.0, "rect_flipped": 4.0, "cube": 6.0}
    for name, area in exact.items():
        assert shapes[name].area == pytest.approx(area, rel=1e-12), name
    analytic = {"disk": (math.pi / 4, polygon_area_ratio(64)), "tube": (math.pi, polygon_perimeter_ratio(64))}
    for name, (area, ratio) in analytic.items():
        assert shapes[name].area == pytest.approx(area * ratio, rel=1e-9), name
        assert 0 < area - shapes[name].area < 2e-3 * area
    # an icosphere of 1,280 triangles: inscribed, within half a percent
    assert 0.995 * math.pi < shapes["ball"].area < math.pi


def test_shape_normals_face_outwards_or_plus_z(shapes):
    for name, facing in (("rect", 1), ("disk", 1), ("rect_flipped", -1)):
        obj = shapes[name]
        np.testing.assert_allclose(face_normals(obj), np.tile([0, 0, facing], (obj.n_triangles, 1)), atol=1e-12)
        np.testing.assert_allclose(obj.normals, np.tile([0, 0, facing], (obj.n_vertices, 1)), atol=1e-12)
    for name, centre in (("cube", (0, 3, 0)), ("ball", (3, 0, 0))):
        obj = shapes[name]
        assert (np.einsum("ij,ij->i", face_normals(obj), centroids(obj) - centre) > 0).all(), name
        assert (np.einsum("ij,ij->i", obj.normals, obj.positions - centre) > 0).all(), name
    tube = shapes["tube"]
    radial = tube.positions - [-3, 0, 0]
    radial[:, 2] = 0
    np.testing.assert_allclose(tube.normals, radial / 0.25, atol=1e-12)  # smooth: the exact radial normal
    outwards = centroids(tube) - [-3, 0, 0]
    outwards[:, 2] = 0
    assert (np.einsum("ij,ij->i", face_normals(tube), outwards) > 0).all()


def test_tessellation_sets_the_triangle_counts():
    coarse = {o.name: o for o in load_quietly(DATA / "shapes.xml", Tessellation(segments=8, sphere_levels=1)).objects}
    fine = {o.name: o for o in load_quietly(DATA / "shapes.xml", Tessellation(segments=100, sphere_levels=4)).objects}
    assert {n: coarse[n].n_triangles for n in ("disk", "tube", "ball", "rect", "cube")} == {
        "disk": 8, "tube": 16, "ball": 80, "rect": 2, "cube": 12}
    assert {n: fine[n].n_triangles for n in ("disk", "tube", "ball")} == {"disk": 100, "tube": 200, "ball": 5120}
    assert coarse["disk"].area == pytest.approx(math.pi / 4 * polygon_area_ratio(8))
    assert coarse["ball"].area < fine["ball"].area < math.pi


@pytest.mark.parametrize("kwargs", [{"segments": 2}, {"segments": 4097}, {"segments": 8.0}, {"sphere_levels": -1},
                                    {"sphere_levels": 8}])
def test_tessellation_out_of_range_is_refused(kwargs):
    with pytest.raises(InputError, match="tessellation"):
        Tessellation(**kwargs)


@pytest.mark.parametrize("body, problem", [
    ('<shape type="sphere"><float name="radius" value="0"/></shape>', "radius must be > 0"),
    ('<shape type="cylinder"><point name="p1" value="0, 0, 0"/></shape>', "p0 != p1"),
    ('<shape type="heightfield"/>', "shape type 'heightfield' is not read"),
    ('<shape type="obj"/>', "needs a 'filename'"),
    ('<shape type="obj"><string name="filename" value="nowhere.obj"/></shape>', "not found"),
    ('<shape type="instance"/>', "shapegroup"),
])
def test_a_bad_shape_is_refused_naming_its_line(tmp_path, body, problem):
    path = write_scene(tmp_path, body)
    message = refusal(path)
    assert problem in message and f"{path}:3:" in message


def test_shapegroup_instances_are_placed_by_their_transforms(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="shapegroup" id="pair">
            <shape type="rectangle"/>
            <shape type="disk"><transform name="to_world"><translate z="1"/></transform></shape>
        </shape>
        <shape type="instance"><ref id="pair"/><transform name="to_world"><translate x="10"/></transform></shape>
        <shape type="instance"><ref id="pair"/><transform name="to_world"><translate x="-10"/></transform></shape>
    """)
    objects = load_quietly(path, Tessellation(segments=8)).objects
    assert len(objects) == 4  # the group itself is not drawn
    centres = sorted(tuple(np.round(o.positions.mean(axis=0), 9)) for o in objects)
    assert centres == [(-10, 0, 0), (-10, 0, 1), (10, 0, 0), (10, 0, 1)]


# -- mesh files --------------------------------------------------------------------------


def file_normals(name):
    """The normals as written in tests/data/mitsuba/meshes/patch.*, unit length."""
    lines = (DATA / "meshes" / name).read_text().splitlines()
    if name.endswith(".obj"):
        rows = [line.split()[1:] for line in lines if line.startswith("vn ")]
    else:
        start = lines.index("end_header") + 1
        rows = [line.split()[3:] for line in lines[start:start + 4]]
    n = np.array(rows, dtype=float)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_mesh_files_keep_their_normals_unless_face_normals():
    scene = load_quietly(DATA / "meshes.xml")
    obj, ply, faceted = (scene.object(n) for n in ("obj", "ply", "obj_faceted"))
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_allclose(obj.positions, square)
    np.testing.assert_allclose(ply.positions, square + [0, 0, 1])
    np.testing.assert_allclose(obj.normals, file_normals("patch.obj"), atol=1e-9)
    np.testing.assert_allclose(ply.normals, file_normals("patch.ply"), atol=1e-6)  # float in the file
    assert not np.allclose(obj.normals, ply.normals)  # they lean different ways: each file's own
    np.testing.assert_allclose(faceted.normals, np.tile([0.0, 0, 1], (faceted.n_vertices, 1)))
    np.testing.assert_allclose(faceted.positions[:, 2], 2)


def test_mesh_normals_turn_with_the_transform(tmp_path):
    (tmp_path / "patch.obj").write_bytes((DATA / "meshes" / "patch.obj").read_bytes())
    path = write_scene(tmp_path, """<shape type="obj"><string name="filename" value="patch.obj"/>
        <transform name="to_world"><rotate x="1" angle="90"/></transform></shape>""")
    (obj,) = load_quietly(path).objects
    np.testing.assert_allclose(obj.normals, file_normals("patch.obj") @ RX90.T, atol=1e-9)


# -- serialized --------------------------------------------------------------------------

TETRA = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
QUAD = (np.array([[0.0, 0, 0], [2, 0, 0], [2, 0.5, 0], [0, 0.5, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))
TRIANGLE = (np.array([[0.0, 0, 0], [0.25, 0, 0], [0, 0.75, 0]]), np.array([[0, 1, 2]]))


def serialized_shape(positions, faces, *, version=4, double=False, normals=None, extras=False, name="part"):
    """One shape as Mitsuba writes it (the layout of read_serialized's docstring)."""
    real = "<f8" if double else "<f4"
    flags = (0x2000 if double else 0x1000) | (0x1 if normals is not None else 0) | (0xA if extras else 0)
    body = struct.pack("<I", flags)
    if version == 4:
        body += name.encode("utf-8") + b"\0"
    body += struct.pack("<QQ", len(positions), len(faces)) + np.asarray(positions, real).tobytes()
    if normals is not None:
        body += np.asarray(normals, real).tobytes()
    if extras:  # texture coordinates and colours, to be skipped
        body += np.full((len(positions), 2), 0.5, real).tobytes() + np.full((len(positions), 3), 0.25, real).tobytes()
    body += np.asarray(faces, "<u4").tobytes()
    return struct.pack("<HH", 0x041C, version) + zlib.compress(body)


def serialized_file(shapes, version=4):
    data, offsets = b"", []
    for shape in shapes:
        offsets.append(len(data))
        data += shape
    return data + struct.pack(f"<{len(offsets)}{'Q' if version == 4 else 'I'}", *offsets) + struct.pack(
        "<I", len(offsets))


def three_shapes(version, double):
    tetra_normals = TETRA[0] - 0.25
    return serialized_file([
        serialized_shape(*TETRA, version=version, double=double, normals=tetra_normals, name="tétra"),
        serialized_shape(*QUAD, version=version, double=double, extras=True),
        serialized_shape(*TRIANGLE, version=version, double=double),
    ], version)


@pytest.mark.parametrize("version", [3, 4])
@pytest.mark.parametrize("double", [False, True], ids=["float", "double"])
def test_serialized_versions_and_precisions(version, double):
    data = three_shapes(version, double)
    positions, faces, normals, texcoords = read_serialized(data, 0)
    np.testing.assert_array_equal(positions, TETRA[0])
    np.testing.assert_array_equal(faces, TETRA[1])
    np.testing.assert_array_equal(normals, TETRA[0] - 0.25)
    assert texcoords is None
    for index, (p, f) in ((1, QUAD), (2, TRIANGLE)):
        positions, faces, normals, texcoords = read_serialized(data, index)
        np.testing.assert_array_equal(positions, p)
        np.testing.assert_array_equal(faces, f)
        assert normals is None
        if index == 1:  # the quad's texture coordinates (its colours skipped)
            np.testing.assert_array_equal(texcoords, np.full((4, 2), 0.5))
        else:
            assert texcoords is None
    if double:  # a value float32 cannot hold comes back exactly
        p = TRIANGLE[0] + 0.1
        assert (read_serialized(serialized_file([serialized_shape(p, TRIANGLE[1], double=True)]))[0] == p).all()


def test_serialized_shape_index_in_a_scene(tmp_path):
    (tmp_path / "parts.serialized").write_bytes(three_shapes(4, False))
    path = write_scene(tmp_path, """
        <shape type="serialized" id="quad"><string name="filename" value="parts.serialized"/>
            <integer name="shape_index" value="1"/></shape>
        <shape type="serialized" id="first"><string name="filename" value="parts.serialized"/>
            <transform name="to_world"><translate z="5"/></transform></shape>
    """)
    quad, tetra = load_quietly(path).objects
    assert quad.area == pytest.approx(1.0) and quad.n_triangles == 2
    assert tetra.n_triangles == 4 and tetra.positions[:, 2].min() == 5
    # its own normals are kept (they point away from the middle: outwards)
    assert (np.einsum("ij,ij->i", tetra.normals, tetra.positions - [0.25, 0.25, 5.25]) > 0).all()


def test_serialized_shape_index_out_of_range_names_the_line(tmp_path):
    (tmp_path / "parts.serialized").write_bytes(three_shapes(3, True))
    path = write_scene(tmp_path, '<shape type="serialized"><string name="filename" value="parts.serialized"/>'
                                 '<integer name="shape_index" value="3"/></shape>')
    message = refusal(path)
    assert f"{path}:3:" in message and "shape_index 3 is not among its 3 shapes" in message


def damaged_files():
    good = three_shapes(4, False)
    first = serialized_shape(*TETRA)
    zlib_start = 4
    bad_zlib = struct.pack("<HH", 0x041C, 4) + b"not a zlib stream at all"
    short_body = zlib.compress(struct.pack("<I", 0x1000) + b"x\0" + struct.pack("<QQ", 4, 4) + b"\0" * 20)
    bad_index = zlib.compress(struct.pack("<I", 0x1000) + b"x\0" + struct.pack("<QQ", 3, 1)
                              + np.zeros((3, 3), "<f4").tobytes() + np.array([0, 1, 3], "<u4").tobytes())
    no_name_end = zlib.compress(struct.pack("<I", 0x1000) + b"no end to this name")
    squeeze = zlib.compressobj(9)
    inflating = squeeze.compress(struct.pack("<I", 0x1000) + b"x\0" + struct.pack("<QQ", 10**8, 10**8))
    inflating += squeeze.compress(bytes(1 << 24)) + squeeze.flush()
    return {
        "empty": (b"", "too short"),
        "not serialized": (b"PK\x03\x04" + good[4:], "not a Mitsuba serialized mesh"),
        "version 5": (struct.pack("<HH", 0x041C, 5) + good[4:], "version 5"),
        "cut short": (good[:-7], "table of shapes is damaged"),
        "no shapes": (first + struct.pack("<I", 0), "table of shapes is damaged"),
        "offset outside": (first + struct.pack("<QI", len(first) + 99, 1), "outside the file"),
        "offset not at a shape": (first + struct.pack("<QI", 2, 1), "does not start with the serialized mesh header"),
        "bad zlib": (serialized_file([bad_zlib]), "compressed data is damaged"),
        "zlib cut short": (serialized_file([first[:zlib_start + 20]]), "holds 15 bytes where 4 vertices and 4 triangles"),
        "too few bytes": (serialized_file([first[:4] + short_body]), "need"),
        "no vertex": (serialized_file([first[:4] + bad_index]), "vertex that does not exist"),
        "name without end": (serialized_file([first[:4] + no_name_end]), "cut short"),
        # 10^8 vertices of zeros: a few hundred KB that would inflate to gigabytes (a held-out input)
        "inflates": (serialized_file([first[:4] + inflating]), "claims 100,000,000 vertices"),
    }


DAMAGED = damaged_files()


@pytest.mark.parametrize("case", DAMAGED, ids=list(DAMAGED))
def test_damaged_serialized_files_are_refused(case):
    data, problem = DAMAGED[case]
    with pytest.raises(InputError, match=problem) as info:
        read_serialized(data, 0, where="mesh.serialized")
    assert str(info.value).startswith("mesh.serialized: ") and "\n" not in str(info.value)


def test_a_damaged_serialized_file_in_a_scene_names_the_element(tmp_path):
    (tmp_path / "broken.serialized").write_bytes(DAMAGED["bad zlib"][0])
    path = write_scene(tmp_path, '<shape type="serialized"><string name="filename" value="broken.serialized"/></shape>')
    message = refusal(path)
    assert f"{path}:3: <shape type='serialized'>: broken.serialized: " in message


# -- the document ------------------------------------------------------------------------


def test_parameters_references_and_includes():
    scene = load_quietly(DATA / "document.xml")
    assert [o.name for o in scene.objects] == ["first", "second", "included"]
    for obj in scene.objects:  # one bsdf, by <ref> (named or not), from the including file too
        assert obj.material.diffuse == (0.25, 0.5, 0.75)
    assert scene.object("second").positions[:, 2].tolist() == [2.0] * 4  # $height
    np.testing.assert_allclose(scene.object("included").positions[:, 2], -2.0)  # -$height in the included file


@pytest.mark.parametrize("name, where, problem", [
    ("bad_unknown_parameter.xml", 5, "unknown parameter $size (no <default name='size'>)"),
    ("bad_unknown_id.xml", 5, "no element has id 'missing'"),
    ("bad_malformed.xml", 6, "malformed XML: mismatched tag"),
    ("bad_area_outside.xml", 5, "an area emitter must be inside the <shape> that emits"),
])
def test_failures_name_the_file_and_line(name, where, problem):
    message = refusal(DATA / name)
    assert message.startswith(f"{DATA / name}:{where}: ") and problem in message


def test_a_root_that_is_not_a_scene():
    assert refusal(DATA / "bad_root.xml") == f"{DATA / 'bad_root.xml'}: not a Mitsuba scene (the root element must be <scene>)"


def test_a_ref_to_the_wrong_kind_of_element(tmp_path):
    path = write_scene(tmp_path, """<integrator type="path" id="tracer"/>
        <shape type="rectangle"><ref id="tracer"/></shape>""")
    message = refusal(path)
    assert f"{path}:4:" in message and "id 'tracer' is a <integrator>, not a <bsdf> or <texture>" in message


def test_include_problems(tmp_path):
    missing = write_scene(tmp_path, '<include filename="elsewhere.xml"/>', name="missing.xml")
    assert "elsewhere.xml' not found" in refusal(missing) and f"{missing}:3:" in refusal(missing)
    loop = write_scene(tmp_path, '<include filename="loop.xml"/><shape type="rectangle"/>', name="loop.xml")
    assert "includes nested more than 16 deep" in refusal(loop)


@pytest.mark.parametrize("version", ["0.3.0", "4.0.0", "three"])
def test_versions_this_reader_does_not_know(tmp_path, version):
    path = write_scene(tmp_path, '<shape type="rectangle"/>', version=version)
    assert f"version {version!r}" in refusal(path) or f"version {version} " in refusal(path)


def test_the_05_spelling_gives_the_30_scene():
    old, new = load_quietly(DATA / "spelling_05.xml"), load_quietly(DATA / "spelling_30.xml")
    assert old.camera == new.camera and old.film == new.film == (8, 6)
    assert [o.name for o in old.objects] == [o.name for o in new.objects] == ["wall", "ball", "lamp"]
    for a, b in zip(old.objects, new.objects, strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.faces, b.faces)
        for field in ("diffuse", "specular", "emission"):
            np.testing.assert_allclose(getattr(a.material, field), getattr(b.material, field), rtol=1e-9)
        assert a.material.exponent == b.material.exponent
    # #336699 decoded to linear: not the sRGB numbers 0.2, 0.4, 0.6
    np.testing.assert_allclose(old.object("wall").material.diffuse, [0.0331047666, 0.1328683216, 0.3185467781], rtol=1e-9)
    # plastic with int_ior 1.6 over 1.0 (not the default 1.49 over air), whatever the spelling
    from radiosity.scene.microfacet import phong_lobe_for

    grey = old.object("ball").material.diffuse  # #808080 decoded, after the interface
    _, ks, _, _ = phong_lobe_for("plastic", int_ior=1.6, ext_ior=1.0, diffuse_reflectance=0.2158605001)
    np.testing.assert_allclose(old.object("ball").material.specular, ks, rtol=1e-9)
    assert not np.allclose(ks, phong_lobe_for("plastic", diffuse_reflectance=0.2158605001)[1])
    assert 0 < grey[0] < 0.2158605001


def test_nesting_200_deep_is_one_line(tmp_path):
    path = tmp_path / "deep.xml"
    path.write_text('<scene version="3.0.0">' + "<shape>" * 200 + "</shape>" * 200 + "</scene>")
    message = refusal(path)
    assert message.startswith(f"{path}:1: ") and "nested more than" in message


def test_billion_laughs_is_refused_quickly(tmp_path):
    entities = ['<!ENTITY lol0 "lol">'] + [f'<!ENTITY lol{i} "{f"&lol{i - 1};" * 10}">' for i in range(1, 10)]
    path = tmp_path / "laughs.xml"
    path.write_text('<?xml version="1.0"?>\n<!DOCTYPE scene [\n' + "\n".join(entities) + "\n]>\n"
                    '<scene version="3.0.0"><shape type="rectangle" id="&lol9;"/></scene>\n')
    start = time.perf_counter()
    message = refusal(path)  # expat's amplification limit (expat >= 2.4)
    assert time.perf_counter() - start < 2
    assert message.startswith(f"{path}:") and "malformed XML" in message


def test_an_unknown_top_level_element(tmp_path):
    path = write_scene(tmp_path, '<shape type="rectangle"/>\n<camera type="perspective"/>')
    assert refusal(path).startswith(f"{path}:4: <camera type='perspective'>: ")


# -- materials ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def materials():
    return load_warned(DATA / "materials.xml")


def test_diffuse_reflectance(materials):
    scene, _ = materials
    assert scene.object("matte").material.diffuse == (0.2, 0.4, 0.6)


def test_colour_spellings(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="rectangle" id="grey"><bsdf type="diffuse"><rgb name="reflectance" value="0.25"/></bsdf></shape>
        <shape type="disk" id="flat"><bsdf type="diffuse"><spectrum name="reflectance" value="0.4"/></bsdf></shape>
        <shape type="cube" id="srgb"><bsdf type="diffuse"><srgb name="reflectance" value="1, 0.5, 0"/></bsdf></shape>
        <shape type="sphere" id="sampled"><bsdf type="diffuse">
            <spectrum name="reflectance" value="400:0.1, 500:0.3, 600:0.5, 700:0.7"/></bsdf></shape>
    """)
    scene, messages = load_warned(path)
    assert scene.object("grey").material.diffuse == (0.25, 0.25, 0.25)
    assert scene.object("flat").material.diffuse == (0.4, 0.4, 0.4)
    np.testing.assert_allclose(scene.object("srgb").material.diffuse, (1, ((0.5 + 0.055) / 1.055) ** 2.4, 0))
    # as Mitsuba 3.9.1's scalar_rgb reads this spectrum: (0.582, 0.3858, 0.1811) (radiosity.scene.spectra: within 2 %)
    np.testing.assert_allclose(scene.object("sampled").material.diffuse, (0.582023, 0.385849, 0.181116), rtol=0.02)
    assert len(messages) == 1 and messages[0].startswith(f"{path}:8: <spectrum name='reflectance'>: a sampled spectrum")


def test_twosided_open_surface_gets_a_back_behind_it(materials):
    scene, _ = materials
    front, back = scene.object("sheet"), scene.object("sheet (back)")
    offset = BACK_OFFSET * scene.diagonal
    np.testing.assert_allclose(back.positions, front.positions - offset * front.normals)
    np.testing.assert_allclose(back.positions[:, 2], 1 - offset)
    np.testing.assert_allclose(back.normals, -front.normals)
    np.testing.assert_allclose(face_normals(back), np.tile([0, 0, -1.0], (back.n_triangles, 1)))
    assert back.material == front.material and back.material.diffuse == (0.3, 0.3, 0.3)


def test_a_twosided_lamp_emits_from_its_front_alone(tmp_path):
    # Mitsuba's area emitter shines from the front whatever its bsdf: a twosided one reflects on both sides
    path = write_scene(tmp_path, """<shape type="rectangle" id="lamp">
        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.4"/></bsdf></bsdf>
        <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter></shape>""")
    scene = load_quietly(path)
    front, back = scene.object("lamp"), scene.object("lamp (back)")
    assert front.material.emission == (3, 2, 1) and back.material.emission == (0, 0, 0)
    assert back.material.diffuse == front.material.diffuse == (0.4, 0.4, 0.4)
    assert back.material.name == f"{front.material.name} (back)"  # the kernels' table keys materials by name
    assert [o.name for o in scene.emitters] == ["lamp"]
    assert scene.materials[back.material.name] is back.material


def test_twosided_closed_mesh_gets_no_back(materials):
    scene, _ = materials
    names = [o.name for o in scene.objects]
    assert "box" in names and "box (back)" not in names


def test_a_dielectric_is_glass_of_mitsuba_s_indices_without_a_warning(materials):
    scene, messages = materials
    glass = scene.object("glass").material
    assert glass.is_glass and glass.glass.kind == "dielectric" and not glass.is_reflective
    assert glass.glass.eta == pytest.approx(1.5 / 1.000277)  # ext_ior: Mitsuba's default, air
    assert not [m for m in messages if "dielectric" in m]


@pytest.mark.parametrize("bsdf, expected", [
    ('<bsdf type="thindielectric"><float name="int_ior" value="1.52"/><string name="ext_ior" value="vacuum"/></bsdf>',
     dict(kind="thindielectric", eta=1.52, alpha=0.0)),
    ('<bsdf type="roughdielectric"><string name="int_ior" value="water"/><float name="alpha_u" value="0.2"/>'
     '<rgb name="specular_transmittance" value="0.5, 0.6, 0.7"/></bsdf>',
     dict(kind="roughdielectric", eta=1.333 / 1.000277, alpha=0.2, distribution="beckmann",
          specular_transmittance=(0.5, 0.6, 0.7))),
    ('<bsdf type="twosided"><bsdf type="dielectric"><string name="int_ior" value="diamond"/></bsdf></bsdf>',
     dict(kind="dielectric", eta=2.419 / 1.000277)),
])
def test_the_glass_kinds_keep_their_parameters(tmp_path, bsdf, expected):
    path = write_scene(tmp_path, f'<shape type="sphere" id="ball">{bsdf}</shape>')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_mitsuba(path)
    glass = scene.object("ball").material.glass
    for key, value in expected.items():
        assert getattr(glass, key) == (pytest.approx(value) if isinstance(value, float) else value), key
    assert len(scene.objects) == 1 and not caught  # no back added to a two-sided glass, no warning


def test_an_interface_of_equal_indices_is_left_out_with_a_warning(tmp_path):
    path = write_scene(tmp_path, '<shape type="rectangle" id="kept"/><shape type="sphere" id="ball">'
                       '<bsdf type="dielectric"><float name="int_ior" value="1.3"/><float name="ext_ior" value="1.3"/>'
                       '</bsdf></shape>')
    with pytest.warns(SceneWarning, match="int_ior equals ext_ior"):
        scene = load_mitsuba(path)
    assert [o.name for o in scene.objects] == ["kept"]


def test_approximated_bsdfs_warn_and_keep_what_they_can(materials):
    scene, messages = materials
    where = {"mask": 25, "bumpmap": 32, "blendbsdf": 39, "hair": 47}
    for kind, line in where.items():
        assert any(m.startswith(f"{DATA / 'materials.xml'}:{line}: <bsdf type='{kind}'>") for m in messages), kind
    assert scene.object("masked").material.diffuse == (0.1, 0.2, 0.3)  # opacity 0.8: opaque
    assert scene.object("bumpy").material.diffuse == (0.6, 0.5, 0.4)
    np.testing.assert_allclose(scene.object("blend").material.diffuse, 0.75 * 0.8 + 0.25 * 0.4)
    assert scene.object("unknown").material.diffuse == (0.5, 0.5, 0.5)
    assert len(messages) == 4  # mask, bumpmap, blendbsdf, hair: one each


def test_a_mostly_transparent_mask_leaves_the_shape_out(tmp_path):
    path = write_scene(tmp_path, """<shape type="rectangle" id="kept"/>
        <shape type="disk" id="leaf"><bsdf type="mask"><float name="opacity" value="0.2"/><bsdf type="diffuse"/></bsdf>
        </shape>""")
    scene, messages = load_warned(path)
    assert [o.name for o in scene.objects] == ["kept"] and "left out" in messages[0]


def rough_surface(tmp_path, kind, alpha, extra=""):
    rough = f'<float name="alpha" value="{alpha}"/>' if alpha is not None else ""
    path = write_scene(tmp_path, f'<shape type="rectangle"><bsdf type="{"rough" if alpha else ""}{kind}">{rough}{extra}'
                                 "</bsdf></shape>")
    (obj,) = load_quietly(path).objects
    return obj.material


@pytest.mark.parametrize("kind", ["plastic", "conductor"])
def test_glossy_bsdfs_sharpen_as_roughness_falls(tmp_path, kind):
    alphas = [0.6, 0.4, 0.2, 0.1, 0.05, 0.02]
    rough = [rough_surface(tmp_path, kind, a) for a in alphas]
    smooth = rough_surface(tmp_path, kind, None)
    exponents = [m.exponent for m in rough] + [smooth.exponent]
    assert all(math.isfinite(e) and e > 0 for e in exponents), exponents
    assert all(a < b for a, b in zip(exponents, exponents[1:])), exponents  # strictly sharper
    for m in rough + [smooth]:
        assert min(m.specular) > 0
        assert m.fresnel is not None  # the measured rule gives plastics and conductors Fresnel
        assert albedo(m, np.linspace(0, 1, 101)).max() <= 1 + 1e-4
        if kind == "conductor":
            assert m.diffuse == (0, 0, 0)
        else:
            assert min(m.diffuse) > 0


def test_conductor_colours_and_anisotropy(tmp_path):
    mirror = rough_surface(tmp_path, "conductor", None)  # material 'none': a perfect mirror
    np.testing.assert_allclose(mirror.specular, 1, atol=1e-6)
    gold = rough_surface(tmp_path, "conductor", 0.1, '<rgb name="eta" value="0.2, 0.45, 1.4"/>'
                                                     '<rgb name="k" value="3.6, 2.4, 1.8"/>')
    normal = albedo(gold, 1.0)  # the colour is in F0 now, ks the fitted scale
    assert normal[0] >= normal[1] > normal[2]
    path = write_scene(tmp_path, '<shape type="rectangle"><bsdf type="roughconductor"><float name="alpha_u" value="0.05"/>'
                                 '<float name="alpha_v" value="0.2"/></bsdf></shape>')
    scene, messages = load_warned(path)
    assert "anisotropic roughness (0.05, 0.2) taken as isotropic 0.1" in messages[0]
    assert scene.objects[0].material.exponent == rough_surface(tmp_path, "conductor", 0.1).exponent
    named = rough_surface(tmp_path, "conductor", None, '<string name="material" value="Au"/>')
    normal = albedo(named, 1.0)  # red and green may both reach the energy bound
    assert normal[0] + 1e-9 >= normal[1] > normal[2]  # gold: Mitsuba's preset
    bad = write_scene(tmp_path, '<shape type="rectangle"><bsdf type="conductor"><string name="material" value="Fe"/>'
                                "</bsdf></shape>")
    assert "unknown material 'Fe'" in refusal(bad)  # Mitsuba has no plain Fe either


def test_a_bitmap_texture_counts_as_its_mean_colour_where_it_is_not_a_diffuse_reflectance(tmp_path):
    """A bitmap as a diffuse reflectance is a texture (tests/radiosity/scene/test_mitsuba_textures.py);
    elsewhere (a conductor's specular reflectance, a blend's weight) its mean colour."""
    from PIL import Image

    Image.fromarray(np.array([[[255, 0, 0], [0, 0, 255]], [[255, 0, 0], [0, 0, 255]]], np.uint8)).save(
        tmp_path / "red_blue.png")
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(tmp_path / "grey.png")
    path = write_scene(tmp_path, """
        <texture type="bitmap" id="grey"><string name="filename" value="grey.png"/></texture>
        <shape type="rectangle" id="pattern"><bsdf type="conductor">
            <texture type="bitmap" name="specular_reflectance"><string name="filename" value="red_blue.png"/></texture>
        </bsdf></shape>
        <shape type="disk" id="plain"><bsdf type="blendbsdf"><ref name="weight" id="grey"/>
            <bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf></shape>
    """)
    scene, messages = load_warned(path)
    specular = scene.object("pattern").material.specular
    assert specular[0] == pytest.approx(specular[2]) and specular[1] == 0  # linear: red and blue, 1 and 0 averaged
    assert not scene.object("pattern").textured and not scene.object("plain").textured
    assert any(m.startswith(f"{path}:6: <texture type='bitmap' name='specular_reflectance'>: texture 'red_blue.png' "
                            "taken as its mean colour (0.5, 0.0, 0.5)") for m in messages)
    assert any(m.startswith(f"{path}:4: <texture type='bitmap'>: texture 'grey.png' taken as its mean colour (0.2159")
               for m in messages)


# -- emitters ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def emitters():
    return load_warned(DATA / "emitters.xml")


def test_area_emitter_radiance(emitters):
    scene, _ = emitters
    panel = scene.object("panel")
    assert panel.material.emission == (4, 5, 6)
    np.testing.assert_allclose(face_normals(panel), np.tile([0, 0, -1.0], (2, 1)), atol=1e-12)  # turned to face down


def test_point_spot_and_directional_emitters_are_the_scenes_delta_lights(emitters):
    scene, _ = emitters
    bulb, spot, sun = scene.lights
    assert (bulb.kind, bulb.source, bulb.spot) == ("point", "bulb", None)
    np.testing.assert_array_equal(bulb.points, [[0.5, 0.5, 1]])
    np.testing.assert_array_equal(bulb.radiance, [10, 20, 30])
    # a spot at its to_world's translation, pointing along its +z, Mitsuba 3's defaults: 20 degrees, 3/4 of it
    assert (spot.kind, spot.source) == ("point", "spot")
    np.testing.assert_allclose(spot.points, [[-0.5, -0.5, 1]], atol=1e-12)
    np.testing.assert_allclose(spot.spot.axis, [0, 0, -1], atol=1e-12)
    assert (spot.spot.cutoff_deg, spot.spot.beam_deg) == (20, 15)
    np.testing.assert_array_equal(spot.radiance, [3, 3, 3])
    # a directional light's direction is the way its light travels
    assert (sun.kind, sun.source) == ("direction", "sun")
    np.testing.assert_allclose(sun.points, [[2**-0.5, 0, -(2**-0.5)]], atol=1e-12)
    np.testing.assert_array_equal(sun.radiance, [2, 3, 4])
    # none is an object: nothing sees them
    assert [o.name for o in scene.objects] == ["floor", "panel"]


def test_emitter_warnings(emitters):
    scene, messages = emitters
    where = f"{DATA / 'emitters.xml'}"
    assert not any(m.startswith((f"{where}:14:", f"{where}:18:", f"{where}:26:")) for m in messages)  # point, spot, sun
    # the constant emitter is the scene's environment; the envmap after it a second one, left out
    assert not any(m.startswith(f"{where}:24:") for m in messages)
    assert scene.environment.constant and np.allclose(scene.environment.radiance([[0, 1, 0], [1, 0, 0]]), 1.0)
    assert any(m.startswith(f"{where}:25: <emitter type='envmap'>") and "second environment" in m and "left out" in m
               for m in messages)
    assert any(m.startswith(f"{where}:30: <emitter type='sun'>") and "left out" in m for m in messages)


def test_spot_and_directional_in_0x_spelling_and_by_transform(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="rectangle"><bsdf type="diffuse"/></shape>
        <emitter type="spot">
            <transform name="toWorld"><lookAt origin="0, 0, 2" target="1, 0, 2"/></transform>
            <float name="cutoffAngle" value="30"/>
            <float name="beamWidth" value="10"/>
            <spectrum name="intensity" value="7"/>
        </emitter>
        <emitter type="directional">
            <transform name="toWorld"><rotate y="1" angle="90"/></transform>
            <spectrum name="irradiance" value="0.5"/>
        </emitter>
    """, version="0.6.0")
    scene = load_quietly(path)
    spot, sun = scene.lights
    np.testing.assert_allclose(spot.spot.axis, [1, 0, 0], atol=1e-12)
    assert (spot.spot.cutoff_deg, spot.spot.beam_deg) == (30, 10)
    np.testing.assert_allclose(spot.radiance, [7, 7, 7])
    np.testing.assert_allclose(sun.points[0], [1, 0, 0], atol=1e-12)  # +z turned about y by 90 degrees
    np.testing.assert_allclose(sun.radiance, [0.5] * 3)


@pytest.mark.parametrize("body, fragment", [
    ('<emitter type="spot"><float name="cutoff_angle" value="10"/><float name="beam_width" value="12"/></emitter>',
     "beam width must be in [0, the cutoff angle 10]"),
    ('<emitter type="spot"><float name="cutoff_angle" value="0"/></emitter>', "cutoff angle must be in (0, 180]"),
    ('<emitter type="directional"><vector name="direction" value="0, 0, 0"/></emitter>', "must not be zero"),
    ('<emitter type="point"><rgb name="intensity" value="1, -1, 1"/></emitter>', "must not be negative"),
    ('<emitter type="directional"><vector name="direction" value="0, 0, 1"/>'
     '<transform name="to_world"><translate x="1"/></transform></emitter>', "give 'direction' or 'to_world'"),
])
def test_bad_lights_are_refused_in_one_line(tmp_path, body, fragment):
    path = write_scene(tmp_path, f'<shape type="rectangle"><bsdf type="diffuse"/></shape>\n{body}')
    message = refusal(path)
    assert fragment in message and f"{path}:4:" in message


# -- the sensor --------------------------------------------------------------------------


def test_sensor_lookat_and_film():
    scene = load_quietly(DATA / "sensor.xml")
    camera = scene.camera
    assert camera.eye == (0, 0, 4) and camera.look_at == (0, 0, 3) and camera.up == (0, 1, 0)
    assert scene.film == (8, 6) and (camera.width, camera.height) == (8, 6)
    assert camera.fov_y_deg == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(30)) * 6 / 8)))


def test_a_missing_file_is_named_with_every_other_missing_file(tmp_path):
    (tmp_path / "here.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    path = write_scene(tmp_path, """<shape type="obj"><string name="filename" value="here.obj"/></shape>
        <shape type="obj"><string name="filename" value="gone.obj"/></shape>
        <shape type="obj"><string name="filename" value="also/gone.ply"/></shape>
        <emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>""")
    message = refusal(path)
    assert message.startswith(f"{path}:4: <shape type='obj'>: file '{tmp_path / 'gone.obj'}' not found")
    assert message.endswith("(2 more files it names are missing too: also/gone.ply, sky.exr)")
    (tmp_path / "gone.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert refusal(path).endswith(f"file '{tmp_path / 'also' / 'gone.ply'}' not found (1 more file it names is "
                                  "missing too: sky.exr)")


def test_a_shape_of_degenerate_triangles_alone_is_left_out_as_mitsuba_does(tmp_path):
    (tmp_path / "line.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 3 2 1\n")
    path = write_scene(tmp_path, """<shape type="obj" id="line"><string name="filename" value="line.obj"/></shape>
        <shape type="rectangle" id="floor"/>""")
    scene, messages = load_warned(path)
    assert [o.name for o in scene.objects] == ["floor"]
    assert len(messages) == 1 and "object 'line'" in messages[0] and messages[0].endswith(
        "all 2 triangle(s) are degenerate (zero area): the object is left out")
    alone = write_scene(tmp_path, '<shape type="obj"><string name="filename" value="line.obj"/></shape>', name="a.xml")
    with pytest.warns(SceneWarning):
        assert "every shape's triangles are degenerate" in refusal(alone)


@pytest.mark.parametrize("version, tag, read", [("0.4.0", "lookAt", True), ("0.5.0", "lookAt", True),
                                                ("0.6.0", "lookat", True), ("3.0.0", "lookAt", False)])
def test_look_at_spellings(tmp_path, version, tag, read):
    # Mitsuba 0.4-0.6's scene handler read <lookAt> and <lookat> as one tag; Mitsuba 2-3 know only <lookat>
    path = write_scene(tmp_path, f"""<sensor type="perspective"><float name="fov" value="40"/>
        <transform name="toWorld"><scale x="-1"/><scale x="-1"/>
        <{tag} origin="0, 2, 15" target="0, -2, 2.5" up="0, 1, 0"/></transform></sensor>
        <shape type="rectangle"/>""", version=version)
    if not read:
        assert f"<{tag}>: not a transform step" in refusal(path)
        return
    camera = load_quietly(path).camera
    assert camera.eye == pytest.approx((0, 2, 15)) and camera.up[1] > 0.9
    forward = np.subtract(camera.look_at, camera.eye)
    assert forward / np.linalg.norm(forward) == pytest.approx(np.array([0, -4, -12.5]) / math.hypot(4, 12.5))


def vertical_fov(fov, spans, height):
    """The vertical field of view of a camera whose ``fov`` spans ``spans`` pixels."""
    return math.degrees(2 * math.atan(math.tan(math.radians(fov) / 2) * height / spans))


def sensor_scene(tmp_path, fov_properties, width, height, transform=None):
    transform = transform or '<lookat origin="0, 0, 5" target="0, 0, 0"/>'
    return write_scene(tmp_path, f"""<sensor type="perspective">{fov_properties}
        <transform name="to_world">{transform}</transform>
        <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/></film>
        </sensor><shape type="rectangle"/>""")


@pytest.mark.parametrize("width, height", [(8, 6), (6, 8)])
@pytest.mark.parametrize("axis", ["x", "y", "diagonal", "smaller", "larger"])
def test_fov_axis(tmp_path, axis, width, height):
    spans = {"x": width, "y": height, "diagonal": math.hypot(width, height), "smaller": min(width, height),
             "larger": max(width, height)}[axis]
    path = sensor_scene(tmp_path, f'<float name="fov" value="70"/><string name="fov_axis" value="{axis}"/>', width,
                        height)
    camera = load_quietly(path).camera
    assert camera.fov_y_deg == pytest.approx(vertical_fov(70, spans, height), rel=1e-12)
    assert (camera.width, camera.height) == (width, height)


def test_focal_length_of_06(tmp_path):
    # Mitsuba 0.6 and 3: the focal length sets the diagonal field of view of a 36 x 24 mm film;
    # Mitsuba 3.x gives x_fov 38.18484 degrees for 50 mm on an 8 x 6 film (seen with mitsuba 3)
    path = sensor_scene(tmp_path, '<string name="focalLength" value="50mm"/>', 8, 6)
    camera = load_quietly(path).camera
    assert camera.fov_y_deg == pytest.approx(vertical_fov(38.18484, 8, 6), abs=1e-4)
    diagonal = math.degrees(2 * math.atan(math.hypot(36, 24) / (2 * 35)))
    path = sensor_scene(tmp_path, '<string name="focalLength" value="35mm"/>', 6, 8)
    assert load_quietly(path).camera.fov_y_deg == pytest.approx(vertical_fov(diagonal, 10, 8), rel=1e-12)
    path = sensor_scene(tmp_path, '<string name="focal_length" value="24"/>', 8, 6)  # "mm" may be left out
    assert load_quietly(path).camera.fov_y_deg == pytest.approx(vertical_fov(71.59152, 8, 6), abs=1e-4)  # Mitsuba 3
    for focal in ("wide", "0mm", "1.2.3mm", "-5mm"):
        path = sensor_scene(tmp_path, f'<string name="focal_length" value="{focal}"/>', 8, 6)
        assert f"focal length {focal!r}" in refusal(path)


def test_a_tilted_up_vector_is_made_orthogonal(tmp_path):
    path = sensor_scene(tmp_path, '<float name="fov" value="40"/>', 8, 6,
                        '<lookat origin="1, 2, 3" target="1, 2, 0" up="1, 1, 0"/>')
    camera = load_quietly(path).camera
    assert camera.eye == (1, 2, 3) and camera.look_at == (1, 2, 2)
    np.testing.assert_allclose(camera.up, np.array([1, 1, 0]) / math.sqrt(2))


def test_a_mirroring_sensor_warns(tmp_path):
    path = sensor_scene(tmp_path, '<float name="fov" value="40"/>', 8, 6,
                        '<scale x="-1"/><lookat origin="0, 0, 5" target="0, 0, 0"/>')
    scene, messages = load_warned(path)
    assert scene.camera.eye == (0, 0, 5) and "mirrors the image" in messages[0]


# -- the command line --------------------------------------------------------------------


def test_scene_info_reads_a_mitsuba_scene(capsys):
    from display.cli import main

    assert main(["scene-info", str(DATA / "sensor.xml")]) == 0
    out = capsys.readouterr().out
    assert "floor" in out and "lamp" in out


def test_scene_info_names_a_glass_and_what_it_reflects(tmp_path, capsys):
    from display.cli import main

    path = write_scene(tmp_path, '<shape type="rectangle" id="floor"/><shape type="sphere" id="ball">'
                       '<bsdf type="roughdielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/>'
                       '<string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf></shape>')
    assert main(["scene-info", str(path)]) == 0
    ball = next(line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("ball ")
                and "roughdielectric" in line)
    assert "roughdielectric 1.5 ggx 0.2" in ball and "0.040 / 0.089" in ball  # Fresnel at 0 and 60 degrees


def test_truth_renders_at_the_film_size(tmp_path, capsys):
    from PIL import Image

    from display.cli import main

    out = tmp_path / "truth.png"
    assert main(["truth", str(DATA / "sensor.xml"), "--spp", "1", "-o", str(out)]) == 0
    assert "path traced 8x6" in capsys.readouterr().out
    with Image.open(out) as image:
        assert image.size == (8, 6)


@pytest.mark.parametrize("name", ["bad_malformed.xml", "bad_unknown_parameter.xml", "bad_root.xml"])
def test_a_bad_scene_is_exit_2_and_one_line(capsys, name):
    from display.cli import main

    assert main(["scene-info", str(DATA / name)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1 and str(DATA / name) in lines[0] and lines[0].startswith("vlights scene-info: error: ")


def test_rough_plastics_and_conductors_keep_their_own_model_beside_the_phong_stand_in(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="rectangle" id="floor"><bsdf type="roughplastic"><string name="distribution" value="ggx"/>
            <float name="alpha" value="0.15"/><rgb name="diffuse_reflectance" value="0.35, 0.3, 0.25"/>
            <boolean name="nonlinear" value="true"/></bsdf></shape>
        <shape type="sphere" id="gold"><bsdf type="twosided"><bsdf type="roughconductor">
            <float name="alpha" value="0.1"/><string name="material" value="Au"/></bsdf></bsdf></shape>
        <shape type="sphere" id="mirror"><bsdf type="conductor"/></shape>
        <shape type="sphere" id="shiny"><bsdf type="plastic"/></shape>""")
    scene = load_quietly(path)
    floor, gold = scene.materials["floor"], scene.materials["gold"]
    assert floor.microfacet.kind == "roughplastic" and floor.microfacet.distribution == "ggx"
    assert floor.microfacet.alpha == 0.15 and floor.microfacet.nonlinear
    assert floor.microfacet.eta == pytest.approx((1.49 / 1.000277,) * 3)
    assert floor.microfacet.diffuse_reflectance == pytest.approx((0.35, 0.3, 0.25))
    assert floor.fresnel is not None and floor.exponent > 0  # the stand-in beside it
    assert gold.microfacet.kind == "roughconductor" and gold.microfacet.distribution == "beckmann"
    assert gold.microfacet.eta == pytest.approx(microfacet.METALS["Au"][0])
    assert gold.microfacet.k == pytest.approx(microfacet.METALS["Au"][1])
    assert scene.materials["mirror"].microfacet is None and scene.materials["shiny"].microfacet is None


def test_a_roughness_beyond_the_model_s_range_is_clipped_with_a_warning(tmp_path):
    path = write_scene(tmp_path, """
        <shape type="sphere" id="glassy"><bsdf type="roughconductor"><float name="alpha" value="1e-6"/></bsdf></shape>
        <shape type="sphere" id="chalky"><bsdf type="roughplastic"><float name="alpha" value="9"/></bsdf></shape>""")
    scene, warned = load_warned(path)
    assert scene.materials["glassy"].microfacet.alpha == 1e-4 and scene.materials["chalky"].microfacet.alpha == 4.0
    assert any("alpha 1e-06 taken as 0.0001" in w for w in warned) and any("alpha 9 taken as 4" in w for w in warned)
