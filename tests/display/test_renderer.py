"""GPU output against numpy evaluations of the same formulas (float framebuffers).

The fitted model's programs are checked against ``fitting.model.shade_arrays``: Gouraud
through the vertex colours read back by transform feedback (shade at the vertices), per
pixel against shade at the interpolated position, normal and coefficients read back from
the same rasterisation (``render_attributes``). Tolerances: float32 on the GPU against
float64; pow(c, p) multiplies c's relative rounding by p (300 here), so 2e-4 relative
plus 1e-5 absolute (the colours are 0.1 to 30).

Pictures compared pixel by pixel with numpy are drawn with one sample per pixel
(``samples=1``: the pixel centres, where ``render_attributes`` reads what is
interpolated); antialiasing has its own tests (test_antialiasing.py).
"""

import json

import numpy as np
import pytest
import trimesh
from renderer_probes import ProbedRenderer

from display.renderer import tonemap
from fitting import FittedModel, FittedObject, load_fit, shade
from fitting.model import directional, shade_arrays
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.scene import geometry

pytestmark = pytest.mark.gl

MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 30.0, "emission": [0.0, 0.0, 0.0]}
RTOL, ATOL = 2e-4, 1e-5  # GPU float32 against numpy float64 (module docstring)


def random_lights(rng, kinds):
    """(K, 4) light_pos of ``kinds`` ("d" directional, "p" a point light 1.3 to 2.5 from
    the origin, in front of the view), unit directions with z > 0."""
    rows = []
    for kind in kinds:
        d = rng.normal(size=3)
        d[2] = abs(d[2]) + 0.3
        d /= np.linalg.norm(d)
        rows.append(np.append(d, 0.0) if kind == "d" else np.append(d * rng.uniform(1.3, 2.5), 1.0))
    return np.array(rows, np.float32).reshape(-1, 4)


def ball_model(rng, lights=3, kinds=None, per_light=False, shininess=(5.0, 40.0, 300.0)):
    """A unit icosphere; ``kinds`` a string of "d" and "p" (default: ``lights`` directional);
    ``per_light``: (V, K, 3) coefficients."""
    kinds = kinds or "d" * lights
    k = len(kinds)
    s = trimesh.creation.icosphere(subdivisions=3)
    positions = np.asarray(s.vertices, np.float32)
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    v = len(positions)
    obj = FittedObject(
        name="ball", positions=positions, normals=normals.astype(np.float32), faces=np.asarray(s.faces, np.int32),
        emitted=rng.uniform(0, 0.3, (v, 3)).astype(np.float32),
        specular=rng.uniform(0.2, 1.0, (v, k, 3) if per_light else (v, 3)).astype(np.float32),
        light_pos=random_lights(rng, kinds), light_rgb=rng.uniform(0.5, 3.0, (k, 3)).astype(np.float32),
        shininess=np.resize(np.float32(shininess), k),
    )
    return FittedModel(objects=(obj,), source="test")


def first_lights(obj, k):
    """``obj`` with only its first k lights (and their coefficients)."""
    specular = obj.specular[:, :k] if obj.per_light else obj.specular
    return FittedObject(name=obj.name, positions=obj.positions, normals=obj.normals, faces=obj.faces, emitted=obj.emitted,
                        specular=specular, light_pos=obj.light_pos[:k], light_rgb=obj.light_rgb[:k],
                        shininess=obj.shininess[:k])


