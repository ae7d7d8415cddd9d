"""Stopping a run: Ctrl-C at any moment (start-up, solve, fit), SIGTERM and SIGHUP
while a file is being saved. One line, the right exit status, no traceback, and no
file (final or temporary) left behind.

Each signal is sent when the child shows it has reached the moment meant (a module
imported, a progress bar moving, a line on stderr), never after a guessed sleep:
the tests hold on a loaded machine and take no longer than the work does."""

import re
import signal
import sys
import textwrap
import time

import pytest
from child_process import Child, vlights

pytestmark = [pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals"), pytest.mark.subprocess]

SLOW_SAVE = textwrap.dedent(
    """
    import sys, threading
    import numpy as np
    real = np.savez_compressed
    def stalled_savez(file, *args, **kwargs):
        real(file, *args, **kwargs)   # the temporary file now holds data
        print("saving", file=sys.stderr, flush=True)
        threading.Event().wait(600)   # held here until the signal
    np.savez_compressed = stalled_savez
    from display.cli import main
    sys.exit(main(sys.argv[1:]))
    """
)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_during_the_save_leaves_no_file(tmp_path, signum):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    child = Child([sys.executable, "-c", SLOW_SAVE, "solve", "cornell", "--photons", "2000", "--max-edge", "400",
                   "-o", out_dir / "solution.npz"], terminal=False)
    child.wait_for(r"(?m)^saving\n")  # the whole line: the signal must not split it
    assert len(list(out_dir.iterdir())) == 1  # the temporary file, being written
    child.send(signum)
    code, _, err = child.finish(timeout=60)
    assert code == 128 + signum, err
    assert err.strip().splitlines()[-1] == f"vlights solve: stopped by {signal.Signals(signum).name}"
    assert "Traceback" not in err
    assert list(out_dir.iterdir()) == []


@pytest.mark.parametrize("module", ["numpy", "display.commands", "radiosity.cli"])
def test_ctrl_c_while_starting_up(module):
    """SIGINT as soon as ``module`` is imported (python -X importtime says so on stderr):
    early, midway and late in vlights' start-up."""
    child = Child(vlights("scene-info", "cornell-teapot"), terminal=False, python_flags=("-X", "importtime"))
    child.wait_for(rf"(?m)^import time:\s+\d+ \|\s+\d+ \| +{re.escape(module)}\n")
    child.send(signal.SIGINT)
    code, out, err = child.finish(timeout=60)
    said = [line for line in err.splitlines() if not line.startswith("import time:")]
    if code == 0 or (out.strip() and code == -signal.SIGINT):
        # done before the signal came, or it came as the interpreter was shutting down
        # after the command had printed everything (Python's own exit, not ours)
        pytest.skip(f"finished before the signal came (after {module})")
    assert code == 130, said
    assert "Traceback" not in err and len(said) == 1, said
    assert said[0] in ("vlights: interrupted while starting; nothing was written", "vlights: interrupted",
                       "vlights scene-info: interrupted")


@pytest.fixture(scope="module")
def small_solution(tmp_path_factory):
    from display.cli import main

    path = tmp_path_factory.mktemp("solution") / "solution.npz"
    assert main(["solve", "cornell-teapot", "--photons", "20000", "--gather-samples", "16", "--light-samples", "4",
                 "--grid", "8", "-o", str(path)]) == 0
    return path


@pytest.mark.parametrize("moment", [r"fit:\s+0%", r"\| *[1-9]\d*/\d+ \[", r"\w: 2 lights\]"])
def test_ctrl_c_during_fit(tmp_path, small_solution, moment):
    """SIGINT when the fit's progress bar shows ``moment``: at its start, once some objects
    are done (tqdm redraws at most every 0.1 s: the count may go from 0 to 2 at once), and
    inside the first glossy object's search for lights (its second light)."""
    out = tmp_path / "fit.npz"
    child = Child(vlights("fit", small_solution, "--lights", "8", "--iterations", "5000", "-o", out))
    child.wait_for(moment)
    child.send(signal.SIGINT)
    code, _, err = child.finish()
    if code == 0:
        pytest.skip(f"the fit finished after {moment!r} before the signal came")
    assert code == 130, err
    assert err.strip().splitlines()[-1] == "vlights fit: interrupted" and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("signum, status, said", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "stopped by SIGTERM")])
