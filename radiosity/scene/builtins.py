"""Built-in meshes (``builtin = "..."`` in a scene file) and built-in scenes.

Meshes, each a raw (positions (V, 3) float64, faces (F, 3) int64) pair, fronts out:

    teapot          the Utah teapot, data units (height 3.15), y up, bottom on y = 0
    sphere          unit icosphere about the origin
    quad            unit square in the xz plane about the origin, front facing +y
    cube            unit cube about the origin
    cornell:<part>  a part of the measured Cornell box, millimetres: floor, ceiling,
                    back_wall, left_wall, right_wall, short_block, tall_block, light;
                    walls face into the box, blocks face out, the light faces down

Scenes are TOML files shipped in ``radiosity/scene/data``: ``cornell``, ``cornell-teapot`` and
``plates`` (glossy plates under sphere lamps, after Veach's multiple-importance-sampling scene).
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources

import numpy as np
import trimesh

from radiosity.formats.errors import InputError
from radiosity.scene import teapot

SCENES = ("cornell", "cornell-teapot", "plates")
MESHES = ("teapot", "sphere", "quad", "cube", "disk", "cylinder", "cornell:<part>")
LIGHT_DROP_MM = 0.1  # the measured light lies in the ceiling plane; lower it this much


@lru_cache(maxsize=1)
def cornell_data():
    return json.loads(resources.files("radiosity.scene").joinpath("data/cornell_box.json").read_text())


def cornell_parts():
    return tuple(cornell_data()["objects"])


def scene_path(name):
    """Path of a built-in scene's TOML file."""
    if name not in SCENES:
        raise InputError(f"unknown built-in scene {name!r}; built-in scenes: {', '.join(SCENES)}")
    return resources.files("radiosity.scene").joinpath(f"data/{name}.toml")


def mesh(spec, *, resolution=None, subdivisions=None, segments=None):
    """Positions and faces of the built-in mesh named ``spec``.

    ``resolution`` applies to the teapot (segments per patch side, default 8),
    ``subdivisions`` to the sphere (icosphere levels, default 3), ``segments`` to the
    disk (the unit disk in z = 0, facing +z) and the cylinder (radius 1, z from 0 to 1,
    open, facing out), around their circle (default 64).
    """
    if segments is not None and spec not in ("disk", "cylinder"):
        raise InputError(f"'segments' applies to builtin 'disk' and 'cylinder' only, not {spec!r}")
    if spec in ("disk", "cylinder"):
        n = 64 if segments is None else segments
        if not isinstance(n, int) or isinstance(n, bool) or not 3 <= n <= 4096:
            raise InputError(f"{spec} segments must be a whole number from 3 to 4096, got {n!r}")
        return disk(n) if spec == "disk" else cylinder(n)
    if resolution is not None and spec != "teapot":
        raise InputError(f"'resolution' applies to builtin 'teapot' only, not {spec!r}")
    if subdivisions is not None and spec != "sphere":
        raise InputError(f"'subdivisions' applies to builtin 'sphere' only, not {spec!r}")
    if spec == "teapot":
        res = 8 if resolution is None else resolution
        if not isinstance(res, int) or isinstance(res, bool) or not 2 <= res <= 256:
            raise InputError(f"teapot resolution must be a whole number from 2 to 256, got {res!r}")
        return teapot.tessellate(res)
    if spec == "sphere":
        levels = 3 if subdivisions is None else subdivisions
        if not isinstance(levels, int) or isinstance(levels, bool) or not 0 <= levels <= 8:
            raise InputError(f"sphere subdivisions must be a whole number from 0 to 8, got {levels!r}")
        s = trimesh.creation.icosphere(subdivisions=levels, radius=1.0)
        return np.asarray(s.vertices, dtype=np.float64), np.asarray(s.faces, dtype=np.int64)
    if spec == "quad":
        p = np.array([[-0.5, 0, -0.5], [-0.5, 0, 0.5], [0.5, 0, 0.5], [0.5, 0, -0.5]], dtype=np.float64)
        return p, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    if spec == "cube":
        b = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
        return np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces, dtype=np.int64)
    if spec.startswith("cornell:"):
        return _cornell_part(spec.split(":", 1)[1])
    raise InputError(
        f"unknown builtin mesh {spec!r}; built-in meshes: {', '.join(MESHES)} "
        f"(parts: {', '.join(cornell_parts())})"
    )


