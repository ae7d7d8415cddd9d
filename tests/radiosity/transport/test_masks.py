"""Opacity masks (a leaf's cut-out) through the stages: the loader reads a mask's image
(its alpha channel, else its colour), the ray tracer's filter lets every query through
the holes (where the mask reads below the cut-off, bilinear as ``lookup`` reads it), the
solver and the path tracer see the same holes as geometry cut to their shape would
make, and the files keep the mask (solution and fit version 9).
"""

import json

import imageio.v3 as iio
import numpy as np
import pytest
from scene_files import load_warned

from radiosity.files.solution import load_solution
from radiosity.physics.materials import Material
from radiosity.physics.textures import OPACITY_CUTOFF, Cutout, TexturedDiffuse, cutout_atlas, lookup
from radiosity.scene.model import Scene, build_object
from radiosity.transport.embree import RayTracer
from radiosity.transport.pathtrace import PathTracer
from radiosity.transport.solve import SolveOptions, solve

QUAD = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
QUAD_FACES = np.array([[0, 1, 2], [0, 2, 3]])


def random_mask(rng, size=(6, 5)):
    """A blocky mask of 0 and 1 (bilinear between them: a cut-off line through each edge)."""
    return (rng.random(size) > 0.5).astype(np.float32)


def tracer_with(mask, rng, extra=0):
    """A masked unit quad at z = 0 (uvs = its x, y) over an opaque quad at z = -1, and
    ``extra`` random opaque triangles off to the side; the tracer and the cutout."""
    positions = np.concatenate([QUAD, QUAD + [0, 0, -1.0]])
    faces = np.concatenate([QUAD_FACES, QUAD_FACES + 4])
    if extra:
        more = rng.random((3 * extra, 3)) + [2.0, 0.0, -0.5]
        faces = np.concatenate([faces, len(positions) + np.arange(3 * extra).reshape(-1, 3)])
        positions = np.concatenate([positions, more])
    uvs = np.zeros((len(positions), 2))
    uvs[:4] = QUAD[:, :2]
    image = np.full(len(faces), -1, np.int64)
    image[:2] = 0
    cutout = Cutout(image, uvs.astype(np.float32)[faces].reshape(-1, 6), *cutout_atlas([mask]))
    return RayTracer(positions.astype(np.float32), faces.astype(np.int32), threads=1, cutout=cutout), positions, faces


def test_rays_pass_through_a_masks_holes_in_both_queries(rng):
    """Rays straight down at random points of the masked quad: each stops on it exactly
    where the mask reads at least the cut-off (numpy's ``lookup``), else goes on to the
    quad beneath; a shadow ray the same. Points within 1e-4 of the cut-off are left out
    (single against double precision)."""
    mask = random_mask(rng)
    tracer, _, _ = tracer_with(mask, rng)
    xy = rng.random((4000, 2))
    reads = lookup(mask[..., None], xy)[:, 0]
    clear = np.abs(reads - OPACITY_CUTOFF) > 1e-4
    origins = np.concatenate([xy, np.full((len(xy), 1), 1.0)], axis=1).astype(np.float32)
    down = np.tile(np.array([0, 0, -1.0], np.float32), (len(xy), 1))
    hits = tracer.intersect(origins, down)
    assert (hits.triangle >= 0).all()
    on_mask = hits.triangle < 2
    covered = reads >= OPACITY_CUTOFF
    assert 0.2 < covered.mean() < 0.8
    assert np.array_equal(on_mask[clear], covered[clear])
    assert np.all(hits.triangle[~on_mask] >= 2) and np.allclose(hits.t[~on_mask], 2.0)
    blocked = tracer.occluded(origins, down, np.full(len(xy), 1.5, np.float32))
    assert np.array_equal(blocked[clear], covered[clear])
    tracer.close()