VIEW = Camera(eye=(0.3, 0.4, 3.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=45.0, width=96, height=80)


def expected_pixels(renderer, obj, view, lights=None):
    """shade_arrays at each covered pixel's interpolated position, normal and coefficients."""
    position, normal, emitted, specular, covered = renderer.render_attributes(view)
    k = obj.n_lights if lights is None else min(lights, obj.n_lights)
    if specular.ndim == 4:
        specular = specular[:, :, :k]
    n = normal / np.linalg.norm(normal, axis=2, keepdims=True).clip(1e-12)
    w = np.asarray(view.eye) - position
    w /= np.linalg.norm(w, axis=2, keepdims=True).clip(1e-12)
    part = first_lights(obj, k)
    return shade_arrays(emitted, specular, n, position, part.lights, w), emitted, covered


def assert_pixels(renderer, obj, view, shading="pixel", lights=None, rtol=RTOL, atol=ATOL):
    image = renderer.render(view, "fitted", shading, lights)
    expected, emitted, covered = expected_pixels(renderer, obj, view, lights)
    assert np.isfinite(image).all()
    assert covered.sum() > 500 and (~covered).sum() > 100
    diff = np.abs(image[covered] - expected[covered])
    assert (diff <= rtol * np.abs(expected[covered]) + atol).all(), diff.max()
    assert (image[~covered] == 0).all()  # background 0
    return image, expected, emitted, covered


def assert_vertices(renderer, obj, view, lights=None, rtol=RTOL, atol=ATOL):
    got = renderer.vertex_colours(view, obj.name, "fitted", lights=lights)
    w = np.asarray(view.eye) - obj.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    k = obj.n_lights if lights is None else min(lights, obj.n_lights)
    expected = shade(FittedModel(objects=(first_lights(obj, k),)), obj.name, w)
    assert np.isfinite(got).all()
    assert np.allclose(got, expected, rtol=rtol, atol=atol), np.abs(got - expected).max()
    return got, expected


def test_fitted_per_pixel_equals_the_shading_formula(gl_context, rng):
    model = ball_model(rng)
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    assert_pixels(r, model.objects[0], VIEW)
    r.release()


def test_gouraud_vertex_colours_equal_shade_at_the_vertices(gl_context, rng):
    model = ball_model(rng)
    r = ProbedRenderer(gl_context, fit=model)
    o = model.objects[0]
    for lights in (None, 1, 2):
        assert_vertices(r, o, VIEW, lights)
    # and the rasterised Gouraud image stays within the vertex colours' range
    image = r.render(VIEW, "fitted", "gouraud")
    assert image.max() <= r.vertex_colours(VIEW, "ball", "fitted").max() * (1 + 1e-5)
    r.release()


def test_diffuse_mode_is_the_emitted_colour(gl_context, rng):
    model = ball_model(rng)
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "diffuse", "pixel")
    _, _, emitted, _, covered = r.render_attributes(VIEW)
    assert np.allclose(image[covered], emitted[covered], rtol=1e-6, atol=1e-7)
    assert (image[~covered] == 0).all()
    r.release()


# point lights, directional and point lights in one object, coefficients shared or per light
CASES = {"point": ("ppp", False), "mixed": ("dpdp", False), "per-light": ("ddd", True),
         "mixed per-light": ("pdpd", True), "point per-light": ("ppp", True)}


@pytest.mark.parametrize("case", list(CASES))
def test_point_lights_and_per_light_coefficients_per_pixel(gl_context, rng, case):
    kinds, per_light = CASES[case]
    model = ball_model(rng, kinds=kinds, per_light=per_light)
    o = model.objects[0]
    assert o.per_light == per_light and o.positional.tolist() == [c == "p" for c in kinds]
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image, expected, emitted, covered = assert_pixels(r, o, VIEW)
    assert (image[covered] - emitted[covered]).max() > 0.5  # the lights show
    r.release()


@pytest.mark.parametrize("case", list(CASES))
def test_point_lights_and_per_light_coefficients_gouraud(gl_context, rng, case):
    kinds, per_light = CASES[case]
    model = ball_model(rng, kinds=kinds, per_light=per_light)
    o = model.objects[0]
    r = ProbedRenderer(gl_context, fit=model)
    for lights in (None, 0, 1, 2):
        assert_vertices(r, o, VIEW, lights)
    # the rasterised Gouraud picture is the vertex colours interpolated: between their extremes
    image = r.render(VIEW, "fitted", "gouraud")
    colours = r.vertex_colours(VIEW, "ball", "fitted")
    assert np.isfinite(image).all() and image.max() <= colours.max() * (1 + 1e-5)
    r.release()


