"""Outputs of render, compare and demo: refused before any work (no GL context made,
nothing written) when they cannot be written, and a write that fails half-way (a full
disk, Ctrl-C) leaves no file behind, in one line with exit status 2 (130 for Ctrl-C)."""

import errno
import os

import numpy as np
import pytest
from display_fixtures import assert_refused, listing, tiny_solution

from display.outputs import check_output_dir, staged_directory
from radiosity.files.atomic import OutputError
from radiosity.files.errors import InputError

ENOSPC = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

# flag -> (command line before the path, the output's name, the command)
OUTPUTS = {
    "-o": (["render", "{fit}", "--size", "8x8", "-o"], "x.png", "render"),
    "--hdr": (["render", "{fit}", "--size", "8x8", "--hdr"], "x.npy", "render"),
    "--video": (["render", "{fit}", "--size", "8x8", "--frames", "2", "--video"], "x.mp4", "render"),
    "compare --out": (["compare", "{fit}", "{solution}", "--size", "8x8", "--out"], "cmp", "compare"),
    "demo --out": (["demo", "--size", "8x8", "--out"], "demo", "demo"),
}


def command_line(flag, tiny_pair, path):
    head, _, _ = OUTPUTS[flag]
    fit, solution = tiny_pair
    return [a.format(fit=fit, solution=solution) for a in head] + [path]


def deny_writing(monkeypatch, directory):
    """Make ``directory`` read-only as far as the permission checks can tell: we run as
    root, for whom a chmod'ed directory is writable anyway, so what this checks is that
    the answer "not writable" is asked for and heeded before any work."""
    real = os.access

    def access(path, mode, *args, **kwargs):
        if os.path.abspath(os.fspath(path)) == os.path.abspath(directory) and mode & os.W_OK:
            return False
        return real(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)