def test_a_mask_that_covers_everything_changes_no_hit(rng):
    """The masked triangles in a geometry of their own (each a NaN in the other): with a
    mask of ones, random rays hit what the tracer without a cutout hits, the same
    triangle at the same distance."""
    tracer, positions, faces = tracer_with(np.ones((2, 2), np.float32), rng, extra=200)
    plain = RayTracer(positions.astype(np.float32), faces.astype(np.int32), threads=1)
    origins = (rng.random((5000, 3)) * [4.0, 2.0, 3.0] - [0.5, 0.5, 1.5]).astype(np.float32)
    directions = rng.normal(size=(5000, 3))
    directions = (directions / np.linalg.norm(directions, axis=1, keepdims=True)).astype(np.float32)
    a, b = tracer.intersect(origins, directions), plain.intersect(origins, directions)
    assert (a.triangle >= 0).mean() > 0.1
    assert np.array_equal(a.triangle, b.triangle)
    np.testing.assert_allclose(a.t[a.triangle >= 0], b.t[b.triangle >= 0], rtol=1e-6)
    assert np.array_equal(tracer.occluded(origins, directions, np.full(5000, 2.0, np.float32)),
                          plain.occluded(origins, directions, np.full(5000, 2.0, np.float32)))


# -- the solver and the path tracer ---------------------------------------------------------

LAMP = Material("lamp", diffuse=(0.0, 0.0, 0.0), emission=(5.0, 5.0, 5.0))
GREY = Material("floor", diffuse=(0.5, 0.5, 0.5))
LEAF = Material("leaf", diffuse=(0.3, 0.6, 0.2))


def _rect(x0, x1, z0, z1, y, up=True):
    p = np.array([[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]])
    f = np.array([[0, 2, 1], [0, 3, 2]]) if up else np.array([[0, 1, 2], [0, 2, 3]])
    return p, f


def _scenes():
    """A floor lit by a small lamp above, a leaf between: a 2 x 2 quad masked to its
    right half and its upper quarter (x > 0, or z > 0.5), and the same leaf cut as
    geometry (three quads)."""
    floor = build_object("floor", GREY, *_rect(-3, 3, -3, 3, 0.0))
    lamp = build_object("lamp", LAMP, *_rect(-0.3, 0.3, -0.3, 0.3, 2.0, up=False))
    p, f = _rect(-1, 1, -1, 1, 1.0)
    mask = np.zeros((8, 8), np.float32)
    mask[:, 4:] = 1.0
    mask[:2, :] = 1.0  # row 0 the top: v > 0.75, z > 0.5
    uvs = (p[:, [0, 2]] + 1.0) / 2.0
    masked = build_object("leaf", LEAF, p, f, uvs=uvs, opacity=mask)
    cut = [build_object(f"leaf{i}", LEAF, *_rect(*r, 1.0)) for i, r in enumerate([(0, 1, -1, 0.5), (-1, 0, 0.5, 1),
                                                                                   (0, 1, 0.5, 1)])]
    return Scene("masked", (floor, lamp, masked)), Scene("cut", (floor, lamp, *cut))


def test_the_solver_sees_a_masks_holes_as_cut_geometry():
    """The floor's irradiance under a masked leaf is that under the leaf cut to the
    mask's shape, within the photons' noise (the cut's edges fall on the bilinear
    cut-off line: the mask's texel edges at 0 and 0.5)."""
    masked, cut = _scenes()
    opts = SolveOptions(photons=400_000, max_edge=0.25, seed=5, gather_samples=4)
    a = solve(masked, opts).object("floor")
    b = solve(cut, opts).object("floor")
    ea, eb = a.radiance[:, 0, 0], b.radiance[:, 0, 0]
    under = (np.abs(a.positions[:, 0]) < 1.2) & (np.abs(a.positions[:, 2]) < 1.2)
    assert abs(ea[under].mean() / eb[under].mean() - 1) < 0.03
    assert np.sqrt(np.mean((ea[under] - eb[under]) ** 2)) / eb[under].mean() < 0.15
    # and the shadow is there: under the covered half darker than under the hole
    hole = under & (a.positions[:, 0] < -0.4) & (a.positions[:, 2] < 0.2)
    covered = under & (a.positions[:, 0] > 0.4) & (a.positions[:, 2] < 0.2)
    assert ea[hole].mean() > 1.5 * ea[covered].mean()


