"""Scenes whose pictures are known, for the displays' depth and sides, and the numpy
ray caster that knows them.

A room of side ``ROOM`` (10 m at scale 1), open towards -z: floor, ceiling, left, right
and back walls, each one-sided and facing in; a panel hung ``GAP`` (1 mm) in front of the
back wall, facing the room; and across the middle a two-sided partition, built as the
scene loaders build one (``radiosity.scene.model.with_backs``: the front and a reversed
copy BACK_OFFSET of the diagonal behind it, each with its own radiance here, as the
solver gives each its own). Every object is diffuse with one radiance, so each display
mode shows that radiance, and a pixel's answer is the radiance of the nearest triangle
its centre's ray meets if the ray meets its front, 0 if its back (surfaces are
one-sided: the back absorbs), the environment (or 0) if none: ``expected``, in float64,
against every triangle. Everything scales by ``scale`` (1e-3: a 1 cm room with a 1 um
gap; 1e4: a 100 km room with a 10 m gap), eyes included.
"""

import numpy as np

from fitting import FittedModel, FittedObject
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.physics.environment import EnvironmentLight
from radiosity.physics.materials import Material
from radiosity.scene.model import BACK_OFFSET, build_object, with_backs

ROOM = 10.0   # the room's side at scale 1 (metres)
GAP = 1e-3    # the panel's gap in front of the back wall at scale 1
SIZE = (96, 72)
SKY = (0.05, 0.15, 0.6)  # the constant environment's radiance, where one is given

# name: (radiance, a corner, the two edges from it; the front is edge 1 x edge 2)
WALLS = {
    "floor": ((0.30, 0.25, 0.20), (0, 0, 0), (0, 0, 10), (10, 0, 0)),
    "ceiling": ((0.60, 0.60, 0.55), (0, 10, 0), (10, 0, 0), (0, 0, 10)),
    "left": ((0.20, 0.30, 0.50), (0, 0, 0), (0, 10, 0), (0, 0, 10)),
    "right": ((0.50, 0.30, 0.20), (10, 0, 0), (0, 0, 10), (0, 10, 0)),
    "back": ((0.40, 0.40, 0.30), (0, 0, 10), (0, 10, 0), (10, 0, 0)),
    "panel": ((0.90, 0.10, 0.10), (3, 6.5, 10 - GAP), (0, 2.5, 0), (4, 0, 0)),
    "partition": ((0.10, 0.80, 0.20), (2, 0, 5), (0, 6, 0), (6, 0, 0)),
    "rug": ((0.20, 0.60, 0.60), (3, GAP, 6), (0, 0, 3.5), (4, 0, 0)),
}
PARTITION_BACK = (0.80, 0.70, 0.10)  # the partition's back copy: seen from +z

# name: (eye, look at) at scale 1
VIEWS = {
    "inside, the partition's front": ((5.0, 3.0, 1.0), (5.2, 3.5, 10.0)),
    "inside, the partition's back": ((5.0, 3.0, 9.0), (4.8, 3.5, 0.0)),
    "inside, the panel's gap": ((5.0, 7.5, 6.0), (5.3, 7.6, 10.0)),
    "inside, along the partition": ((1.0, 3.0, 4.0), (9.0, 3.2, 5.6)),
    "outside, in at the open side": ((5.0, 5.0, -20.0), (5.0, 5.0, 10.0)),
    "outside, behind the back wall": ((5.5, 5.0, 22.0), (5.0, 5.0, 0.0)),
    "inside, grazing along the back wall": ((0.5, 7.5, 9.0), (9.5, 7.7, 9.9)),
    "inside, the rug on the floor": ((5.0, 1.6, 5.2), (5.1, 0.0, 9.0)),
}


def room_objects(scale=1.0):
    """The room's objects (``radiosity.scene.model.SceneObject``) at ``scale``, the
    partition two-sided (``with_backs``), and {name: radiance}."""
    objects, radiance = [], {}
    for name, (rgb, corner, u, v) in WALLS.items():
        c, u, v = (np.asarray(x, np.float64) * scale for x in (corner, u, v))
        # split in 2 x 2 cells: the walls' triangles are long, as an interior's are, but not one
        n = 2
        s, t = np.meshgrid(np.arange(n + 1) / n, np.arange(n + 1) / n, indexing="ij")
        positions = c + s.reshape(-1, 1) * u + t.reshape(-1, 1) * v
        i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
        faces = np.concatenate([np.stack([i, i + n + 1, i + 1], 1), np.stack([i + 1, i + n + 1, i + n + 2], 1)])
        objects.append(build_object(name, Material(name, (0.5, 0.5, 0.5)), positions, faces))
        radiance[name] = rgb
    objects = with_backs(objects, {"partition"})
    radiance["partition (back)"] = PARTITION_BACK
    return objects, radiance


def view(name, scale=1.0, size=SIZE, fov=60.0):
    eye, look = VIEWS[name]
    return Camera(tuple(np.multiply(eye, scale)), tuple(np.multiply(look, scale)), (0.0, 1.0, 0.0), fov, *size)