def test_first_k_lights_with_per_light_coefficients(gl_context, rng):
    # --lights K: the first K lights with their own coefficients (stride K_total in the texture)
    model = ball_model(rng, kinds="pdpdd", per_light=True, shininess=(5.0, 40.0, 300.0, 20.0, 8.0))
    o = model.objects[0]
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    previous = None
    for lights in (0, 1, 2, 4, 5, 99):
        assert_vertices(r, o, VIEW, lights)
        image, *_ = assert_pixels(r, o, VIEW, lights=lights)
        assert previous is None or not np.array_equal(image, previous) or lights == 99
        previous = image
    diffuse = r.render(VIEW, "diffuse", "pixel")
    assert np.array_equal(r.render(VIEW, "fitted", "pixel", lights=0), diffuse)
    r.release()


def test_sixty_four_per_light_coefficients(gl_context, rng):
    # the fitter allows up to 64 lights: no attribute per light, the texture holds them all
    model = ball_model(rng, kinds="dp" * 32, per_light=True, shininess=(5.0, 40.0, 300.0, 12.0))
    o = model.objects[0]
    assert o.n_lights == 64
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    assert_vertices(r, o, VIEW)
    assert_pixels(r, o, VIEW)
    r.release()


def grid_object(name, n, half, height, rng, per_light, light_pos, shininess=10.0):
    """A square grid of n x n vertices in the plane y = height, facing +y."""
    t = np.linspace(-half, half, n)
    x, z = np.meshgrid(t, t)
    positions = np.stack([x.ravel(), np.full(n * n, height), z.ravel()], axis=1).astype(np.float32)
    i = np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]
    i = i.ravel()
    faces = np.concatenate([np.stack([i, i + n, i + 1], 1), np.stack([i + 1, i + n, i + n + 1], 1)]).astype(np.int32)
    v, k = n * n, len(light_pos)
    return FittedObject(
        name=name, positions=positions, normals=np.tile(np.float32([0, 1, 0]), (v, 1)), faces=faces,
        emitted=rng.uniform(0.05, 0.3, (v, 3)).astype(np.float32),
        specular=rng.uniform(0.2, 1.0, (v, k, 3) if per_light else (v, 3)).astype(np.float32),
        light_pos=np.asarray(light_pos, np.float32), light_rgb=rng.uniform(1.0, 3.0, (k, 3)).astype(np.float32),
        shininess=np.full(k, shininess, np.float32),
    )


ABOVE = Camera(eye=(0.0, 2.0, 1.5), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=60.0, width=64, height=48)


@pytest.mark.parametrize("per_light", [False, True])
def test_a_point_light_behind_the_surface(gl_context, rng, per_light):
    # below the plane: the lobe is 0 near the middle (n . h < 0), not at the edges (no n . l
    # gate); off the grid's axes, so that no vertex lies where h = l + w is 0 (ill-conditioned)
    obj = grid_object("plane", 9, 1.2, 0.0, rng, per_light, [[0.13, -0.5, 0.07, 1.0]])
    r = ProbedRenderer(gl_context, fit=FittedModel(objects=(obj,)), samples=1)
    image, expected, emitted, covered = assert_pixels(r, obj, ABOVE)
    dark = covered & np.all(expected == emitted, axis=2)  # where the reference's lobe is 0
    lit = covered & ~dark
    assert dark.sum() > 100 and lit.sum() > 100
    assert np.allclose(image[dark], emitted[dark], rtol=1e-6, atol=0)  # no light at all there
    got, want = assert_vertices(r, obj, ABOVE)
    unlit = np.all(want == obj.emitted, axis=1)
    assert unlit.any() and (~unlit).any() and np.array_equal(got[unlit], obj.emitted[unlit])
    assert np.isfinite(r.render(ABOVE, "fitted", "gouraud")).all()
    r.release()


