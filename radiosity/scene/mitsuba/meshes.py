"""The shapes' triangles: Mitsuba's serialized mesh format, OBJ and PLY files, and the
analytic shapes tessellated (``Tessellation``).
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from radiosity.files.errors import InputError
from radiosity.files.inputs import MESH_BYTES, read_input_bytes
from radiosity.scene import builtins
from radiosity.scene.meshfiles import read_mesh_parts

MAX_SERIALIZED_VERTICES = 1 << 25  # a serialized shape claiming more (33.5 M) is refused before it is inflated


@dataclass(frozen=True)
class Tessellation:
    """How finely analytic shapes become triangles: ``segments`` around a disk or a
    cylinder, ``sphere_levels`` icosphere subdivisions (level 3: 1,280 triangles)."""

    segments: int = 64
    sphere_levels: int = 3

    def __post_init__(self):
        if not (isinstance(self.segments, int) and 3 <= self.segments <= 4096):
            raise InputError(f"tessellation: segments must be a whole number from 3 to 4096, got {self.segments!r}")
        if not (isinstance(self.sphere_levels, int) and 0 <= self.sphere_levels <= 7):
            raise InputError(
                f"tessellation: sphere levels must be a whole number from 0 to 7, got {self.sphere_levels!r}"
            )



_SERIALIZED_MAGIC = 0x041C
_HAS_NORMALS, _HAS_TEXCOORDS, _HAS_COLORS, _DOUBLE = 0x0001, 0x0002, 0x0008, 0x2000


def read_serialized(data, index=0, where="serialized"):
    """Positions (V, 3), faces (F, 3), normals (V, 3) or None and texture coordinates
    (V, 2) or None (as stored: Mitsuba's convention, v down) of shape ``index`` of a
    Mitsuba ``.serialized`` file's bytes.

    Layout (Mitsuba's documentation of ``serialized``): a file is a run of shapes, each
    a uint16 format identifier 0x041C, a uint16 version (3 or 4), then a zlib stream
    of: uint32 flags (0x1 normals, 0x2 texture coordinates, 0x8 colours, 0x2000 double
    precision), in version 4 the shape's UTF-8 name ending in NUL, uint64 vertex count,
    uint64 triangle count, positions, normals, texture coordinates (2 per vertex) and
    colours as present, in float32 or float64, then the triangles' vertex indices
    (uint32, or uint64 beyond 2^32 vertices). The file ends in a table of each shape's
    byte offset (uint64 in version 4, uint32 in 3) and a uint32 count of shapes.
    """
    if len(data) < 8:
        raise InputError(f"{where}: too short for a serialized mesh")
    (count,) = struct.unpack_from("<I", data, len(data) - 4)
    magic, version = struct.unpack_from("<HH", data, 0)
    if magic != _SERIALIZED_MAGIC or version not in (3, 4):
        raise InputError(f"{where}: not a Mitsuba serialized mesh (format 0x{magic:04X}, version {version})")
    wide = version == 4
    table_bytes = count * (8 if wide else 4)
    if count == 0 or table_bytes + 4 > len(data):
        raise InputError(f"{where}: its table of shapes is damaged ({count} shapes)")
    if not 0 <= index < count:
        raise InputError(f"{where}: shape_index {index} is not among its {count} shapes")
    offsets = struct.unpack_from(f"<{count}{'Q' if wide else 'I'}", data, len(data) - 4 - table_bytes)
    start = offsets[index]
    end = offsets[index + 1] if index + 1 < count else len(data) - 4 - table_bytes
    if not 0 <= start < end <= len(data):
        raise InputError(f"{where}: shape {index}'s offset is outside the file")
    magic, version = struct.unpack_from("<HH", data, start)
    if magic != _SERIALIZED_MAGIC or version not in (3, 4):
        raise InputError(f"{where}: shape {index} does not start with the serialized mesh header")
    try:
        head = zlib.decompressobj().decompress(data[start + 4:end], 4096)  # its counts, before the rest is inflated
        _serialized_counts(head, version == 4, where)
        body = zlib.decompressobj().decompress(data[start + 4:end], MESH_BYTES)
    except zlib.error as exc:
        raise InputError(f"{where}: shape {index}'s compressed data is damaged ({exc})") from None
    return _serialized_body(body, version == 4, where)


def _serialized_counts(head, named, where):
    """(flags, vertex count, triangle count, where the arrays start) of a shape's
    inflated header; InputError where it is cut short or claims more than
    ``MAX_SERIALIZED_VERTICES`` vertices or twice as many triangles."""
    try:
        (flags,) = struct.unpack_from("<I", head, 0)
        at = 4
        if named:
            at = head.index(b"\0", at) + 1
        n_vertices, n_faces = struct.unpack_from("<QQ", head, at)
    except (struct.error, ValueError):
        raise InputError(f"{where}: the shape's header is cut short") from None
    if n_vertices > MAX_SERIALIZED_VERTICES or n_faces > 2 * MAX_SERIALIZED_VERTICES:
        raise InputError(f"{where}: the shape claims {n_vertices:,} vertices and {n_faces:,} triangles, more than the "
                         f"{MAX_SERIALIZED_VERTICES:,} vertices (and twice as many triangles) a mesh may have")
    return flags, n_vertices, n_faces, at + 16


def _serialized_body(body, named, where):
    flags, n_vertices, n_faces, at = _serialized_counts(body, named, where)
    real = np.float64 if flags & _DOUBLE else np.float32
    index = np.uint64 if n_vertices > 2**32 else np.uint32
    sizes = [("positions", 3, real), ("normals", 3 if flags & _HAS_NORMALS else 0, real),
             ("texcoords", 2 if flags & _HAS_TEXCOORDS else 0, real),
             ("colors", 3 if flags & _HAS_COLORS else 0, real)]
    need = sum(n_vertices * k * np.dtype(t).itemsize for _, k, t in sizes) + n_faces * 3 * np.dtype(index).itemsize
    if n_vertices == 0 or n_faces == 0 or at + need > len(body):
        raise InputError(f"{where}: holds {len(body) - at:,} bytes where {n_vertices:,} vertices and "
                         f"{n_faces:,} triangles need {need:,}")
    arrays = {}
    for name, k, dtype in sizes:
        if k:
            n = n_vertices * k
            arrays[name] = np.frombuffer(body, dtype=dtype, count=n, offset=at).reshape(-1, k).astype(np.float64)
            at += n * np.dtype(dtype).itemsize
    faces = np.frombuffer(body, dtype=index, count=n_faces * 3, offset=at).reshape(-1, 3).astype(np.int64)
    if faces.max() >= n_vertices:
        raise InputError(f"{where}: a triangle refers to a vertex that does not exist")
    return arrays["positions"], faces, arrays.get("normals"), arrays.get("texcoords")


def _mesh_file(doc, node, props):
    """Positions, faces, normals (or None) and uvs (or None, ours: v up) of an obj, ply
    or serialized shape. Mitsuba 3 flips an obj's v (``vt`` runs up, its own v down),
    and takes ply's and serialized texture coordinates as stored (its convention)."""
    filename = props.string("filename")
    if filename is None:
        raise node.fail("needs a 'filename'")
    path = doc.resolve(node, filename)
    kind = node.attrs["type"]
    if kind == "serialized":
        data = read_input_bytes(path, "mesh", MESH_BYTES)
        index = props.integer("shape_index", 0)
        positions, faces, normals, texcoords = read_serialized(data, index, where=f"{node.where}: {filename}")
        return positions, faces, normals, None if texcoords is None else _flip_v(texcoords)
    positions, faces, normals, uvs = read_mesh_parts(path, node.where)
    if kind == "ply" and uvs is not None:
        uvs = _flip_v(uvs)
    return positions, faces, normals, uvs


def _flip_v(uvs):
    """Texture coordinates between Mitsuba's convention (v down) and ours (v up)."""
    return np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)


# Mitsuba 3's cube: 24 vertices, each face [0, 1]^2 in its (u, v) (its convention, v down)
_CUBE_POSITIONS = np.array([
    [1, -1, -1], [1, -1, 1], [-1, -1, 1], [-1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, 1, 1], [1, 1, 1],
    [1, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1], [-1, -1, 1],
    [-1, -1, 1], [-1, 1, 1], [-1, 1, -1], [-1, -1, -1], [1, 1, -1], [1, -1, -1], [-1, -1, -1], [-1, 1, -1]],
    dtype=np.float64)
_CUBE_UVS = np.tile(np.array([[0.0, 1], [1, 1], [1, 0], [0, 0]]), (6, 1))
_CUBE_FACES = np.concatenate([[[k, k + 1, k + 2], [k + 3, k, k + 2]] for k in range(0, 24, 4)]).astype(np.int64)


def _coordinate_system(n):
    """Mitsuba's frame about a unit vector n (Duff et al. 2017): (s, t), with (s, t,
    n) right-handed; the cylinder's local x and y."""
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return (np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]]),
            np.array([b, sign + n[1] * n[1] * a, -n[1]]))


