"""Mitsuba bitmap textures: what the reader makes of them, and Mitsuba 3 itself as the
oracle of the texture coordinates.

The oracle (skipped where Mitsuba 3 is not installed: /work/mitsuba-venv, or
$VLIGHTS_MITSUBA_PYTHON): for each shape kind (rectangle, disk, sphere, cube, cylinder,
obj, ply, serialized), each under a transform, and for the bitmap's to_uv, wrap modes,
raw flag and an OpenEXR image, Mitsuba traces rays at the shape and evaluates the
diffuse reflectance where they hit (``eval_diffuse_reflectance``: the bitmap through
the shape's (u, v), its to_uv and wrap mode); we take the same points on our
tessellation and read kd * lookup(texture, uv). An asymmetric image (every texel its
own random colour), so a flipped, mirrored, rotated or shifted mapping fails.
"""

import json
import struct
import warnings
import zlib

import numpy as np
import pytest
import trimesh
from mitsuba_oracle import require_mitsuba, run_mitsuba
from PIL import Image
from scene_files import load_warned
from scipy.spatial import cKDTree

from radiosity.files.errors import SceneWarning
from radiosity.physics.textures import as_repeating, lookup, srgb_to_linear, wrapped_lookup
from radiosity.scene import microfacet
from radiosity.scene.mitsuba import Tessellation, load_mitsuba

FINE = Tessellation(segments=512, sphere_levels=6)


def _image(shape=(5, 7), seed=3):
    """An 8-bit sRGB image, every texel its own colour."""
    return np.random.default_rng(seed).integers(0, 256, size=(*shape, 3), dtype=np.uint8)


