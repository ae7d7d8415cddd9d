"""The environment (the light from outside the scene) on the WebGL page: where no object
is, the page draws it with the renderer's own background shaders from the image in
scene.glb (a version 4 export), and its screenshot must equal ``vlights render`` at the
same camera within test_web's tolerance (2/255 on average), over the whole picture and
over the background alone. The map is asymmetric (random texels), turned and scaled; the
views see it around the objects, and up near its pole across its seam, where a page
reading it upside down, mirrored, unturned or unscaled would fail. Skipped where chromium
or Playwright is missing (test_web's set-up).
"""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
import test_web
from display_fixtures import lit_model
from scipy.spatial.transform import Rotation
from test_web import assert_matches, needs_browser, open_page, rendered, screenshot, view_query

from display.serve import start
from fitting import load_fit
from radiosity.physics.environment import EnvironmentLight

TURN = Rotation.from_euler("xyz", [20, -70, 10], degrees=True).as_matrix()  # world from environment
SCALE = 1.3
browser = test_web.browser  # chromium, once for this module (test_web's fixture)


def sky(rng, rows=9, columns=16):
    """An asymmetric map: each texel its own random colour (0.1 .. 3, times SCALE at most
    3.9: under test_web's exposure 0.2 no pixel is white)."""
    return rng.uniform(0.1, 3.0, (rows, columns, 3)).astype(np.float32)


def _pole_view():
    """Looking up towards the environment's zenith (34 degrees off the view's centre)
    across its seam (u = 0, the environment's -z), fov 90: in world coordinates, through TURN."""
    look = TURN @ (np.array([0.0, 1.5, -1.0]) / np.sqrt(3.25))
    eye = np.array([0.3, 0.2, -1.9])
    return {"eye": tuple(eye), "look": tuple(eye + look), "up": tuple(TURN @ [0.0, 1.0, 0.0]), "fov": 90.0}


VIEWS = {
    "around": {"eye": (0.3, 0.2, -2.6), "look": (0.0, 0.05, 0.0), "up": (0.0, 1.0, 0.0), "fov": 60.0},  # the objects in the middle
    "pole": _pole_view(),  # the environment alone
}
CASES = [  # (environment kind: the site, mode, view)
    ("map", "fitted", "around"),
    ("map", "diffuse", "around"),
    ("map", "fitted", "pole"),
    ("constant", "fitted", "around"),
]


def environment(kind, rng):
    if kind == "constant":
        return EnvironmentLight.uniform([0.5, 1.0, 2.0], SCALE, TURN, source="test constant")
    return EnvironmentLight.from_image(sky(rng), SCALE, TURN, source="test map")


def with_environment(fit, tmp_path, name, env):
    """fit.npz with its environment replaced by ``env`` (None: none), saved as ``tmp_path/name``."""
    path = tmp_path / name
    dataclasses.replace(load_fit(fit), environment=env).save(path)
    return path


