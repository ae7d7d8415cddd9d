"""Every display command refuses a wrong input file in one line, before any work: a
missing file, a file that is not one of ours, a directory, and a fit where a solution
is expected or the other way round."""

import pytest
from display_fixtures import assert_refused
from test_code_shape import OUTSIDE

import display.window

COMMANDS = {  # the command line before the input file, after it
    "render": (["render"], ["--size", "8x8", "-o", "{tmp}/x.png"]),
    "video": (["render"], ["--size", "8x8", "--frames", "2", "--video", "{tmp}/x.mp4"]),
    "view": (["view"], ["--frames", "1"]),
}


@pytest.fixture
def some_display(monkeypatch):
    """view checks for a display first: pretend there is one (no window is opened: every
    case here is refused before that)."""
    monkeypatch.setattr(display.window, "display_problem", lambda environ=None: None)


def bad_file(kind, tmp_path, tiny_pair):
    fit, solution = tiny_pair
    if kind == "missing":
        return tmp_path / "absent.npz", "not found"
    if kind == "text":
        (tmp_path / "notes.npz").write_text("not an archive")
        return tmp_path / "notes.npz", "is not a fit.npz or a solution.npz"
    if kind == "other npz":
        import numpy as np

        np.savez(tmp_path / "other.npz", a=np.zeros(3))
        return tmp_path / "other.npz", "is not a fit.npz or a solution.npz"
    if kind == "directory":
        (tmp_path / "dir.npz").mkdir()
        return tmp_path / "dir.npz", "is a directory"
    raise ValueError(kind)


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("kind", ["missing", "text", "other npz", "directory"])
def test_a_bad_input_file_is_refused(command, kind, tiny_pair, tmp_path, cli, no_gl, some_display):
    path, fragment = bad_file(kind, tmp_path, tiny_pair)
    before, after = COMMANDS[command]
    after = [a.format(tmp=tmp_path) for a in after]
    assert_refused(cli(*before, path, *after), repr(str(path)), fragment)
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "x.mp4").exists()


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_the_solution_flag_takes_a_solution_next_to_a_fit(command, tiny_pair, tmp_path, cli, no_gl, some_display):
    fit, solution = tiny_pair
    before, after = COMMANDS[command]
    after = [a.format(tmp=tmp_path) for a in after]
    assert_refused(cli(*before, fit, "--solution", fit, *after), "--solution", "is a fit.npz, not a solution.npz")
    assert_refused(cli(*before, solution, "--solution", solution, *after), "--solution goes next to a fit.npz")
    path, fragment = bad_file("missing", tmp_path, tiny_pair)
    assert_refused(cli(*before, fit, "--solution", path, *after), "--solution", fragment)


@pytest.mark.parametrize("case", ["swapped", "two fits", "two solutions", "missing fit", "text solution", "directory"])
def test_compare_takes_a_fit_then_its_solution(case, tiny_pair, tmp_path, cli, no_gl):
    fit, solution = tiny_pair
    args, fragments = {
        "swapped": ((solution, fit), ["wrong way round", "is a solution.npz", "give the fit.npz first"]),
        "two fits": ((fit, fit), ["the solution", "is a fit.npz, not a solution.npz"]),
        "two solutions": ((solution, solution), ["the fit", "is a solution.npz, not a fit.npz"]),
        "missing fit": ((tmp_path / "absent.npz", solution), ["the fit", "not found"]),
        "text solution": ((fit, bad_file("text", tmp_path, tiny_pair)[0]), ["the solution", "is not a fit.npz"]),
        "directory": ((tmp_path, solution), ["the fit", "is a directory"]),
    }[case]
    assert_refused(cli("compare", *args, "--out", tmp_path / "cmp"), *fragments, command="compare")
    assert not (tmp_path / "cmp").exists()


def test_view_checks_its_flags_before_reading(tiny_pair, tmp_path, cli, some_display, monkeypatch):
    import display.gl

    fit, _ = tiny_pair
    assert_refused(cli("view", fit, "--screenshot", tmp_path / "a.png"), "--screenshot", "--frames")
    assert_refused(cli("view", fit, "--frames", "1", "--screenshot", tmp_path / "a.jpg"), "must end in .png")
    assert_refused(cli("view", fit, "--frames", "1", "--screenshot", tmp_path / "nowhere" / "a.png"), "does not exist")
    monkeypatch.setattr(display.gl, "available_memory", lambda: 1_000_000)
    assert_refused(cli("view", fit, "--size", "400x300"), "--size 400x300 needs about")


@pytest.mark.parametrize("command", ["render", "compare", "view", "demo"])
def test_help_names_the_files_and_no_design_document(command, cli):
    code, out, _ = cli(command, "--help")
    assert code == 0
    assert not OUTSIDE.search(out), out
    if command != "demo":
        assert "fit.npz" in out and "solution.npz" in out


EXPOSURE_COMMANDS = {  # every display command with --exposure: the command line before the value
    "render": lambda fit, solution, tmp: ["render", fit, "--size", "8x8", "-o", tmp / "x.png"],
    "video": lambda fit, solution, tmp: ["render", fit, "--size", "8x8", "--frames", "2", "--video", tmp / "x.mp4"],
    "compare": lambda fit, solution, tmp: ["compare", fit, solution, "--size", "8x8", "--out", tmp / "cmp"],
    "view": lambda fit, solution, tmp: ["view", fit, "--frames", "1"],
    "truth": lambda fit, solution, tmp: ["truth", solution, "--size", "8x8", "--spp", "2", "--hdr", tmp / "x.npy"],
}


@pytest.mark.parametrize("command", sorted(EXPOSURE_COMMANDS))
@pytest.mark.parametrize("value", ["inf", "-inf", "nan", "0", "-1"])
def test_an_exposure_that_is_not_a_positive_finite_number_is_refused(command, value, tiny_pair, tmp_path, cli, no_gl,
                                                                       some_display):
    fit, solution = tiny_pair
    argv = EXPOSURE_COMMANDS[command](fit, solution, tmp_path)
    assert_refused(cli(*argv, f"--exposure={value}"), "--exposure must be a positive finite number", f"got {value}")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_every_display_command_with_an_exposure_is_tested():
    from display.cli import build_parser

    subparsers = next(a for a in build_parser()._actions if a.dest == "command")
    with_exposure = {name for name, parser in subparsers.choices.items()
                     if any("--exposure" in action.option_strings for action in parser._actions)}
    assert with_exposure == set(EXPOSURE_COMMANDS) - {"video"}