def solution(scale=1.0, environment=False):
    """The room as a ``Solution`` (every object one radiance in every direction) and as a
    ``FittedModel`` of no lights (the same radiance emitted)."""
    objects, radiance = room_objects(scale)
    env = EnvironmentLight(np.float32([[SKY]]), 1.0, constant=True) if environment else None
    material = {"diffuse": [0.5, 0.5, 0.5], "specular": [0.0, 0.0, 0.0], "exponent": 0.0, "emission": [0.0, 0.0, 0.0]}
    solved, fitted = [], []
    for o in objects:
        v = len(o.positions)
        rgb = np.tile(np.float32(radiance[o.name]), (v, 1))
        solved.append(ObjectSolution(o.name, o.positions.astype(np.float32), o.normals.astype(np.float32),
                                     o.tangents.astype(np.float32), o.faces.astype(np.int32),
                                     directions.grid_directions(1).astype(np.float32), rgb[:, None, :], material))
        fitted.append(FittedObject(name=o.name, positions=o.positions.astype(np.float32),
                                   normals=o.normals.astype(np.float32), faces=o.faces.astype(np.int32), emitted=rgb,
                                   specular=np.zeros((v, 3), np.float32), light_pos=np.zeros((0, 4), np.float32),
                                   light_rgb=np.zeros((0, 3), np.float32), shininess=np.zeros(0, np.float32)))
    return (Solution(objects=tuple(solved), scene="depth", environment=env),
            FittedModel(objects=tuple(fitted), source="depth", environment=env))


CHUNK = 16384  # rays cast at a time (each against every triangle of an object)


def expected(objects, camera, background=(0.0, 0.0, 0.0)):
    """What each pixel's centre sees, by ray casting in float64 against every triangle of
    ``objects`` ((name, positions (V, 3), faces (F, 3), rgb) tuples: ``casting``): (image
    (H, W, 3) float64, row 0 at the top: the nearest triangle's rgb where the ray meets
    its front, 0 where its back, ``background`` where none; what (H, W) int: the nearest
    object's index, -1 where none; front (H, W) bool)."""
    rays = camera.pixel_rays().reshape(-1, 3)
    eye = np.asarray(camera.eye, np.float64)
    best = np.full(len(rays), np.inf)
    what = np.full(len(rays), -1)
    front = np.zeros(len(rays), bool)
    for index, (_, positions, faces, _) in enumerate(objects):
        # Moller-Trumbore with the eye fixed: det, u and v are dot products of the ray with
        # a vector per triangle, a chunk of rays against every triangle in three products
        tri = np.asarray(positions, np.float64)[faces]  # (T, 3, 3)
        a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        normal = np.cross(e1, e2)  # det = -d . normal
        s = eye[None, :] - a
        w = np.cross(e2, s)  # u det = d . w
        q = np.cross(s, e1)  # v det = d . q
        tq = np.einsum("tc,tc->t", e2, q)  # t det
        for start in range(0, len(rays), CHUNK):
            d = rays[start:start + CHUNK]
            det = -(d @ normal.T)  # (P, T)
            ok = np.abs(det) > 1e-300
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            u, v, t = (d @ w.T) * inv, (d @ q.T) * inv, tq[None, :] * inv
            t = np.where(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0), t, np.inf)
            nearest = t.argmin(axis=1)
            tn = t[np.arange(len(d)), nearest]
            closer = tn < best[start:start + CHUNK]
            rows = np.nonzero(closer)[0] + start
            best[rows] = tn[closer]
            what[rows] = index
            front[rows] = np.einsum("pc,pc->p", d[closer], normal[nearest[closer]]) < 0
    image = np.tile(np.float64(background), (len(rays), 1))
    for index, (_, _, _, rgb) in enumerate(objects):
        image[(what == index) & front] = rgb
        image[(what == index) & ~front] = 0.0
    shape = (camera.height, camera.width)
    return image.reshape(*shape, 3), what.reshape(shape), front.reshape(shape)


def interior(what, front, radius=1):
    """(H, W) bool: pixels whose neighbourhood of (2 radius + 1)^2 pixels sees the same
    object from the same side (an edge's pixels depend on the rasteriser's rounding,
    and with several samples a pixel on its coverage: not checked), those ``radius``
    from the picture's border excluded (what lies beyond it is not known here)."""
    key = np.where(front, what + 1, -(what + 2))
    padded = np.pad(key, radius, constant_values=np.iinfo(key.dtype).min)
    same = np.ones(key.shape, bool)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            same &= padded[radius + dy: radius + dy + key.shape[0], radius + dx: radius + dx + key.shape[1]] == key
    return same


def casting(model):
    """(name, positions, faces, rgb) of every object of a Solution or a FittedModel:
    ``expected``'s input (each object's radiance is uniform)."""
    out = []
    for o in model.objects:
        rgb = o.radiance[0, 0] if hasattr(o, "radiance") else o.emitted[0]
        out.append((o.name, o.positions, o.faces, tuple(float(c) for c in rgb)))
    return out


def wrong_pixels(image, want, checked, rtol=1e-3, atol=1e-4):
    """(H, W) bool: checked pixels of ``image`` differing from ``want`` beyond the tolerance."""
    return checked & (np.abs(np.asarray(image, np.float64) - want) > rtol * np.abs(want) + atol).any(axis=2)


__all__ = ["BACK_OFFSET", "GAP", "ROOM", "SIZE", "SKY", "VIEWS", "WALLS", "casting", "expected", "interior",
           "room_objects", "solution", "view", "wrong_pixels"]
