"""``vlights compare --reference IMAGE``: every display and the path tracer against an
outside HDR image at the scene's camera. The path tracer's own picture, saved as EXR,
is matched by the path tracer (exactly with the same seed, within its noise with
another); a reference twice as bright halves every display's mean ratio; bad
references and flags are refused in one line before any work."""

import dataclasses
import json

import numpy as np
import pytest
from display_fixtures import assert_refused, listing

from display.compare import reference_at, reference_files
from display.metrics import mean_ratio
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError
from radiosity.files.solution import load_solution

OpenEXR = pytest.importorskip("OpenEXR")

EYE = ("--eye", "0", "0", "-4", "--look-at", "0", "0", "0")  # the tiny scene's wall and tile, in frame


def write_exr(path, image):
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION}, {"RGB": np.ascontiguousarray(image, np.float32)}) as f:
        f.write(str(path))
    return path


def reference_numbers(out):
    return json.loads((out / "compare.json").read_text())["reference_image"]


def test_reference_at_box_averages_by_a_whole_factor():
    image = np.arange(4 * 6 * 3, dtype=np.float32).reshape(4, 6, 3)
    same, factor = reference_at(image, None, "x")
    assert same is image and factor == 1
    assert reference_at(image, (6, 4), "x")[0] is image
    shrunk, factor = reference_at(image, (3, 2), "x")
    assert factor == 2 and shrunk.shape == (2, 3, 3)
    np.testing.assert_allclose(shrunk[1, 2], image[2:4, 4:6].mean(axis=(0, 1)))
    with pytest.raises(InputError, match=r"is 6x4 \(aspect ratio 1\.5\), but --size 4x4 has aspect ratio 1"):
        reference_at(image, (4, 4), "x")
    for size in ((12, 8), (4, 8 / 3)):
        with pytest.raises(InputError, match="not it shrunk by a whole factor|aspect ratio"):
            reference_at(image, size, "x")
    with pytest.raises(InputError, match="not it shrunk by a whole factor"):
        reference_at(np.ones((8, 12, 3), np.float32), (9, 6), "x")


def test_mean_ratio_is_how_much_of_the_light():
    ref = np.full((2, 3, 3), 2.0, np.float32)
    assert mean_ratio(ref, ref) == 1.0
    assert mean_ratio(ref, ref / 4) == 0.25
    test = ref.copy()
    test[0] = 0.0  # half the pixels dark: half the light, wherever it is missing
    assert mean_ratio(ref, test) == 0.5
    with pytest.raises(InputError, match="is black"):
        mean_ratio(np.zeros_like(ref), ref)


def test_reference_files_name_the_path_tracer_only_when_traced():
    assert "reference/path_tracer.npy" not in reference_files(False)
    assert {"reference/image.png", "reference/path_tracer.npy", "reference/fitted_display_flip.png",
            "reference/diffuse_display.png"} <= set(reference_files(True))