TEXTURED_MESHES = ("quad", "disk", "cube")


def textured_mesh(spec, positions, faces):
    """The built-in mesh ``spec`` (its ``mesh`` (positions, faces)) with texture
    coordinates: (positions, faces, uvs (V, 2) float64), v up (``textures``). Each
    face reads the whole image, unmirrored seen from the front:

        quad  u = x + 1/2, v = 1/2 - z (seen from +y with -z up)
        disk  u = (x + 1) / 2, v = (y + 1) / 2 (seen from +z with +y up)
        cube  each face its own copy of the image, +y up on the sides, -z up on the
              top, +z up on the bottom (24 vertices)

    InputError for the other built-ins, which have no texture coordinates.
    """
    if spec == "quad":
        return positions, faces, np.stack([positions[:, 0] + 0.5, 0.5 - positions[:, 2]], axis=1)
    if spec == "disk":
        return positions, faces, 0.5 * (positions[:, :2] + 1.0)
    if spec == "cube":
        return _textured_cube()
    raise InputError(
        f"builtin {spec!r} has no texture coordinates: a textured material needs builtin "
        f"{', '.join(TEXTURED_MESHES[:-1])} or {TEXTURED_MESHES[-1]}, or a mesh file with uvs"
    )


def _textured_cube():
    positions, faces, uvs = [], [], []
    y, z = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    for normal in np.concatenate([np.eye(3), -np.eye(3)]):
        up = y if abs(normal[1]) == 0 else -normal[1] * z  # top: -z up; bottom: +z up
        right = np.cross(up, normal)
        corners = [0.5 * (normal + su * right + sv * up) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        base = len(positions)
        positions += corners
        uvs += [[(su + 1) / 2, (sv + 1) / 2] for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]  # counter-clockwise about the normal
    return np.array(positions), np.array(faces, dtype=np.int64), np.array(uvs)


def _cornell_part(part):
    objects = cornell_data()["objects"]
    if part not in objects:
        raise InputError(f"unknown Cornell box part {part!r}; parts: {', '.join(objects)}")
    quads = np.asarray(objects[part]["quads"], dtype=np.float64)  # (Q, 4, 3)
    if part == "light":
        quads[:, :, 1] -= LIGHT_DROP_MM
    # the measured winding is not consistent: orient each quad by where it must face
    box_centre = np.array([278.0, 274.4, 279.6])
    part_centre = quads.reshape(-1, 3).mean(axis=0)
    positions, faces = [], []
    for q in quads:
        normal = np.cross(q[1] - q[0], q[2] - q[0]) + np.cross(q[2] - q[0], q[3] - q[0])
        if part == "light":
            wanted = np.array([0.0, -1.0, 0.0])
        elif part.endswith("block"):
            wanted = q.mean(axis=0) - part_centre  # out of the block
        else:
            wanted = box_centre - q.mean(axis=0)  # into the box
        if normal @ wanted < 0:
            q = q[::-1]
        base = 4 * len(positions)
        positions.append(q)
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return np.concatenate(positions), np.asarray(faces, dtype=np.int64)


def disk(segments):
    """The unit disk in z = 0, facing +z: a fan of ``segments`` triangles."""
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    positions = np.concatenate([[[0.0, 0.0, 0.0]], np.stack([np.cos(angles), np.sin(angles), 0 * angles], 1)])
    ring = np.arange(segments)
    faces = np.stack([np.zeros(segments, dtype=np.int64), 1 + ring, 1 + (ring + 1) % segments], 1)
    return positions, faces


def cylinder(segments):
    """The open cylinder of radius 1 from z = 0 to z = 1, facing outwards."""
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], 1)
    positions = np.concatenate([np.c_[circle, np.zeros(segments)], np.c_[circle, np.ones(segments)]])
    ring = np.arange(segments)
    nxt = (ring + 1) % segments
    faces = np.concatenate([np.stack([ring, nxt, segments + nxt], 1), np.stack([ring, segments + nxt, segments + ring], 1)])
    return positions, faces.astype(np.int64)
