"""The WebGL walkthrough (display/web, written by ``vlights export``) in a real browser.

Headless Debian chromium renders WebGL2 through SwiftShader; Playwright for Python drives
it. The page's screenshot at a camera given in the URL must equal ``vlights render
--shading pixel -o`` at the same camera within 2/255 on average, for directional and
point lights, coefficients shared and per light, fitted and diffuse-only, for a
version 3 fit (the emitters' highlights from a sphere and a polygon, reflection probes)
with everything drawn and with each part off (``off=``, ``--off``), and for textured
objects (an export of version 3); keys must switch what it shows. Skipped where chromium or Playwright is missing (the test set-up,
``tests/install_browser``, installs chromium where apt can).
"""

import importlib.util
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from display_fixtures import lit_model
from PIL import Image
from test_export import DELTA_LAMPS, LAMPS, glossy_model, microfacet_model, own_parts_model, rewrite_json
from test_export_textures import KDS, textured_model

from display.export import PAGE, SHADERS, SHADING, WEB, page_files, page_source, shading_module
from display.serve import start

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
BROWSER_FLAGS = [
    "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox",
    "--force-color-profile=srgb", "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run",
]
SIZE = (160, 120)
VIEW = {"eye": (0.3, 0.2, -1.9), "look": (0.0, 0.05, 0.0), "up": (0.0, 1.0, 0.0), "fov": 50.0}
IMPORT = re.compile(r"""^(?:import|export|\})[^'"\n;]*?\bfrom\s*['"]([^'"]+)['"]""", re.M)  # module specifiers
EXPOSURE = 0.2  # the test scene's colours reach 3, and its highlights more: almost no pixel is white

_no_browser = pytest.mark.skipif(
    CHROMIUM is None or importlib.util.find_spec("playwright") is None,
    reason="needs chromium (apt-get install chromium) and playwright (pip install playwright)",
)


def needs_browser(test):
    """A test in chromium: marked ``browser`` (``-m "not browser"`` leaves them out), and
    skipped where chromium or Playwright is missing."""
    return pytest.mark.browser(_no_browser(test))


def test_page_files_resolve_every_import():
    """Every module the page loads, through the import map or a relative path, and every
    shader file it fetches are among the files export copies: the exported directory
    works with no network."""
    files = {str(p) for p in page_files()} | {SHADING}  # shading.js is written by export itself
    assert {PAGE, "walkthrough.js", "three/LICENSE", "three/build/three.module.js", "three/build/three.core.js"} <= files
    html = (WEB / PAGE).read_text()
    imports = dict(re.findall(r'"(three[^"]*)":\s*"\./([^"]+)"', html))
    assert imports == {"three": "three/build/three.module.js", "three/addons/": "three/examples/jsm/"}
    pending, seen = ["walkthrough.js"], set()
    while pending:
        name = pending.pop()
        if name in seen:
            continue
        seen.add(name)
        assert name in files, f"{name} is imported but not exported"
        if name == SHADING:
            continue
        for spec in IMPORT.findall((WEB / name).read_text()):
            if spec == "three":
                target = imports["three"]
            elif spec.startswith("three/addons/"):
                target = imports["three/addons/"] + spec[len("three/addons/"):]
            else:
                target = os.path.normpath(Path(name).parent / spec)
            pending.append(target)
    assert "three/examples/jsm/loaders/GLTFLoader.js" in seen and "three/build/three.core.js" in seen
    assert SHADING in seen
    script = (WEB / "walkthrough.js").read_text()
    fetched = set(re.findall(r"'(\w+\.glsl)'", script))
    assert {"es_header.glsl", "web_vertex.glsl", "fitted_fragment.glsl", "tonemap_fragment.glsl"} <= fetched
    pending = list(fetched)
    while pending:  # and every file they include
        name = pending.pop()
        assert f"{SHADERS}/{name}" in files, f"{name} is fetched but not exported"
        pending += re.findall(r'^#include "([^"]+)"', page_source(f"{SHADERS}/{name}").read_text(), re.M)


def test_every_glsl_function_is_defined_once():
    """The shader files hold one definition of each function (the web page, the window
    and the renderer all compile these files: no copy anywhere else)."""
    from display.glsl import SHADERS as SHADER_DIR
    from display.glsl import shader_files

    definition = re.compile(r"^(?:vec[234]|ivec3|float|int|bool|void)\s+(\w+)\s*\(", re.M)
    where = {}
    for name in shader_files():
        text = (SHADER_DIR / name).read_text()
        # a part compiled out (#ifdef VL_NO_...) defines a stub of the same function: count the real one
        text = re.sub(r"#ifdef VL_NO_\w+\n.*?#else\n", "", text, flags=re.S)
        for function in definition.findall(text):
            if function != "main":
                where.setdefault(function, []).append(name)
    assert {"shade", "lights_shade", "probe_term", "emitter_term", "tonemap", "lookup"} <= set(where)
    assert {f: files for f, files in where.items() if len(files) > 1} == {}
    for text in (WEB / "walkthrough.js").read_text(), (Path(__file__).parents[2] / "display" / "window.py").read_text():
        assert "pow(x, vec3(1.0 / 2.4))" not in text and "void main()" not in text  # no GLSL of their own


