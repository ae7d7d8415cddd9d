"""The glossy models' parts in the displays (emitter highlights, probes, lights), GPU against numpy (float framebuffers):
the emitters' highlights and the reflection probe of the fitted model (per pixel and
Gouraud, each part switched off in turn), the reference display's highlights added back
to the solution's rest, and no light counted twice (a glossy floor under a square lamp
through every display against the closed forms).

Per pixel the numpy side evaluates ``FittedObject`` 's formula at what the fragment
interpolates: its triangle's vertex ids and barycentrics (``render_triangles``) blend
the position, normal, emitted colour, probe weight and visibility. Tolerances: float32
on the GPU (the highlight's quadrature in single precision, a sharp lobe's exponent
multiplying the rounding) against float64: 2e-3 relative plus 1e-5 absolute."""

import dataclasses
import textwrap

import numpy as np
import pytest
import trimesh
from analytic import SQUARE_LIGHT, polygon_irradiance
from renderer_probes import ProbedRenderer

from display.renderer import PARTS
from fitting import FittedModel, FittedObject
from fitting.model import Highlight
from fitting.probe import Probe, albedo_table, decode
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.emitters import EmitterPart, SpotProfile, emitter_grid, emitter_radiance
from radiosity.physics.materials import Microfacet

pytestmark = pytest.mark.gl

RTOL, ATOL = 2e-3, 1e-5
VIEW = Camera(eye=(0.4, 0.6, 3.2), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=45.0, width=96, height=80)
EXPONENT = 60.0
KS = np.array([0.5, 0.45, 0.4])


def parts():
    lamp = EmitterPart("polygon", [[-0.4, 2.0, 1.0], [-0.4, 2.0, 1.6], [0.4, 2.0, 1.6], [0.4, 2.0, 1.0]][::-1], 0.0,
                       [6.0, 5.0, 4.0], "panel")
    assert lamp.normal[1] < -0.99  # facing down
    ball = EmitterPart("sphere", [[1.5, 1.0, 2.0]], 0.25, [3.0, 6.0, 9.0], "lamp")
    own = EmitterPart("sphere", [[0.0, 0.0, 0.0]], 0.5, [1.0, 1.0, 1.0], "ball")  # the ball's own: never seen
    return (lamp, ball, own)


def delta_parts():
    """A point, a spot whose cone's edge and transition cross the ball, and a direction
    (radiosity.physics.emitters' delta parts)."""
    point = EmitterPart("point", [[1.2, 1.4, 1.8]], 0.0, [2.0, 1.5, 1.0], "bulb")
    spot = EmitterPart("point", [[-0.8, 1.2, 2.6]], 0.0, [3.0, 3.0, 4.0], "torch",
                       SpotProfile([0.924, -1.099, -1.649], 10.0, 6.0))
    sun = EmitterPart("direction", [[-0.3, -1.0, -0.6]], 0.0, [0.8, 0.7, 0.5], "sun")
    return (point, spot, sun)


def ball_model(rng, probe=True, highlight=True, lights=2, fresnel=None, emitters=None):
    s = trimesh.creation.icosphere(subdivisions=3)
    positions = np.asarray(s.vertices, np.float32)
    normals = (positions / np.linalg.norm(positions, axis=1, keepdims=True)).astype(np.float32)
    v = len(positions)
    m = 8
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    dirs = decode(np.stack([(i + 0.5) / m, (j + 0.5) / m], axis=-1))
    texels = (0.3 + 0.2 * dirs + 0.1 * np.sin(4 * dirs[..., ::-1])).astype(np.float32)
    k = lights
    light_pos = np.array([[0.3, 0.8, 0.5, 0.0], [1.0, 1.5, 2.0, 1.0]][:k], np.float32)
    light_pos[:, :3][light_pos[:, 3] == 0] /= np.linalg.norm(light_pos[:, :3][light_pos[:, 3] == 0], axis=1, keepdims=True)
    pp = parts() if emitters is None else emitters
    obj = FittedObject(
        name="ball", positions=positions, normals=normals, faces=np.asarray(s.faces, np.int32),
        emitted=rng.uniform(0, 0.1, (v, 3)).astype(np.float32),
        specular=rng.uniform(0.1, 0.5, (v, k, 3)).astype(np.float32), light_pos=light_pos,
        light_rgb=np.ones((k, 3), np.float32), shininess=np.array([20.0, 150.0][:k], np.float32),
        highlight=Highlight(pp, 8, KS, EXPONENT, rng.uniform(0.3, 1.0, (v, len(pp))).astype(np.float32), fresnel)
        if highlight else None,
        probe=Probe(texels, np.zeros(3), np.array([[-3.0, -1.0, -3.0], [3.0, 4.0, 4.0]]), albedo_table(EXPONENT))
        if probe else None,
        probe_weight=rng.uniform(0.2, 0.8, (v, 3)).astype(np.float32) if probe else None,
    )
    return FittedModel(objects=(obj,), source="test", emitters=pp, emitter_nodes=8)


