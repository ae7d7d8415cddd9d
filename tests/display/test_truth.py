"""The ground truth next to the display: the path tracer and the solution's reference
display see the same diffuse box alike, and the truth's own machinery (halves, files)
does what it says."""

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

from display.metrics import against_truth
from display.renderer import Renderer
from display.truth import ground_truth, load_truth, scene_for_truth
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError
from radiosity.transport.pathtrace import PathTracer, scene_of_solution


@pytest.fixture(scope="module")
def diffuse_box(cornell_draft):
    return cornell_draft


def object_ids(renderer, camera, names):
    """(H, W) index of the object each pixel's centre sees, -1 for none."""
    ids = np.full((camera.height, camera.width), -1)
    for i, name in enumerate(names):
        ids[renderer.object_mask(camera, [name])] = i
    return ids


@pytest.mark.gl
def test_path_tracer_and_reference_display_agree_on_the_diffuse_box(gl_context, diffuse_box):
    camera = diffuse_box.camera.sized(96, 96)
    renderer = Renderer(gl_context, solution=diffuse_box, samples=4)
    display = renderer.render(camera, "reference").astype(np.float64)
    ids = object_ids(renderer, camera, diffuse_box.names)
    renderer.release()
    with PathTracer(scene_of_solution(diffuse_box)) as tracer:
        truth = tracer.render(camera, 256, seed=5)
    # away from edges (where either image mixes two surfaces) and the light (its edge pixels are noisy)
    edge = np.zeros(ids.shape, bool)
    for axis in (0, 1):
        step = np.diff(ids, axis=axis) != 0
        lo = [slice(None), slice(None)]
        hi = [slice(None), slice(None)]
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        edge[tuple(lo)] |= step
        edge[tuple(hi)] |= step
    keep = ~binary_dilation(edge) & (ids >= 0) & (ids != diffuse_box.names.index("light"))
    assert keep.sum() > 5000
    traced = truth.radiance.astype(np.float64)
    assert abs(traced[keep].mean() / display[keep].mean() - 1) < 0.02
    for i, name in enumerate(diffuse_box.names):
        where = keep & (ids == i)
        if where.sum() > 100:
            assert abs(traced[where].mean() / display[where].mean() - 1) < 0.03, name
    # most pixels within the path tracer's noise (the median |z| of pure noise is 0.67)
    z = (traced[keep] - display[keep]) / np.maximum(truth.standard_error[keep], 1e-9)
    assert np.median(np.abs(z)) < 1.0


def test_ground_truth_is_the_two_halves_together_with_their_noise_floor(diffuse_box):
    camera = diffuse_box.camera.sized(12, 10)
    truth = ground_truth(diffuse_box, camera, 8, seed=4)
    with PathTracer(scene_of_solution(diffuse_box)) as tracer:
        whole = tracer.render(camera, 8, seed=4)
    assert np.allclose(truth.radiance, whole.radiance, rtol=1e-5, atol=1e-6)
    assert 0 < truth.noise_flip < 1
    assert truth.stats["paths"] == 8 * 120
    assert ground_truth(diffuse_box, camera, 1).noise_flip is None  # one sample: no halves


def test_errors_against_the_truth_are_zero_for_the_truth_itself():
    truth = np.random.default_rng(0).random((8, 8, 3)).astype(np.float32) + 0.1
    numbers, errors = against_truth(truth, {"same": truth, "darker": truth * 0.5})
    assert numbers["same"]["flip_mean"] == 0 and numbers["same"]["relative_mse"] == 0
    assert numbers["darker"]["flip_mean"] > 0.05 and numbers["darker"]["relative_mse"] > 0.01
    assert errors["darker"].shape == (8, 8, 3)


def test_truth_files_must_fit_the_view(tmp_path):
    camera = Camera((0, 0, -1), (0, 0, 0), width=4, height=3)
    good = tmp_path / "good.npy"
    np.save(good, np.ones((3, 4, 3), np.float32))
    assert load_truth(good, camera).shape == (3, 4, 3)
    cases = {
        "wrong.npy": (np.ones((4, 3, 3), np.float32), r"is \(4, 3, 3\), but the view is 4x3"),
        "nan.npy": (np.full((3, 4, 3), np.nan, np.float32), "finite, non-negative"),
        "negative.npy": (-np.ones((3, 4, 3), np.float32), "finite, non-negative"),
        "ints.npy": (np.ones((3, 4, 3), np.int32), "finite, non-negative"),
    }
    for name, (array, message) in cases.items():
        np.save(tmp_path / name, array)
        with pytest.raises(InputError, match=message):
            load_truth(tmp_path / name, camera)
    (tmp_path / "text.npy").write_text("not an array")
    with pytest.raises(InputError, match="not a .npy image"):
        load_truth(tmp_path / "text.npy", camera)
    with pytest.raises(InputError, match="not found"):
        load_truth(tmp_path / "missing.npy", camera)


def test_the_truth_reads_solutions_and_scenes_but_not_fits(tmp_path, diffuse_box):
    from fitting import FitOptions, fit

    path = tmp_path / "solution.npz"
    diffuse_box.save(path)
    assert scene_for_truth(path).names == diffuse_box.names
    assert [o.name for o in scene_for_truth("cornell").objects] == list(diffuse_box.names)
    fit(diffuse_box, FitOptions(lights=1)).save(tmp_path / "fit.npz")
    with pytest.raises(InputError, match="holds no materials"):
        scene_for_truth(tmp_path / "fit.npz")
    with pytest.raises(InputError, match="not found"):
        scene_for_truth(tmp_path / "missing.npz")


