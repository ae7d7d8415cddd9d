"""Sides and depth on the WebGL page, against the numpy ray caster of test_depth's scenes
(``depth_scenes``: a 10 m room with 1 mm gaps and a two-sided partition, at scales 1e-3,
1 and 1e4, seen from inside and from outside).

The page draws as the renderer does: fronts, then backs black with a strict depth test;
reversed Z into a float depth buffer where the browser has EXT_clip_control (chromium
has), else the conventional range with a larger near plane. Its screenshot, one sample a
pixel, 640 x 480, must be the tone-mapped answer within 2/255 at every pixel whose
neighbours see the same surface. Why 640 x 480: chromium's SwiftShader snaps vertices to
1/16 of a pixel (SUBPIXEL_BITS 4; llvmpipe 1/256), which moves a surface seen at a slant
by 1/16 of its depth's change across a pixel: where a 96 x 72 picture looks along the
floor at the rug 1 mm above it, that is more than the gap, and 3.9 % of all the checked
pixels were wrong on the page, nearly all of them there (none in the renderer's); at
320 x 240 and 640 x 480 none. Skipped where chromium or Playwright is missing
(test_web's set-up).
"""

import functools
import io
import subprocess
import sys

import numpy as np
import pytest
import test_web
from depth_scenes import SKY, VIEWS, casting, expected, interior, solution, view
from PIL import Image
from test_web import needs_browser

from display.export import PAGE
from display.renderer import tonemap
from display.serve import start

SIZE = (640, 480)
browser = test_web.browser  # chromium, once for this module (test_web's fixture)
# The page without EXT_clip_control (as a browser without it): the extension hidden
NO_CLIP_CONTROL = """{
  const get = WebGL2RenderingContext.prototype.getExtension;
  WebGL2RenderingContext.prototype.getExtension = function (name) {
    return name === 'EXT_clip_control' ? null : get.call(this, name); };
  const supported = WebGL2RenderingContext.prototype.getSupportedExtensions;
  WebGL2RenderingContext.prototype.getSupportedExtensions = function () {
    return supported.call(this).filter((name) => name !== 'EXT_clip_control'); };
}"""


@pytest.fixture(scope="module", params=[(1e-3, False), (1.0, True), (1e4, False)],
                ids=["1e-3", "1-environment", "1e4"])
