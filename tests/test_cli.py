"""The ``vlights`` command: subcommands, scene-info, and bad input refused cleanly."""

import json
import shutil
import subprocess

import pytest
from bad_inputs import BAD_INPUTS, bad_input_path

from display.cli import main

SUBCOMMANDS = ["solve", "fit", "render", "view", "compare", "demo", "scene-info"]


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_help_lists_every_subcommand(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for command in SUBCOMMANDS:
        assert command in out


def test_scene_info_describes_the_demo_scene(capsys):
    code, out, err = run(["scene-info", "cornell-teapot"], capsys)
    assert code == 0, err
    for word in ("teapot", "tall_block", "glaze", "satin", "emitters (1)", "refined", "diagonal"):
        assert word in out
    code, out, _ = run(["scene-info", "cornell-teapot", "--max-edge", "25", "--json"], capsys)
    info = json.loads(out)
    assert info["refinement"] == {"max_edge": 25.0, "chosen_by": "--max-edge"}
    assert info["totals"]["refined_triangles"] > info["totals"]["triangles"]


def test_scene_info_names_a_microfacet_material_s_own_model_and_its_albedo(capsys):
    from pathlib import Path

    from radiosity.scene.kinds import oracle
    from radiosity.scene.loaders import load_scene

    xml = Path(__file__).parent / "data" / "mitsuba" / "validate_kinds.xml"
    code, out, err = run(["scene-info", str(xml), "--json"], capsys)
    assert code == 0, err
    m = json.loads(out)["materials"]["ball_conductor_beckmann"]
    assert m["kind"] == "roughconductor beckmann 0.25" and m["microfacet"]["kind"] == "roughconductor"
    own = oracle(load_scene(xml).materials["ball_conductor_beckmann"]).albedo(0.5)[0]
    assert m["albedo_60deg"] == pytest.approx(list(own), abs=1e-4)
    code, out, _ = run(["scene-info", str(xml)], capsys)
    assert "roughplastic ggx 0.12" in out and "Phong lobe its displays draw" in out


def test_quality_presets_refine_more_as_quality_rises(capsys):
    counts = []
    for quality in ("draft", "medium", "high"):
        code, out, _ = run(["scene-info", "cornell", "--quality", quality, "--json"], capsys)
        assert code == 0
        counts.append(json.loads(out)["totals"]["refined_triangles"])
    assert counts[0] < counts[1] < counts[2]


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_scene_one_line_exit_2(case, tmp_path, capsys):
    code, out, err = run(["scene-info", bad_input_path(case, tmp_path)], capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("vlights scene-info: error: ")
    assert "Traceback" not in err


@pytest.mark.parametrize(
    "argv", [["scene-info"], ["scene-info", "cornell", "--max-edge", "-3"], ["scene-info", "cornell", "--quality", "ultra"], ["frobnicate"]]
)
def test_bad_flags_one_line_exit_2(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse exits by itself
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1, err


def test_degenerate_triangles_warn_in_one_line(tmp_path, capsys):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n")
    (tmp_path / "s.toml").write_text('[materials.m]\ndiffuse=0.5\n[[objects]]\nname="a"\nmesh="m.obj"\nmaterial="m"\n')
    code, out, err = run(["scene-info", str(tmp_path / "s.toml")], capsys)
    assert code == 0
    assert err.strip() == "vlights: warning: object 'a' (%s): dropped 1 degenerate triangle(s)" % (tmp_path / "m.obj")


@pytest.mark.subprocess
@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_installed_entry_point(tmp_path):
    ok = subprocess.run(["vlights", "scene-info", "cornell"], capture_output=True, text=True)
    assert ok.returncode == 0 and "short_block" in ok.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text("[materials.m\n")
    fail = subprocess.run(["vlights", "scene-info", str(bad)], capture_output=True, text=True)
    assert fail.returncode == 2 and fail.stdout == ""
    assert fail.stderr.count("\n") == 1 and "line 1" in fail.stderr and "Traceback" not in fail.stderr


@pytest.mark.subprocess
def test_ctrl_c_during_solve_leaves_no_file(tmp_path):
    import signal

    from child_process import Child, vlights

    out = tmp_path / "solution.npz"
    child = Child(vlights("solve", "cornell-teapot", "--photons", "400000000", "-o", out))
    child.wait_for(r"photons:\s+\d+%\|[^\r\n]*\| *[1-9][\d.]*[kMG]?/")  # the photon pass, some photons traced
    child.send(signal.SIGINT)
    code, _, err = child.finish()
    assert code == 130, err
    assert err.strip().splitlines()[-1] == "vlights solve: interrupted" and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # no solution, no temporary file


def test_solve_writes_a_readable_solution_and_a_summary(tmp_path, capsys):
    from radiosity.files.solution import load_solution

    out = tmp_path / "s.npz"
    code, stdout, _ = run(
        ["solve", "cornell", "-o", str(out), "--photons", "20000", "--max-edge", "200", "--seed", "3"], capsys
    )
    assert code == 0
    for word in ("photons", "rays/s", "density", "gather", "total", "wrote", "MB"):
        assert word in stdout
    solution = load_solution(out)
    assert solution.stats["photons"] == 20000 and solution.stats["seed"] == 3
    assert set(solution.stats["time_s"]) == {"setup", "photons", "density", "gather", "highlights"}
    assert {"photons", "rays", "threads", "quality", "seed"} <= set(solution.stats)


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--photons", "0"], "--photons"),
        (["--gather-samples", "-4"], "--gather-samples"),
        (["--grid", "0"], "--grid"),
        (["--threads", "0"], "--threads"),
        (["--max-edge", "0"], "--max-edge"),
        (["-o", "out.txt"], "must end in .npz"),
    ],
)
def test_solve_refuses_bad_knobs(flags, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["solve", "cornell"] + flags, capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def small_solution(tmp_path_factory):
    out = tmp_path_factory.mktemp("sol") / "s.npz"
    code = main(["solve", "cornell-teapot", "-o", str(out), "--photons", "20000", "--max-edge", "150",
                 "--gather-samples", "16", "--light-samples", "4", "--grid", "8"])
    assert code == 0
    return out


def test_fit_writes_a_model_and_reports_errors(small_solution, tmp_path, capsys):
    from fitting import load_fit

    capsys.readouterr()
    out = tmp_path / "f.npz"
    code, stdout, _ = run(["fit", str(small_solution), "-o", str(out), "--lights", "2", "--method", "paper"], capsys)
    assert code == 0
    assert "teapot" in stdout and "rel. RMS" in stdout and "diffuse only" in stdout
    model = load_fit(out)
    assert model.object("teapot").n_lights == 2 and model.object("floor").n_lights == 0
    assert model.object("teapot").info["error"]["relative_rms"] < model.object("teapot").info["error"]["diffuse_only_relative_rms"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--lights", "many"], "--lights"),
        (["--lights", "-1"], "--lights"),
        (["--exponent-bounds", "10", "1"], "exponent bounds"),
        (["--target", "0"], "--target"),
        (["--iterations", "-2"], "--iterations"),
    ],
)
def test_fit_refuses_bad_flags(small_solution, args, message, tmp_path, capsys):
    capsys.readouterr()
    code, out, err = run(["fit", str(small_solution), "-o", str(tmp_path / "f.npz")] + args, capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("content", [b"", b"not a zip", None])
def test_fit_refuses_bad_solution_files(content, tmp_path, capsys):
    path = tmp_path / "bad.npz"
    if content is not None:
        path.write_bytes(content)
    code, out, err = run(["fit", str(path), "-o", str(tmp_path / "f.npz")], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "f.npz").exists()


@pytest.fixture(scope="module")
def small_fit(small_solution, tmp_path_factory):
    out = tmp_path_factory.mktemp("fit") / "f.npz"
    assert main(["fit", str(small_solution), "-o", str(out), "--lights", "2", "--method", "paper"]) == 0
    return out


@pytest.mark.gl
def test_render_writes_hdr_and_png(small_solution, small_fit, tmp_path, capsys, gl_context):
    import numpy as np
    from PIL import Image

    hdr, png = tmp_path / "a.npy", tmp_path / "a.png"
    code, out, err = run(["render", str(small_fit), "--hdr", str(hdr), "-o", str(png), "--size", "64x48"], capsys)
    assert code == 0, err
    image = np.load(hdr)
    assert image.shape == (48, 64, 3) and image.dtype == np.float32
    assert np.isfinite(image).all() and image.max() > 0
    away = tmp_path / "away.npy"  # from the open front, looking away from the box: background only
    assert main(["render", str(small_fit), "--eye", "278", "273", "-800", "--look-at", "278", "273", "-1600",
                 "--hdr", str(away), "--size", "16x16"]) == 0
    assert (np.load(away) == 0).all()
    assert Image.open(png).size == (64, 48)
    # 2 lights against none: the fitted picture differs from the diffuse one
    diffuse = tmp_path / "d.npy"
    assert main(["render", str(small_fit), "--mode", "diffuse", "--hdr", str(diffuse), "--size", "64x48"]) == 0
    assert not np.array_equal(np.load(diffuse), image)
    # a solution renders in reference mode by default, and with the fit next to it
    ref = tmp_path / "r.npy"
    assert main(["render", str(small_solution), "--hdr", str(ref), "--size", "64x48", "--shading", "gouraud"]) == 0
    assert np.load(ref).max() > 0
    views = tmp_path / "views.json"
    views.write_text('{"side": {"eye": [50, 300, -300], "look_at": [278, 200, 280], "fov_y_deg": 50}}')
    assert main(["render", str(small_fit), "--solution", str(small_solution), "--mode", "reference",
                 "--views", str(views), "--view", "side", "--hdr", str(ref), "--size", "32x32"]) == 0
    # the solution display by its name, and by its first name ("reference"): the same picture
    named = tmp_path / "n.npy"
    assert main(["render", str(small_fit), "--solution", str(small_solution), "--mode", "solution",
                 "--views", str(views), "--view", "side", "--hdr", str(named), "--size", "32x32"]) == 0
    assert np.array_equal(np.load(named), np.load(ref))


@pytest.mark.parametrize(
    "args, message",
    [
        (["--size", "10by10"], "WIDTHxHEIGHT"),
        (["--mode", "reference"], "needs a solution"),
        (["--mode", "solution"], "needs a solution"),
        (["--mode", "truth"], "'truth' is not a display: choose fitted, solution or diffuse"),
        (["--view", "x"], "--views"),
        (["--exposure", "0"], "--exposure"),
        (["-o", "x.jpg"], ".png"),
        (["--eye", "0", "0", "0", "--look-at", "0", "0", "0"], "look-at equals the eye"),
    ],
)
def test_render_refuses_bad_input(small_fit, args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(["render", str(small_fit)] + args)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.gl
def test_compare_writes_the_figures_and_numbers(small_solution, small_fit, tmp_path, capsys, gl_context):
    import json

    out = tmp_path / "cmp"
    code, stdout, err = run(["compare", str(small_fit), str(small_solution), "--out", str(out), "--size", "48x40"], capsys)
    assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert names == {"figure5_view1.png", "figure5_view2.png", "figure5_view3.png", "figure6.png", "figure7.png", "compare.json"}
    results = json.loads((out / "compare.json").read_text())
    assert results["glossy_objects"] == ["tall_block", "teapot"]
    for figure in ("figure5", "figure6", "figure7"):
        for numbers in results[figure].values():
            assert 0 <= numbers["flip_mean"] <= 1 and numbers["psnr_db"] > 0 and numbers["relative_mse"] >= 0
            assert numbers["glossy_pixels"] > 0 and numbers["flip_mean_glossy"] >= numbers["flip_mean"] * 0.5
    assert "figure 7, diffuse only" in stdout


def test_compare_metrics_know_the_answer():
    import numpy as np

    from display.metrics import metrics

    rng = np.random.default_rng(1)
    reference = rng.uniform(0, 1, (32, 32, 3)).astype(np.float32)
    same, _ = metrics(reference, reference)
    assert same["flip_mean"] == 0 and same["psnr_db"] == float("inf") and same["relative_mse"] == 0
    brighter, image = metrics(reference, reference * 1.5, mask=np.eye(32, dtype=bool))
    assert brighter["flip_mean"] > 0.01 and brighter["psnr_db"] < 40 and image.shape == (32, 32, 3)
    expected = np.mean((0.5 * reference.astype(np.float64)) ** 2 / (reference.astype(np.float64) ** 2 + 0.01))
    assert brighter["relative_mse"] == pytest.approx(expected, rel=1e-6)
    assert brighter["glossy_pixels"] == 32


@pytest.mark.gl
def test_render_video(small_fit, tmp_path, capsys, gl_context):
    import imageio.v2 as imageio

    out = tmp_path / "walk.mp4"
    code, _, err = run(["render", str(small_fit), "--video", str(out), "--frames", "12", "--size", "64x48"], capsys)
    assert code == 0, err
    assert imageio.get_reader(str(out)).count_frames() == 12
    reader = imageio.get_reader(str(out))  # counting used the first reader up
    frames = [reader.get_data(i) for i in (0, 6, 11)]
    assert frames[0].shape == (48, 64, 3)
    assert (frames[0] != frames[1]).any()  # the camera moves
    assert [p.name for p in tmp_path.iterdir()] == ["walk.mp4"]  # no partial file left
