"""GPU output against numpy evaluations of the same formulas (float framebuffers)."""

import numpy as np
import pytest
import trimesh

from display.renderer import Renderer, tonemap
from fitting import FittedModel, FittedObject, shade
from fitting.model import shade_arrays
from radiosity.formats import Camera, directions
from radiosity.formats.solution import ObjectSolution, Solution
from radiosity.scene import geometry

pytestmark = pytest.mark.gl

MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 30.0, "emission": [0.0, 0.0, 0.0]}


def ball_model(rng, lights=3):
    s = trimesh.creation.icosphere(subdivisions=3)
    positions = np.asarray(s.vertices, np.float32)
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    dirs = rng.normal(size=(lights, 3))
    dirs[:, 2] = np.abs(dirs[:, 2])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    obj = FittedObject(
        name="ball", positions=positions, normals=normals.astype(np.float32), faces=np.asarray(s.faces, np.int32),
        emitted=rng.uniform(0, 0.3, (len(positions), 3)).astype(np.float32),
        specular=rng.uniform(0.2, 1.0, (len(positions), 3)).astype(np.float32),
        light_dirs=dirs.astype(np.float32), light_rgb=rng.uniform(0.5, 3.0, (lights, 3)).astype(np.float32),
        shininess=np.array([5.0, 40.0, 300.0][:lights], np.float32),
    )
    return FittedModel(objects=(obj,), source="test")


VIEW = Camera(eye=(0.3, 0.4, 3.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y_deg=45.0, width=96, height=80)


def test_fitted_per_pixel_equals_the_shading_formula(gl_context, rng):
    model = ball_model(rng)
    r = Renderer(gl_context, fit=model)
    image = r.render(VIEW, "fitted", "pixel")
    position, normal, emitted, specular, covered = r.render_attributes(VIEW)
    o = model.objects[0]
    n = normal / np.linalg.norm(normal, axis=2, keepdims=True).clip(1e-12)
    w = np.asarray(VIEW.eye) - position
    w /= np.linalg.norm(w, axis=2, keepdims=True).clip(1e-12)
    expected = shade_arrays(emitted, specular, n, o.light_dirs, o.light_rgb, o.shininess, w)
    assert covered.sum() > 1000 and (~covered).sum() > 1000
    diff = np.abs(image[covered] - expected[covered])
    # float32 on the GPU against float64: pow(c, 300) amplifies c's rounding by 300
    assert (diff <= 2e-4 * np.abs(expected[covered]) + 1e-5).all(), diff.max()
    assert (image[~covered] == 0).all()  # background 0
    r.release()


def test_gouraud_vertex_colours_equal_shade_at_the_vertices(gl_context, rng):
    model = ball_model(rng)
    r = Renderer(gl_context, fit=model)
    o = model.objects[0]
    w = np.asarray(VIEW.eye) - o.positions.astype(np.float64)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    for lights in (None, 1, 2):
        got = r.vertex_colours(VIEW, "ball", "fitted", lights=lights)
        k = o.n_lights if lights is None else lights
        partial = FittedModel(objects=(FittedObject(
            name="ball", positions=o.positions, normals=o.normals, faces=o.faces, emitted=o.emitted, specular=o.specular,
            light_dirs=o.light_dirs[:k], light_rgb=o.light_rgb[:k], shininess=o.shininess[:k]),))
        expected = shade(partial, "ball", w)
        assert np.allclose(got, expected, rtol=2e-4, atol=1e-5)
    # and the rasterised Gouraud image stays within the vertex colours' range
    image = r.render(VIEW, "fitted", "gouraud")
    assert image.max() <= r.vertex_colours(VIEW, "ball", "fitted").max() * (1 + 1e-5)
    r.release()


def test_diffuse_mode_is_the_emitted_colour(gl_context, rng):
    model = ball_model(rng)
    r = Renderer(gl_context, fit=model)
    image = r.render(VIEW, "diffuse", "pixel")
    _, _, emitted, _, covered = r.render_attributes(VIEW)
    assert np.allclose(image[covered], emitted[covered], rtol=1e-6, atol=1e-7)
    assert (image[~covered] == 0).all()
    r.release()


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
    r = Renderer(gl_context, solution=solution)
    vertex = 2
    w = world(obj, vertex, directions.grid_directions(6)[cell])
    eye = obj.positions[vertex].astype(float) + 3.0 * w
    view = Camera(eye=tuple(eye), look_at=tuple(obj.positions[vertex].astype(float)), up=(0.3, 0.2, 0.9),
                fov_y_deg=30.0, width=8, height=8)
    got = r.vertex_colours(view, "quad", "reference")[vertex]
    # float32 atan/sqrt on the GPU move the bilinear weights by ~1e-5: neighbours leak in that much
    assert np.allclose(got, obj.radiance[vertex, cell], rtol=1e-3), (got, obj.radiance[vertex, cell])
    r.release()


def test_reference_interpolates_between_centres(gl_context, rng):
    solution = quad_solution(rng, grid=8)
    obj = solution.objects[0]
    r = Renderer(gl_context, solution=solution)
    vertex = 1
    for a, b in [(0.1, -0.3), (-0.55, 0.2), (0.0, 0.0)]:
        local = directions.square_to_hemisphere(a, b)
        idx, weight = directions.grid_lookup_weights(local, 8)
        expected = (weight[:, None] * obj.radiance[vertex, idx]).sum(axis=0)
        eye = obj.positions[vertex].astype(float) + 2.0 * world(obj, vertex, local)
        view = Camera(eye=tuple(eye), look_at=tuple(obj.positions[vertex].astype(float)), up=(0.3, 0.2, 0.9),
                    fov_y_deg=30.0, width=8, height=8)
        got = r.vertex_colours(view, "quad", "reference")[vertex]
        assert np.allclose(got, expected, rtol=1e-3), (a, b, got, expected)
    r.release()


def test_reference_per_pixel_matches_a_numpy_lookup(gl_context, rng):
    solution = quad_solution(rng, grid=8)
    obj = solution.objects[0]
    view = Camera(eye=(0.4, 1.5, 2.2), look_at=(0.0, 0.0, 0.0), fov_y_deg=60.0, width=40, height=30)
    r = Renderer(gl_context, solution=solution)
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
