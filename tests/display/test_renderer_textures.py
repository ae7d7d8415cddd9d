"""A textured object on the GPU against numpy: every display adds kd * texture(uv) / pi
* E per pixel, uv and E interpolated from the vertices, the texture read as
``radiosity.physics.textures.lookup`` reads it (bilinear between texel centres,
repeating, v up).

The scene: a square facing the camera, drawn with one sample per pixel (the pixel
centres), its uvs and irradiance affine in position (so interpolating them from the
corners is exact, and each pixel centre's values are known in closed form) and the
texture magnified (each texel several pixels wide, where GL reads mip level 0).
"""

import numpy as np
import pytest

from display.renderer import Renderer
from fitting import FitOptions, fit
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.textures import TexturedDiffuse, lookup

pytestmark = pytest.mark.gl

KD = (0.9, 0.7, 0.5)
CAMERA = Camera((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=45, width=40, height=40)
RTOL, ATOL = 2e-4, 1e-5


def uv_of(p):
    """The square's uvs: u runs past 1 (the texture repeats), v up."""
    return np.stack([(p[..., 0] + 1) * 0.75, (p[..., 1] + 1) * 0.5], axis=-1)


def irradiance_of(p):
    return np.stack([2 + p[..., 0], 2 + 0.5 * p[..., 1], 1.5 - 0.3 * p[..., 0] + 0.2 * p[..., 1]], axis=-1)


def square_solution(texture, glossy=False, rest=0.05):
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    tangents = np.tile([1.0, 0.0, 0.0], (4, 1))
    textured = TexturedDiffuse(uvs=uv_of(positions), irradiance=irradiance_of(positions), texture=texture, kd=KD)
    if glossy:
        from radiosity.physics.directions import grid_directions

        dirs = grid_directions(4)
        material = {"diffuse": list(KD), "specular": [0.05] * 3, "exponent": 4.0, "emission": [0, 0, 0]}
    else:
        dirs = np.array([[0.0, 0.0, 1.0]])
        material = {"diffuse": list(KD), "specular": [0, 0, 0], "exponent": 0.0, "emission": [rest] * 3}
    radiance = np.full((4, len(dirs), 3), rest)
    obj = ObjectSolution(name="square", positions=positions, normals=normals, tangents=tangents, faces=faces,
                         directions=dirs, radiance=radiance, material=material, textured=textured)
    return Solution(objects=(obj,), scene="test")


def expected_image(texture, camera=CAMERA):
    """kd * lookup(texture, uv) / pi * E at each pixel centre's point on the square
    (z = 0), and the mask of pixels whose centre is on it (away from its edges)."""
    d = camera.pixel_rays()
    s = -camera.eye[2] / d[..., 2]
    p = np.asarray(camera.eye) + s[..., None] * d
    inside = (np.abs(p[..., 0]) < 0.97) & (np.abs(p[..., 1]) < 0.97)
    value = np.asarray(KD) / np.pi * lookup(texture, uv_of(p)) * irradiance_of(p)
    return value, inside


@pytest.fixture
def texture(rng):
    return rng.uniform(0.05, 1.0, (3, 5, 3)).astype(np.float32)  # each texel its own colour: asymmetric


@pytest.mark.parametrize("mode, shading", [
    ("reference", "pixel"), ("reference", "gouraud"), ("fitted", "pixel"), ("fitted", "gouraud"),
    ("diffuse", "pixel"), ("diffuse", "gouraud"),
])
def test_every_display_adds_the_texture_per_pixel(gl_context, texture, mode, shading):
    solution = square_solution(texture)
    model = fit(solution, FitOptions.for_quality("draft"))
    renderer = Renderer(gl_context, fit=model, solution=solution, samples=1)
    image = renderer.render(CAMERA, mode=mode, shading=shading).astype(np.float64)
    expected, inside = expected_image(texture)
    rest = model.object("square").emitted[0] if mode == "fitted" else np.full(3, 0.05)
    assert inside.sum() > 400
    assert np.allclose(image[inside], expected[inside] + rest, rtol=RTOL, atol=ATOL + 2e-3 * (mode == "fitted"))
    # not mirrored or flipped: the image upside down is far off
    assert np.abs(image[::-1][inside] - expected[inside] - rest).max() > 0.05
    renderer.release()


def test_a_glossy_textured_object_in_the_reference_display(gl_context, texture):
    solution = square_solution(texture, glossy=True)
    renderer = Renderer(gl_context, solution=solution, samples=1)
    image = renderer.render(CAMERA, mode="reference", shading="pixel").astype(np.float64)
    expected, inside = expected_image(texture)
    assert np.allclose(image[inside], expected[inside] + 0.05, rtol=RTOL, atol=ATOL)
    renderer.release()


def test_an_untextured_object_beside_it_is_untouched(gl_context, texture):
    """The textured program is used for the textured object alone."""
    solution = square_solution(texture)
    o = solution.object("square")
    plain = ObjectSolution(name="plain", positions=o.positions * [2, 2, 1] + [0, 0, -0.5], normals=o.normals, tangents=o.tangents,
                           faces=o.faces, directions=o.directions, radiance=o.radiance * 0 + 0.3, material=o.material)
    both = Solution(objects=(o, plain), scene="test")
    wide = Camera((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=80, width=40, height=40)
    image = Renderer(gl_context, solution=both, samples=1).render(wide, mode="reference")
    d = wide.pixel_rays()
    p = np.asarray(wide.eye) + (-(wide.eye[2] + 0.5) / d[..., 2])[..., None] * d
    behind = (np.abs(p[..., 0]) < 1.97) & (np.abs(p[..., 1]) < 1.97)
    front = np.asarray(wide.eye) + (-wide.eye[2] / d[..., 2])[..., None] * d
    uncovered = behind & ~((np.abs(front[..., 0]) < 1.03) & (np.abs(front[..., 1]) < 1.03))
    assert uncovered.sum() > 20
    assert np.allclose(image[uncovered], 0.3, rtol=1e-6)


def halves(texture, other):
    """The square as two objects, its left half textured with ``texture`` and its right
    half with ``other``: the same array, or an equal copy."""
    square = square_solution(texture).object("square")
    objects = []
    for name, x0, image in (("left", -1.0, texture), ("right", 0.0, other)):
        positions = np.array([[x0, -1, 0], [x0 + 1, -1, 0], [x0 + 1, 1, 0], [x0, 1, 0]], np.float64)
        textured = TexturedDiffuse(uvs=uv_of(positions), irradiance=irradiance_of(positions), texture=image, kd=KD)
        objects.append(ObjectSolution(name=name, positions=positions, normals=square.normals, tangents=square.tangents,
                                      faces=square.faces, directions=square.directions, radiance=square.radiance,
                                      material=square.material, textured=textured))
    return Solution(objects=tuple(objects), scene="test")


@pytest.mark.parametrize("same", [True, False])
def test_objects_that_share_an_image_share_its_texture(gl_context, texture, same):
    """Two objects with the very same image array (as a file's reader gives objects that
    share an image) make one texture, counted once in the renderer's estimate and its
    uploaded bytes; an equal copy makes its own. Either draws the square as one object."""
    solution = halves(texture, texture if same else texture.copy())
    renderer = Renderer(gl_context, solution=solution, samples=1)
    image = renderer.render(CAMERA, mode="reference", shading="pixel").astype(np.float64)
    expected, inside = expected_image(texture)
    inside &= np.abs(np.arange(CAMERA.width) - (CAMERA.width - 1) / 2) > 1.0  # off the seam between the halves
    assert np.allclose(image[inside], expected[inside] + 0.05, rtol=RTOL, atol=ATOL)
    made = len(renderer.images._textures)
    assert made == (1 if same else 2)
    assert renderer.images.nbytes == made * texture.size * 4 * 4 // 3
    one = Renderer(gl_context, solution=halves(texture, texture), samples=1)
    two = Renderer(gl_context, solution=halves(texture, texture.copy()), samples=1)
    assert two.estimate.buffers - one.estimate.buffers == texture.size * 4 * 4 // 3
    for r in (renderer, one, two):
        r.release()