def room(request, tmp_path_factory):
    """(scale, environment, the solution, the served export's URL) of the room."""
    scale, environment = request.param
    sol, fit = solution(scale, environment)
    base = tmp_path_factory.mktemp("web-depth")
    fit.save(base / "fit.npz")
    out = subprocess.run([sys.executable, "-m", "display", "export", str(base / "fit.npz"), "-o", str(base / "web")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    with start(base / "web") as server:
        yield scale, environment, sol, server.url


def page_pictures(browser, url, scale, init_script=None):
    """{view: the page's screenshot (H, W, 3) float64 in 0..255} of every view of
    ``depth_scenes.VIEWS`` (one page, its camera set from the script between them), and
    whether the page drew with reversed Z."""
    first = view(next(iter(VIEWS)), scale, SIZE)
    page = browser.new_page(viewport={"width": SIZE[0], "height": SIZE[1]}, device_scale_factor=1)
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    if init_script:
        page.add_init_script(init_script)
    vec = lambda v: ",".join(repr(float(x)) for x in v)  # noqa: E731
    page.goto(f"{url}{PAGE}?overlay=0&samples=1&exposure=1&eye={vec(first.eye)}&look={vec(first.look_at)}"
              f"&up=0,1,0&fov={first.fov_y_deg}")
    page.wait_for_function("document.title === 'rendered' || document.title === 'error'", timeout=120_000)
    try:
        assert page.title() == "rendered", (page.evaluate("window.vlights && window.vlights.error"), errors)
        reversed_ = page.evaluate("window.vlights.walkthrough.reversed")
        shots = {}
        for name in VIEWS:
            camera = view(name, scale, SIZE)
            page.evaluate("""([eye, look, fov]) => { const w = window.vlights.walkthrough;
                w.start = { eye, look, up: [0, 1, 0], fov }; w.resetCamera(); w.frame(); }""",
                          [list(camera.eye), list(camera.look_at), camera.fov_y_deg])
            picture = Image.open(io.BytesIO(page.locator("#view").screenshot())).convert("RGB")
            shots[name] = np.asarray(picture, np.float64)
    finally:
        page.close()
    assert errors == []
    return shots, reversed_


@functools.cache
def answer(scale, environment, name):
    """``depth_scenes.expected`` of the room at ``scale`` seen from view ``name`` at SIZE
    (cast once for both tests)."""
    sol, _ = solution(scale, environment)
    return expected(casting(sol), view(name, scale, SIZE), SKY if environment else (0.0, 0.0, 0.0))


def wrong_on_the_page(shots, scale, environment):
    """{view: (wrong pixels, checked pixels)}: a checked pixel (its 3 x 3 neighbours see
    one surface from one side) is wrong beyond 2/255 of the tone-mapped answer."""
    counts = {}
    for name, got in shots.items():
        want, what, front = answer(scale, environment, name)
        checked = interior(what, front)
        assert got.shape == want.shape and checked.mean() > 0.8, name
        bad = checked & (np.abs(got - tonemap(want)).max(axis=2) > 2)
        counts[name] = (int(bad.sum()), int(checked.sum()))
    return counts


@needs_browser
def test_the_page_draws_the_nearest_front_with_reversed_depth(browser, room):
    scale, environment, sol, url = room
    shots, reversed_ = page_pictures(browser, url, scale)
    assert reversed_  # chromium has EXT_clip_control
    counts = wrong_on_the_page(shots, scale, environment)
    assert all(wrong == 0 for wrong, _ in counts.values()), counts
    # not vacuous: the back copy shows from behind, the wall from behind is black
    names = [o.name for o in sol.objects]
    _, what, front = answer(scale, environment, "inside, the partition's back")
    assert ((what == names.index("partition (back)")) & front).mean() > 0.3
    got = shots["outside, behind the back wall"]
    _, what, front = answer(scale, environment, "outside, behind the back wall")
    wall = interior(what, front) & (what == names.index("back"))
    assert wall.mean() > 0.3 and (got[wall] == 0).all()


@needs_browser
def test_the_page_without_clip_control_draws_them_too(browser, room):
    """A browser without EXT_clip_control: the conventional depth range into 24 bits,
    its near plane 1e-3 of the far one, the backs pushed back by a polygon offset (as
    the renderer without clip control), draws them right too."""
    scale, environment, _, url = room
    shots, reversed_ = page_pictures(browser, url, scale, NO_CLIP_CONTROL)
    assert not reversed_
    counts = wrong_on_the_page(shots, scale, environment)
    assert all(wrong == 0 for wrong, _ in counts.values()), counts


def test_the_page_mirrors_the_renderers_depth_constants():
    """walkthrough.js repeats display.renderer's near planes and back-face offset (the page
    draws the renderer's picture): the same numbers."""
    import re

    from display.export import WEB
    from display.renderer import BACK_FACE_OFFSET, NEAR_FRACTION

    script = (WEB / "walkthrough.js").read_text()
    near = re.search(r"const NEAR_FRACTION = \{ true: ([\d.e+-]+), false: ([\d.e+-]+) \};", script)
    offset = re.search(r"const BACK_FACE_OFFSET = \[([\d.e+-]+), ([\d.e+-]+)\];", script)
    assert near and offset
    assert (float(near[1]), float(near[2])) == (NEAR_FRACTION[True], NEAR_FRACTION[False])
    assert (float(offset[1]), float(offset[2])) == BACK_FACE_OFFSET
