"""``vlights fit``: the output checked before any work, --quality, and the report."""

import hashlib
import os

import numpy as np
import pytest
from test_fit import synthetic

from display.cli import main
from fitting import load_fit
from fitting.cli import format_report
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.policies.presets import preset

DIFFUSE_MATERIAL = {"diffuse": [0.5, 0.5, 0.5], "specular": [0.0, 0.0, 0.0], "exponent": 0.0, "emission": [0.0, 0.0, 0.0]}


def small_solution(path, quality="medium"):
    """A glossy dome (a known two-light model, 6 x 6 directions) and a diffuse floor."""
    glossy, _ = synthetic(np.random.default_rng(1), lights=2, shininess=30.0, grid=6, subdivisions=1)
    dome = glossy.objects[0]
    floor = ObjectSolution(
        name="floor", positions=np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32),
        normals=np.tile(np.float32([0, 0, 1]), (3, 1)), tangents=np.tile(np.float32([1, 0, 0]), (3, 1)),
        faces=np.array([[0, 1, 2]], np.int32), directions=np.float32([[0, 0, 1]]),
        radiance=np.full((3, 1, 3), 0.25, np.float32), material=DIFFUSE_MATERIAL,
    )
    settings = {} if quality is None else {"quality": quality}
    Solution(objects=(dome, floor), settings=settings, scene="test").save(path)
    return path


@pytest.fixture(scope="module")
def solution_file(tmp_path_factory):
    return small_solution(tmp_path_factory.mktemp("sol") / "s.npz")


def run(argv, capsys):
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse exits by itself
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest(), os.stat(path).st_mtime_ns