def expected_pixels(renderer, obj, view, parts, which=0):
    """The formula at each pixel object ``which`` covers: blended from its triangle's vertices."""
    index, vertices, bary = renderer.render_triangles(view)
    covered = index == which
    b = bary[covered].astype(np.float64)
    ids = vertices[covered]

    def blend(a):
        return np.einsum("pv,pv...->p...", b, np.asarray(a, np.float64)[ids])

    x = blend(obj.positions)
    n = blend(obj.normals)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    w = np.asarray(view.eye) - x
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    blended = FittedObject(
        name=obj.name, positions=x, normals=n, faces=np.zeros((1, 3), np.int32), emitted=blend(obj.emitted),
        specular=blend(obj.specular), light_pos=obj.light_pos, light_rgb=obj.light_rgb, shininess=obj.shininess,
        highlight=None if obj.highlight is None else Highlight(obj.highlight.parts, 8, obj.highlight.ks,
                                                               obj.highlight.exponent, blend(obj.highlight.visibility),
                                                               obj.highlight.fresnel, obj.highlight.indices,
                                                               obj.highlight.microfacet),
        probe=obj.probe, probe_weight=None if obj.probe is None else blend(obj.probe_weight),
    )
    return blended.shade(w, parts=parts), covered


@pytest.mark.parametrize("off", [(), ("emitters",), ("probe",), ("lights",), PARTS])
def test_per_pixel_equals_the_formula_with_each_part_on_and_off(gl_context, rng, off):
    model = ball_model(rng)
    obj = model.objects[0]
    parts_on = tuple(p for p in PARTS if p not in off)
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "fitted", "pixel", parts=parts_on)
    expected, covered = expected_pixels(r, obj, VIEW, parts_on)
    assert covered.sum() > 500
    diff = np.abs(image[covered] - expected)
    assert (diff <= RTOL * np.abs(expected) + ATOL).all(), diff.max()
    assert (image[~covered] == 0).all()
    # each part shows: switching it off changes the picture
    if len(off) == 1:
        full = r.render(VIEW, "fitted", "pixel")
        assert np.abs(full - image).max() > 0.01
    r.release()


def test_objects_drawing_their_own_parts_per_pixel_equal_the_formula(gl_context, rng):
    """A scene of 40 small lamps (more than one object may draw) and two balls, each
    drawing its own 16 of them (a version 6 fit: a table of its own parts bound for it):
    per pixel, each ball equals its formula, and each shows a highlight the other's
    parts would not give it."""
    lamps = tuple(EmitterPart("sphere", [[0.15 * i - 3.0, 1.5 + 0.02 * i, 2.0]], 0.1, [4.0, 3.0, 2.0 + 0.1 * i],
                              f"lamp{i}") for i in range(40))
    chosen = (tuple(range(0, 32, 2)), tuple(range(20, 36)))
    balls = []
    for k, own in enumerate(chosen):
        obj = ball_model(rng, probe=False, lights=1, emitters=tuple(lamps[i] for i in own)).objects[0]
        h = obj.highlight
        balls.append(dataclasses.replace(
            obj, name=f"ball{k}", positions=obj.positions * 0.6 + np.float32([1.4 * k - 0.7, 0.0, 0.0]),
            highlight=Highlight(h.parts, h.nodes, h.ks, h.exponent, h.visibility, h.fresnel, own)))
    model = FittedModel(objects=tuple(balls), source="test", emitters=lamps, emitter_nodes=8)
    assert model.version == 6
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "fitted", "pixel")
    for k, ball in enumerate(balls):
        expected, covered = expected_pixels(r, ball, VIEW, PARTS, which=k)
        assert covered.sum() > 300
        diff = np.abs(image[covered] - expected)
        assert (diff <= RTOL * np.abs(expected) + ATOL).all(), (k, diff.max())
        other = chosen[1 - k]
        swapped = dataclasses.replace(ball, highlight=dataclasses.replace(
            ball.highlight, parts=tuple(lamps[i] for i in other), indices=other))
        wrong, _ = expected_pixels(r, swapped, VIEW, PARTS, which=k)
        assert np.abs(wrong - expected).max() > 0.01  # the parts drawn are the object's own
    r.release()


