"""A masked object at display: its fragments are discarded where the mask reads below the
cut-off (the solver's and the path tracer's holes), from its front and from its back, in
the solution display and the fitted one; the pixels against numpy's ``covered`` at each
pixel centre's point on the leaf."""

import numpy as np
import pytest

from display.renderer import Renderer
from fitting import FitOptions, fit
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.textures import TexturedDiffuse, lookup

BLACK = [0.0, 0.0, 0.0]
DIFFUSE = np.array([[0.0, 0.0, 1.0]])


def _quad(name, y, size, radiance, facing_up, textured=None):
    p = np.array([[-size, y, -size], [size, y, -size], [size, y, size], [-size, y, size]], float)
    faces = np.array([[0, 2, 1], [0, 3, 2]]) if facing_up else np.array([[0, 1, 2], [0, 2, 3]])
    normal = [0.0, 1.0 if facing_up else -1.0, 0.0]
    material = {"diffuse": [0.5, 0.5, 0.5], "specular": BLACK, "exponent": 0.0, "emission": BLACK}
    return ObjectSolution(name=name, positions=p, normals=np.tile(normal, (4, 1)), tangents=np.tile([1.0, 0, 0], (4, 1)),
                          faces=faces, directions=DIFFUSE, radiance=np.full((4, 1, 3), radiance), material=material,
                          textured=textured)


def _mask(rng):
    return np.kron((rng.random((5, 4)) > 0.5), np.ones((1, 1))).astype(np.float32)


def _leaf(mask, facing_up):
    """A 2 x 2 leaf at y = 1, black, its uvs its (x, z) mapped to [0, 1]."""
    p = np.array([[-1.0, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1]])
    textured = TexturedDiffuse(uvs=(p[:, [0, 2]] + 1) / 2, irradiance=np.zeros((4, 3)), texture=np.ones((1, 1, 3)),
                               kd=(0.0, 0.0, 0.0), opacity=mask)
    return _quad("leaf", 1.0, 1.0, 0.0, facing_up, textured)


def _expected(camera, mask):
    """(1 where the pixel centre's ray passes the leaf's plane through a hole or beside
    the leaf, 0 where the leaf is there; a margin near the cut-off line and the edges)."""
    d = camera.pixel_rays()
    eye = np.asarray(camera.eye)
    s = (1.0 - eye[1]) / d[..., 1]
    x = eye + s[..., None] * d
    uv = (x[..., [0, 2]] + 1) / 2
    inside = (np.abs(x[..., 0]) < 1) & (np.abs(x[..., 2]) < 1)
    reads = lookup(mask[..., None], uv)[..., 0]
    sure = (np.abs(reads - 0.5) > 0.15) & (np.abs(np.abs(x[..., [0, 2]]) - 1).min(axis=-1) > 0.05)
    return np.where(inside & (reads >= 0.5), 0.0, 1.0), sure


@pytest.mark.gl
@pytest.mark.parametrize("side", ["front", "back"])
def test_a_masked_leaf_shows_what_lies_behind_its_holes(gl_context, rng, side):
    """Seen from above (its front) over an emitting floor, or from below (its back: the
    back pass's black has the holes too) under an emitting ceiling."""
    mask = _mask(rng)
    facing_up = True
    if side == "front":
        light = _quad("floor", 0.0, 4.0, 1.0, True)
        camera = Camera((0.0, 3.0, 0.3), (0.0, 0.0, 0.0), fov_deg=60, width=64, height=64)
    else:
        light = _quad("ceiling", 2.0, 4.0, 1.0, False)
        camera = Camera((0.0, -1.0, 0.3), (0.0, 2.0, 0.0), fov_deg=60, width=64, height=64)
    solution = Solution(objects=(_leaf(mask, facing_up), light), scene="leaf")
    expected, sure = _expected(camera, mask)
    assert sure.sum() > 1500 and 0.2 < (expected[sure] == 0).mean() < 0.8
    reference = Renderer(gl_context, solution=solution, samples=1)
    for mode in ("reference", "diffuse"):
        image = reference.render(camera, mode)[..., 0]
        np.testing.assert_allclose(image[sure], expected[sure], atol=1e-4, err_msg=mode)
    for shading in ("gouraud", "pixel"):
        image = reference.render(camera, "reference", shading=shading)[..., 0]
        np.testing.assert_allclose(image[sure], expected[sure], atol=1e-4, err_msg=shading)
    reference.release()
    model = fit(solution, FitOptions.for_quality("draft"))
    assert model.version == 9 and model.object("leaf").textured.opacity is not None
    fitted = Renderer(gl_context, fit=model, samples=1)
    np.testing.assert_allclose(fitted.render(camera, "fitted")[..., 0][sure], expected[sure], atol=1e-4)
    fitted.release()


def test_the_export_keeps_a_mask_as_its_images_alpha_and_reads_it_back(tmp_path, rng, cli):
    """glTF version 8: a masked object's image is RGBA, its material's alphaMode MASK at the
    cut-off; ``load_export`` gives the mask back exactly (8-bit codes) and the white
    texture spread to the mask's size. A mask the size of neither its texture nor 1 x 1 is
    left out, and the command names the object."""
    from dataclasses import replace

    from display.export import export_glb, file_version
    from display.export_reader import load_export

    mask = _mask(rng)
    solution = Solution(objects=(_leaf(mask, True), _quad("floor", 0.0, 4.0, 1.0, True)), scene="leaf")
    model = fit(solution, FitOptions.for_quality("draft"))
    assert file_version(model) == 8
    (tmp_path / "scene.glb").write_bytes(export_glb(model))
    back = load_export(tmp_path / "scene.glb").object("leaf").textured
    assert np.array_equal(back.opacity, mask) and back.texture.shape == (*mask.shape, 3) and (back.texture == 1).all()
    leaf = model.object("leaf")
    odd = replace(leaf, textured=replace(leaf.textured, texture=np.full((3, 3, 3), 0.5, np.float32)))
    other = replace(model, objects=(odd, model.object("floor")))
    assert file_version(other) < 8
    other.save(tmp_path / "odd.npz")
    code, out, err = cli("export", tmp_path / "odd.npz", "-o", tmp_path / "page", "--no-page")
    assert code == 0, err
    assert "left out the masks of 1 object(s) (leaf)" in out
