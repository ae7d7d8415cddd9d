"""The walkthrough window under a virtual X server (skipped where Xvfb is missing)."""

import os
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

pytestmark = [pytest.mark.gl, pytest.mark.skipif(shutil.which("Xvfb") is None, reason="Xvfb is not installed")]


@pytest.fixture(scope="module")
def x_display():
    """A virtual X server, ready when it says so: Xvfb -displayfd writes the display
    number it chose (a free one) to the pipe once it accepts connections."""
    read, write = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1024x768x24"], pass_fds=(write,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as ready:
        number = ready.readline().strip()  # "" if Xvfb ended without starting
    if not number.isdigit():
        proc.kill()
        proc.wait(timeout=10)
        pytest.fail(f"Xvfb did not start (exit status {proc.poll()})")
    yield f":{number}"
    proc.terminate()
    proc.wait(timeout=10)


def view(x_display, model, tmp_path, name, *extra):
    shot = tmp_path / f"{name}.png"
    env = dict(os.environ, DISPLAY=x_display)
    run = subprocess.run(
        ["vlights", "view", str(model), "--frames", "3", "--screenshot", str(shot), "--size", "160x120", *extra],
        capture_output=True, text=True, env=env, timeout=120,
    )
    assert run.returncode == 0, run.stderr[-800:]
    return np.asarray(Image.open(shot))


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_window_opens_draws_switches_mode_and_screenshots(x_display, tmp_path):
    import trimesh

    from fitting import FittedModel, FittedObject
    from fitting.model import directional

    s = trimesh.creation.icosphere(subdivisions=2)
    n = len(s.vertices)
    obj = FittedObject(
        name="ball", positions=np.asarray(s.vertices, np.float32), normals=np.asarray(s.vertex_normals, np.float32),
        faces=np.asarray(s.faces, np.int32), emitted=np.full((n, 3), 0.1, np.float32), specular=np.ones((n, 3), np.float32),
        light_pos=directional(np.array([[0.3, 0.5, 0.8]]) / np.linalg.norm([0.3, 0.5, 0.8])),
        light_rgb=np.array([[2.0, 1.5, 1.0]], np.float32), shininess=np.array([20.0], np.float32),
    )
    model_path = tmp_path / "fit.npz"
    FittedModel(objects=(obj,), source="").save(model_path)
    fitted = view(x_display, model_path, tmp_path, "fitted")
    assert fitted.shape == (120, 160, 3) and fitted.max() > 50  # not blank
    diffuse = view(x_display, model_path, tmp_path, "diffuse", "--press", "m")  # m: fitted -> diffuse
    assert not np.array_equal(fitted, diffuse)
    brighter = view(x_display, model_path, tmp_path, "bright", "--press", "++")
    assert brighter.astype(int).sum() > fitted.astype(int).sum()


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_window_draws_point_lights_with_per_light_coefficients(x_display, tmp_path):
    # version 2: a directional and two point lights, a coefficient per light; L (2 / all
    # lights) drops the third light, G switches to Gouraud
    import trimesh

    from fitting import FittedModel, FittedObject

    s = trimesh.creation.icosphere(subdivisions=3)
    n = len(s.vertices)
    specular = np.ones((n, 3, 3), np.float32)
    specular[:, 2] *= 3.0
    obj = FittedObject(
        name="ball", positions=np.asarray(s.vertices, np.float32), normals=np.asarray(s.vertex_normals, np.float32),
        faces=np.asarray(s.faces, np.int32), emitted=np.full((n, 3), 0.05, np.float32), specular=specular,
        light_pos=np.array([[0.0, 0.6, 0.8, 0.0], [1.2, 0.5, 1.5, 1.0], [-1.0, -0.6, 1.6, 1.0]], np.float32),
        light_rgb=np.array([[1.0, 0.8, 0.6], [0.6, 0.8, 1.0], [1.0, 0.3, 0.3]], np.float32),
        shininess=np.array([30.0, 60.0, 20.0], np.float32),
    )
    model_path = tmp_path / "fit.npz"
    FittedModel(objects=(obj,), source="").save(model_path)
    every = view(x_display, model_path, tmp_path, "all")
    two = view(x_display, model_path, tmp_path, "two", "--press", "l")
    gouraud = view(x_display, model_path, tmp_path, "gouraud", "--press", "g")
    no_lights = view(x_display, model_path, tmp_path, "nolights", "--press", "3")  # key 3: the lights off
    back_on = view(x_display, model_path, tmp_path, "backon", "--press", "33")
    assert every.max() > 50 and two.max() > 50 and gouraud.max() > 50
    assert two.astype(int).sum() < every.astype(int).sum()  # the third light's highlight is gone
    assert not np.array_equal(every, gouraud)
    assert no_lights.astype(int).sum() < two.astype(int).sum() and np.array_equal(back_on, every)


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_the_window_draws_antialiased_edges(x_display, tmp_path):
    # a white tile (radiance 1) on a black wall, its edges 2 degrees off the pixel columns:
    # with 4 samples a pixel the edge pixels lie between the two sides, with 1 they are one or the other
    from display_fixtures import tilted_tile_solution, tiny_fit

    model_path = tmp_path / "fit.npz"
    tiny_fit(tilted_tile_solution(0.0, 1.0, 2.0), lights=0).save(model_path)
    camera = ["--eye", "0", "0", "-5", "--look-at", "0", "0", "0", "--fov", "40"]
    between = {}
    for samples in ("4", "1"):
        shot = view(x_display, model_path, tmp_path, f"samples{samples}", *camera, "--samples", samples)
        below_status_line = shot[40:]
        assert below_status_line.max() == 255 and below_status_line.min() == 0
        between[samples] = int(((below_status_line > 0) & (below_status_line < 255)).any(axis=2).sum())
    assert between["1"] == 0
    assert between["4"] > 40  # some 140: the tile's edges below the status line