def test_a_fresnel_highlight_per_pixel_and_at_the_vertices_equals_the_formula(gl_context, rng):
    """The emitter term of a Fresnel material: ks weighted by Schlick's F(n . w), on the GPU
    as in radiosity.physics.emitters (per pixel and Gouraud), and it changes the picture."""
    f0 = np.array([0.04, 0.3, 0.9])
    model = ball_model(rng, probe=False, lights=1, fresnel=f0)
    obj = model.objects[0]
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "fitted", "pixel", parts=("emitters",))
    expected, covered = expected_pixels(r, obj, VIEW, ("emitters",))
    assert covered.sum() > 500 and expected.max() > 0.01
    diff = np.abs(image[covered] - expected)
    assert (diff <= RTOL * np.abs(expected) + ATOL).all(), diff.max()
    w = np.asarray(VIEW.eye) - obj.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    got = r.vertex_colours(VIEW, "ball")
    assert np.allclose(got, obj.shade(w), rtol=RTOL, atol=ATOL)
    without = FittedModel(objects=(dataclasses.replace(obj, highlight=dataclasses.replace(obj.highlight, fresnel=None)),),
                          source="test", emitters=model.emitters, emitter_nodes=8)
    rp = ProbedRenderer(gl_context, fit=without, samples=1)
    assert np.abs(rp.render(VIEW, "fitted", "pixel", parts=("emitters",)) - image).max() > 0.01
    r.release()
    rp.release()


@pytest.mark.parametrize("distribution,alpha", [("ggx", 0.08), ("ggx", 0.4), ("beckmann", 0.25)])
def test_microfacet_highlights_per_pixel_and_at_the_vertices_equal_the_formula(gl_context, rng, distribution, alpha):
    """A microfacet lobe's highlights (display/shaders/ltc.glsl: linearly transformed cosines
    for the panel and the sphere lamp, the lobe itself for a point, a spot and a direction)
    on the GPU as in radiosity.physics.emitters, per pixel and Gouraud; every part shows,
    and the lobe differs from the Phong stand-in's."""
    mf = Microfacet("roughconductor", distribution, alpha, (0.2, 0.9, 1.1), (3.9, 2.4, 2.2), (0.9, 0.8, 1.0))
    pp = parts() + delta_parts()
    model = ball_model(rng, probe=False, lights=1, emitters=pp)
    obj = model.objects[0]
    obj = dataclasses.replace(obj, highlight=dataclasses.replace(obj.highlight, microfacet=mf))
    model = dataclasses.replace(model, objects=(obj,))
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "fitted", "pixel", parts=("emitters",))
    expected, covered = expected_pixels(r, obj, VIEW, ("emitters",))
    assert covered.sum() > 500 and expected.max() > 0.05
    diff = np.abs(image[covered] - expected)
    # single precision where the panel is clipped to a horizon: within 3 % of the highlight at a few pixels
    loose = diff > RTOL * np.abs(expected) + ATOL
    assert loose.any(axis=1).sum() <= 3 and (diff <= 6e-3 * np.abs(expected) + ATOL).all(), diff.max()
    w = np.asarray(VIEW.eye) - obj.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    assert np.allclose(r.vertex_colours(VIEW, "ball"), obj.shade(w), rtol=RTOL, atol=ATOL)
    h = obj.highlight
    for part in pp[:2] + pp[3:]:  # the ball's own sphere is never drawn
        k = pp.index(part)
        one = dataclasses.replace(obj, highlight=dataclasses.replace(h, parts=(part,), visibility=h.visibility[:, k:k + 1]))
        alone = expected_pixels(r, one, VIEW, ("emitters",))[0] - expected_pixels(r, one, VIEW, ())[0]
        assert (alone.max(axis=1) > 1e-3).sum() > 20, part.source
    phong = dataclasses.replace(obj, highlight=dataclasses.replace(h, microfacet=None))
    assert np.abs(expected_pixels(r, phong, VIEW, ("emitters",))[0] - expected).max() > 0.05
    r.release()