# -- the commands ------------------------------------------------------------------------------


def test_truth_command_writes_both_files(tmp_path, cli):
    hdr, png = tmp_path / "truth.npy", tmp_path / "truth.png"
    code, out, err = cli("truth", "cornell", "--size", "8x6", "--spp", "2", "--hdr", hdr, "-o", png)
    assert code == 0, err
    image = np.load(hdr)
    assert image.shape == (6, 8, 3) and image.dtype == np.float32 and image.max() > 0
    assert png.stat().st_size > 0
    assert "2 samples per pixel" in out and "M paths/s" in out and "noise floor" in out
    # the same seed and samples give the same image, whatever the threads
    code, _, _ = cli("truth", "cornell", "--size", "8x6", "--spp", "2", "--hdr", tmp_path / "t1.npy", "--threads", "1")
    assert code == 0 and np.array_equal(np.load(tmp_path / "t1.npy"), image)


def test_truth_command_refuses_bad_input_in_one_line(tmp_path, cli, tiny_pair):
    from display_fixtures import assert_refused

    fit_path, _ = tiny_pair
    assert_refused(cli("truth", fit_path, "--spp", "1"), "holds no materials")
    assert_refused(cli("truth", "cornell", "--spp", "0"), "--spp must be")
    assert_refused(cli("truth", "cornell", "--threads", "0"), "--threads")
    assert_refused(cli("truth", tmp_path / "missing.toml"), "missing.toml")
    assert_refused(cli("truth", "cornell", "-o", tmp_path), "-o")
    assert_refused(cli("truth", "cornell", "--exposure", "0"), "--exposure")
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_compare_measures_every_display_against_the_truth(tmp_path, cli, diffuse_box, gl_context):
    import json

    from fitting import FitOptions, fit

    solution_path, fit_path = tmp_path / "solution.npz", tmp_path / "fit.npz"
    diffuse_box.save(solution_path)
    fit(diffuse_box, FitOptions(lights=1)).save(fit_path)
    truth = tmp_path / "view1.npy"
    assert cli("truth", solution_path, "--size", "24x24", "--spp", "4", "--hdr", truth)[0] == 0
    code, out, err = cli("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "c",
                         "--truth", truth, "--truth-spp", "2")
    assert code == 0, err
    results = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert set(results["truth"]) == {"view1", "view2", "view3"} and results["truth"]["view2"]["noise_flip"] > 0
    assert results["truth"]["view1"]["spp"] == 0 and results["truth"]["view2"]["spp"] == 2  # a file; traced
    for view in results["truth"].values():
        for mode in ("reference", "fitted", "diffuse"):
            assert 0 <= view[mode]["flip_mean"] <= 1 and view[mode]["relative_mse"] >= 0
    assert "against the path-traced truth, view 1 (from a file)" in out
    # the truth panel widens figure 5 by one picture and one error image
    from PIL import Image

    with_truth = Image.open(tmp_path / "c" / "figure5_view1.png").size[0]
    assert cli("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "d")[0] == 0
    assert with_truth > Image.open(tmp_path / "d" / "figure5_view1.png").size[0] + 2 * 24


def test_compare_refuses_truths_that_do_not_fit(tmp_path, cli, tiny_pair, no_gl):
    from display_fixtures import assert_refused

    fit_path, solution_path = tiny_pair
    args = ("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "c")
    assert_refused(cli(*args, "--truth", tmp_path / "missing.npy"), "not found")
    assert_refused(cli(*args, "--truth", tmp_path / "a.png"), "must be an .npy")
    assert_refused(cli(*args, "--truth-spp", "-1"), "--truth-spp must be")
    for name in "abcd":
        np.save(tmp_path / f"{name}.npy", np.ones((24, 24, 3), np.float32))
    assert_refused(cli(*args, "--truth", *(tmp_path / f"{n}.npy" for n in "abcd")), "at most 3")


def test_compare_refuses_a_black_truth_or_one_of_another_size(tmp_path, cli, tiny_pair, gl_context):
    from display_fixtures import assert_refused

    fit_path, solution_path = tiny_pair
    # the tiny scene's radiance is made up: nothing in it emits, so its path-traced truth is black
    # (found once traced: the progress lines come first, then the one line of the refusal)
    code, _, err = cli("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "c",
                       "--truth-spp", "1")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "truth of view 1 (eye at (" in err and ") is black" in err and "turned" not in err, err
    # a view 2 or 3 that turns behind a wall: the line says where its eye is and why it is there
    np.save(tmp_path / "lit.npy", np.ones((24, 24, 3), np.float32))
    np.save(tmp_path / "dark.npy", np.zeros((24, 24, 3), np.float32))
    code, _, err = cli("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "c",
                       "--truth", tmp_path / "lit.npy", tmp_path / "dark.npy")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "truth of view 2 (eye at (" in err and "view 1 turned 35 degrees about its look-at point) is black" in err
    assert "an eye nearer to it keeps them inside" in err
    np.save(tmp_path / "small.npy", np.ones((8, 8, 3), np.float32))
    assert_refused(cli("compare", fit_path, solution_path, "--size", "24x24", "--out", tmp_path / "c",
                       "--truth", tmp_path / "small.npy"), "but the view is 24x24")
    assert not (tmp_path / "c" / "compare.json").exists()