def test_view_without_a_display_says_so(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    run = subprocess.run(["vlights", "view", "nothing.npz"], capture_output=True, text=True, env=env, timeout=60)
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "display" in run.stderr


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_the_window_says_nothing_on_stderr(x_display, tiny_pair, tmp_path):
    # moderngl-window logs "moderngl_window - INFO - Context Version ..." unless told not to
    env = dict(os.environ, DISPLAY=x_display)
    shot = tmp_path / "shot.png"
    run = subprocess.run(["vlights", "view", str(tiny_pair[0]), "--frames", "2", "--size", "64x48", "--screenshot",
                          str(shot)], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0 and run.stderr == "", run.stderr[-800:]
    assert run.stdout.strip() == f"screenshot: {shot}" and Image.open(shot).size == (64, 48)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.png"]  # written atomically: no temporary left


FULL_DISK = """
import errno, os, sys
from PIL import Image

def full(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

Image.Image.save = full
from display.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_screenshot_on_a_full_disk_fails_the_run(x_display, tiny_pair, tmp_path):
    import sys

    env = dict(os.environ, DISPLAY=x_display)
    run = subprocess.run([sys.executable, "-c", FULL_DISK, "view", str(tiny_pair[0]), "--frames", "2", "--size", "64x48",
                          "--screenshot", str(tmp_path / "shot.png")], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr[-800:]
    assert "shot.png" in run.stderr and "No space left on device" in run.stderr
    assert list(tmp_path.iterdir()) == []


WINDOW_DEPTH = """
import moderngl
from display.gl import depth_control
ctx = moderngl.create_standalone_context()  # GLX on the X server of DISPLAY, as the window's
print(ctx.info["GL_VERSION"], depth_control(ctx) is not None)
"""


def test_a_glx_context_gets_clip_control(x_display):
    """The window's context is GLX's, not EGL's: ``display.gl.depth_control`` finds
    glClipControl through glXGetProcAddressARB there (Xvfb's Mesa has OpenGL 4.5)."""
    import sys

    env = dict(os.environ, DISPLAY=x_display)
    run = subprocess.run([sys.executable, "-c", WINDOW_DEPTH], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr[-800:]
    version, found = run.stdout.split()[0], run.stdout.split()[-1]
    assert found == ("True" if float(version) >= 4.5 else "False"), run.stdout


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_the_window_draws_sides_and_depth_right(x_display, tmp_path, scale):
    """test_depth's room (1 mm gaps, a two-sided partition, the walls seen from behind)
    in the window, which draws with the same renderer: the screenshot is the tone-mapped
    answer of the numpy ray caster within 1/255 at every pixel whose neighbours see one
    surface, below the status line."""
    from depth_scenes import casting, expected, interior, solution
    from depth_scenes import view as scene_view

    from display.renderer import tonemap

    sol, fit = solution(scale)
    fit.save(tmp_path / "fit.npz")
    for name in ("inside, the partition's back", "inside, the panel's gap", "outside, behind the back wall"):
        camera = scene_view(name, scale, (320, 240))
        flags = ["--eye", *map(repr, camera.eye), "--look-at", *map(repr, camera.look_at), "--up", "0", "1", "0",
                 "--fov", "60", "--samples", "1", "--size", "320x240"]
        got = view(x_display, tmp_path / "fit.npz", tmp_path, name.replace(" ", "-").replace(",", ""), *flags)
        want, what, front = expected(casting(sol), camera)
        checked = interior(what, front)
        checked[:40] = False  # the status line
        assert checked.mean() > 0.6, name
        diff = np.abs(got[..., :3].astype(int) - tonemap(want).astype(int)).max(axis=2)
        assert (diff[checked] <= 1).all(), (name, int((diff[checked] > 1).sum()))


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_the_window_keeps_the_scene_fov_along_its_axis_as_render_does(x_display, tmp_path):
    # the scene camera's fov along x of a 16:9 film, the window 4:3: the window draws what render draws
    from display_fixtures import lit_model

    from display.cli import main
    from radiosity.files.camera import Camera

    camera = Camera((0.5, 0.25, -6.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 24.0, 64, 36, "x")
    model_path = tmp_path / "fit.npz"
    lit_model(True, np.random.default_rng(11), camera=camera).save(model_path)
    shot = view(x_display, model_path, tmp_path, "axis").astype(np.float64)
    assert main(["render", str(model_path), "--size", "160x120", "-o", str(tmp_path / "render.png")]) == 0
    want = np.asarray(Image.open(tmp_path / "render.png").convert("RGB"), np.float64)
    diff = np.abs(shot[40:] - want[40:])  # below the status line
    assert diff.mean() <= 1.0 and np.mean(diff.max(axis=2) > 16) < 0.01, diff.mean()
    assert np.mean(want[40:].max(axis=2) > 10) > 0.3  # not vacuous: the scene is in the frame


@pytest.mark.skipif(shutil.which("vlights") is None, reason="the vlights entry point is not installed")
def test_the_window_draws_glass_as_render_does(x_display, tmp_path, gl_context):
    """A glass ball in a white environment: the window's screenshot (below its status line)
    is `vlights render`'s picture for each --glass, and the approaches differ."""
    from test_glass_display import _ball, _furnace, _opaque

    from display.renderer import Renderer, tonemap
    from fitting import FitOptions, fit
    from radiosity.files.camera import Camera

    solution = _furnace(_ball(), *_opaque())
    model = fit(solution, FitOptions.for_quality("draft"))
    model.save(tmp_path / "fit.npz")
    camera = Camera((0.0, 0.5, 4.0), (0.0, 0.0, 0.0), fov_deg=40, width=160, height=120)
    flags = ["--eye", "0", "0.5", "4", "--look-at", "0", "0", "0", "--up", "0", "1", "0", "--fov", "40", "--samples", "1"]
    shots = {}
    for approach in ("blend", "none"):
        got = view(x_display, tmp_path / "fit.npz", tmp_path, approach, *flags, "--glass", approach)[..., :3]
        renderer = Renderer(gl_context, fit=model, samples=1)
        renderer.glass_approach = approach
        want = tonemap(renderer.render(camera, "fitted"))
        renderer.release()
        diff = np.abs(got.astype(int) - want.astype(int)).max(axis=2)[40:]
        assert np.mean(diff <= 1) > 0.98, (approach, np.mean(diff <= 1))
        shots[approach] = got
    assert np.abs(shots["blend"].astype(int) - shots["none"].astype(int)).max() > 10
