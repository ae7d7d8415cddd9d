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
from radiosity.files.errors import InputError

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


LLVMPIPE = SimpleNamespace(max_samples=4, info={"GL_RENDERER": "llvmpipe (LLVM 15.0.6, 256 bits)",
                                                "GL_MAX_TEXTURE_SIZE": 16384, "GL_MAX_RENDERBUFFER_SIZE": 16384,
                                                "GL_MAX_VIEWPORT_DIMS": (16384, 16384)})


@pytest.mark.parametrize("size, samples, drawn, most", [
    (2048, 32, "6144x6144 image of 4 samples", 16), (2048, 64, "8192x8192", 16), (1500, 64, "6000x6000", 36),
    (4096, 16, "8192x8192", 4), (12000, 1, "12000x12000 image of 1 sample a pixel", 0),
])
def test_a_buffer_the_driver_refuses_is_refused_first(size, samples, drawn, most):
    """The sizes an adversarial sweep found that ended in "framebuffer incomplete": one line, with the
    most samples that fit."""
    from display.gl import check_samples

    with pytest.raises(InputError) as refused:
        check_samples(LLVMPIPE, samples, size, size)
    said = str(refused.value)
    assert said.startswith(f"--samples {samples} at {size}x{size} draws a {drawn}") and "2.1 GB or more" in said
    assert (f"use --samples {most} or fewer at this size" if most else "choose a smaller size") in said
    if most:
        check_samples(LLVMPIPE, most, size, size)  # the advice holds


@pytest.mark.parametrize("size, samples", [(2048, 16), (5792, 4), (4096, 4), (11584, 1), (1500, 36)])
def test_the_largest_buffers_that_fit_are_drawn(size, samples):
    from display.gl import check_samples

    assert check_samples(LLVMPIPE, samples, size, size).samples == samples


def test_the_limit_counts_what_the_driver_holds():
    """llvmpipe multisamples with 4 alone: 2 samples cost as much as 4 there."""
    from display.gl import MAX_BUFFER_BYTES, check_samples, held_samples, largest_buffer_bytes, sample_plan

    other = SimpleNamespace(max_samples=4, info={**LLVMPIPE.info, "GL_RENDERER": "another"})
    assert held_samples(LLVMPIPE, 2) == 4 and held_samples(other, 2) == 2 and held_samples(LLVMPIPE, 1) == 1
    with pytest.raises(InputError, match="6000x6000 image of 4 samples"):
        check_samples(LLVMPIPE, 2, 6000, 6000)
    check_samples(other, 2, 6000, 6000)
    # each side is rounded up to BUFFER_ALIGN: 5792 x 5793 is 5792 x 5824 in the driver's layout
    assert largest_buffer_bytes(sample_plan(4), 5792, 5792) < MAX_BUFFER_BYTES <= largest_buffer_bytes(sample_plan(4), 5792, 5793)


def test_a_framebuffer_the_driver_still_refuses_is_one_line():
    import moderngl

    from display.gl import framebuffer_refusals

    with pytest.raises(InputError, match=r"a 640x480 image with 8 samples per pixel \(the framebuffer is not complete"):
        with framebuffer_refusals((640, 480), 8):
            raise moderngl.Error("the framebuffer is not complete (INCOMPLETE_ATTACHMENT)")
    with pytest.raises(moderngl.Error, match="something else"), framebuffer_refusals((640, 480), 8):
        raise moderngl.Error("something else")


@pytest.mark.gl
@pytest.mark.parametrize("command", ["render", "compare"])
@pytest.mark.parametrize("size, samples", [(2048, 32), (2048, 64), (1500, 64), (4096, 16)])
def test_commands_refuse_a_buffer_too_large_before_any_work(command, size, samples, tiny_pair, tmp_path, cli,
                                                            gl_context):
    if "llvmpipe" not in gl_context.info["GL_RENDERER"]:
        pytest.skip("the sizes are llvmpipe's")
    fit, solution = tiny_pair
    argv = {"render": ["render", fit, "-o", tmp_path / "a.png"],
            "compare": ["compare", fit, solution, "--out", tmp_path / "cmp"]}[command]
    assert_refused(cli(*argv, "--size", f"{size}x{size}", "--samples", samples), f"--samples {samples} at {size}x{size}",
                   "or fewer at this size", command=command)
    assert listing(tmp_path) == []


@pytest.mark.slow
@pytest.mark.gl
def test_the_limit_is_the_drivers(gl_context):
    """On llvmpipe, MAX_BUFFER_BYTES is where the driver stops: the largest buffer just
    under it is made, the one just over it is not (each allocates and clears ~2 GB)."""
    import moderngl

    from display.gl import BUFFER_ALIGN, MAX_BUFFER_BYTES, largest_buffer_bytes, sample_plan

    if "llvmpipe" not in gl_context.info["GL_RENDERER"]:
        pytest.skip("the limit measured is llvmpipe's")
    free = available_memory()
    if free is not None and free < 3 * MAX_BUFFER_BYTES:
        pytest.skip("needs ~6 GB free")

    def made(side):
        colour = gl_context.renderbuffer((side, side), 4, samples=4, dtype="f4")
        try:
            gl_context.framebuffer(color_attachments=[colour]).release()
            return True
        except moderngl.Error:
            return False
        finally:
            colour.release()

    side = 5792  # 5792^2 x 4 samples x 16 bytes: just under 2 GiB
    assert largest_buffer_bytes(sample_plan(4), side, side) < MAX_BUFFER_BYTES and made(side)
    assert largest_buffer_bytes(sample_plan(4), side + 1, side + 1) >= MAX_BUFFER_BYTES and not made(side + 1)
    assert side % BUFFER_ALIGN == 0


@pytest.mark.gl
def test_a_framebuffer_refused_past_the_checks_is_one_line_and_no_file(tiny_pair, tmp_path, cli, monkeypatch,
                                                                       gl_context):
    """Were the buffer limit unknown (another driver), the driver's own refusal is still
    one line and exit 2, and nothing is written."""
    if "llvmpipe" not in gl_context.info["GL_RENDERER"]:
        pytest.skip("the size is llvmpipe's")
    monkeypatch.setattr(display.gl, "MAX_BUFFER_BYTES", 1 << 40)
    fit, _ = tiny_pair
    assert_refused(cli("render", fit, "--size", "2048x2048", "--samples", "32", "-o", tmp_path / "a.png"),
                   "cannot make the framebuffers of a 2048x2048 image with 32 samples", "not complete", command="render")
    assert listing(tmp_path) == []