def test_stopping_the_path_tracer_leaves_no_file(tmp_path, signum, status, said):
    hdr, png = tmp_path / "truth.npy", tmp_path / "truth.png"
    child = Child(vlights("truth", "cornell", "--size", "256x256", "--spp", "100000", "--hdr", hdr, "-o", png))
    child.wait_for(r"path tracing:\s+\d+%\|[^\r\n]*\| *[1-9][\d.]*[kMG]?/")  # into the path tracing, some paths done
    child.send(signum)
    code, _, err = child.finish()
    assert code == status, err
    assert err.strip().splitlines()[-1] == f"vlights truth: {said}" and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_bar_caught_half_made_still_ends_its_line(capsys):
    """A signal inside tqdm's __init__ after its first draw and before its clock is set:
    its close() returns without ending the line it drew; the line is ended all the same,
    so "interrupted" is a line of its own (test_ctrl_c_during_fit at "fit: 0%" once saw
    the message glued to the bar, on loaded cores)."""
    from tqdm import tqdm

    from display.cli import _close_progress_bars

    half = tqdm.__new__(tqdm)  # registered in tqdm._instances; __init__ stopped after its draw
    half.disable, half.pos, half.sp = False, 0, print
    try:
        _close_progress_bars()
        assert capsys.readouterr().err == "\n"
    finally:
        tqdm._instances.discard(half)
    _close_progress_bars()  # no bar left: nothing written
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("signum, status, said", [(signal.SIGINT, 130, "vlights: interrupted"),
                                                  (signal.SIGTERM, 143, "vlights: stopped by SIGTERM")])
def test_a_signal_between_the_imports_and_the_commands_handler_is_one_line(monkeypatch, capsys, signum, status, said):
    """The entry point's own handler (KeyboardInterrupt carrying the signal's number)
    firing after the imports, before ``display.cli.main`` catches anything."""
    import display.__main__ as entry
    import display.cli

    def stopped(argv=None):
        raise KeyboardInterrupt(int(signum))

    monkeypatch.setattr(display.cli, "main", stopped)
    previous = signal.getsignal(signal.SIGTERM)  # the entry point installs its own
    try:
        assert entry.main(["scene-info", "cornell-teapot"]) == status
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert capsys.readouterr().err.strip().splitlines() == [said]


def test_an_import_that_a_ctrl_c_stopped_is_an_interruption(monkeypatch, capsys):
    """An extension module stopped by Ctrl-C while it is imported (scipy's, 1.6 s into
    ``vlights fit``) reports "ImportError: initialization failed" with no KeyboardInterrupt
    behind it: the signal handler remembers it, and the run ends as interrupted (130, one
    line), not in a traceback. An ImportError with no signal stays an error."""
    import argparse
    import os

    from display import cli

    def parser_with(func):
        parser = argparse.ArgumentParser(prog="vlights")
        sub = parser.add_subparsers(dest="command")
        sub.add_parser("fit").set_defaults(func=func)
        return lambda: parser

    def stopped_import(_args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt:  # what the extension's init does with it
            pass
        raise ImportError("initialization failed")

    # as in the command's own process (a test runner's worker may have set another handler)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        monkeypatch.setattr(cli, "build_parser", parser_with(stopped_import))
        assert cli.main(["fit"]) == 130
        assert capsys.readouterr().err == "vlights fit: interrupted\n"
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored
    finally:
        signal.signal(signal.SIGINT, before)

    def broken_import(_args):
        raise ImportError("no module named nowhere")

    monkeypatch.setattr(cli, "build_parser", parser_with(broken_import))
    with pytest.raises(ImportError):
        cli.main(["fit"])