@pytest.mark.parametrize("fresnel", [None, (0.04, 0.3, 0.9)])
def test_delta_parts_highlights_per_pixel_and_at_the_vertices_equal_the_formula(gl_context, rng, fresnel):
    """A point, a spot and a direction: their highlights (the lobe at their one
    direction, 1 / d^2 and the spot's profile for the point lights) on the GPU as in
    radiosity.physics.emitters, per pixel and Gouraud; each shows on the ball, and the
    spot's edge crosses it."""
    pp = delta_parts()
    model = ball_model(rng, probe=False, lights=1, fresnel=None if fresnel is None else np.array(fresnel), emitters=pp)
    obj = model.objects[0]
    r = ProbedRenderer(gl_context, fit=model, samples=1)
    image = r.render(VIEW, "fitted", "pixel", parts=("emitters",))
    expected, covered = expected_pixels(r, obj, VIEW, ("emitters",))
    assert covered.sum() > 500 and expected.max() > 0.05
    diff = np.abs(image[covered] - expected)
    assert (diff <= RTOL * np.abs(expected) + ATOL).all(), diff.max()
    w = np.asarray(VIEW.eye) - obj.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    assert np.allclose(r.vertex_colours(VIEW, "ball"), obj.shade(w), rtol=RTOL, atol=ATOL)
    # not vacuous: each part lights some of the ball's pixels, and the spot's transition crosses its highlight
    h = obj.highlight
    alone = []
    for i, part in enumerate(pp):
        one = dataclasses.replace(obj, highlight=dataclasses.replace(h, parts=(part,), visibility=h.visibility[:, i:i + 1]))
        alone.append(expected_pixels(r, one, VIEW, ("emitters",))[0] - expected_pixels(r, one, VIEW, ())[0])
        assert (alone[-1].max(axis=1) > 1e-3).sum() > 20, part.source
    unspotted = dataclasses.replace(pp[1], spot=None)
    one = dataclasses.replace(obj, highlight=dataclasses.replace(h, parts=(unspotted,), visibility=h.visibility[:, 1:2]))
    full = expected_pixels(r, one, VIEW, ("emitters",))[0] - expected_pixels(r, one, VIEW, ())[0]
    partly = (alone[1] > 0.05 * full) & (alone[1] < 0.95 * full) & (full > 1e-3)
    assert partly.all(axis=1).sum() > 10
    r.release()


def test_gouraud_vertex_colours_equal_the_formula_at_the_vertices(gl_context, rng):
    model = ball_model(rng)
    obj = model.objects[0]
    r = ProbedRenderer(gl_context, fit=model)
    got = r.vertex_colours(VIEW, "ball")
    w = np.asarray(VIEW.eye) - obj.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    expected = obj.shade(w)
    assert np.allclose(got, expected, rtol=RTOL, atol=ATOL), np.abs(got - expected).max()
    # diffuse mode: the emitted colour alone, every part off
    diffuse = r.vertex_colours(VIEW, "ball", mode="diffuse")
    assert np.allclose(diffuse, obj.emitted, rtol=1e-6, atol=1e-7)
    r.release()