def test_the_path_tracer_sees_a_masks_holes_as_cut_geometry():
    """Looking down on the leaf from above the lamp's side: the picture of the masked leaf
    is the picture of the leaf cut to the mask's shape, but at the cut-off line's pixels."""
    from radiosity.files.camera import Camera

    masked, cut = _scenes()
    camera = Camera((0.0, 4.0, 2.5), (0.0, 0.5, 0.0), fov_deg=45, width=48, height=36)
    with PathTracer(masked, threads=2) as tracer:
        a = tracer.render(camera, 16, seed=2).radiance
    with PathTracer(cut, threads=2) as tracer:
        b = tracer.render(camera, 16, seed=2).radiance
    assert abs(a.mean() / b.mean() - 1) < 0.02
    differs = np.abs(a - b).max(axis=2) > 0.5 * b.max()
    assert differs.mean() < 0.03


# -- the loader and the files --------------------------------------------------------------------


def _leaf_xml(tmp_path, mask_attrs="", inner='<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.2"/></bsdf>'):
    return (tmp_path / "scene.xml").write_text(f'''<?xml version="1.0"?>
<scene version="3.0.0">
  <shape type="rectangle" id="leaf">
    <bsdf type="mask"><texture type="bitmap" name="opacity"><string name="filename" value="leaf.png"/>{mask_attrs}</texture>
      {inner}</bsdf></shape>
  <shape type="rectangle" id="lamp"><transform name="to_world"><translate z="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>
</scene>''') and tmp_path / "scene.xml"


def test_the_loader_reads_a_masks_alpha_else_its_colour(tmp_path):
    """An RGBA image's alpha is the opacity (as Tungsten reads a leaf's cut-out); an RGB
    image's the mean of its channels, sRGB-decoded as Mitsuba decodes a bitmap; an
    untextured shape beneath is given a white texture (the files carry a mask with the
    textured term), and its colour stays kd."""
    rgba = np.zeros((4, 6, 4), np.uint8)
    rgba[..., :3] = 255
    rgba[:, 3:, 3] = 255
    iio.imwrite(tmp_path / "leaf.png", rgba)
    scene, messages = load_warned(_leaf_xml(tmp_path))
    leaf = scene.object("leaf")
    assert not messages, messages
    assert np.array_equal(leaf.opacity, (rgba[..., 3] / 255.0).astype(np.float32))
    assert np.array_equal(leaf.texture, np.ones((1, 1, 3), np.float32)) and leaf.uvs is not None
    assert leaf.material.diffuse == pytest.approx((0.2, 0.6, 0.2))
    grey = np.full((4, 6, 3), 188, np.uint8)  # sRGB 188: linear 0.5
    iio.imwrite(tmp_path / "leaf.png", grey)
    leaf = load_warned(_leaf_xml(tmp_path))[0].object("leaf")
    np.testing.assert_allclose(leaf.opacity, 0.5029, atol=1e-3)


def test_a_mask_that_maps_its_coordinates_is_left_out_saying_so(tmp_path):
    iio.imwrite(tmp_path / "leaf.png", np.zeros((4, 4, 4), np.uint8))
    scene, messages = load_warned(_leaf_xml(tmp_path, '<transform name="to_uv"><scale x="2" y="2"/></transform>'))
    assert scene.object("leaf").opacity is None
    assert any("the mask 'leaf.png' or the texture beneath it maps its texture coordinates" in m for m in messages)