@pytest.mark.parametrize("how", ["same path", "another path", "symlink", "hard link"])
def test_output_onto_the_input_is_refused_and_the_input_kept(how, tmp_path, capsys):
    solution = small_solution(tmp_path / "s.npz")
    (tmp_path / "sub").mkdir()
    if how == "same path":
        output = solution
    elif how == "another path":
        output = tmp_path / "sub" / ".." / "s.npz"
    elif how == "symlink":
        output = tmp_path / "link.npz"
        output.symlink_to(solution)
    else:
        output = tmp_path / "hard.npz"
        os.link(solution, output)
    before = digest(solution)
    code, out, err = run(["fit", str(solution), "-o", str(output), "--method", "paper"], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "-o" in err and "input" in err, err
    assert digest(solution) == before
    assert not [p for p in tmp_path.iterdir() if p.suffix == ".tmp"]


@pytest.mark.parametrize("output, message", [("fit.txt", "must end in .npz"), ("nowhere/fit.npz", "does not exist"),
                                             (".", "is a directory")])
def test_bad_outputs_are_refused_before_any_work(output, message, solution_file, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["fit", str(solution_file), "-o", output], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "recorded, flags, quality, lights, iterations",
    [
        ("medium", [], "medium", preset("medium").fit_lights, preset("medium").fit_iterations),
        (None, [], "draft", preset("draft").fit_lights, preset("draft").fit_iterations),
        ("ultra", [], "draft", preset("draft").fit_lights, preset("draft").fit_iterations),
        ("medium", ["--quality", "high"], "high", preset("high").fit_lights, preset("high").fit_iterations),
        ("medium", ["--quality", "high", "--iterations", "3", "--lights", "2"], "high", 2, 3),
        ("draft", ["--lights", "1"], "draft", 1, preset("draft").fit_iterations),
    ],
)
def test_quality_sets_lights_and_iterations_explicit_flags_win(recorded, flags, quality, lights, iterations,
                                                                tmp_path, capsys):
    solution = small_solution(tmp_path / "s.npz", quality=recorded)
    out = tmp_path / "f.npz"
    code, stdout, err = run(["fit", str(solution), "-o", str(out), "--method", "paper"] + flags, capsys)
    assert code == 0, err
    model = load_fit(out)
    assert model.settings["quality"] == quality
    assert model.settings["lights"] == lights and model.settings["iterations"] == iterations
    assert model.object("dome").n_lights == lights
    assert f"quality {quality} (lights {lights}, iterations {iterations})" in stdout


def test_unknown_quality_is_refused(solution_file, tmp_path, capsys):
    code, out, err = run(["fit", str(solution_file), "-o", str(tmp_path / "f.npz"), "--quality", "ultra"], capsys)
    assert code == 2 and out == "" and "--quality" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_report_shows_no_numbers_for_diffuse_objects(solution_file, tmp_path, capsys):
    out = tmp_path / "f.npz"
    code, stdout, err = run(["fit", str(solution_file), "-o", str(out), "--method", "paper", "--lights", "2"], capsys)
    assert code == 0, err
    lines = stdout.splitlines()
    assert "rel. RMS" in lines[0] and "diffuse only" in lines[0] and "model" in lines[0]
    [floor] = [line for line in lines if line.startswith("floor")]
    assert "a diffuse material" in floor and "0.0000" not in floor
    [dome] = [line for line in lines if line.startswith("dome")]
    # name, model, K, kinds (point and directional), probe, floats per vertex, exponent, three errors, time
    words = dome.split()
    assert words[1] == "lights" and words[2] == "2" and words[3:5] == ["0P", "2D"] and len(words) == 12
    assert format_report(load_fit(out), out) == stdout.rstrip("\n")


@pytest.mark.parametrize("flags, message", [
    (["--probe-size", "abc"], "--probe-size: takes a whole number or 'auto'"),
    (["--probe-size", "1"], "--probe-size must be 'auto' or a whole number from 2 to 128"),
    (["--model-target", "0"], "--model-target must be an error between 0 and 10"),
    (["--model", "glare"], "invalid choice: 'glare'"),
    (["--loss", "log"], "invalid choice: 'log'"),
])
def test_bad_model_flags_are_one_line_and_no_file(flags, message, solution_file, tmp_path, capsys):
    out = tmp_path / "f.npz"
    code, _, err = run(["fit", str(solution_file), "-o", str(out), *flags], capsys)
    assert code == 2 and message in err and err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("flags, message", [
    (["--model", "probe", "--lights", "3"], "--lights shapes virtual lights: --model probe has none"),
    (["--model", "emitters", "--coefficients", "shared"], "--coefficients shapes virtual lights: --model emitters"),
    (["--model", "diffuse", "--method", "per-light"], "--method shapes virtual lights: --model diffuse has none"),
    (["--model", "probe", "--light-kind", "positional"], "--light-kind shapes virtual lights"),
    (["--model", "probe", "--iterations", "5"], "--iterations shapes virtual lights"),
    (["--model", "probe", "--exponent-bounds", "2", "50"], "--exponent-bounds shapes virtual lights"),
    (["--model", "lights", "--probe-size", "16"], "--probe-size shapes the reflection probe: --model lights has none"),
    (["--model", "emitters", "--probe-size", "16"], "--probe-size shapes the reflection probe"),
    (["--model", "diffuse", "--loss", "linear"], "--model diffuse fits nothing"),
    (["--model", "probe+lights", "--lights", "0"], "--lights 0 leaves --model probe+lights no lights"),
    (["--model", "probe", "--method", "paper"], "--method paper fits virtual lights alone"),
    (["--method", "paper", "--light-kind", "positional"], "--method paper has directional lights"),
    (["--lights", "4", "--target", "0.05"], "--target is for --lights auto"),
    (["--max-lights", "4"], "--max-lights is for --lights auto (how many lights it adds): it does nothing with the "
                            "quality's number of lights"),
])
def test_a_flag_the_model_cannot_honour_is_refused_in_one_line(flags, message, solution_file, tmp_path, capsys):
    out = tmp_path / "f.npz"
    code, _, err = run(["fit", str(solution_file), "-o", str(out), *flags], capsys)
    assert code == 2 and message in err and err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("flags, model, check", [
    (["--model", "probe", "--probe-size", "8", "--loss", "linear"], "probe",
     lambda o: o.probe.size == 8 and o.info["loss"] == "linear"),
    (["--model", "lights", "--lights", "auto", "--target", "0.2", "--max-lights", "3"], "lights",
     lambda o: 1 <= o.n_lights <= 3),
    (["--method", "paper", "--light-kind", "directional", "--coefficients", "shared", "--lights", "2"], "lights",
     lambda o: o.n_lights == 2 and not o.positional.any() and o.info["coefficients"] == "shared"),
    (["--model", "probe+lights", "--lights", "1", "--coefficients", "shared", "--probe-size", "8"], "probe+lights",
     lambda o: o.n_lights == 1 and o.probe.size == 8 and o.info["coefficients"] == "shared"),
])
def test_flags_the_model_honours_are_taken(flags, model, check, solution_file, tmp_path, capsys):
    out = tmp_path / "f.npz"
    code, _, err = run(["fit", str(solution_file), "-o", str(out), *flags], capsys)
    assert code == 0 and out.exists(), err
    dome = load_fit(out).object("dome")
    assert dome.info["model"] == model and check(dome), dome.info


@pytest.mark.parametrize("quality", ["draft", "medium", "high"])
def test_fit_options_for_a_quality_follow_its_preset(quality):
    from fitting import FitOptions
    from radiosity.policies.presets import preset

    options, knobs = FitOptions.for_quality(quality), preset(quality)
    assert (options.lights, options.iterations, options.probe_sizes, options.probe_lights) == (
        knobs.fit_lights, knobs.fit_iterations, tuple(knobs.probe_sizes), knobs.probe_lights)


@pytest.mark.parametrize("quality", [None, "medium"])
def test_one_default_for_python_and_the_command(quality, tmp_path, capsys):
    """``FitOptions()`` is the default quality's preset; ``fitting.fit(solution)`` with no
    options fits at the quality the solution was solved at (the default where it records
    none), and writes the same model, bit for bit, as ``vlights fit`` with no flag."""
    from fitting import FitOptions, fit
    from radiosity.files.solution import load_solution
    from radiosity.policies.presets import DEFAULT_QUALITY

    assert FitOptions() == FitOptions.for_quality(DEFAULT_QUALITY)
    path = small_solution(tmp_path / "s.npz", quality)
    code, _, err = run(["fit", str(path), "-o", str(tmp_path / "cli.npz"), "--workers", "1"], capsys)
    assert code == 0, err
    fit(load_solution(path)).save(tmp_path / "python.npz")
    cli, python = load_fit(tmp_path / "cli.npz"), load_fit(tmp_path / "python.npz")
    assert [o.info["chosen_by"] for o in cli.objects] == [o.info["chosen_by"] for o in python.objects]
    for a, b in zip(cli.objects, python.objects, strict=True):
        for key, value in a.arrays().items():
            assert np.array_equal(value, b.arrays()[key]), (a.name, key)
    iterations = preset(quality or DEFAULT_QUALITY).fit_iterations
    assert cli.object("dome").info.get("iterations", iterations) <= iterations
