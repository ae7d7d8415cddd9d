"""The WebGL page's texture limits (display/web/walkthrough.js): at load it checks every
object's textures (its lights, per-light coefficients, emitters' visibility, probe), the
emitter table and the environment's image against the GPU's MAX_TEXTURE_SIZE, and
refuses one too large in one line on the page naming the object and the limit, instead
of drawing it as zeros. The limit is the GPU's, or the query's ``maxtexture`` when
smaller (what a smaller GPU shows): the same check, on a lower number. The textures it
counts are those ``display.export_limits.object_textures`` counts for the export's
warning. Skipped where chromium or Playwright is missing (test_web's set-up).
"""

import dataclasses
import subprocess
import sys

import numpy as np
import test_web
from display_fixtures import lit_model
from test_web import PAGE, needs_browser, open_page, view_query

from display.export_limits import ObjectSizes, object_textures
from display.serve import start
from fitting import load_fit
from radiosity.physics.environment import EnvironmentLight

browser = test_web.browser  # chromium, once for this module (test_web's fixtures)
site = test_web.site  # the tiny lit scene exported, per-light and shared coefficients

GPU_LIMIT = "document.createElement('canvas').getContext('webgl2').getParameter(WebGL2RenderingContext.MAX_TEXTURE_SIZE)"


def load(browser, url, query):
    """A page of ``url`` with ``query`` once loaded: (page, its title)."""
    page = browser.new_page(viewport={"width": 64, "height": 48})
    page.goto(f"{url}{PAGE}?overlay=0&{query}")
    page.wait_for_function("document.title === 'rendered' || document.title === 'error'", timeout=120_000)
    return page, page.title()


@needs_browser
def test_the_limit_is_the_gpus_or_the_querys_if_smaller(browser, site):
    _, url = site
    page = open_page(browser, url, view_query())
    try:
        gpu = page.evaluate(GPU_LIMIT)
        assert gpu >= 4096 and page.evaluate("window.vlights.maxTexture") == gpu  # SwiftShader: 8192
    finally:
        page.close()
    page = open_page(browser, url, f"{view_query()}&maxtexture=4096")
    try:
        assert page.evaluate("window.vlights.maxTexture") == 4096
    finally:
        page.close()
    page = open_page(browser, url, f"{view_query()}&maxtexture={10 * gpu}")
    try:
        assert page.evaluate("window.vlights.maxTexture") == gpu  # never more than the GPU's
    finally:
        page.close()


@needs_browser
def test_an_object_whose_texture_is_too_large_is_refused_by_name(browser, site):
    """On a GPU of 2048 texels (WebGL2's least): the tile's per-light coefficients, in a
    texture 4096 wide, are refused in one line naming it and the limit, shown on the
    page (even without the overlay); shared coefficients need no such texture, and the
    same page draws."""
    fit, url = site
    tile = load_fit(fit).object("tile")
    page, title = load(browser, url, f"{view_query()}&maxtexture=2048")
    try:
        if tile.per_light:
            want = (f"object 'tile' needs a 4096 x 1 texture for its per-light coefficients ({len(tile.positions)} "
                    "vertices x 3 lights); this browser's textures are at most 2048 x 2048 (MAX_TEXTURE_SIZE), so it "
                    "cannot be drawn here")
            assert title == "error" and page.evaluate("window.vlights.error") == want
            status = page.locator("#status")
            assert status.is_visible() and status.inner_text() == f"error: {want}"
        else:
            assert title == "rendered" and page.evaluate("window.vlights.state().frames") >= 1
    finally:
        page.close()