def test_a_solution_keeps_the_mask_and_reads_it_back(tmp_path):
    """Version 9: the mask as 8-bit codes where they give it back exactly, float32
    otherwise; the path tracer of the file's scene sees the same holes."""
    masked, _ = _scenes()
    sol = solve(masked, SolveOptions(photons=20_000, max_edge=1.0, seed=1))
    leaf = sol.object("leaf")
    assert isinstance(leaf.textured, TexturedDiffuse) and sol.version == 9
    assert leaf.textured.arrays("leaf")["leaf/opacity"].dtype == np.uint8
    sol.save(tmp_path / "s.npz")
    back = load_solution(tmp_path / "s.npz")
    assert back.version == 9
    assert np.array_equal(back.object("leaf").textured.opacity, leaf.textured.opacity)
    smooth = TexturedDiffuse(uvs=np.zeros((3, 2)), irradiance=np.zeros((3, 3)), texture=np.ones((1, 1, 3)),
                             kd=(1, 1, 1), opacity=np.full((2, 2), 0.3))
    assert smooth.arrays("x")["x/opacity"].dtype == np.float32
    assert np.array_equal(smooth.covered(np.array([[0.5, 0.5]])), [False])


def test_a_mask_on_a_mesh_without_texture_coordinates_is_left_out_saying_so(tmp_path):
    """An OBJ without vt: the mask cannot be read, the shape stays opaque, and the warning
    names the image."""
    iio.imwrite(tmp_path / "leaf.png", np.zeros((4, 4, 4), np.uint8))
    (tmp_path / "leaf.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    xml = _leaf_xml(tmp_path).read_text().replace('<shape type="rectangle" id="leaf">',
                                                  '<shape type="obj" id="leaf"><string name="filename" value="leaf.obj"/>')
    (tmp_path / "scene.xml").write_text(xml)
    scene, messages = load_warned(tmp_path / "scene.xml")
    assert scene.object("leaf").opacity is None
    assert any("the mesh has no texture coordinates: the mask 'leaf.png' is left out (opaque)" in m for m in messages)


@pytest.fixture(scope="module")
def masked_solution_file(tmp_path_factory):
    """A small solve of the masked scene, saved once for the tests that corrupt it."""
    masked, _ = _scenes()
    path = tmp_path_factory.mktemp("masked") / "s.npz"
    solve(masked, SolveOptions(photons=5_000, max_edge=1.0, seed=1)).save(path)
    return path


@pytest.mark.parametrize("opacity, words", [(np.full((2, 2), 1.5, np.float32), "outside [0, 1]"),
                                            (np.ones((2, 2, 2), np.float32), "has shape (2, 2, 2)"),
                                            (np.array([["a"]]), "dtype")])
def test_a_solution_with_a_bad_mask_is_refused_in_one_line(tmp_path, masked_solution_file, opacity, words):
    from radiosity.files.errors import InputError
    from radiosity.files.npz import write_archive

    with np.load(masked_solution_file, allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files if k != "meta"}
        meta = json.loads(str(f["meta"]))
    arrays["leaf/opacity"] = opacity
    write_archive(tmp_path / "bad.npz", meta, arrays)
    with pytest.raises(InputError) as refused:
        load_solution(tmp_path / "bad.npz")
    message = str(refused.value)
    assert words in message and "leaf" in message and "\n" not in message, message


def test_shapes_that_share_a_mask_share_its_array(tmp_path):
    """An RGB mask (its opacity the mean of its channels) read once for every shape that
    refers to its bsdf: one array, so the ray tracer's atlas and the files hold it once."""
    iio.imwrite(tmp_path / "leaf.png", np.full((4, 4, 3), 200, np.uint8))
    (tmp_path / "scene.xml").write_text('''<?xml version="1.0"?>
<scene version="3.0.0">
  <bsdf type="mask" id="m"><texture type="bitmap" name="opacity"><string name="filename" value="leaf.png"/></texture>
    <bsdf type="diffuse"/></bsdf>
  <shape type="rectangle" id="a"><ref id="m"/></shape>
  <shape type="rectangle" id="b"><transform name="to_world"><translate z="1"/></transform><ref id="m"/></shape>
  <shape type="rectangle" id="lamp"><transform name="to_world"><translate z="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>
</scene>''')
    scene, _ = load_warned(tmp_path / "scene.xml")
    assert scene.object("a").opacity is scene.object("b").opacity
    assert scene.merged().cutout.offsets.shape == (1,)