def test_shading_module_holds_the_renderers_defines():
    """The page compiles the renderer's shader files after the renderer's own #define
    lines: shading.js holds defines(nodes) verbatim, for the fit's emitter nodes, and the
    constants of the textures' layout."""
    from display.glsl import FLOAT_TEXTURE_WIDTH, TABLE_WIDTH, defines
    from fitting.probe import ALBEDO_POINTS

    for nodes, text in ((8, shading_module()), (8, shading_module(8)), (5, shading_module(5))):
        literal = re.search(r"export const DEFINES = (.*);\n", text).group(1)
        assert json.loads(literal) == defines(nodes)
        assert f"export const TEXTURE_WIDTH = {FLOAT_TEXTURE_WIDTH};" in text
        assert f"export const EMITTER_NODES = {nodes};" in text
        assert f"export const TABLE_WIDTH = {TABLE_WIDTH};" in text
        assert f"export const ALBEDO_POINTS = {ALBEDO_POINTS};" in text
    assert shading_module(5) != shading_module(8)


def test_exported_directory_has_the_page(tmp_path, cli, rng):
    glossy_model(True, rng, nodes=6).save(tmp_path / "fit.npz")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")
    assert code == 0, err
    for name in page_files():
        assert (tmp_path / "web" / name).read_bytes() == page_source(name).read_bytes()
    assert (tmp_path / "web" / SHADERS / "shade.glsl").exists()
    assert (tmp_path / "web" / SHADING).read_text() == shading_module(6)  # the fit's emitter nodes
    assert f"wrote {tmp_path / 'web' / PAGE}" in out
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "glb", "--no-page")
    assert code == 0 and sorted(p.name for p in (tmp_path / "glb").iterdir()) == ["scene.glb"]


def test_export_serve_refuses_no_page(tmp_path, cli, rng):
    lit_model(True, rng).save(tmp_path / "fit.npz")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web", "--no-page", "--serve")
    assert code == 2 and "--serve needs the page" in err and not (tmp_path / "web").exists()


def test_export_serve_port_in_use_writes_nothing(tmp_path, cli, rng):
    """The port is taken before the export is written: a busy port leaves no directory."""
    import socket

    lit_model(True, rng).save(tmp_path / "fit.npz")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web", "--serve", "--port", port)
    assert code == 2 and f"cannot serve on 127.0.0.1:{port}" in err and err.count("\n") == 1
    assert not (tmp_path / "web").exists()


def test_export_serve_prints_the_url_and_serves(tmp_path, rng):
    """``export --serve``: writes, prints the URL, serves the page, stops on Ctrl-C (130)."""
    lit_model(False, rng).save(tmp_path / "fit.npz")
    proc = subprocess.Popen(
        [sys.executable, "-m", "display", "export", str(tmp_path / "fit.npz"), "-o", str(tmp_path / "web"),
         "--serve", "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # a background job starts with it ignored
    )
    try:
        url = None
        deadline = time.monotonic() + 60
        while url is None and time.monotonic() < deadline:
            line = proc.stdout.readline()
            match = re.search(r"at (http://127\.0\.0\.1:\d+/)", line)
            url = match.group(1) if match else None
        assert url, proc.stderr.read() if proc.poll() is not None else "no URL printed"
        with urllib.request.urlopen(url + PAGE, timeout=10) as r:
            assert r.read() == (WEB / PAGE).read_bytes()
        with urllib.request.urlopen(url + "scene.glb", timeout=10) as r:
            assert r.headers["Content-Type"] == "model/gltf-binary" and r.read()[:4] == b"glTF"
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 130
    finally:
        if proc.poll() is None:
            proc.kill()


# ---------------------------------------------------------------------------- in chromium

@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None or importlib.util.find_spec("playwright") is None:
        pytest.skip("needs chromium and playwright")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=BROWSER_FLAGS)
        yield b
        b.close()