@needs_browser
def test_an_environment_too_large_is_refused(browser, tmp_path):
    """The environment's image (16 x 9 texels) on a GPU of 12: refused, naming it; on one
    of 16, drawn."""
    rng = np.random.default_rng(5)
    env = EnvironmentLight.from_image(rng.uniform(0.1, 2, (9, 16, 3)).astype(np.float32), 1.0, np.eye(3), source="t")
    dataclasses.replace(lit_model(False, rng), environment=env).save(tmp_path / "fit.npz")
    out = subprocess.run([sys.executable, "-m", "display", "export", str(tmp_path / "fit.npz"), "-o",
                          str(tmp_path / "web")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    with start(tmp_path / "web") as server:
        page, title = load(browser, server.url, f"{view_query()}&maxtexture=12")
        try:
            assert title == "error"
            assert page.evaluate("window.vlights.error") == (
                "the scene needs a 16 x 9 texture for its environment; this browser's textures are at most 12 x 12 "
                "(MAX_TEXTURE_SIZE), so it cannot be drawn here")
        finally:
            page.close()
        page, title = load(browser, server.url, f"{view_query()}&maxtexture=16")
        page.close()
        assert title == "rendered"


@needs_browser
def test_a_bad_maxtexture_is_refused(browser, site):
    _, url = site
    for value in ("0", "2.5", "big"):
        page, title = load(browser, url, f"maxtexture={value}")
        try:
            assert title == "error"
            assert page.evaluate("window.vlights.error") == f"maxtexture: want a whole number >= 1, got '{value}'"
        finally:
            page.close()


CASES = [  # (the object's extras as the page reads them, V, P), Python's ObjectSizes of the same
    ({"lights": 20, "per_light": True}, 1_000_000, 0),
    ({"lights": 3, "per_light": False}, 10_000_000, 0),
    ({"lights": 0, "per_light": False}, 10, 0),
    ({"lights": 2, "per_light": True, "probe": {"size": 64}}, 250_000, 7),
    ({"lights": 1, "per_light": False}, 4096 * 4096 // 3 + 1, 3),
]


@needs_browser
def test_the_page_counts_the_textures_the_export_counts(browser, site):
    """walkthrough.js ``textureNeeds`` and ``display.export_limits.object_textures`` give the
    same textures (what, width, height) for the same object; and the page's refusal of the
    largest at 4096 (what a page may assume) names 4883 rows."""
    _, url = site
    page = open_page(browser, url, view_query())
    try:
        got = page.evaluate("""async (cases) => {
            const m = await import('./walkthrough.js');
            return cases.map(([info, v, p]) => m.textureNeeds(info, v, p).map((t) => [t.what, t.width, t.height]));
        }""", CASES)
        refusal = page.evaluate("""async () => {
            const m = await import('./walkthrough.js');
            const needs = m.textureNeeds({ lights: 20, per_light: true }, 1000000, 0);
            return [m.textureRefusal("object 'big'", needs, 4096).message, m.textureRefusal("object 'big'", needs, 4883)];
        }""")
    finally:
        page.close()
    for (info, v, p), textures in zip(CASES, got, strict=True):
        sizes = ObjectSizes("o", v, info["lights"], info["per_light"], p, info.get("probe", {}).get("size", 0), {})
        assert textures == [[t.what, t.width, t.height] for t in object_textures(sizes)]
    assert got[0][1] == ["its per-light coefficients (1,000,000 vertices x 20 lights)", 4096, 4883]
    assert refusal == ["object 'big' needs a 4096 x 4883 texture for its per-light coefficients (1,000,000 vertices "
                       "x 20 lights); this browser's textures are at most 4096 x 4096 (MAX_TEXTURE_SIZE), so it cannot "
                       "be drawn here", None]


def test_the_cases_hold_each_kind_of_texture():
    """Not vacuous: the cases above hold lights, per-light, visibility and probe textures."""
    kinds = {t.what.split(" (")[0] for info, v, p in CASES
             for t in object_textures(ObjectSizes("o", v, info["lights"], info["per_light"], p,
                                                  info.get("probe", {}).get("size", 0), {}))}
    assert {"its per-light coefficients", "its emitters' visibility", "its probe", "its 0 lights", "its 20 lights"} <= kinds