def test_compare_refuses_bad_references_before_any_work(tmp_path, cli, tiny_pair, no_gl):
    fit_path, solution_path = tiny_pair
    out = tmp_path / "c"
    args = ("compare", fit_path, solution_path, "--out", out, *EYE)
    image = np.full((24, 32, 3), 0.5, np.float32)
    ok = write_exr(tmp_path / "ok.exr", image)
    np.save(tmp_path / "truth.npy", image)
    assert_refused(cli(*args, "--reference", ok, "--truth", tmp_path / "truth.npy"), "--reference and --truth",
                   command="compare")
    assert_refused(cli(*args, "--reference", ok, "--size", "32x32"), "ok.exr' is 32x24", "aspect ratio")
    assert_refused(cli(*args, "--reference", ok, "--size", "24x18"), "not it shrunk by a whole factor")
    assert_refused(cli(*args, "--reference", tmp_path / "missing.exr"), "missing.exr", "not found")
    write_exr(tmp_path / "black.exr", image * 0)
    assert_refused(cli(*args, "--reference", tmp_path / "black.exr"), "black.exr", "is black")
    bad = image.copy()
    bad[3, 4, 1] = np.nan
    write_exr(tmp_path / "nan.exr", bad)
    assert_refused(cli(*args, "--reference", tmp_path / "nan.exr"), "nan.exr", "1 NaN")
    bad[3, 4, 1] = -2.0
    np.save(tmp_path / "negative.npy", bad)
    assert_refused(cli(*args, "--reference", tmp_path / "negative.npy"), "negative.npy", "1 negative values")
    (tmp_path / "cut.exr").write_bytes(ok.read_bytes()[:-30])
    assert_refused(cli(*args, "--reference", tmp_path / "cut.exr"), "cut.exr", "truncated or corrupt")
    np.save(tmp_path / "two.npy", image[..., :2])
    assert_refused(cli(*args, "--reference", tmp_path / "two.npy"), "two.npy", "has 2 channels")
    (tmp_path / "picture.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    assert_refused(cli(*args, "--reference", tmp_path / "picture.png"), "not a linear HDR image")
    assert not out.exists()


@pytest.mark.gl
def test_compare_refuses_a_reference_with_no_camera_to_take_it_from(tmp_path, cli, tiny_pair, gl_context):
    fit_path, solution_path = tiny_pair  # the tiny scene has no camera: a framing view is no image's view
    ok = write_exr(tmp_path / "ok.exr", np.full((24, 32, 3), 0.5, np.float32))
    assert_refused(cli("compare", fit_path, solution_path, "--out", tmp_path / "c", "--reference", ok),
                   "the solution has no camera", "--eye, --look-at")
    assert not (tmp_path / "c").exists()


@pytest.mark.gl
@pytest.mark.parametrize("pair", ["tiny_pair", "flat_pair"])
def test_a_reference_twice_as_bright_halves_every_mean_ratio(tmp_path, cli, pair, gl_context, request):
    fit_path, solution_path = request.getfixturevalue(pair)
    render = tmp_path / "display.npy"  # the reference display, as compare draws it (size, samples, shading)
    code, _, err = cli("render", solution_path, "--mode", "reference", "--size", "32x24", *EYE, "--hdr", render)
    assert code == 0, err
    display = np.load(render).astype(np.float64)
    assert display.max() > 0
    image = write_exr(tmp_path / "twice.exr", display * 2)  # one run (FLIP takes most of a second an image)
    out = tmp_path / "c"
    code, stdout, err = cli("compare", fit_path, solution_path, "--out", out, *EYE, "--reference", image)
    assert code == 0, err
    assert f"against the reference image {image} (32x24)" in stdout
    numbers = reference_numbers(out)["displays"]
    assert set(numbers) == {"reference", "fitted", "diffuse"}  # no path tracer without --truth-spp
    for mode, m in numbers.items():
        drawn = np.load(out / "reference" / f"{mode}_display.npy").astype(np.float64)
        assert m["mean_ratio"] == pytest.approx(drawn.mean() / (2 * display.mean()), rel=1e-6)
        if pair == "flat_pair" or mode == "reference":  # the wall alone: every display is the reference display
            assert m["mean_ratio"] == pytest.approx(0.5, rel=1e-5)
    np.testing.assert_allclose(np.load(out / "reference" / "reference_display.npy"), display, rtol=1e-6)
    # relative MSE of x against 2x, pixel by pixel (the way up is the Cornell box's test: this scene is symmetric)
    expected = np.mean(display ** 2 / (4 * display ** 2 + 0.01))
    assert numbers["reference"]["relative_mse"] == pytest.approx(expected, rel=1e-4)
    if pair == "tiny_pair":  # the tile's glossy radiance: the fitted model is not the solution
        assert numbers["fitted"]["mean_ratio"] != pytest.approx(0.5, rel=1e-4)
    assert "reference/fitted_display_flip.png" in listing(out)


@pytest.fixture(scope="module")
def cornell_pair(tmp_path_factory, cornell_draft):
    """(fit.npz, solution.npz) of the Cornell box, draft: a lit scene with a camera."""
    from fitting import FitOptions, fit

    solution = cornell_draft
    folder = tmp_path_factory.mktemp("cornell")
    solution.save(folder / "solution.npz")
    fit(solution, FitOptions(lights=1)).save(folder / "fit.npz")
    return folder / "fit.npz", folder / "solution.npz"


@pytest.mark.gl
def test_the_path_tracers_own_exr_is_matched_by_the_path_tracer(tmp_path, cli, cornell_pair, gl_context):
    fit_path, solution_path = cornell_pair
    traced = tmp_path / "traced.npy"  # at the scene's camera (the solution's meta.camera)
    code, _, err = cli("truth", solution_path, "--size", "32x32", "--spp", "16", "--seed", "5", "--hdr", traced)
    assert code == 0, err
    exr = write_exr(tmp_path / "mitsuba-like.exr", np.load(traced))
    runs = {}
    for seed in ("5", "6"):
        out = tmp_path / f"seed{seed}"
        code, stdout, err = cli("compare", fit_path, solution_path, "--out", out, "--reference", exr,
                                "--truth-spp", "16", "--seed", seed)
        assert code == 0, err
        assert "path tracer (16 spp)" in stdout
        runs[seed] = reference_numbers(out)
    same, other = runs["5"]["displays"]["path_tracer"], runs["6"]["displays"]["path_tracer"]
    assert same["mean_ratio"] == 1.0 and same["flip_mean"] == 0.0 and same["relative_mse"] == 0.0  # bit for bit
    assert other["mean_ratio"] == pytest.approx(1, abs=0.05)  # another seed: the mean within its noise
    assert 0 < other["flip_mean"] < other["noise_flip"]  # 16 spp against 16 spp: below the floor of 8 against 8
    assert runs["6"]["width"] == runs["6"]["height"] == 32 and runs["6"]["downsampled_by"] == 1
    assert runs["6"]["camera"]["eye"] == [278.0, 273.0, -800.0]  # the scene's camera
    for mode in ("reference", "fitted", "diffuse"):  # the solver's displays see the box as the path tracer does
        assert runs["6"]["displays"][mode]["mean_ratio"] == pytest.approx(1, abs=0.1)
    files = listing(tmp_path / "seed6")
    assert {"reference/path_tracer.npy", "reference/path_tracer_flip.png", "reference/path_tracer.png",
            "reference/image.png", "compare.json", "figure5_view1.png"} <= set(files)
    # --size may shrink the image by a whole factor, box-averaged as a display pixel averages its samples
    code, stdout, err = cli("compare", fit_path, solution_path, "--out", tmp_path / "half", "--reference", exr,
                            "--size", "16x16")
    assert code == 0, err
    half = reference_numbers(tmp_path / "half")
    assert half["width"] == 16 and half["downsampled_by"] == 2 and "box-averaged by 2" in stdout
    assert half["mean"] == pytest.approx(runs["6"]["mean"], rel=1e-5)


@pytest.mark.gl
def test_a_reference_of_another_aspect_keeps_the_fov_along_its_axis(tmp_path, cli, cornell_pair, gl_context):
    """A Mitsuba sensor's fov along x on a 16:9 film, and a square reference image: every
    display and the path tracer draw it with that fov along x (the vertical fov of a square
    image), not with the film's vertical fov."""
    fit_path, solution_path = cornell_pair
    solution = load_solution(solution_path)
    scene = solution.camera
    dataclasses.replace(solution, camera=Camera(scene.eye, scene.look_at, scene.up, 39.3, 64, 36, "x")).save(
        tmp_path / "solution.npz")
    flags = ["--eye", *map(repr, scene.eye), "--look-at", *map(repr, scene.look_at), "--up", *map(repr, scene.up),
             "--fov", "39.3", "--size", "32x32"]  # that view, said with a vertical fov
    traced, drawn = tmp_path / "traced.npy", tmp_path / "drawn.npy"
    code, _, err = cli("truth", solution_path, *flags, "--spp", "16", "--seed", "5", "--hdr", traced)
    assert code == 0, err
    code, _, err = cli("render", solution_path, "--mode", "reference", *flags, "--hdr", drawn)
    assert code == 0, err
    out = tmp_path / "c"
    code, _, err = cli("compare", fit_path, tmp_path / "solution.npz", "--out", out, "--truth-spp", "16", "--seed", "5",
                       "--reference", write_exr(tmp_path / "square.exr", np.load(traced)))
    assert code == 0, err
    numbers = reference_numbers(out)
    camera = numbers["camera"]
    assert (camera["fov_deg"], camera["fov_axis"], camera["film"]) == (39.3, "x", [32, 32])
    assert camera["fov_y_deg"] == pytest.approx(39.3, rel=1e-12)  # not the film's 22.6
    tracer = numbers["displays"]["path_tracer"]
    assert tracer["flip_mean"] == 0.0 and tracer["mean_ratio"] == 1.0  # the same view, bit for bit
    np.testing.assert_allclose(np.load(out / "reference" / "reference_display.npy"), np.load(drawn), rtol=1e-6)