@pytest.mark.parametrize("per_light", [False, True])
def test_a_point_light_at_a_vertex(gl_context, rng, per_light):
    # l = normalize(p - x) is 0/0 at that vertex: no light there, no NaN anywhere
    obj = grid_object("plane", 9, 1.2, 0.0, rng, per_light, [[0.0, 0.0, 0.0, 1.0], [0.3, 0.8, 0.2, 1.0]],
                      shininess=4.0)
    centre = 40
    assert np.array_equal(obj.positions[centre], [0.0, 0.0, 0.0])
    r = ProbedRenderer(gl_context, fit=FittedModel(objects=(obj,)), samples=1)
    got, want = assert_vertices(r, obj, ABOVE)
    alone = first_lights(obj, 1)  # the light at the vertex alone adds nothing there
    assert np.array_equal(r.vertex_colours(ABOVE, "plane", "fitted", lights=1)[centre], obj.emitted[centre])
    assert np.array_equal(shade(FittedModel(objects=(alone,)), "plane", np.float64([[0, 1, 0]] * 81))[centre],
                          obj.emitted[centre])
    assert_pixels(r, obj, ABOVE)
    assert_pixels(r, obj, ABOVE, lights=1)
    assert np.isfinite(r.render(ABOVE, "fitted", "gouraud")).all()
    r.release()


def test_objects_with_shared_and_per_light_coefficients_in_one_frame(gl_context, rng):
    # each object its own program (per-light: vertex ids and barycentrics), lights and coefficient base
    floor = grid_object("floor", 7, 2.0, -1.2, rng, False, [[0.5, 1.0, 0.5, 1.0]])
    ball = ball_model(rng, kinds="pdp", per_light=True).objects[0]
    top = grid_object("top", 5, 0.6, 1.2, rng, True, [[0.0, 0.6, 0.8, 0.0], [0.2, 2.0, 1.0, 1.0]])
    model = FittedModel(objects=(floor, ball, top))
    view = Camera(eye=(0.5, 2.5, 3.5), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=60.0, width=96, height=80)
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    for lights in (None, 1):
        image = r.render(view, "fitted", "pixel", lights)
        position, normal, emitted, specular, covered = r.render_attributes(view)
        which, _, _ = r.render_triangles(view)
        assert specular.shape == (80, 96, 3, 3) and np.array_equal(which >= 0, covered)
        n = normal / np.linalg.norm(normal, axis=2, keepdims=True).clip(1e-12)
        w = np.asarray(view.eye) - position
        w /= np.linalg.norm(w, axis=2, keepdims=True).clip(1e-12)
        for i, o in enumerate(model.objects):
            here = which == i
            assert here.sum() > 100, o.name
            part = first_lights(o, o.n_lights if lights is None else lights)
            expected = shade_arrays(emitted[here], specular[here][:, : part.n_lights], n[here], position[here],
                                    part.lights, w[here])
            assert np.allclose(image[here], expected, rtol=RTOL, atol=ATOL), o.name
        for o in model.objects:
            assert_vertices(r, o, view, lights)
    r.release()


def test_a_version_1_fit_file_renders_as_its_version_2(gl_context, rng, tmp_path):
    # version 1: light_dirs (K, 3), specular (V, 3); read as directional lights (w = 0)
    obj = ball_model(rng).objects[0]
    dirs = obj.light_pos[:, :3]
    v1 = tmp_path / "v1.npz"
    meta = {"format": "vlights.fit", "version": 1, "objects": {"ball": {"lights": obj.n_lights}}}
    np.savez(v1, meta=np.array(json.dumps(meta)), **{
        "ball/positions": obj.positions, "ball/normals": obj.normals, "ball/faces": obj.faces,
        "ball/emitted": obj.emitted, "ball/specular": obj.specular, "ball/light_dirs": dirs,
        "ball/light_rgb": obj.light_rgb, "ball/shininess": obj.shininess,
    })
    v2 = tmp_path / "v2.npz"
    FittedModel(objects=(obj,)).save(v2)
    assert json.loads(str(np.load(v2)["meta"]))["version"] == 3
    old, new = load_fit(v1), load_fit(v2)
    o = old.objects[0]
    assert not o.per_light and not o.positional.any()
    assert np.array_equal(o.light_pos, directional(dirs).astype(np.float32))
    a, b = ProbedRenderer(gl_context, fit=old, samples=1), ProbedRenderer(gl_context, fit=new, samples=1)
    for shading in ("pixel", "gouraud"):
        assert np.array_equal(a.render(VIEW, "fitted", shading), b.render(VIEW, "fitted", shading))
    assert np.array_equal(a.vertex_colours(VIEW, "ball"), b.vertex_colours(VIEW, "ball"))
    assert_pixels(a, o, VIEW)
    assert_vertices(a, o, VIEW)
    a.release()
    b.release()