def exported_and_served(base):
    """Export ``base``/fit.npz with the ``vlights export`` command, serve it, and yield
    (fit.npz, the page's URL) while it is served: every page fixture's body."""
    out = subprocess.run([sys.executable, "-m", "display", "export", str(base / "fit.npz"), "-o", str(base / "web")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    with start(base / "web") as server:
        yield base / "fit.npz", server.url


@pytest.fixture(scope="module", params=["per-light", "shared"])
def site(request, tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny lit scene."""
    base = tmp_path_factory.mktemp(f"web-{request.param}")
    lit_model(request.param == "per-light", np.random.default_rng(11)).save(base / "fit.npz")
    yield from exported_and_served(base)


def open_page(browser, url, query, size=SIZE):
    page = browser.new_page(viewport={"width": size[0], "height": size[1]}, device_scale_factor=1)
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"{url}{PAGE}?overlay=0&{query}")
    page.wait_for_function("document.title === 'rendered' || document.title === 'error'", timeout=120_000)
    assert page.title() == "rendered", (page.evaluate("window.vlights && window.vlights.error"), errors)
    return page


def view_query(mode="fitted", exposure=EXPOSURE, view=VIEW):
    vec = lambda v: ",".join(repr(float(x)) for x in v)  # noqa: E731
    return (f"eye={vec(view['eye'])}&look={vec(view['look'])}&up={vec(view['up'])}&fov={view['fov']}"
            f"&mode={mode}&exposure={exposure}")


def screenshot(page):
    """The canvas as the browser composites it, (H, W, 3) float64 in 0..255."""
    return np.asarray(Image.open(io.BytesIO(page.locator("#view").screenshot())).convert("RGB"), np.float64)


def rendered(tmp_path, fit, mode="fitted", exposure=EXPOSURE, view=VIEW, size=SIZE, off=()):
    """``vlights render --shading pixel -o`` of the same camera (``off``: ``--off`` those
    parts), (H, W, 3) float64 in 0..255."""
    from display.cli import main

    out = tmp_path / f"render-{mode}-{exposure}-{'-'.join(off)}.png"
    code = main(["render", str(fit), "--shading", "pixel", "--mode", mode, "--exposure", str(exposure),
                 "--size", f"{size[0]}x{size[1]}", "-o", str(out), "--eye", *map(str, view["eye"]),
                 "--look-at", *map(str, view["look"]), "--up", *map(str, view["up"]), "--fov", str(view["fov"]),
                 *(["--off", *off] if off else [])])
    assert code == 0
    return np.asarray(Image.open(out).convert("RGB"), np.float64)


def wait_frames(page, after):
    page.wait_for_function(f"window.vlights.state().frames > {after}", timeout=60_000)


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("mode", ["fitted", "diffuse"])
def test_page_equals_render(browser, site, tmp_path, mode, gl_context):  # gl_context: skip where no EGL
    fit, url = site
    page = open_page(browser, url, view_query(mode))
    try:
        got = screenshot(page)
    finally:
        page.close()
    want = rendered(tmp_path, fit, mode)
    assert got.shape == want.shape == (SIZE[1], SIZE[0], 3)
    diff = np.abs(got - want)
    assert diff.mean() <= 2.0, diff.mean()
    assert np.mean(diff.max(axis=2) > 16) < 0.02  # only antialiased edges may differ by more
    # not vacuous: the scene fills the frame, and the lights show in the fitted mode
    assert np.mean(want.max(axis=2) > 10) > 0.8 and np.mean(want == 255) < 0.01
    if mode == "fitted":
        assert np.abs(want - rendered(tmp_path, fit, "diffuse")).mean() > 4.0


@needs_browser
@pytest.mark.gl
def test_keys_switch_mode_exposure_and_move(browser, site, tmp_path, gl_context):
    fit, url = site
    page = open_page(browser, url, view_query("fitted"))
    try:
        state = page.evaluate("window.vlights.state()")
        assert state["mode"] == "fitted" and state["frames"] >= 1
        page.keyboard.press("m")
        wait_frames(page, state["frames"])
        assert page.evaluate("window.vlights.state().mode") == "diffuse"
        diffuse = screenshot(page)
        page.keyboard.press("Equal")  # "+": exposure x 2
        wait_frames(page, page.evaluate("window.vlights.state().frames") - 1)
        assert page.evaluate("window.vlights.state().exposure") == pytest.approx(2 * EXPOSURE)
        brighter = screenshot(page)
        eye = np.array(page.evaluate("window.vlights.state().eye"))
        page.keyboard.down("w")
        page.wait_for_timeout(300)
        page.keyboard.up("w")
        moved = np.array(page.evaluate("window.vlights.state().eye"))
    finally:
        page.close()
    assert np.abs(diffuse - rendered(tmp_path, fit, "diffuse")).mean() <= 2.0
    assert np.abs(brighter - rendered(tmp_path, fit, "diffuse", 2 * EXPOSURE)).mean() <= 2.0
    forward = np.subtract(VIEW["look"], VIEW["eye"]) * [1, 0, 1]  # W walks level: along the view, across the up axis
    step = moved - eye
    assert np.linalg.norm(step) > 0.01
    assert np.dot(step, forward) > 0.999 * np.linalg.norm(step) * np.linalg.norm(forward)


@needs_browser
def test_page_reports_a_bad_file_and_a_bad_query(browser, site, tmp_path):
    _, url = site
    page = browser.new_page(viewport={"width": 64, "height": 64})
    try:
        for query, fragment in (("file=missing.glb", "missing.glb"), ("mode=reference", "mode: want fitted or diffuse"),
                                ("eye=1,2", "eye: want three numbers"),
                                ("off=probe,glare", "off: want parts among lights,probe,emitters, got 'glare'")):
            page.goto(f"{url}{PAGE}?{query}")
            page.wait_for_function("document.title === 'error' || document.title === 'rendered'", timeout=60_000)
            assert page.title() == "error"
            assert fragment in page.evaluate("window.vlights.error"), query
            assert fragment in page.locator("#status").inner_text()
    finally:
        page.close()


@needs_browser
def test_mouse_look_and_orbit(browser, site):
    """A click locks the pointer and moving the mouse turns the view about the up axis
    (the eye stays); O switches to orbiting, which keeps the distance to the target."""
    _, url = site
    page = open_page(browser, url, view_query("fitted"), size=(120, 90))
    try:
        camera = "window.vlights.walkthrough.camera"
        before = np.array(page.evaluate(f"{camera}.getWorldDirection(new {camera}.position.constructor()).toArray()"))
        eye = np.array(page.evaluate("window.vlights.state().eye"))
        page.mouse.click(60, 45)
        page.wait_for_function("window.vlights.walkthrough.walk.isLocked", timeout=10_000)
        page.mouse.move(100, 45, steps=4)
        page.wait_for_function(f"""(d) => {{ const v = {camera}.getWorldDirection(new {camera}.position.constructor());
                                         return Math.abs(v.x - d[0]) + Math.abs(v.z - d[2]) > 1e-3; }}""",
                               arg=before.tolist(), timeout=10_000)  # the view has turned
        after = np.array(page.evaluate(f"{camera}.getWorldDirection(new {camera}.position.constructor()).toArray()"))
        assert np.allclose(page.evaluate("window.vlights.state().eye"), eye)
        assert np.degrees(np.arccos(np.clip(before @ after, -1, 1))) > 1.0
        assert after[1] == pytest.approx(before[1], abs=1e-6)  # a turn about the up axis (y)
        page.keyboard.press("Escape")
        page.keyboard.press("o")
        target = np.array(page.evaluate("window.vlights.walkthrough.orbit.target.toArray()"))
        page.mouse.move(40, 45)
        page.mouse.down()
        page.mouse.move(90, 50, steps=5)
        page.mouse.up()
        page.wait_for_function("""(e) => { const p = window.vlights.state().eye;
                                           return Math.hypot(p[0] - e[0], p[1] - e[1], p[2] - e[2]) > 0.05; }""",
                               arg=eye.tolist(), timeout=10_000)  # the eye has moved
        orbited = np.array(page.evaluate("window.vlights.state().eye"))
    finally:
        page.close()
    assert np.linalg.norm(orbited - eye) > 0.05
    assert np.linalg.norm(orbited - target) == pytest.approx(np.linalg.norm(eye - target), rel=1e-4)


# ------------------------------------------------------- the scene camera's fov along its axis

AXIS_CAMERA = {"eye": [0.5, 0.25, -6.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_deg": 24.0,
               "fov_axis": "x", "width": 64, "height": 36}  # a Mitsuba-like sensor: fov along x of a 16:9 film


@pytest.fixture(scope="module")
def site_axis(tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny lit scene whose camera's fov is along x."""
    from radiosity.files.camera import Camera

    base = tmp_path_factory.mktemp("web-axis")
    lit_model(True, np.random.default_rng(11), camera=Camera(**AXIS_CAMERA)).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("size", [(160, 120), (90, 160)], ids=["wider", "taller"])
def test_the_page_keeps_the_scene_fov_along_its_axis_as_render_does(browser, site_axis, tmp_path, size, gl_context):
    from display.cli import main
    from radiosity.files.camera import fov_y_deg

    fit, url = site_axis
    page = open_page(browser, url, f"mode=fitted&exposure={EXPOSURE}", size=size)  # the start camera: the fit's
    try:
        got = screenshot(page)
        fov = page.evaluate("window.vlights.walkthrough.camera.fov")
    finally:
        page.close()
    assert fov == pytest.approx(fov_y_deg(24.0, "x", *size), rel=1e-9)
    out = tmp_path / "render.png"  # the renderer's default camera: the fit's, at --size
    assert main(["render", str(fit), "--shading", "pixel", "--mode", "fitted", "--exposure", str(EXPOSURE),
                 "--size", f"{size[0]}x{size[1]}", "-o", str(out)]) == 0
    want = np.asarray(Image.open(out).convert("RGB"), np.float64)
    assert got.shape == want.shape == (size[1], size[0], 3)
    diff = np.abs(got - want)
    assert diff.mean() <= 2.0, diff.mean()
    assert np.mean(diff.max(axis=2) > 16) < 0.02
    assert np.mean(want.max(axis=2) > 10) > 0.3  # not vacuous: the scene is in the frame
    page = open_page(browser, url, "fov=33", size=size)  # a fov in the URL is vertical
    try:
        assert page.evaluate("window.vlights.walkthrough.camera.fov") == 33
    finally:
        page.close()


# ------------------------------------------------------------------ version 3: emitters, probes

def assert_matches(got, want):
    """The screenshot test's tolerance: 2/255 on average, more only at a few edges."""
    assert got.shape == want.shape == (SIZE[1], SIZE[0], 3)
    diff = np.abs(got - want)
    assert diff.mean() <= 2.0, diff.mean()
    assert np.mean(diff.max(axis=2) > 16) < 0.02  # only antialiased edges may differ by more


@pytest.fixture(scope="module", params=["per-light", "shared"])
def site_v3(request, tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny scene as a version 3 fit."""
    base = tmp_path_factory.mktemp(f"web-v3-{request.param}")
    glossy_model(request.param == "per-light", np.random.default_rng(5)).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("off", [(), ("emitters",), ("probe",), ("lights",), ("emitters", "probe", "lights")],
                         ids=lambda off: "+".join(off) or "all")
def test_version_3_page_equals_render(browser, site_v3, tmp_path, off, gl_context):
    """The emitters' highlights, the probe and the lights drawn as ``vlights render``
    draws them, with everything on and with ``off=`` any of them (``--off``)."""
    fit, url = site_v3
    page = open_page(browser, url, view_query() + (f"&off={','.join(off)}" if off else ""))
    try:
        assert page.evaluate("window.vlights.state().off") == [p for p in ("lights", "probe", "emitters") if p in off]
        got = screenshot(page)
    finally:
        page.close()
    want = rendered(tmp_path, fit, off=off)
    assert_matches(got, want)
    assert np.mean(want.max(axis=2) > 10) > 0.8 and np.mean(want == 255) < 0.01
    if not off:  # not vacuous: each part shows on a good part of the picture
        for part in ("emitters", "probe", "lights"):
            without = rendered(tmp_path, fit, off=(part,))
            assert np.mean(np.abs(want - without).max(axis=2) > 8) > 0.05, part


@pytest.fixture(scope="module")
def site_v5(tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny scene as a version 5 fit: a sphere
    lamp and a panel, and a point light, a spot and a directional light (``DELTA_LAMPS``)."""
    base = tmp_path_factory.mktemp("web-v5")
    glossy_model(True, np.random.default_rng(9), lamps=LAMPS[:2] + DELTA_LAMPS).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
def test_version_5_delta_lights_page_equals_render(browser, site_v5, tmp_path, gl_context):
    """A point light's, a spot's and a directional light's highlights on the page as
    ``vlights render`` draws them; and they show (the emitters' highlights off, the
    picture changes where they are)."""
    fit, url = site_v5
    page = open_page(browser, url, view_query())
    try:
        got = screenshot(page)
    finally:
        page.close()
    want = rendered(tmp_path, fit)
    assert_matches(got, want)
    import dataclasses

    from fitting import load_fit

    model = load_fit(fit)
    assert [p.kind for p in model.emitters] == ["sphere", "polygon", "point", "point", "direction"]
    # the same fit without its delta parts: they show on a good part of the picture
    area = model.emitters[:2]
    objects = tuple(dataclasses.replace(o, highlight=dataclasses.replace(
        o.highlight, parts=area, visibility=o.highlight.visibility[:, :2])) for o in model.objects)
    dataclasses.replace(model, objects=objects, emitters=area).save(tmp_path / "area.npz")
    without = rendered(tmp_path, tmp_path / "area.npz")
    assert np.mean(np.abs(want - without).max(axis=2) > 8) > 0.05


def page_matches_render(browser, url, fit, tmp_path):
    """The page at ``url`` (no error reported) against ``vlights render`` of ``fit`` from the
    same view; returns the render."""
    page = open_page(browser, url, view_query())
    try:
        got = screenshot(page)
        assert page.evaluate("window.vlights.error") in (None, "")
    finally:
        page.close()
    want = rendered(tmp_path, fit)
    assert_matches(got, want)
    return want


@pytest.fixture(scope="module")
def site_v7(tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny scene as a version 8 fit whose
    highlights are microfacet lobes (``microfacet_model``: GGX gold, Beckmann satin)."""
    base = tmp_path_factory.mktemp("web-v7")
    microfacet_model(np.random.default_rng(13)).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
def test_version_7_microfacet_highlights_page_equals_render(browser, site_v7, tmp_path, gl_context):
    """Microfacet lobes' highlights (linearly transformed cosines, the lobe at a delta
    light's direction) on the page as ``vlights render`` draws them; and they are not
    the Phong stand-in's (the picture changes without the lobe)."""
    fit, url = site_v7
    want = page_matches_render(browser, url, fit, tmp_path)
    import dataclasses

    from fitting import load_fit

    model = load_fit(fit)
    assert model.version == 8
    phong = tuple(dataclasses.replace(o, highlight=dataclasses.replace(o.highlight, microfacet=None))
                  for o in model.objects)
    dataclasses.replace(model, objects=phong).save(tmp_path / "phong.npz")
    assert np.mean(np.abs(want - rendered(tmp_path, tmp_path / "phong.npz")).max(axis=2) > 8) > 0.05


@pytest.fixture(scope="module")
def site_v6(tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny scene as a version 6 fit: 40 small
    sphere lamps, each object drawing its own 16 (``own_parts_model``)."""
    base = tmp_path_factory.mktemp("web-v6")
    own_parts_model(np.random.default_rng(11)).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
def test_version_6_objects_own_parts_page_equals_render(browser, site_v6, tmp_path, gl_context):
    """Each object drawing its own emitter parts of a scene's 40 on the page as ``vlights
    render`` draws them; and they show (the emitters' highlights off, the picture changes)."""
    fit, url = site_v6
    want = page_matches_render(browser, url, fit, tmp_path)
    without = rendered(tmp_path, fit, off=("emitters",))
    assert np.mean(np.abs(want - without).max(axis=2) > 8) > 0.02


@needs_browser
@pytest.mark.gl
def test_version_3_diffuse_mode_is_the_emitted_colour(browser, site_v3, tmp_path, gl_context):
    fit, url = site_v3
    page = open_page(browser, url, view_query("diffuse"))
    try:
        got = screenshot(page)
    finally:
        page.close()
    want = rendered(tmp_path, fit, "diffuse")
    assert_matches(got, want)
    assert np.abs(want - rendered(tmp_path, fit, off=("emitters", "probe", "lights"))).max() == 0


@needs_browser
@pytest.mark.gl
def test_keys_1_2_3_switch_the_parts(browser, site_v3, tmp_path, gl_context):
    """1, 2, 3 switch the emitters' highlights, the probe, the lights off (and on again):
    each picture is ``vlights render --off`` of the parts off."""
    fit, url = site_v3
    page = open_page(browser, url, view_query())
    shots = []
    try:
        for key, off in (("1", ["emitters"]), ("2", ["probe", "emitters"]), ("3", ["lights", "probe", "emitters"]),
                         ("1", ["lights", "probe"])):
            frames = page.evaluate("window.vlights.state().frames")
            page.keyboard.press(key)
            wait_frames(page, frames)
            assert page.evaluate("window.vlights.state().off") == off, key
            shots.append((off, screenshot(page)))
        status = page.locator("#status").inner_text()
    finally:
        page.close()
    assert "off: lights, probe" in status and "1 2 3 emitters/probe/lights off/on" in status
    for off, got in shots:
        assert_matches(got, rendered(tmp_path, fit, off=tuple(off)))


@needs_browser
def test_page_reads_version_1_and_refuses_other_nodes(browser, site):
    """A version 1 file (no emitters, no probes) shows as its version 2; a file whose
    emitters need another quadrature than shading.js's is refused (export it again)."""
    from display.export import export_glb

    fit, url = site
    web = fit.parent / "web"
    shutil.copyfile(web / "scene.glb", web / "v1.glb")

    def to_version_1(header):
        extras = header["scenes"][0]["extras"]
        extras["version"] = 1
        for key in ("emitters", "emitter_nodes", "emitter_table"):
            del extras[key]

    rewrite_json(web / "v1.glb", to_version_1)
    (web / "nodes6.glb").write_bytes(export_glb(glossy_model(True, np.random.default_rng(1), nodes=6)))
    shots = []
    for name in ("scene.glb", "v1.glb"):
        page = open_page(browser, url, f"{view_query()}&file={name}")
        try:
            shots.append(screenshot(page))
        finally:
            page.close()
    assert np.array_equal(shots[0], shots[1])
    page = browser.new_page(viewport={"width": 64, "height": 64})
    try:
        page.goto(f"{url}{PAGE}?file=nodes6.glb")
        page.wait_for_function("document.title === 'error' || document.title === 'rendered'", timeout=60_000)
        assert page.title() == "error"
        assert "drawn with 6 nodes, this page's shading.js with 8" in page.evaluate("window.vlights.error")
    finally:
        page.close()


@needs_browser
@pytest.mark.gl
def test_the_page_compiles_the_renderers_shader_files(browser, site, gl_context):
    """Each stage the page compiles is the page's header, the renderer's #define lines and
    the renderer's own file with its includes resolved as display.glsl.resolve does
    (the fragment stage is the one of the renderer's per-pixel program, VL_TRIANGLE)."""
    from display.glsl import ES_HEADER, defines, read, resolve

    _, url = site
    page = open_page(browser, url, view_query("fitted"), size=(64, 48))
    try:
        for name in ("web_vertex.glsl", "fitted_fragment.glsl", "full_screen_vertex.glsl", "tonemap_fragment.glsl"):
            got = page.evaluate("async (name) => (await import('./walkthrough.js')).stageSource(name)", name)
            assert got == read(ES_HEADER) + defines(8) + resolve(name), name
    finally:
        page.close()


@needs_browser
@pytest.mark.parametrize("nodes", [1, 8, 32])
def test_the_shading_glsl_compiles_in_webgl2(browser, nodes):
    """The shading formula (shade.glsl and its includes, display.glsl.shade_glsl(nodes)),
    every part of it, after the page's header, is GLSL ES 3.00 that WebGL2 compiles and
    links (the fewest and the most emitter nodes)."""
    from display.glsl import ES_HEADER, read, shade_glsl

    fragment = ("#version 300 es\n" + read(ES_HEADER)
                + shade_glsl(nodes) + "\nin vec3 v;\nout vec4 f_colour;\n"
                "void main() { f_colour = vec4(shade(normalize(v), v, normalize(-v), v, v, v, ivec3(v), v), 1.0); }\n")
    vertex = "#version 300 es\nin vec3 p;\nout vec3 v;\nvoid main() { v = p; gl_Position = vec4(p, 1.0); }\n"
    page = browser.new_page()
    try:
        log = page.evaluate("""([vs, fs]) => {
            const gl = document.createElement('canvas').getContext('webgl2');
            if (!gl) return 'no webgl2';
            const program = gl.createProgram();
            for (const [type, source] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
                const shader = gl.createShader(type);
                gl.shaderSource(shader, source);
                gl.compileShader(shader);
                if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) return gl.getShaderInfoLog(shader);
                gl.attachShader(program, shader);
            }
            gl.linkProgram(program);
            return gl.getProgramParameter(program, gl.LINK_STATUS) ? 'ok' : gl.getProgramInfoLog(program);
        }""", [vertex, fragment])
    finally:
        page.close()
    assert log == "ok", log


# ------------------------------------------------------------------ version 3: textured objects

TEXTURED_CASES = {  # textured_model's arguments
    "per-light": {"per_light": True},  # the tile drawn with one vertex per triangle corner
    "shared": {"per_light": False},  # indexed
    "minified": {"per_light": False, "uv_scale": 10.0},  # about one texel a pixel and less: the mipmaps
    "half": {"per_light": True, "tiles": False},  # the tile untextured: both programs in one frame
}


@pytest.fixture(scope="module", params=list(TEXTURED_CASES))
def site_textured(request, tmp_path_factory):
    """(fit.npz, the served export's URL) of the tiny scene with its objects textured
    (``test_export_textures.textured_model``), as ``TEXTURED_CASES`` says."""
    base = tmp_path_factory.mktemp(f"web-textured-{request.param}")
    textured_model(rng=np.random.default_rng(3), **TEXTURED_CASES[request.param]).save(base / "fit.npz")
    yield from exported_and_served(base)


def with_textures(fit, tmp_path, name, change):
    """fit.npz with each textured object's texture replaced by ``change(texture)`` (None:
    untextured), saved as ``tmp_path/name``."""
    import dataclasses

    from fitting import load_fit

    model = load_fit(fit)
    objects = []
    for o in model.objects:
        texture = None if o.textured is None else change(o.textured.texture)
        objects.append(dataclasses.replace(o, textured=None if texture is None else dataclasses.replace(
            o.textured, texture=texture)))
    path = tmp_path / name
    dataclasses.replace(model, objects=tuple(objects)).save(path)
    return path


GRAZING = {"eye": (-1.3, 0.2, -0.3), "look": (1.0, 0.0, 0.0), "up": (0.0, 1.0, 0.0), "fov": 50.0}  # along the wall


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("mode, view", [("fitted", VIEW), ("diffuse", VIEW), ("fitted", GRAZING)],
                         ids=["fitted", "diffuse", "grazing"])
def test_textured_page_equals_render(browser, site_textured, tmp_path, mode, view, gl_context):
    """kd * texture(uv) / pi * E per pixel, as ``vlights render`` draws it (both modes
    add it); the image is the material's PNG, sampled with the GPU's one sRGB decode,
    repeating, mipmapped, v down the image as glTF has it. Not vacuous: the page is far
    from the same fit untextured, with its images upside down, left sRGB-encoded (read
    as linear) or decoded twice. Seen from the front and along the wall (the image
    minified across the view: mipmapped, no anisotropic filtering, as the renderer's)."""
    from fitting import load_fit

    fit, url = site_textured
    page = open_page(browser, url, view_query(mode, view=view))
    try:
        got = screenshot(page)
        textures = page.evaluate("""() => window.vlights.walkthrough.fit.scene.children.map((m) => {
            const t = m.material.uniforms.diffuse_texture?.value;
            if (!t) return [m.name, null];
            return [m.name, t.colorSpace, t.flipY, t.wrapS === t.wrapT ? t.wrapS : -1, t.minFilter, t.magFilter,
                    t.generateMipmaps, m.material.uniforms.texture_kd.value.toArray()];
        })""")
        constants = page.evaluate("""async () => { const THREE = await import('three');
            return [THREE.SRGBColorSpace, THREE.RepeatWrapping, THREE.LinearMipmapLinearFilter, THREE.LinearFilter]; }""")
    finally:
        page.close()
    srgb, repeat, mipmapped, linear = constants
    model = load_fit(fit)
    assert textures == [[o.name, srgb, False, repeat, mipmapped, linear, True, list(KDS[o.name])] if o.textured
                        else [o.name, None] for o in model.objects]
    want = rendered(tmp_path, fit, mode, view=view)
    assert_matches(got, want)
    filled = 0.8 if view is VIEW else 0.5  # along the wall, the background takes the left
    assert np.mean(want.max(axis=2) > 10) > filled and np.mean(want == 255) < 0.01
    from radiosity.physics.materials import srgb_to_linear
    from radiosity.physics.textures import linear_to_srgb8

    for name, change in (("untextured", lambda t: None), ("flipped", lambda t: t[::-1]),
                         ("encoded", lambda t: linear_to_srgb8(t) / np.float32(255)),
                         ("decoded twice", lambda t: srgb_to_linear(t).astype(np.float32))):
        other = rendered(tmp_path, with_textures(fit, tmp_path, f"{name}.npz", change), mode, view=view)
        assert np.abs(got - other).mean() > 2 * 2.0, name  # twice the tolerance: a page drawing it would fail


@needs_browser
@pytest.mark.gl
def test_a_textured_object_compiles_the_renderers_textured_program(browser, site_textured, gl_context):
    """A textured object's stages are the page's header, the renderer's #define lines with
    VL_TEXTURED (display.glsl.defines(extra=("VL_TEXTURED",))) and the renderer's files;
    the untextured program stays without it."""
    from display.glsl import ES_HEADER, defines, read, resolve

    _, url = site_textured
    page = open_page(browser, url, view_query("fitted"), size=(64, 48))
    try:
        for name in ("web_vertex.glsl", "fitted_fragment.glsl"):
            got = page.evaluate("async (name) => { const m = await import('./walkthrough.js'); "
                                "return m.stageSource(name, m.TEXTURED); }", name)
            assert got == read(ES_HEADER) + defines(8, extra=("VL_TEXTURED",)) + resolve(name), name
        shaders = page.evaluate("() => { const s = window.vlights.walkthrough.fit.shaders; "
                                "return [s.texturedVertex, s.texturedFragment, s.fittedFragment]; }")
        assert shaders[0] == read(ES_HEADER) + defines(8, extra=("VL_TEXTURED",)) + resolve("web_vertex.glsl")
        assert "\n#define VL_TEXTURED\n" in shaders[1] and "\n#define VL_TEXTURED\n" not in shaders[2]
    finally:
        page.close()


# ------------------------------------------------------------------ version 8: masks

@pytest.fixture(scope="module")
def site_masked(tmp_path_factory):
    """(fit.npz, the served export's URL) of a masked leaf (a random blocky mask) over an
    emitting floor and under an emitting ceiling: a version 9 fit, a version 8 export."""
    from test_masks_display import _leaf, _mask, _quad

    from fitting import FitOptions, fit
    from radiosity.files.solution import Solution

    base = tmp_path_factory.mktemp("web-masked")
    objects = (_leaf(_mask(np.random.default_rng(3)), True), _quad("floor", 0.0, 4.0, 1.0, True),
               _quad("ceiling", 2.0, 4.0, 0.5, False))
    fit(Solution(objects=objects, scene="leaf"), FitOptions.for_quality("draft")).save(base / "fit.npz")
    yield from exported_and_served(base)


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("side", ["front", "back"])
def test_version_8_masks_page_equals_render(browser, site_masked, tmp_path, side, gl_context):
    """A masked leaf on the page as ``vlights render`` draws it, from its front (the floor
    through its holes) and from its back (the ceiling through them, its back black
    elsewhere); and the mask shows (about half the leaf's pixels are holes)."""
    fit, url = site_masked
    view = ({"eye": (0.0, 1.9, 0.2), "look": (0.0, 0.0, 0.0), "up": (0.0, 0.0, -1.0), "fov": 90.0} if side == "front"
            else {"eye": (0.0, 0.3, 0.2), "look": (0.0, 2.0, 0.0), "up": (0.0, 0.0, -1.0), "fov": 90.0})
    page = open_page(browser, url, view_query(exposure=1.0, view=view))
    try:
        got = screenshot(page)
        assert page.evaluate("window.vlights.error") in (None, "")
    finally:
        page.close()
    want = rendered(tmp_path, fit, exposure=1.0, view=view)
    assert_matches(got, want)
    from display.export_reader import load_export

    model = load_export(fit.parent / "web" / "scene.glb")
    assert model.object("leaf").textured.opacity is not None
    dark = want.max(axis=2) < 20
    assert 0.1 < dark.mean() < 0.6  # the leaf's black, with holes