def test_the_reference_display_adds_the_highlights_back_to_the_rest(gl_context, rng):
    # a solution whose grid holds a constant rest plus the highlights in closed form: the
    # reference display shows the rest (bilinear: constant) plus the highlights per pixel
    s = trimesh.creation.icosphere(subdivisions=3)
    positions = np.asarray(s.vertices, np.float32)
    normals = (positions / np.linalg.norm(positions, axis=1, keepdims=True)).astype(np.float32)
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    tangents = np.cross(normals, helper)
    tangents = (tangents / np.linalg.norm(tangents, axis=1, keepdims=True)).astype(np.float32)
    from radiosity.physics.directions import grid_directions

    dirs = grid_directions(12)
    pp = parts()
    vis = rng.uniform(0.3, 1.0, (len(positions), len(pp))).astype(np.float32)
    material = {"diffuse": [0.1, 0.1, 0.1], "specular": KS.tolist(), "exponent": EXPONENT, "emission": [0, 0, 0]}
    highlight = emitter_grid(pp, positions, normals, tangents, dirs, KS, EXPONENT, visibility=vis, nodes=8, source="ball")
    rest = np.array([0.05, 0.1, 0.15])
    ball = ObjectSolution("ball", positions, normals, tangents, np.asarray(s.faces, np.int32), dirs,
                          (rest + highlight).astype(np.float32), material, visibility=vis)
    sol = Solution(objects=(ball,), emitters=pp, emitter_nodes=8)
    r = ProbedRenderer(gl_context, solution=sol, samples=1)
    image = r.render(VIEW, "reference", "pixel")
    # the barycentrics come from a fitted model of the same mesh (its per-pixel program's)
    fit_like = FittedModel(objects=(FittedObject(
        name="ball", positions=positions, normals=normals, faces=np.asarray(s.faces, np.int32),
        emitted=np.zeros_like(positions), specular=np.zeros((len(positions), 0, 3), np.float32),
        light_pos=np.zeros((0, 4), np.float32), light_rgb=np.zeros((0, 3), np.float32), shininess=np.zeros(0, np.float32),
        highlight=Highlight(pp, 8, KS, EXPONENT, vis)),), emitters=pp)
    rr = ProbedRenderer(gl_context, fit=fit_like, solution=sol, samples=1)
    expected, covered = expected_pixels(rr, fit_like.objects[0], VIEW, ("emitters",))
    got = rr.render(VIEW, "reference", "pixel")
    assert np.allclose(got, image)
    diff = np.abs(got[covered] - (rest + expected))
    assert (diff <= RTOL * np.abs(rest + expected) + ATOL).all(), diff.max()
    # without the highlights: the rest alone
    bare = rr.render(VIEW, "reference", "pixel", parts=("lights", "probe"))
    assert np.allclose(bare[covered], rest, rtol=1e-5, atol=1e-5)  # (L - E in float32)
    # at the vertices (Gouraud): the solution's own radiance in the view's direction
    colours = rr.vertex_colours(VIEW, "ball", mode="reference")
    w = np.asarray(VIEW.eye) - positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    at_vertices = rest + emitter_radiance(pp, positions, normals, w, KS, EXPONENT, visibility=vis, source="ball")
    assert np.allclose(colours, at_vertices, rtol=RTOL, atol=ATOL)
    r.release()
    rr.release()


def test_no_light_counted_twice_a_glossy_floor_under_a_square_lamp(gl_context, tmp_path):
    """SQUARE_LIGHT with a glossy floor: every display shows kd E / pi (the lamp's
    irradiance, Lambert's closed form) plus the lamp's glossy reflection (the closed form
    tested against quadrature) once: the reference display, and the fitted one."""
    from fitting import FitOptions, fit
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    text = SQUARE_LIGHT.replace("[materials.floor]\n    diffuse = 0.5",
                                "[materials.floor]\n    diffuse = 0.4\n    specular = 0.5\n    exponent = 40")
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(text))
    scene = load_scene(path)
    sol = solve(scene, SolveOptions(photons=1_000_000, gather_samples=64, light_samples=4, grid=16, max_edge=0.05, seed=3))
    assert [p.source for p in sol.emitters] == ["lamp"]
    model = fit(sol, FitOptions(model="probe", probe_size=8))
    view = Camera(eye=(0.0, 0.9, 1.4), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=40.0, width=64, height=64)
    r = ProbedRenderer(gl_context, fit=model, solution=sol, samples=1)
    index, vertices, bary = r.render_triangles(view)
    floor_index = [o.name for o in r.objects].index("floor")
    on_floor = index == floor_index
    floor = sol.object("floor")
    x = np.einsum("pv,pvi->pi", bary[on_floor].astype(float), floor.positions[vertices[on_floor]].astype(float))
    w = np.asarray(view.eye) - x
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    up = np.array([0.0, 1.0, 0.0])
    lamp = scene.object("lamp")
    corners = lamp.positions[[0, 1, 2, 3]]
    diffuse = 0.4 / np.pi * polygon_irradiance(x, up, corners, 1.0)
    glossy = emitter_radiance(sol.emitters, x, np.broadcast_to(up, x.shape), w, [0.5] * 3, 40.0)[:, 0]
    expected = diffuse + glossy
    assert glossy.max() > 0.3 * diffuse.max()  # the highlight matters: counted twice, it would show
    inside = (np.abs(x[:, 0]) < 0.4) & (np.abs(x[:, 2]) < 0.4)  # away from the floor's edges
    for mode in ("reference", "fitted"):
        got = r.render(view, mode, "pixel")[on_floor][:, 0]
        relative = got[inside] / expected[inside] - 1
        assert abs(np.median(relative)) < 0.03, (mode, np.median(relative))
        assert np.percentile(np.abs(relative), 90) < 0.1, (mode, np.percentile(np.abs(relative), 90))
    r.release()
