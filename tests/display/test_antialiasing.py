"""Antialiasing: each pixel is the mean of its samples, all inside it (a box filter over
the pixel, as the path tracer integrates radiance over the pixel).

The known answer: a tile of uniform radiance TILE in front of a wall of uniform radiance
WALL, its edges straight lines ANGLE degrees off the pixel columns and rows. A pixel
covered by the tile over an area fraction a (the pixel clipped by the projected tile, in
numpy) is exactly WALL + a (TILE - WALL) for a box filter. With N samples the fraction
seen is c / N, c the samples inside the tile, so:

* it is a multiple of 1 / N (the mean of N samples, each WALL or TILE);
* |c / N - a| <= 1 / M + k + delta (the bound checked), where k = tan(ANGLE) is the
  edge's slope against the nearer pixel axis, M the number of strata of the pattern
  across that axis, and delta = 0.01 for the rasteriser's sub-pixel precision (8 bits
  on llvmpipe, 1 / 256 of a pixel) and float rounding. Derivation: across the pixel the
  edge moves by at most k, so every sample left of c0 - k / 2 is inside and every sample
  right of c0 + k / 2 outside (c0 where the edge crosses the pixel's middle). The
  standard MSAA patterns (D3D's, Mesa llvmpipe's 4x: x and y in {1, 3, 5, 7} / 8) put
  the N samples in M columns of equal width with N / M samples each (M = N: each its
  own column and row), so the count left of any t is within N / M of N t. Both c / N and
  a then lie in an interval of width k + 2 / M around the same point, a inside it
  less 1 / M on either side: |c / N - a| <= k + 1 / M. MSAA alone: M = msaa. Supersampled
  factor x factor, each sub-pixel the same MSAA pattern: M = msaa x factor columns of
  factor samples each (16 samples: 8 columns; 64: 16).

Pixels within two pixels of a corner (two edges) are left out; interior pixels must be
TILE or WALL to float32 rounding (what is interpolated across a triangle, a constant
here, comes out to within an ulp of it).
"""

import math

import numpy as np
import pytest
from display_fixtures import assert_refused, listing, tilted_tile_solution, tiny_fit
from renderer_probes import ProbedRenderer

import display.gl
import display.window
from display.gl import (
    DEFAULT_SAMPLES,
    MAX_SAMPLES,
    check_image_memory,
    framebuffer_bytes,
    sample_plan,
)
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError

WALL, TILE = 0.25, 2.0
ANGLE = 2.0  # degrees: the edge moves 0.035 pixel a row, so the rows see every sub-pixel position
DELTA = 0.01
VIEW = Camera(eye=(0.0, 0.0, -5.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=40.0, width=64, height=48)
MODES = [("fitted", "pixel"), ("fitted", "gouraud"), ("reference", "pixel"), ("reference", "gouraud")]


@pytest.fixture(scope="module")
def scene():
    solution = tilted_tile_solution(WALL, TILE, ANGLE)
    return tiny_fit(solution, lights=0), solution


def window_corners(view, points):
    """(n, 2) window coordinates (x right, y up, pixel centres at half-integers) of world ``points`` (n, 3)."""
    clip = view.projection_matrix(0.1, 100.0) @ view.view_matrix() @ np.c_[points, np.ones(len(points))].T
    ndc = clip[:2] / clip[3]
    return ((ndc + 1) / 2 * np.array([[view.width], [view.height]])).T


def clipped_area(polygon, x0, y0):
    """Area of the convex ``polygon`` ((n, 2)) inside the pixel [x0, x0 + 1] x [y0, y0 + 1]
    (Sutherland-Hodgman against its four sides, then the shoelace formula)."""
    points = list(polygon)
    for axis, bound, keep in ((0, x0, 1), (0, x0 + 1, -1), (1, y0, 1), (1, y0 + 1, -1)):
        kept = []
        for a, b in zip(points, points[1:] + points[:1]):
            a_in, b_in = keep * (a[axis] - bound) >= 0, keep * (b[axis] - bound) >= 0
            if a_in != b_in:
                kept.append(a + (bound - a[axis]) / (b[axis] - a[axis]) * (b - a))
            if b_in:
                kept.append(b)
        points = kept
        if not points:
            return 0.0
    x, y = np.array(points).T
    return 0.5 * abs(x @ np.roll(y, -1) - y @ np.roll(x, -1))


def coverage(view, solution):
    """(H, W) fraction of each pixel the tile covers, row 0 at the top; (H, W) bool: pixels
    within two pixels of one of its corners; the tile's edges' slope against the nearer axis."""
    tile = solution.object("tile")
    corners = window_corners(view, tile.positions.astype(np.float64))
    fraction = np.zeros((view.height, view.width))
    for row in range(view.height):
        for col in range(view.width):
            fraction[row, col] = clipped_area(corners, col, view.height - 1 - row)
    x = np.arange(view.width) + 0.5
    y = view.height - 0.5 - np.arange(view.height)
    near_corner = np.zeros(fraction.shape, bool)
    for cx, cy in corners:
        near_corner |= (np.abs(x[None, :] - cx) < 2) & (np.abs(y[:, None] - cy) < 2)
    d = np.diff(np.vstack([corners, corners[:1]]), axis=0)
    slope = max(np.min(np.abs(d), axis=1) / np.max(np.abs(d), axis=1))
    return fraction, near_corner, slope


@pytest.mark.gl
@pytest.mark.parametrize("mode, shading", MODES)
@pytest.mark.parametrize("samples", [4, 16, 64])  # 4: MSAA alone; 16, 64: supersampled 2x2, 4x4 (of MSAA 4 here)
def test_an_edge_pixel_is_the_covered_fraction_of_the_two_sides(samples, mode, shading, scene, gl_context):
    fit, solution = scene
    renderer = ProbedRenderer(gl_context, fit=fit, solution=solution, samples=samples)
    plan = renderer.plan
    image = renderer.render(VIEW, mode, shading)
    one = renderer.render(VIEW, mode, shading, samples=1)
    renderer.release()
    fraction, near_corner, slope = coverage(VIEW, solution)
    assert slope == pytest.approx(math.tan(math.radians(ANGLE)), rel=1e-3)
    assert np.ptp(image, axis=2).max() == 0  # grey: the three channels alike
    seen = (image[..., 0].astype(np.float64) - WALL) / (TILE - WALL)

    inside, outside = fraction > 1 - 1e-9, fraction < 1e-9
    edge = ~inside & ~outside & ~near_corner
    assert inside.sum() > 300 and outside.sum() > 1000 and edge.sum() > 80
    assert np.allclose(image[inside], TILE, rtol=1e-6, atol=0) and np.allclose(image[outside], WALL, rtol=1e-6, atol=0)

    assert plan.per_pixel == samples
    counts = seen[edge] * plan.per_pixel
    assert np.abs(counts - np.rint(counts)).max() < 1e-3  # the mean of per_pixel samples
    bound = 1 / (plan.msaa * plan.factor) + slope + DELTA
    error = np.abs(seen[edge] - fraction[edge])
    assert error.max() <= bound, (error.max(), bound)
    # and far below one sample's error on the same pixels (up to 1, 0.29 RMS for a random edge)
    one_error = np.abs((one[..., 0][edge] - WALL) / (TILE - WALL) - fraction[edge])
    assert np.sqrt(np.mean(error ** 2)) < 0.5 * np.sqrt(np.mean(one_error ** 2))


@pytest.mark.gl
def test_one_sample_is_the_pixel_centre(scene, gl_context):
    # samples=1 is the display as it was: each pixel the surface its centre sees
    fit, solution = scene
    renderer = ProbedRenderer(gl_context, fit=fit, solution=solution, samples=1)
    image = renderer.render(VIEW, "fitted", "pixel")
    default = ProbedRenderer(gl_context, fit=fit, solution=solution)
    assert default.samples == DEFAULT_SAMPLES
    assert np.array_equal(default.render(VIEW, "fitted", "pixel", samples=1), image)
    assert not np.array_equal(default.render(VIEW, "fitted", "pixel"), image)
    corners = window_corners(VIEW, solution.object("tile").positions.astype(np.float64))
    x = np.arange(VIEW.width) + 0.5
    y = VIEW.height - 0.5 - np.arange(VIEW.height)
    centres = np.stack(np.broadcast_arrays(x[None, :], y[:, None]), axis=-1)  # (H, W, 2)
    side = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        d = b - a
        side.append((d[0] * (centres[..., 1] - a[1]) - d[1] * (centres[..., 0] - a[0])) / np.linalg.norm(d))
    side = np.stack(side)  # signed distances of the centres to the four edge lines, pixels
    clear = np.abs(side).min(axis=0) > 0.01
    within = np.all(side > 0, axis=0) | np.all(side < 0, axis=0)
    assert np.array_equal(image[clear & within], np.full(((clear & within).sum(), 3), TILE, np.float32))
    assert np.array_equal(image[clear & ~within], np.full(((clear & ~within).sum(), 3), WALL, np.float32))
    renderer.release()
    default.release()


@pytest.mark.gl
def test_masks_and_ids_stay_one_sample(scene, gl_context):
    fit, solution = scene
    many, one = ProbedRenderer(gl_context, fit=fit, samples=16), ProbedRenderer(gl_context, fit=fit, samples=1)
    assert np.array_equal(many.object_mask(VIEW, ["tile"]), one.object_mask(VIEW, ["tile"]))
    for a, b in zip(many.render_triangles(VIEW), one.render_triangles(VIEW)):
        assert np.array_equal(a, b)
    for a, b in zip(many.render_attributes(VIEW), one.render_attributes(VIEW)):
        assert np.array_equal(a, b)
    many.release()
    one.release()


def test_the_sample_plan():
    # (samples, the context's MSAA) -> (MSAA, supersampling factor): MSAA first, then the smallest factor
    table = {(1, 4): (1, 1), (2, 4): (2, 1), (3, 4): (4, 1), (4, 4): (4, 1), (5, 4): (4, 2), (16, 4): (4, 2),
             (17, 4): (4, 3), (36, 4): (4, 3), (64, 4): (4, 4), (4, 1): (1, 2), (64, 8): (8, 3), (16, 16): (16, 1)}
    for (samples, max_msaa), (msaa, factor) in table.items():
        plan = sample_plan(samples, max_msaa)
        assert (plan.msaa, plan.factor) == (msaa, factor), (samples, max_msaa, plan)
        assert plan.per_pixel >= samples
    for bad in (0, -1, MAX_SAMPLES + 1):
        with pytest.raises(InputError, match=f"must be 1 to {MAX_SAMPLES}"):
            sample_plan(bad)


def test_the_memory_estimate_grows_with_the_samples():
    at_default = check_image_memory(100, 10)
    assert check_image_memory(100, 10, samples=DEFAULT_SAMPLES) == at_default
    for samples in (1, 16, 64):
        assert check_image_memory(100, 10, samples=samples) - at_default == 1000 * (
            framebuffer_bytes(samples) - framebuffer_bytes(DEFAULT_SAMPLES))
    assert framebuffer_bytes(1) < framebuffer_bytes(4) < framebuffer_bytes(16) < framebuffer_bytes(64)


# -- the command line --------------------------------------------------------------------

COMMANDS = {
    "render": ["render", "{fit}", "--size", "8x8", "-o", "{tmp}/x.png"],
    "video": ["render", "{fit}", "--size", "8x8", "--frames", "2", "--video", "{tmp}/x.mp4"],
    "compare": ["compare", "{fit}", "{solution}", "--size", "8x8", "--out", "{tmp}/cmp"],
    "view": ["view", "{fit}", "--frames", "1"],
    "demo": ["demo", "--size", "8x8", "--out", "{tmp}/demo"],
}


def command(name, tiny_pair, tmp_path):
    fit, solution = tiny_pair
    return [a.format(fit=fit, solution=solution, tmp=tmp_path) for a in COMMANDS[name]]


@pytest.mark.parametrize("name", sorted(COMMANDS))
@pytest.mark.parametrize("samples", ["0", "-3", str(MAX_SAMPLES + 1)])
def test_bad_sample_counts_are_refused(name, samples, tiny_pair, tmp_path, cli, no_gl, monkeypatch):
    monkeypatch.setattr(display.window, "display_problem", lambda environ=None: None)  # view: as if a display
    assert_refused(cli(*command(name, tiny_pair, tmp_path), "--samples", samples),
                   f"--samples must be 1 to {MAX_SAMPLES} (samples per pixel), got {samples}",
                   command="render" if name == "video" else name)
    assert listing(tmp_path) == []


def test_a_sample_count_must_be_a_number(tiny_pair, tmp_path, cli, no_gl):
    code, out, err = cli(*command("render", tiny_pair, tmp_path), "--samples", "four")
    assert code == 2 and out == "" and err.count("\n") == 1 and "--samples" in err
    assert listing(tmp_path) == []


@pytest.mark.gl
@pytest.mark.parametrize("name", ["render", "video", "compare", "demo"])
def test_a_supersampled_image_beyond_the_context_is_refused(name, tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    monkeypatch.setattr(display.gl, "image_limits", lambda ctx: ((32, "GL_MAX_TEXTURE_SIZE"), (32, "GL_MAX_TEXTURE_SIZE")))

    def no_solve(*_args, **_kwargs):
        raise AssertionError("the solve started")

    import radiosity.transport.solve

    monkeypatch.setattr(radiosity.transport.solve, "solve", no_solve)
    argv = [a if a != "8x8" else "20x20" for a in command(name, tiny_pair, tmp_path)]
    plan = sample_plan(16, gl_context.max_samples)
    side = 20 * plan.factor
    assert side > 32
    assert_refused(cli(*argv, "--samples", "16"), f"--samples 16 draws the 20x20 image {plan.factor} times larger",
                   f"({side}x{side}", "at most 32 pixels wide (GL_MAX_TEXTURE_SIZE = 32)",
                   command="render" if name == "video" else name)
    assert listing(tmp_path) == []


@pytest.mark.gl
def test_the_hdr_file_is_the_averaged_radiance(scene, tmp_path, cli, gl_context):
    fit, solution = scene
    fit.save(tmp_path / "fit.npz")
    camera = ["--eye", "0", "0", "-5", "--look-at", "0", "0", "0", "--fov", "40", "--size", "64x48"]
    written = {}
    for samples in (None, 1, 16):
        hdr = tmp_path / f"{samples}.npy"
        flag = [] if samples is None else ["--samples", str(samples)]
        code, out, err = cli("render", tmp_path / "fit.npz", *camera, *flag, "--hdr", hdr)
        assert code == 0, err
        assert f"{samples or DEFAULT_SAMPLES} samples per pixel" in out
        written[samples] = np.load(hdr)
    # the renderer made after the commands' own contexts are gone (a context made and released
    # by moderngl in this process leaves the earlier ones' objects unusable until re-entered)
    renderer = ProbedRenderer(gl_context, fit=fit)
    for samples, image in written.items():
        assert np.array_equal(image, renderer.render(VIEW, samples=samples))
    renderer.release()


@pytest.mark.gl
def test_compare_records_the_samples(tiny_pair, tmp_path, cli, gl_context):
    import json

    fit, solution = tiny_pair
    for samples in (1, 16):
        out = tmp_path / f"cmp{samples}"
        code, _, err = cli("compare", fit, solution, "--size", "16x12", "--samples", samples, "--out", out)
        assert code == 0, err
        results = json.loads((out / "compare.json").read_text())
        plan = sample_plan(samples, gl_context.max_samples)
        assert results["samples"] == samples
        assert results["antialiasing"] == {"msaa": plan.msaa, "supersampling": plan.factor,
                                           "samples_per_pixel": plan.per_pixel,
                                           "filter": "box (the mean of the samples inside each pixel)"}