@pytest.mark.parametrize("flag", sorted(OUTPUTS))
@pytest.mark.parametrize("case", ["parent is a file", "missing directory", "in the way", "read-only directory"])
def test_unwritable_outputs_are_refused_before_any_work(flag, case, tiny_pair, tmp_path, cli, no_gl, monkeypatch):
    _, name, command = OUTPUTS[flag]
    (tmp_path / "afile").write_text("x")
    if case == "parent is a file":
        path, fragment = tmp_path / "afile" / name, "is a file, not a directory"
    elif case == "missing directory":
        path, fragment = tmp_path / "nowhere" / name, "does not exist"
    elif case == "in the way":  # a directory where a file goes, a file where a directory goes
        path = tmp_path / name
        if name.endswith((".png", ".npy", ".mp4")):
            path.mkdir()
            fragment = "is a directory"
        else:
            path.write_text("x")
            fragment = "exists and is not a directory"
    else:
        (tmp_path / "ro").mkdir()
        deny_writing(monkeypatch, tmp_path / "ro")
        path, fragment = tmp_path / "ro" / name, "permission denied"
    before = listing(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert_refused(cli(*command_line(flag, tiny_pair, path)), flag.split()[-1], fragment, command=command)
    assert listing(tmp_path) == before


@pytest.mark.parametrize("flag", ["compare --out", "demo --out"])
def test_a_read_only_output_directory_is_refused(flag, tiny_pair, tmp_path, cli, no_gl, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    deny_writing(monkeypatch, out)
    assert_refused(cli(*command_line(flag, tiny_pair, out)), "--out", "permission denied")
    assert listing(tmp_path) == ["out"]


@pytest.mark.parametrize("flag", ["-o", "compare --out"])
def test_a_really_read_only_directory_is_refused(flag, tiny_pair, tmp_path, cli, no_gl):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as root: a read-only directory is writable anyway (see the monkeypatched test)")
        _, name, _ = OUTPUTS[flag]
        assert_refused(cli(*command_line(flag, tiny_pair, ro / name)), "permission denied")
        assert listing(ro) == []
    finally:
        ro.chmod(0o755)


def test_files_in_the_way_inside_an_output_directory(tiny_pair, tmp_path, cli, no_gl):
    fit, solution = tiny_pair
    (tmp_path / "cmp" / "figure6.png").mkdir(parents=True)
    assert_refused(cli("compare", fit, solution, "--out", tmp_path / "cmp"), "figure6.png", "is not a file")
    (tmp_path / "demo").mkdir()
    (tmp_path / "demo" / "cornell-teapot").write_text("x")  # where the demo puts a scene's directory
    assert_refused(cli("demo", "--out", tmp_path / "demo"), "cornell-teapot", "is a file")


def test_an_input_is_never_an_output(tiny_pair, tmp_path, cli, no_gl):
    fit, solution = tiny_pair
    assert_refused(cli("render", fit, "--hdr", fit), "--hdr", "must end in .npy")
    copy = tmp_path / "compare.json"  # a fit named like one of compare's outputs
    copy.write_bytes(fit.read_bytes())
    assert_refused(cli("compare", copy, solution, "--out", tmp_path), "would destroy the input")


def test_check_output_dir_creates_nothing(tmp_path):
    assert check_output_dir(tmp_path / "new") == tmp_path / "new"
    assert not (tmp_path / "new").exists()
    with pytest.raises(InputError, match="does not exist"):
        check_output_dir(tmp_path / "a" / "b")


# -- failures half-way -------------------------------------------------------------------


def test_staged_directory_moves_everything_in_at_the_end(tmp_path):
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (out / "old.txt").write_text("kept")
    (out / "a.txt").write_text("old")
    with staged_directory(out) as stage:
        (stage / "a.txt").write_text("new")
        (stage / "sub").mkdir()
        (stage / "sub" / "b.txt").write_text("b")
        (stage / "fresh").mkdir()
        (stage / "fresh" / "c.txt").write_text("c")
        assert not (out / "sub" / "b.txt").exists()  # nothing visible before the end
    assert listing(out) == ["a.txt", "fresh", "fresh/c.txt", "old.txt", "sub", "sub/b.txt"]
    assert (out / "a.txt").read_text() == "new" and (out / "old.txt").read_text() == "kept"


@pytest.mark.parametrize("failure", [ENOSPC, KeyboardInterrupt(), ValueError("bug")])
def test_staged_directory_leaves_nothing_on_failure(tmp_path, failure):
    fresh, existing = tmp_path / "fresh", tmp_path / "existing"
    existing.mkdir()
    (existing / "a.txt").write_text("old")
    for out in (fresh, existing):
        with pytest.raises(type(failure) if not isinstance(failure, OSError) else OutputError) as info:
            with staged_directory(out) as stage:
                (stage / "a.txt").write_text("new")
                raise failure
        if isinstance(failure, OSError):
            assert "No space left on device" in str(info.value) and ".partial" not in str(info.value)
    assert listing(tmp_path) == ["existing", "existing/a.txt"]
    assert (existing / "a.txt").read_text() == "old"


@pytest.mark.gl
def test_render_disk_full_leaves_neither_file(tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    from PIL import Image

    def full(*_args, **_kwargs):
        raise ENOSPC

    monkeypatch.setattr(Image.Image, "save", full)
    fit, _ = tiny_pair
    assert_refused(cli("render", fit, "--size", "8x8", "--hdr", tmp_path / "a.npy", "-o", tmp_path / "a.png"),
                   "cannot write", "a.png", "No space left on device", command="render")
    assert listing(tmp_path) == []  # the .npy was written first, and is gone with the .png


@pytest.mark.gl
def test_render_hdr_disk_full(tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    def full(file, array, *args, **kwargs):
        file.write(b"\x93NUMPY partial")
        raise ENOSPC

    monkeypatch.setattr(np, "save", full)
    fit, _ = tiny_pair
    assert_refused(cli("render", fit, "--size", "8x8", "--hdr", tmp_path / "a.npy"), "a.npy", "No space left on device")
    assert listing(tmp_path) == []


def failing_after(count, failure):
    """A stand-in for PIL's Image.save that saves ``count`` times, then raises ``failure``."""
    from PIL import Image

    real = Image.Image.save
    calls = []

    def save(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > count:
            raise failure
        return real(self, *args, **kwargs)

    return save


@pytest.mark.gl
@pytest.mark.parametrize("failure, status", [(ENOSPC, 2), (KeyboardInterrupt(), 130)])
def test_compare_failing_half_way_leaves_no_file(failure, status, tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    from PIL import Image

    fit, solution = tiny_pair
    monkeypatch.setattr(Image.Image, "save", failing_after(2, failure))  # figures 5, views 1 and 2, are written
    code, _, err = cli("compare", fit, solution, "--size", "16x12", "--out", tmp_path / "cmp")
    assert code == status and err.count("\n") == 1 and "Traceback" not in err, err
    if status == 2:
        assert "cmp/figure5_view3.png" in err and "No space left on device" in err and ".partial" not in err
    assert listing(tmp_path) == []  # not even the directory it made
    # into an existing directory: its old files stay as they were
    (tmp_path / "cmp").mkdir()
    (tmp_path / "cmp" / "compare.json").write_text("old")
    monkeypatch.setattr(Image.Image, "save", failing_after(2, failure))
    code, _, _ = cli("compare", fit, solution, "--size", "16x12", "--out", tmp_path / "cmp")
    assert code == status
    assert listing(tmp_path) == ["cmp", "cmp/compare.json"] and (tmp_path / "cmp" / "compare.json").read_text() == "old"


@pytest.mark.gl
def test_demo_disk_full_leaves_no_file(tmp_path, cli, monkeypatch, gl_context):
    import radiosity.transport.adaptive

    monkeypatch.setattr(radiosity.transport.adaptive, "solve_adaptive", lambda *args, **kwargs: tiny_solution())

    def full(*_args, **_kwargs):
        raise ENOSPC

    monkeypatch.setattr(np, "savez_compressed", full)
    code, out, err = cli("demo", "--size", "8x8", "--out", tmp_path / "demo")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "demo/cornell-teapot/solution.npz" in err and "No space left on device" in err and ".partial" not in err
    assert listing(tmp_path) == []


# -- the video ---------------------------------------------------------------------------

FAKE_FFMPEG = """#!/bin/sh
# stands for ffmpeg on a full disk: reads a little, writes part of the file, fails
for last; do :; done
head -c 100 > "$last"
echo "[out#0/mp4 @ 0x5555] Error writing trailer: No space left on device" >&2
echo "Conversion failed!" >&2
exit 1
"""


@pytest.mark.gl
def test_video_ffmpeg_failure_is_one_line_and_leaves_no_file(tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    import display.video

    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text(FAKE_FFMPEG)
    fake.chmod(0o755)
    monkeypatch.setattr(display.video, "_ffmpeg_exe", lambda: str(fake))
    out = tmp_path / "out"
    out.mkdir()
    fit, _ = tiny_pair
    assert_refused(cli("render", fit, "--size", "16x12", "--frames", "4", "--video", out / "walk.mp4"),
                   "cannot write", "walk.mp4", "ffmpeg: Error writing trailer: No space left on device")
    assert listing(out) == []


@pytest.mark.gl
@pytest.mark.parametrize("failure, status", [(ENOSPC, 2), (KeyboardInterrupt(), 130)])
def test_video_interrupted_stops_ffmpeg_and_leaves_no_file(failure, status, tiny_pair, tmp_path, cli, monkeypatch,
                                                          gl_context):
    import subprocess

    import display.video
    from display.renderer import Renderer

    real_render, calls = Renderer.render, []

    def render(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise failure
        return real_render(self, *args, **kwargs)

    started = []

    class Popen(subprocess.Popen):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            started.append(self)

    monkeypatch.setattr(Renderer, "render", render)
    monkeypatch.setattr(display.video.subprocess, "Popen", Popen)  # the module: other Popens are recorded too
    fit, _ = tiny_pair
    code, _, err = cli("render", fit, "--size", "16x12", "--frames", "6", "--video", tmp_path / "walk.mp4")
    assert code == status and err.count("\n") == 1 and "Traceback" not in err, err
    ffmpeg = [p for p in started if "rawvideo" in p.args]
    assert len(ffmpeg) == 1 and ffmpeg[0].poll() is not None  # ffmpeg is not left running
    assert listing(tmp_path) == []


@pytest.mark.gl
def test_video_of_odd_size(tiny_pair, tmp_path, cli, gl_context):
    import imageio.v2 as imageio

    fit, _ = tiny_pair
    code, out, err = cli("render", fit, "--size", "17x11", "--frames", "3", "--video", tmp_path / "odd.mp4")
    assert code == 0, err
    reader = imageio.get_reader(str(tmp_path / "odd.mp4"))
    assert reader.get_data(0).shape == (12, 18, 3)  # padded to even sides for H.264's yuv420p
    assert listing(tmp_path) == ["odd.mp4"]


def test_video_refuses_pictures_flags_too(tiny_pair, tmp_path, cli, no_gl):
    fit, _ = tiny_pair
    assert_refused(cli("render", fit, "--video", tmp_path / "a.mp4", "-o", tmp_path / "a.png"), "--video", "-o")
    assert listing(tmp_path) == []