@pytest.fixture(scope="module")
def site_env(request, tmp_path_factory):
    """(kind, fit.npz, the served export's URL) of the tiny lit scene with an environment
    of ``kind`` (the parameter: "map" or "constant")."""
    base = tmp_path_factory.mktemp(f"web-environment-{request.param}")
    rng = np.random.default_rng(17)
    model = dataclasses.replace(lit_model(False, rng), environment=environment(request.param, rng))
    model.save(base / "fit.npz")
    out = subprocess.run([sys.executable, "-m", "display", "export", str(base / "fit.npz"), "-o", str(base / "web")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    with start(base / "web") as server:
        yield request.param, base / "fit.npz", server.url


@needs_browser
@pytest.mark.gl
@pytest.mark.parametrize("site_env, mode, view_name", CASES, indirect=["site_env"], scope="module",
                         ids=["-".join(case) for case in CASES])
def test_page_draws_the_environment_as_render(browser, site_env, tmp_path, mode, view_name, gl_context):
    kind, fit, url = site_env
    view = VIEWS[view_name]
    page = open_page(browser, url, view_query(mode, view=view))
    try:
        got = screenshot(page)
        texture = page.evaluate("""async () => {
            const THREE = await import('three');
            const b = window.vlights.walkthrough.background;
            const t = b.material.uniforms.environment.value;
            return { renderOrder: b.renderOrder, frustumCulled: b.frustumCulled, depthWrite: b.material.depthWrite,
                     depthFunc: b.material.depthFunc === THREE.LessEqualDepth, objects: window.vlights.walkthrough.fit.scene.children.indexOf(b),
                     type: t.type === THREE.FloatType, format: t.format === THREE.RGBAFormat, flipY: t.flipY,
                     wrap: [t.wrapS === THREE.RepeatWrapping, t.wrapT === THREE.ClampToEdgeWrapping],
                     filter: [t.minFilter === THREE.LinearFilter, t.magFilter === THREE.LinearFilter], mipmaps: t.generateMipmaps,
                     size: [t.image.width, t.image.height], rgba: Array.from(t.image.data.slice(0, 8)),
                     scale: b.material.uniforms.env_scale.value, rotation: b.material.uniforms.env_rotation.value.elements };
        }""")
    finally:
        page.close()
    env = load_fit(fit).environment
    h, w = env.image.shape[:2]
    assert texture == {"renderOrder": 2, "frustumCulled": False, "depthWrite": False, "depthFunc": True, "objects": 2,
                       "type": True, "format": True, "flipY": False, "wrap": [True, True], "filter": [True, True],
                       "mipmaps": False, "size": [w, h], "rgba": texture["rgba"], "scale": SCALE,
                       "rotation": texture["rotation"]}
    rgba = np.array(texture["rgba"], np.float32).reshape(-1, 4)
    assert np.array_equal(rgba[:, :3], env.image.reshape(-1, 3)[:len(rgba)]) and np.all(rgba[:, 3] == 1)  # row 0 first
    assert np.allclose(np.reshape(texture["rotation"], (3, 3)).T, TURN, atol=1e-7)  # three.js: column-major

    want = rendered(tmp_path, fit, mode, view=view)
    assert_matches(got, want)
    black = rendered(tmp_path, with_environment(fit, tmp_path, "none.npz", None), mode, view=view)
    background = np.abs(want - black).max(axis=2) > 0  # the pixels the environment shows in
    assert background.mean() > (0.95 if view_name == "pole" else 0.3)
    assert np.abs(got - want)[background].mean() <= 2.0
    assert np.mean(want == 255) < 0.01
    if view_name == "around":  # the objects hide it
        assert background.mean() < 0.9

    # not vacuous: a page that drew the map unturned, unscaled, upside down or mirrored would fail
    others = {"unscaled": dataclasses.replace(env, scale=1.0), "unturned": dataclasses.replace(env, rotation=np.eye(3))}
    if kind == "map":
        others["upside down"] = dataclasses.replace(env, image=env.image[::-1])
        others["mirrored"] = dataclasses.replace(env, image=env.image[:, ::-1])
    elif view_name == "around":
        others.pop("unturned")  # a constant environment looks the same turned
    for name, other in others.items():
        picture = rendered(tmp_path, with_environment(fit, tmp_path, f"{name}.npz", other), mode, view=view)
        assert np.abs(got - picture)[background].mean() > 2 * 2.0, name  # twice the tolerance


@needs_browser
@pytest.mark.parametrize("site_env", ["map"], indirect=True)
def test_environment_texture_falls_back_to_half_floats(browser, site_env):
    """Where the GPU cannot filter float32 textures, the image goes up as half floats
    (filterable in every WebGL2), each value within a half float's precision (three.js
    truncates), clamped to 65504; float32 where it can, exact."""
    _, _, url = site_env
    page = open_page(browser, url, view_query(), size=(32, 24))
    try:
        got = page.evaluate("""async () => {
            const THREE = await import('three');
            const { environmentTexture } = await import('./walkthrough.js');
            const rgb = new Float32Array([0.1, 1.5, 3.25, 1e6, 0, 70000]);
            const half = environmentTexture(rgb, 2, 1, false);
            const full = environmentTexture(rgb, 2, 1, true);
            return { half: [half.type === THREE.HalfFloatType, Array.from(half.image.data, THREE.DataUtils.fromHalfFloat)],
                     full: [full.type === THREE.FloatType, Array.from(full.image.data)] };
        }""")
    finally:
        page.close()
    assert got["full"] == [True, [float(np.float32(0.1)), 1.5, 3.25, 1.0, 1e6, 0.0, 70000.0, 1.0]]
    assert got["half"][0] is True
    half = np.array(got["half"][1])
    want = np.array([0.1, 1.5, 3.25, 1.0, 65504.0, 0.0, 65504.0, 1.0])
    assert np.allclose(half, want, rtol=2.0 ** -10, atol=0) and half[4] == half[6] == 65504.0


@needs_browser
@pytest.mark.parametrize("site_env", ["map"], indirect=True)
def test_the_background_is_the_renderers_shader_files(browser, site_env):
    """The background's stages are the page's header, the renderer's #define lines (with
    VL_REVERSED_Z where the page draws with reversed Z, as the renderer's) and the
    renderer's own background_vertex.glsl and background_fragment.glsl (display.glsl)."""
    from display.glsl import ES_HEADER, defines, read, resolve

    _, _, url = site_env
    page = open_page(browser, url, view_query(), size=(32, 24))
    try:
        got = page.evaluate("() => { const w = window.vlights.walkthrough, s = w.fit.shaders; "
                            "return [w.reversed, s.backgroundVertex, s.backgroundFragment]; }")
    finally:
        page.close()
    assert got[0]  # chromium has EXT_clip_control
    assert got[1:] == [read(ES_HEADER) + defines(8, extra=("VL_REVERSED_Z",)) + resolve(name)
                       for name in ("background_vertex.glsl", "background_fragment.glsl")]