def _write_exr(path, image):
    import OpenEXR

    channels = {name: np.ascontiguousarray(image[..., i], dtype=np.float32) for i, name in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
        f.write(str(path))


def _serialized(path, positions, faces, texcoords):
    """One shape in Mitsuba's serialized format (version 4, float32, texcoords)."""
    body = struct.pack("<I", 0x1000 | 0x2) + b"part\0" + struct.pack("<QQ", len(positions), len(faces))
    body += np.asarray(positions, "<f4").tobytes() + np.asarray(texcoords, "<f4").tobytes()
    body += np.asarray(faces, "<u4").tobytes()
    path.write_bytes(struct.pack("<HH", 0x041C, 4) + zlib.compress(body) + struct.pack("<QI", 0, 1))


SQUARE = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
SQUARE_FACES = np.array([[0, 1, 2], [0, 2, 3]])
SQUARE_UVS = np.array([[0.1, 0.0], [0.9, 0.2], [1.0, 1.0], [0.0, 0.8]])  # a skewed map: no symmetry hides an error


def _mesh_files(directory):
    vt = "".join(f"vt {u} {v}\n" for u, v in SQUARE_UVS)
    v = "".join(f"v {x} {y} {z}\n" for x, y, z in SQUARE)
    (directory / "square.obj").write_text(v + vt + "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    ply = ["ply", "format ascii 1.0", "element vertex 4", *[f"property float {p}" for p in "xyzuv"],
           "element face 2", "property list uchar int vertex_indices", "end_header"]
    ply += [f"{x} {y} {z} {u} {w}" for (x, y, z), (u, w) in zip(SQUARE, SQUARE_UVS, strict=True)]
    ply += ["3 0 1 2", "3 0 2 3"]
    (directory / "square.ply").write_text("\n".join(ply) + "\n")
    _serialized(directory / "square.serialized", SQUARE, SQUARE_FACES, SQUARE_UVS)


TURN = '<transform name="to_world"><rotate x="0.6" y="0.8" angle="35"/><scale value="1.5"/></transform>'
BITMAP = '<texture type="bitmap" name="reflectance"><string name="filename" value="{file}"/>{extra}</texture>'

# name: (shape element's type and children, the bitmap's file and extra properties)
CASES = {
    "rectangle": ('type="rectangle">' + TURN, "t.png", ""),
    "disk": ('type="disk">' + TURN, "t.png", ""),
    "sphere": ('type="sphere"><point name="center" x="0.2" y="-0.1" z="0.3"/><float name="radius" value="1.3"/>'
               + TURN, "t.png", ""),
    "cube": ('type="cube">' + TURN, "t.png", ""),
    "cylinder": ('type="cylinder"><point name="p0" x="0.3" y="-0.5" z="-0.6"/><point name="p1" x="-0.2" y="0.4" '
                 'z="0.7"/><float name="radius" value="0.8"/>', "t.png", ""),
    "obj": ('type="obj"><string name="filename" value="square.obj"/>' + TURN, "t.png", ""),
    "ply": ('type="ply"><string name="filename" value="square.ply"/>' + TURN, "t.png", ""),
    "serialized": ('type="serialized"><string name="filename" value="square.serialized"/>' + TURN, "t.png", ""),
    "to_uv": ('type="rectangle">', "t.png",
              '<transform name="to_uv"><scale x="0.7" y="1.3"/><rotate z="1" angle="25"/>'
              '<translate x="0.15" y="-0.2"/></transform>'),
    "mirror": ('type="rectangle">', "t.png", '<string name="wrap_mode" value="mirror"/>'
               '<transform name="to_uv"><scale x="2.6" y="3.2"/><translate x="-0.9" y="-1.1"/></transform>'),
    "clamp": ('type="rectangle">', "t.png", '<string name="wrap_mode" value="clamp"/>'
              '<transform name="to_uv"><scale x="1.8" y="2.2"/><translate x="-0.4" y="-0.6"/></transform>'),
    "raw": ('type="rectangle">', "t.png", '<boolean name="raw" value="true"/>'),
    "exr": ('type="rectangle">', "t.exr", ""),
}

ORACLE = """
import json, sys, numpy as np, mitsuba as mi
mi.set_variant("scalar_rgb")
cases = json.loads(open(sys.argv[1]).read())
out = {}
for name, (path, origins, targets) in cases.items():
    scene = mi.load_file(path)
    rows = []
    for o, t in zip(origins, targets):
        d = np.subtract(t, o)
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*o), mi.Vector3f(*(d / np.linalg.norm(d)))))
        if not si.is_valid():
            continue
        rgb = si.bsdf().eval_diffuse_reflectance(si)
        rows.append([*si.p, *rgb])
    out[name] = rows
open(sys.argv[2], "w").write(json.dumps(out))
"""


def _scene_file(directory, name):
    shape, file, extra = CASES[name]
    bsdf = '<bsdf type="diffuse">' + BITMAP.format(file=file, extra=extra) + "</bsdf>"
    path = directory / f"{name}.xml"
    path.write_text(f'<scene version="3.0.0"><shape id="{name}" {shape}{bsdf}</shape></scene>')
    return path


def _rays(name, rng, count=400):
    """Origins 10 away in random directions, aimed at random points near the shape."""
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    if name in ("to_uv", "mirror", "clamp", "raw", "exr"):  # rectangles seen from the front
        directions[:, 2] = np.abs(directions[:, 2]) + 0.3
    return 10.0 * directions, rng.uniform(-0.9, 0.9, size=(count, 3))


def _nearest(obj, points, candidates=24):
    """(uv (N, 2), distance (N,)) of the points of the object's mesh nearest
    ``points``: the exact closest point on each of the triangles whose centroids are
    nearest, the nearest of those."""
    triangles = obj.positions[obj.faces]
    _, near = cKDTree(triangles.mean(axis=1)).query(points, k=min(candidates, len(triangles)))
    near = np.atleast_2d(near.T).T
    closest = np.stack([trimesh.triangles.closest_point(triangles[near[:, k]], points) for k in range(near.shape[1])],
                       axis=1)
    distance = np.linalg.norm(closest - points[:, None], axis=2)
    best = np.argmin(distance, axis=1)
    rows = np.arange(len(points))
    triangle = near[rows, best]
    bary = trimesh.triangles.points_to_barycentric(triangles[triangle], closest[rows, best])
    return np.einsum("nk,nkd->nd", bary, obj.uvs[obj.faces[triangle]]), distance[rows, best]


def _ours(obj, points):
    """kd * texture(uv) at the points of our tessellation nearest ``points``."""
    uv, distance = _nearest(obj, points)
    return np.asarray(obj.material.diffuse) * lookup(obj.texture, uv), distance


@pytest.fixture(scope="module")
def oracle(tmp_path_factory):
    require_mitsuba()
    directory = tmp_path_factory.mktemp("mitsuba_textures")
    image = _image()
    Image.fromarray(image).save(directory / "t.png")
    _write_exr(directory / "t.exr", srgb_to_linear(image / 255.0) * 1.0)
    _mesh_files(directory)
    rng = np.random.default_rng(7)
    cases = {}
    for name in CASES:
        origins, targets = _rays(name, rng)
        cases[name] = (str(_scene_file(directory, name)), origins.tolist(), targets.tolist())
    (directory / "cases.json").write_text(json.dumps(cases))
    run_mitsuba(ORACLE, directory / "cases.json", directory / "out.json")
    return directory, json.loads((directory / "out.json").read_text())


# the tolerance of each case: Mitsuba keeps 8-bit textures in half precision (3e-3); curved shapes add our
# tessellation's error in (u, v) (a point's nearest point on the mesh is not the analytic one's)
TOLERANCE = {"sphere": 0.03, "cylinder": 0.03, "disk": 0.03}


@pytest.mark.parametrize("name", list(CASES))
def test_texture_coordinates_match_mitsuba_3(oracle, name):
    directory, results = oracle
    rows = np.asarray(results[name])
    assert len(rows) >= 50, f"only {len(rows)} rays hit the {name}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        (obj,) = load_mitsuba(_scene_file(directory, name), FINE).objects
    assert obj.textured
    ours, distance = _ours(obj, rows[:, :3])
    assert distance.max() < 0.01  # the same surface
    error = np.abs(ours - rows[:, 3:]).max(axis=1)
    tolerance = TOLERANCE.get(name, 4e-3)
    # near a sphere's poles and a disk's centre our triangles' (u, v) is least like the analytic one's
    assert np.quantile(error, 0.95) < tolerance / 3 and error.max() < tolerance, (name, np.sort(error)[-5:])
    assert rows[:, 3:].std(axis=0).min() > 0.05  # the rays saw the texture vary


# -- what the reader makes of a bitmap (no Mitsuba needed) ---------------------------------------------


def _write(directory, body, name="scene.xml"):
    path = directory / name
    path.write_text(f'<?xml version="1.0"?>\n<scene version="3.0.0">\n{body}\n</scene>\n')
    return path


def _load(path, tessellation=None):
    return load_warned(path, lambda p: load_mitsuba(p, tessellation))


def test_a_diffuse_bitmap_is_the_texture_on_both_sides_of_a_twosided_rectangle(tmp_path):
    image = _image((2, 2))
    Image.fromarray(image).save(tmp_path / "t.png")
    path = _write(tmp_path, '<shape type="rectangle" id="r"><bsdf type="twosided"><bsdf type="diffuse">'
                  + BITMAP.format(file="t.png", extra="") + "</bsdf></bsdf></shape>")
    scene, said = _load(path)
    assert said == []
    front, back = scene.objects
    assert front.textured and back.textured and front.texture is back.texture
    assert front.material.diffuse == (1.0, 1.0, 1.0)
    np.testing.assert_allclose(front.texture, srgb_to_linear(image / 255.0), atol=1e-6)
    # Mitsuba's rectangle: (u, v) = ((x + 1) / 2, (y + 1) / 2), its v down the image: (-1, -1) is the top-left texel
    corner = np.argmin(np.linalg.norm(front.positions - [-1, -1, 0], axis=1))
    np.testing.assert_allclose(lookup(front.texture, front.uvs[corner] * 0.5 + 0.25), front.texture[0, 0], atol=1e-6)


def test_one_bitmap_read_as_it_is_is_one_array_for_all_its_shapes(tmp_path):
    Image.fromarray(_image()).save(tmp_path / "t.png")
    path = _write(tmp_path, '<bsdf type="diffuse" id="b">' + BITMAP.format(file="t.png", extra="") + "</bsdf>"
                  '<shape type="rectangle"><ref id="b"/></shape><shape type="disk"><ref id="b"/></shape>')
    a, b = _load(path)[0].objects
    assert a.texture is b.texture


@pytest.mark.parametrize("nonlinear", [False, True])
def test_a_plastic_diffuse_bitmap_is_its_brightest_texel_mapped_and_the_rest_relative(tmp_path, nonlinear):
    image = _image((3, 4))
    Image.fromarray(image).save(tmp_path / "t.png")
    texels = srgb_to_linear(image / 255.0)
    extra = f'<boolean name="nonlinear" value="{str(nonlinear).lower()}"/><float name="alpha" value="0.2"/>'
    bitmap = BITMAP.format(file="t.png", extra="").replace('name="reflectance"', 'name="diffuse_reflectance"')
    path = _write(tmp_path, f'<shape type="rectangle"><bsdf type="roughplastic">{extra}{bitmap}</bsdf></shape>')
    scene, said = _load(path)
    (obj,) = scene.objects
    assert said == [] and obj.textured
    brightest = texels.reshape(-1, 3).max(axis=0)
    params = {"diffuse_reflectance": tuple(brightest), "specular_reflectance": (1.0,) * 3, "int_ior": 1.49,
              "ext_ior": 1.000277, "nonlinear": nonlinear}
    kd, ks, n, f0 = microfacet.phong_lobe("roughplastic", "beckmann", 0.2, **params)
    np.testing.assert_allclose(obj.material.diffuse, kd)
    np.testing.assert_allclose(obj.material.specular, ks)
    np.testing.assert_allclose(obj.material.fresnel, f0)
    # each texel's kd is the rule's kd for that texel's diffuse reflectance
    i, j = 1, 2
    single = dict(params, diffuse_reflectance=tuple(texels[i, j]))
    kd_texel, _, _, _ = microfacet.phong_lobe("roughplastic", "beckmann", 0.2, **single)
    np.testing.assert_allclose(np.asarray(kd) * obj.texture[i, j], kd_texel, rtol=2e-3)


def test_a_mirror_wrap_is_a_repeating_texture_reading_the_same(tmp_path):
    Image.fromarray(_image()).save(tmp_path / "t.png")
    extra = ('<string name="wrap_mode" value="mirror"/>'
             '<transform name="to_uv"><scale x="3" y="2"/><translate x="-1" y="-0.5"/></transform>')
    path = _write(tmp_path, '<shape type="rectangle"><bsdf type="diffuse">' + BITMAP.format(file="t.png", extra=extra)
                  + "</bsdf></shape>")
    scene, said = _load(path)
    (obj,) = scene.objects
    assert said == [] and obj.texture.shape == (10, 14, 3)  # the image beside its mirror images
    texels = srgb_to_linear(_image() / 255.0)
    x, y = np.random.default_rng(1).uniform(-1, 1, size=(2, 300))
    m_u, m_v = 3 * (x + 1) / 2 - 1, 2 * (y + 1) / 2 - 0.5  # Mitsuba's (u, v) after to_uv, v down
    expected = wrapped_lookup(texels, np.stack([m_u, 1 - m_v], axis=1), "mirror")
    uv, _ = _nearest(obj, np.stack([x, y, 0 * x], axis=1))
    np.testing.assert_allclose(lookup(obj.texture, uv), expected, atol=1e-6)


def test_nearest_filtering_and_a_mesh_without_uvs_are_named_in_warnings(tmp_path):
    Image.fromarray(_image()).save(tmp_path / "t.png")
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    nearest = BITMAP.format(file="t.png", extra='<string name="filter_type" value="nearest"/>')
    path = _write(tmp_path, f'<shape type="rectangle" id="r"><bsdf type="diffuse">{nearest}</bsdf></shape>'
                  '<shape type="obj" id="m"><string name="filename" value="plain.obj"/><bsdf type="diffuse">'
                  + BITMAP.format(file="t.png", extra="") + "</bsdf></shape>")
    scene, said = _load(path)
    assert scene.object("r").textured and not scene.object("m").textured
    mean = srgb_to_linear(_image() / 255.0).reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(scene.object("m").material.diffuse, mean)
    assert any("filter_type 'nearest' is read bilinear" in m for m in said)
    assert any(m.startswith(f"{path}:3: <shape type='obj'>: the mesh has no texture coordinates") for m in said), said


def test_raw_skips_the_srgb_decoding_and_exr_is_linear(tmp_path):
    image = _image((2, 3))
    Image.fromarray(image).save(tmp_path / "t.png")
    _write_exr(tmp_path / "t.exr", np.full((2, 3, 3), 0.25))
    raw = BITMAP.format(file="t.png", extra='<boolean name="raw" value="true"/>')
    exr = BITMAP.format(file="t.exr", extra="")
    path = _write(tmp_path, f'<shape type="rectangle" id="raw"><bsdf type="diffuse">{raw}</bsdf></shape>'
                  f'<shape type="disk" id="exr"><bsdf type="diffuse">{exr}</bsdf></shape>')
    scene, _ = _load(path)
    np.testing.assert_allclose(scene.object("raw").texture, image / 255.0, atol=1e-6)
    np.testing.assert_allclose(scene.object("exr").texture, 0.25)


def test_as_repeating_gives_up_on_a_clamp_over_a_huge_range():
    texture = np.zeros((4, 4, 3), np.float32)
    uvs = np.array([[0.0, 0.0], [1e4, 0.0], [0.0, 1e4]])
    assert as_repeating(texture, uvs, "clamp", limit=1 << 20) is None
    mirrored, halved = as_repeating(texture, uvs, "mirror")
    assert mirrored.shape == (8, 8, 3) and np.allclose(halved, [[0, 0.5], [5e3, 0.5], [0, 5e3 + 0.5]])


@pytest.mark.parametrize("wrap", ["mirror", "clamp"])
@pytest.mark.parametrize("extent", [0.3, 1.0, 5.0])
def test_as_repeating_reads_what_the_wrap_mode_reads_inside_every_triangle(wrap, extent):
    rng = np.random.default_rng(11)
    texture = rng.random((3, 5, 3)).astype(np.float32)
    uvs = rng.random((40, 2)) * extent - extent / 3
    repeating, new_uvs = as_repeating(texture, uvs, wrap)
    corners = rng.integers(0, 40, size=(500, 3))
    weights = rng.dirichlet([1, 1, 1], size=500)
    inside = np.einsum("nk,nkd->nd", weights, uvs[corners])
    inside_new = np.einsum("nk,nkd->nd", weights, new_uvs[corners])
    np.testing.assert_allclose(lookup(repeating, inside_new), wrapped_lookup(texture, inside, wrap), atol=1e-9)
    assert not np.allclose(wrapped_lookup(texture, inside, wrap), lookup(texture, inside))  # the modes do differ


def test_the_wrap_modes_are_mitsubas():
    """Mitsuba 3.9.1's bitmap at v = 0.25 on a 4 x 2 image, red channel 0.1, 0.3, 0.6, 0.9, for u from -1.25
    in steps of 1/8 (seen with mi.load_dict({'type': 'bitmap', 'wrap_mode': ..., 'raw': True}).eval)."""
    texture = np.zeros((2, 4, 3))
    texture[..., 0] = [0.1, 0.3, 0.6, 0.9]
    u = np.arange(-1.25, 2.3, 0.125)[:13]
    seen = {"repeat": [0.75, 0.9, 0.5, 0.1, 0.2, 0.3, 0.45, 0.6, 0.75, 0.9, 0.5, 0.1, 0.2],
            "mirror": [0.75, 0.9, 0.9, 0.9, 0.75, 0.6, 0.45, 0.3, 0.2, 0.1, 0.1, 0.1, 0.2],
            "clamp": [0.1] * 12 + [0.2]}
    for wrap, values in seen.items():
        ours = wrapped_lookup(texture, np.stack([u, np.full_like(u, 0.25)], axis=1), wrap)[:, 0]
        np.testing.assert_allclose(ours, values, atol=1e-9)
