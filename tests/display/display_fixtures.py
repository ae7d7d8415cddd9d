"""Helpers of the display tests: a tiny hand-made scene (no solve, no fit: made in
milliseconds) and checks of a command's refusal. The scene is a wall (diffuse) with a
tile (glossy, one virtual light) in front of it, seen by the framing view from -z."""

import numpy as np
from refusals import assert_refused  # noqa: F401 (the display tests' name for it)

from fitting import FittedModel, FittedObject
from fitting.model import directional
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions

DIFFUSE = {"diffuse": [0.5, 0.5, 0.5], "specular": [0.0, 0.0, 0.0], "exponent": 0.0, "emission": [0.0, 0.0, 0.0]}
GLOSSY = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.5, 0.5, 0.5], "exponent": 20.0, "emission": [0.0, 0.0, 0.0]}
GRID = 4


def square(half, z):
    """A square in the plane z facing -z (towards the framing view's camera)."""
    positions = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]], np.float32)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    normals = np.tile(np.float32([0, 0, -1]), (4, 1))
    tangents = np.tile(np.float32([1, 0, 0]), (4, 1))
    return positions, faces, normals, tangents


def tiny_solution(scale=1.0, glossy=True):
    """Radiance ``scale`` times a fixed pattern (0: a scene with no light)."""
    rng = np.random.default_rng(7)
    p, f, n, t = square(1.0, 0.0)
    wall = ObjectSolution("wall", p, n, t, f, directions.grid_directions(1).astype(np.float32),
                          np.full((4, 1, 3), 0.5 * scale, np.float32), DIFFUSE)
    objects = [wall]
    if glossy:
        p, f, n, t = square(0.4, -0.2)
        radiance = (rng.uniform(0.2, 2.0, (4, GRID * GRID, 3)) * scale).astype(np.float32)
        objects.append(ObjectSolution("tile", p, n, t, f, directions.grid_directions(GRID).astype(np.float32),
                                      radiance, GLOSSY))
    return Solution(objects=tuple(objects), settings={}, stats={}, scene="test")


def tiny_fit(solution, lights=1):
    """A fit of ``solution``: its radiance averaged over directions as the emitted
    colour, and ``lights`` virtual lights on its glossy objects."""
    objects = []
    for o in solution.objects:
        k = 0 if o.is_diffuse else lights
        dirs = np.tile(np.float32([0.2, 0.3, -0.9]) / np.linalg.norm([0.2, 0.3, -0.9]), (k, 1)).astype(np.float32)
        objects.append(FittedObject(
            name=o.name, positions=o.positions, normals=o.normals, faces=o.faces,
            emitted=o.radiance.mean(axis=1).astype(np.float32),
            specular=np.full((o.num_vertices, 3), 0.5 if k else 0.0, np.float32),
            light_pos=directional(dirs.reshape(k, 3)), light_rgb=np.full((k, 3), 1.5, np.float32),
            shininess=np.full(k, 10.0, np.float32),
        ))
    return FittedModel(objects=tuple(objects), source="test")


def tilted_tile_solution(wall, tile, angle_deg):
    """A wall of uniform radiance ``wall`` (a square of half side 4 at z = 0) and in front
    of it a tile of uniform radiance ``tile`` (half side 1 at z = -0.2), both diffuse and
    facing -z, the tile turned by ``angle_deg`` about the z axis: seen from -z along
    the axis, its edges are straight lines ``angle_deg`` off the pixel rows and columns."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], np.float32)
    objects = []
    for name, half, z, radiance, rotation in (("wall", 4.0, 0.0, wall, np.eye(3, dtype=np.float32)),
                                              ("tile", 1.0, -0.2, tile, turn)):
        p, f, n, t = square(half, z)
        objects.append(ObjectSolution(name, p @ rotation.T, n, t @ rotation.T, f,
                                      directions.grid_directions(1).astype(np.float32),
                                      np.full((4, 1, 3), radiance, np.float32), DIFFUSE))
    return Solution(objects=tuple(objects), settings={}, stats={}, scene="test")


def write_pair(directory, solution, lights=1):
    directory.mkdir(parents=True, exist_ok=True)
    solution_path, fit_path = directory / "solution.npz", directory / "fit.npz"
    solution.save(solution_path)
    tiny_fit(solution, lights).save(fit_path)
    return fit_path, solution_path


def listing(path):
    """Every file and directory under ``path`` (hidden ones included), relative."""
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


CAMERA = Camera(eye=(0.5, 0.25, -6.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=40.0)


def lit_model(per_light, rng, camera=CAMERA):
    """The tiny scene's wall (diffuse) and tile with three lights: two point, one distant;
    coefficients per light or shared, values that float32 rounding would show."""
    objects = []
    for o in tiny_solution().objects:
        v = o.num_vertices
        k = 0 if o.is_diffuse else 3
        light_pos = np.array([[0.3, 0.7, -2.0, 1.0], [-1.1, 0.2, -1.3, 1.0], [0.0, 0.0, 0.0, 0.0]], np.float32)[:k]
        if k:
            d = np.array([0.2, 0.3, -0.9])
            light_pos[2, :3] = d / np.linalg.norm(d)
        shape = (v, k, 3) if per_light and k else (v, 3)
        objects.append(FittedObject(
            name=o.name, positions=o.positions, normals=o.normals, faces=o.faces,
            emitted=rng.uniform(0, 3, (v, 3)).astype(np.float32),
            specular=(rng.uniform(0, 2, shape) if k else np.zeros(shape)).astype(np.float32),
            light_pos=light_pos, light_rgb=np.float32(rng.uniform(0.5, 1.5, (k, 3))),
            shininess=np.float32(rng.uniform(5, 80, k)),
        ))
    return FittedModel(objects=tuple(objects), source="test", model="mixed", camera=camera)