def _mitsuba_disk(segments):
    """The unit disk as a fan with Mitsuba 3's (u, v) = (r, phi / 2 pi) as ours (r,
    1 - phi / 2 pi): the rim's seam vertex doubled, the centre copied per triangle
    (its v the triangle's middle angle)."""
    k = np.arange(segments + 1)
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    rim = np.stack([np.cos(angles), np.sin(angles), 0 * angles], 1)
    positions = np.concatenate([rim, rim[:1], np.zeros((segments, 3))])
    uvs = np.concatenate([np.stack([np.ones(segments + 1), 1.0 - k / segments], 1),
                          np.stack([np.zeros(segments), 1.0 - (k[:-1] + 0.5) / segments], 1)])
    ring = np.arange(segments)
    faces = np.stack([segments + 1 + ring, ring, ring + 1], 1)
    return positions, faces.astype(np.int64), uvs


def _analytic(node, props, tessellation, textured=False):
    """Positions, faces, uvs (with ``textured``: ours, v up, from Mitsuba 3's (u, v)
    of each shape; else None) and the object-to-world matrix of a tessellated analytic
    shape. Mitsuba 3's (u, v): rectangle ((x + 1) / 2, (y + 1) / 2); disk (r, phi / 2
    pi); sphere (phi / 2 pi, theta / pi), theta from +z; cube each face's [0, 1]^2
    (its table); cylinder (phi / 2 pi, z), phi from the axis' frame's first vector
    (``_coordinate_system``); angles in [0, 2 pi) counter-clockwise about +z."""
    kind = node.attrs["type"]
    to_world = props.transform("to_world")
    if kind == "rectangle":
        positions = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
        uvs = _flip_v(0.5 * (positions[:, :2] + 1.0)) if textured else None
        return positions, np.array([[0, 1, 2], [0, 2, 3]]), uvs, to_world
    if kind == "disk":
        if textured:
            return (*_mitsuba_disk(tessellation.segments), to_world)
        return (*builtins.disk(tessellation.segments), None, to_world)
    if kind == "cube":  # [-1, 1]^3: the built-in unit cube doubled, or Mitsuba's own with its uvs
        if textured:
            return _CUBE_POSITIONS, _CUBE_FACES, _flip_v(_CUBE_UVS), to_world
        positions, faces = builtins.mesh("cube")
        return 2.0 * positions, faces, None, to_world
    if kind == "sphere":
        positions, faces = builtins.mesh("sphere", subdivisions=tessellation.sphere_levels)
        uvs = None
        if textured:
            positions, faces, uvs = builtins.spherical_uvs(positions, faces, mitsuba=True)
        radius = props.float("radius", 1.0)
        if not radius > 0:
            raise node.fail(f"radius must be > 0, got {radius}")
        place = np.eye(4)
        place[:3, :3] *= radius
        place[:3, 3] = props.vector("center", np.zeros(3))
        return positions, faces, uvs, to_world @ place
    if kind == "cylinder":
        p0, p1 = props.vector("p0", np.zeros(3)), props.vector("p1", np.array([0.0, 0, 1]))
        radius = props.float("radius", 1.0)
        axis = p1 - p0
        length = np.linalg.norm(axis)
        if not radius > 0 or length == 0:
            raise node.fail("needs radius > 0 and p0 != p1")
        z = axis / length
        x, y = _coordinate_system(z)
        place = np.eye(4)
        place[:3, 0], place[:3, 1], place[:3, 2], place[:3, 3] = radius * x, radius * y, length * z, p0
        if textured:
            positions, faces, uvs = builtins.textured_mesh("cylinder", *builtins.cylinder(tessellation.segments))
            return positions, faces, _flip_v(uvs), to_world @ place  # Mitsuba's v = z runs from p0 down the image
        return (*builtins.cylinder(tessellation.segments), None, to_world @ place)
    raise AssertionError(kind)