def quad_solution(rng, grid=6, scale=1.0):
    p = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    normals = np.tile(np.float32([0, 1, 0]), (4, 1))
    tangents = geometry.tangents(normals).astype(np.float32)
    radiance = (rng.uniform(0.1, 5.0, (4, grid * grid, 3)) * scale).astype(np.float32)
    obj = ObjectSolution(name="quad", positions=p, normals=normals, tangents=tangents, faces=faces,
                         directions=directions.grid_directions(grid).astype(np.float32), radiance=radiance, material=MATERIAL)
    return Solution(objects=(obj,), settings={}, stats={}, scene="test")


def world(obj, vertex, local):
    t = obj.tangents[vertex].astype(float)
    n = obj.normals[vertex].astype(float)
    return local[0] * t + local[1] * np.cross(n, t) + local[2] * n


@pytest.mark.parametrize("cell", [0, 7, 14, 35])
def test_reference_returns_the_stored_radiance_at_cell_centres(gl_context, rng, cell):
    solution = quad_solution(rng)
    obj = solution.objects[0]
    r = ProbedRenderer(gl_context, solution=solution)
    vertex = 2
    w = world(obj, vertex, directions.grid_directions(6)[cell])
    eye = obj.positions[vertex].astype(float) + 3.0 * w
    view = Camera(eye=tuple(eye), look_at=tuple(obj.positions[vertex].astype(float)), up=(0.3, 0.2, 0.9),
                fov_deg=30.0, width=8, height=8)
    got = r.vertex_colours(view, "quad", "reference")[vertex]
    # float32 atan/sqrt on the GPU move the bilinear weights by ~1e-5: neighbours leak in that much
    assert np.allclose(got, obj.radiance[vertex, cell], rtol=1e-3), (got, obj.radiance[vertex, cell])
    r.release()


def test_reference_interpolates_between_centres(gl_context, rng):
    solution = quad_solution(rng, grid=8)
    obj = solution.objects[0]
    r = ProbedRenderer(gl_context, solution=solution)
    vertex = 1
    for a, b in [(0.1, -0.3), (-0.55, 0.2), (0.0, 0.0)]:
        local = directions.square_to_hemisphere(a, b)
        idx, weight = directions.grid_lookup_weights(local, 8)
        expected = (weight[:, None] * obj.radiance[vertex, idx]).sum(axis=0)
        eye = obj.positions[vertex].astype(float) + 2.0 * world(obj, vertex, local)
        view = Camera(eye=tuple(eye), look_at=tuple(obj.positions[vertex].astype(float)), up=(0.3, 0.2, 0.9),
                    fov_deg=30.0, width=8, height=8)
        got = r.vertex_colours(view, "quad", "reference")[vertex]
        assert np.allclose(got, expected, rtol=1e-3), (a, b, got, expected)
    r.release()


