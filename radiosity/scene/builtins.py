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

from radiosity.files.errors import InputError
from radiosity.files.sniff import BUILTIN_SCENES
from radiosity.scene import teapot

SCENES = BUILTIN_SCENES
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


TEXTURED_MESHES = ("quad", "disk", "cube", "sphere", "cylinder", "teapot")


def textured_mesh(spec, positions, faces, *, resolution=None):
    """The built-in mesh ``spec`` (its ``mesh`` (positions, faces)) with texture
    coordinates: (positions, faces, uvs (V, 2) float64), v up (``textures``), each
    unmirrored seen from the front (outside):

        quad      u = x + 1/2, v = 1/2 - z (seen from +y with -z up)
        disk      u = (x + 1) / 2, v = (y + 1) / 2 (seen from +z with +y up)
        cube      each face its own copy of the image, +y up on the sides, -z up on the
                  top, +z up on the bottom (24 vertices)
        sphere    the equirectangular (latitude-longitude) map, +y up: u = 1/2 +
                  atan2(x, z) / 2 pi (the image's middle faces +z, its seam -z), v = 1/2 +
                  asin(y) / pi; the seam's vertices doubled, each pole's copied per triangle
        cylinder  u = phi / 2 pi, phi counter-clockwise about +z from +x, v = z; the
                  seam (phi = 0) doubled
        teapot    each Bezier patch the whole image, upright on the body (``teapot``);
                  the flat ring closing the lid's gap a planar map of x and z

    ``resolution`` is the teapot's (``mesh``). InputError for the other built-ins.
    """
    if spec == "quad":
        return positions, faces, np.stack([positions[:, 0] + 0.5, 0.5 - positions[:, 2]], axis=1)
    if spec == "disk":
        return positions, faces, 0.5 * (positions[:, :2] + 1.0)
    if spec == "cube":
        return _textured_cube()
    if spec == "sphere":
        return spherical_uvs(positions, faces, axis=1, front=2)
    if spec == "cylinder":
        return _textured_cylinder(positions)
    if spec == "teapot":
        return teapot.tessellate_with_uvs(8 if resolution is None else resolution)
    raise InputError(
        f"builtin {spec!r} has no texture coordinates: a textured material needs builtin "
        f"{', '.join(TEXTURED_MESHES[:-1])} or {TEXTURED_MESHES[-1]}, or a mesh file with uvs"
    )


def split_by_corner_uvs(positions, faces, corner_uvs):
    """A mesh whose texture coordinates are given per triangle corner, corner_uvs (F,
    3, 2), as per-vertex uvs: each vertex copied once per distinct uv it takes (a
    seam's two sides, a pole's fan). Returns (positions, faces, uvs)."""
    keys = np.concatenate([faces.reshape(-1, 1).astype(np.float64), corner_uvs.reshape(-1, 2)], axis=1)
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    return positions[unique[:, 0].astype(np.int64)], inverse.reshape(-1, 3).astype(np.int64), unique[:, 1:].copy()


def spherical_uvs(positions, faces, *, axis=1, front=2, mitsuba=False):
    """A sphere mesh about the origin with latitude-longitude texture coordinates
    (``split_by_corner_uvs``: the seam's vertices doubled, u unwrapped per triangle so
    that none spans the seam the long way; a pole's copies take the mean u of their
    triangle's other corners).

    Ours (``mitsuba`` False): ``axis`` the pole (v up towards +axis), ``front`` the
    direction the image's middle faces; u grows anticlockwise about +axis seen from
    outside. ``mitsuba``: Mitsuba 3's sphere, u = phi / 2 pi with phi = atan2(y, x) in
    [0, 2 pi) and its v = theta / pi with theta = acos(z), as our v = 1 - theta / pi.
    """
    p = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    if mitsuba:
        phi = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * np.pi)
        u, v = phi / (2 * np.pi), 1.0 - np.arccos(np.clip(p[:, 2], -1, 1)) / np.pi
        pole = np.hypot(p[:, 0], p[:, 1]) < 1e-9
    else:
        side = 3 - axis - front  # the third axis: u grows from front towards side, (front, side, axis) right-handed
        sign = 1.0 if np.linalg.det(np.eye(3)[[front, side, axis]]) > 0 else -1.0
        u = 0.5 + np.arctan2(sign * p[:, side], p[:, front]) / (2 * np.pi)
        v = 0.5 + np.arcsin(np.clip(p[:, axis], -1, 1)) / np.pi
        pole = np.hypot(p[:, side], p[:, front]) < 1e-9
    corner_u, corner_v, corner_pole = u[faces], v[faces], pole[faces]
    highest = np.where(corner_pole, -np.inf, corner_u).max(axis=1)
    lowest = np.where(corner_pole, np.inf, corner_u).min(axis=1)
    wraps = highest - lowest > 0.5
    corner_u = np.where(wraps[:, None] & (corner_u < 0.5), corner_u + 1.0, corner_u)
    others = np.where(corner_pole, 0.0, corner_u).sum(axis=1) / np.maximum((~corner_pole).sum(axis=1), 1)
    corner_u = np.where(corner_pole, others[:, None], corner_u)
    return split_by_corner_uvs(positions, faces, np.stack([corner_u, corner_v], axis=2))


def _textured_cylinder(positions):
    """The built-in cylinder (``cylinder``: ``segments`` vertices per ring) with the
    seam's column doubled: u = phi / 2 pi, v = z."""
    n = len(positions) // 2
    positions, faces = cylinder(n, seam=True)
    angle = np.arctan2(positions[:, 1], positions[:, 0])
    u = np.mod(angle, 2 * np.pi) / (2 * np.pi)
    u[np.arange(len(u)) % (n + 1) == n] = 1.0  # the seam's second copy
    return positions, faces, np.stack([u, positions[:, 2]], axis=1)


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


def cylinder(segments, seam=False):
    """The open cylinder of radius 1 from z = 0 to z = 1, facing outwards: two rings
    of ``segments`` vertices (``seam``: ``segments + 1``, the last a copy of the first,
    for a texture's seam)."""
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], 1)
    if seam:
        circle = np.concatenate([circle, circle[:1]])
    columns = len(circle)
    positions = np.concatenate([np.c_[circle, np.zeros(columns)], np.c_[circle, np.ones(columns)]])
    ring = np.arange(segments)
    nxt = (ring + 1) % columns
    faces = np.concatenate([np.stack([ring, nxt, columns + nxt], 1), np.stack([ring, columns + nxt, columns + ring], 1)])
    return positions, faces.astype(np.int64)
