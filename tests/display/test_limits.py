"""Image sizes: beyond the GL context's limits refused with the limit, beyond the free
memory refused with the estimate; in one line, before any picture is drawn."""

from types import SimpleNamespace

import pytest
from display_fixtures import assert_refused, listing

import display.gl
from display.gl import (
    COMPARE_BYTES_PER_PIXEL,
    RENDER_BYTES_PER_PIXEL,
    available_memory,
    check_image_memory,
    check_image_size,
    image_limits,
)
from radiosity.formats import InputError

FAKE = SimpleNamespace(info={"GL_MAX_TEXTURE_SIZE": 4096, "GL_MAX_RENDERBUFFER_SIZE": 8192,
                             "GL_MAX_VIEWPORT_DIMS": (16384, 2048)})


def test_the_smallest_limit_of_each_axis_is_named():
    assert image_limits(FAKE) == ((4096, "GL_MAX_TEXTURE_SIZE"), (2048, "GL_MAX_VIEWPORT_DIMS"))
    check_image_size(FAKE, 4096, 2048)  # at the limits: fine
    with pytest.raises(InputError, match=r"--size 4097x10: .* at most 4096 pixels wide \(GL_MAX_TEXTURE_SIZE = 4096\)"):
        check_image_size(FAKE, 4097, 10)
    with pytest.raises(InputError, match=r"at most 2048 pixels high \(GL_MAX_VIEWPORT_DIMS = 2048\)"):
        check_image_size(FAKE, 10, 2049)


@pytest.mark.gl
def test_a_real_context_has_limits(gl_context):
    (width, _), (height, _) = image_limits(gl_context)
    assert width >= 1024 and height >= 1024  # OpenGL 3.3 guarantees at least 1024


def small_limits(monkeypatch, side=32):
    monkeypatch.setattr(display.gl, "image_limits", lambda ctx: ((side, "GL_MAX_TEXTURE_SIZE"), (side, "GL_MAX_TEXTURE_SIZE")))


@pytest.mark.gl
@pytest.mark.parametrize("command", ["render", "video", "compare"])
def test_sizes_beyond_the_context_are_refused(command, tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    small_limits(monkeypatch)
    fit, solution = tiny_pair
    argv = {
        "render": ["render", fit, "-o", tmp_path / "a.png"],
        "video": ["render", fit, "--frames", "2", "--video", tmp_path / "a.mp4"],
        "compare": ["compare", fit, solution, "--out", tmp_path / "cmp"],
    }[command]
    assert_refused(cli(*argv, "--size", "64x16"), "--size 64x16", "at most 32 pixels wide", "GL_MAX_TEXTURE_SIZE = 32")
    assert listing(tmp_path) == []


@pytest.mark.gl
def test_the_renderer_refuses_too(tiny_pair, monkeypatch, gl_context):
    from display.camera import framing_view
    from display.renderer import Renderer
    from fitting import load_fit

    small_limits(monkeypatch, 16)
    renderer = Renderer(gl_context, fit=load_fit(tiny_pair[0]))
    view = framing_view(*renderer.bounds, 8, 20)
    with pytest.raises(InputError, match="image 8x20: .* at most 16 pixels high"):
        renderer.render(view)
    renderer.release()


@pytest.mark.gl
def test_the_demo_refuses_before_the_solve(tmp_path, cli, monkeypatch, gl_context):
    small_limits(monkeypatch)

    def no_solve(*_args, **_kwargs):
        raise AssertionError("the solve started")

    import radiosity.transport.solve

    monkeypatch.setattr(radiosity.transport.solve, "solve", no_solve)
    assert_refused(cli("demo", "--size", "33x8", "--out", tmp_path / "demo"), "at most 32 pixels wide")
    assert listing(tmp_path) == []


def test_available_memory_is_known_here():
    free = available_memory()
    assert free is None or free > 0


def test_memory_estimate():
    assert check_image_memory(100, 10) == 1000 * RENDER_BYTES_PER_PIXEL
    with pytest.raises(InputError, match=r"--size 100000x100000 needs about .* GB .* free"):
        check_image_memory(100_000, 100_000, flag="--size")  # 1.6 TB: more than any machine here


@pytest.mark.gl
@pytest.mark.parametrize("command, per_pixel", [("render", RENDER_BYTES_PER_PIXEL), ("video", RENDER_BYTES_PER_PIXEL),
                                                ("compare", COMPARE_BYTES_PER_PIXEL), ("demo", COMPARE_BYTES_PER_PIXEL)])
def test_sizes_beyond_the_free_memory_are_refused(command, per_pixel, tiny_pair, tmp_path, cli, monkeypatch, gl_context):
    monkeypatch.setattr(display.gl, "available_memory", lambda: 1_000_000)
    fit, solution = tiny_pair
    argv = {
        "render": ["render", fit, "-o", tmp_path / "a.png"],
        "video": ["render", fit, "--frames", "2", "--video", tmp_path / "a.mp4"],
        "compare": ["compare", fit, solution, "--out", tmp_path / "cmp"],
        "demo": ["demo", "--out", tmp_path / "demo"],
    }[command]
    estimate = f"{200 * 100 * per_pixel / 1e6:.1f} MB"
    assert_refused(cli(*argv, "--size", "200x100"), "--size 200x100", f"needs about {estimate}", "only 1.0 MB is free")
    assert listing(tmp_path) == []


def test_sizes_must_be_positive(tiny_pair, cli, no_gl):
    assert_refused(cli("render", tiny_pair[0], "--size", "0x10"), "at least 1x1")