def test_reference_per_pixel_matches_a_numpy_lookup(gl_context, rng):
    solution = quad_solution(rng, grid=8)
    obj = solution.objects[0]
    view = Camera(eye=(0.4, 1.5, 2.2), look_at=(0.0, 0.0, 0.0), fov_deg=60.0, width=40, height=30)
    r = ProbedRenderer(gl_context, solution=solution, samples=1)
    image = r.render(view, "reference", "pixel")
    # numpy: intersect each pixel's ray with the plane y = 0, blend the three vertices' lookups
    rays = view.pixel_rays()
    eye = np.asarray(view.eye)
    t = -eye[1] / rays[..., 1]
    hit = eye + t[..., None] * rays
    inside = (t > 0) & (np.abs(hit[..., 0]) < 0.999) & (np.abs(hit[..., 2]) < 0.999)
    checked = 0
    p = obj.positions.astype(float)
    for y, x in zip(*np.nonzero(inside)):
        point = hit[y, x]
        for face in obj.faces:
            a, b, c = p[face]
            m = np.array([b - a, c - a]).T[[0, 2]]
            uv = np.linalg.solve(m, (point - a)[[0, 2]])
            bary = np.array([1 - uv.sum(), uv[0], uv[1]])
            if (bary >= 1e-3).all():
                w = (eye - point) / np.linalg.norm(eye - point)
                value = 0
                for vert, lam in zip(face, bary):
                    tn, n = obj.tangents[vert].astype(float), obj.normals[vert].astype(float)
                    local = np.array([w @ tn, w @ np.cross(n, tn), w @ n])
                    idx, weight = directions.grid_lookup_weights(local, 8)
                    value = value + lam * (weight[:, None] * obj.radiance[vert, idx]).sum(axis=0)
                assert np.allclose(image[y, x], value, rtol=2e-3), (y, x, image[y, x], value)
                checked += 1
                break
    assert checked > 200
    r.release()


def test_tonemap_exposure_and_srgb():
    hdr = np.array([[[0.0, 0.0031308, 1.0], [0.5, 2.0, 1e8]]], np.float32)
    out = tonemap(hdr, exposure=1.0)
    assert out.dtype == np.uint8 and out.shape == (1, 2, 3)
    assert out[0, 0, 0] == 0 and out[0, 0, 2] == 255 and out[0, 1, 1] == 255 and out[0, 1, 2] == 255
    assert out[0, 1, 0] == round(255 * (1.055 * 0.5 ** (1 / 2.4) - 0.055))
    assert tonemap(hdr, exposure=0.25)[0, 1, 1] == out[0, 1, 0]


def test_the_glsl_tone_map_is_tonemap(gl_context, rng):
    """tonemap.glsl, drawn by ``Renderer.show`` (the window's tone map, and the page's),
    is ``tonemap``'s formula: into a float framebuffer within float32 rounding of it
    (5e-7), into 8 bits within 1 of ``tonemap`` and equal to it at all but a few values
    (the GPU rounds a float32 value to the nearest level, numpy its float64 value half up)."""
    from display_fixtures import tiny_solution

    width, height = 256, 64
    values = np.concatenate([
        np.linspace(0.0, 1.25, 9000), 0.0031308 * (1 + np.linspace(-1e-3, 1e-3, 200)),  # the sRGB threshold
        rng.uniform(0, 0.01, 3000), [0.0, 1.0, 2.0, 1e8, 1e30], rng.uniform(0, 3, width * height * 3),
    ])[: width * height * 3]
    hdr = values.reshape(height, width, 3).astype(np.float32)
    ctx = gl_context
    r = ProbedRenderer(ctx, solution=tiny_solution(), samples=1)
    rgba = np.concatenate([hdr, np.ones((height, width, 1), np.float32)], axis=2)
    source = ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4, rgba.tobytes(), dtype="f4")])
    floats = ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4, dtype="f4")])
    bytes_ = ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4)])
    for exposure in (1.0, 0.37, 4.0):
        x = np.clip(hdr.astype(np.float64) * np.float32(exposure), 0.0, 1.0)
        want = np.where(x < 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
        floats.use()
        r.show(source, exposure)
        got = np.frombuffer(floats.color_attachments[0].read(), np.float32).reshape(height, width, 4)
        assert np.abs(got[..., :3] - want).max() <= 5e-7
        assert (got[..., 3] == 1).all()
        bytes_.use()
        r.show(source, exposure)
        got8 = np.frombuffer(bytes_.color_attachments[0].read(), np.uint8).reshape(height, width, 4)[..., :3]
        want8 = tonemap(hdr, exposure)
        diff = np.abs(got8.astype(int) - want8)
        assert diff.max() <= 1 and np.mean(diff > 0) < 1e-3, (diff.max(), np.mean(diff > 0))
        assert len(np.unique(want8)) > 200  # not vacuous: most levels are met
    for fbo in (source, floats, bytes_):
        fbo.color_attachments[0].release()
        fbo.release()
    r.release()
