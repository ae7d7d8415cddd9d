"""The environment drawn where no object is, against its numpy reference
(``radiosity.physics.environment.EnvironmentLight.radiance`` at each pixel's ray,
``Camera.pixel_rays``), in every mode, turned and scaled; objects in front hide it."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from display.renderer import Renderer
from fitting import FitOptions, fit
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.environment import EnvironmentLight

pytestmark = pytest.mark.gl


def sky(rng, rows=9, columns=16):
    return rng.uniform(0.1, 3.0, (rows, columns, 3)).astype(np.float32)


def square(z=0.0, half=0.5):
    positions = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], np.float64)
    material = {"diffuse": [0.5, 0.5, 0.5], "specular": [0, 0, 0], "exponent": 0.0, "emission": [0, 0, 0]}
    return ObjectSolution(name="square", positions=positions, normals=np.tile([0.0, 0, 1], (4, 1)),
                          tangents=np.tile([1.0, 0, 0], (4, 1)), faces=np.array([[0, 1, 2], [0, 2, 3]]),
                          directions=np.array([[0.0, 0.0, 1.0]]), radiance=np.full((4, 1, 3), 0.25), material=material)


@pytest.mark.parametrize("mode", ["reference", "fitted", "diffuse"])
@pytest.mark.parametrize("turned", [False, True])
def test_the_background_is_the_environment(gl_context, rng, mode, turned):
    rotation = Rotation.from_euler("xyz", [20, -70, 10], degrees=True).as_matrix() if turned else np.eye(3)
    env = EnvironmentLight(sky(rng), 1.7, rotation)
    solution = Solution(objects=(square(),), scene="test", environment=env)
    model = fit(solution, FitOptions.for_quality("draft"))
    assert model.environment is env
    camera = Camera((0.3, 0.2, 3.0), (0.0, 0.1, 0.0), up=(0.0, 1.0, 0.0), fov_deg=100, width=48, height=32)
    renderer = Renderer(gl_context, fit=model, solution=solution, samples=1)
    image = renderer.render(camera, mode=mode).astype(np.float64)
    rays = camera.pixel_rays()
    s = -camera.eye[2] / rays[..., 2]
    p = np.asarray(camera.eye) + s[..., None] * rays
    on_square = (s > 0) & (np.abs(p[..., 0]) < 0.52) & (np.abs(p[..., 1]) < 0.52)
    background = ~on_square
    expected = env.radiance(rays.reshape(-1, 3)).reshape(image.shape)
    assert background.sum() > 1000
    assert np.allclose(image[background], expected[background], rtol=2e-3, atol=1e-4)
    inside = (s > 0) & (np.abs(p[..., 0]) < 0.45) & (np.abs(p[..., 1]) < 0.45)
    assert not np.allclose(image[inside], expected[inside], rtol=0.05)  # the object hides it
    renderer.release()


def test_without_an_environment_the_background_is_black(gl_context):
    solution = Solution(objects=(square(),), scene="test")
    camera = Camera((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), fov_deg=90, width=16, height=16)
    image = Renderer(gl_context, solution=solution, samples=1).render(camera, mode="reference")
    assert image[0, 0].tolist() == [0.0, 0.0, 0.0]
