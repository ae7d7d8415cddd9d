"""A scene's emitters as analytic parts (``radiosity.physics.emitters.EmitterPart``):
what the displays draw the emitters' glossy highlights from.

Each emitting object becomes, in this order of preference:

- one ``sphere``: its vertices lie on a sphere (within ``SPHERE_TOLERANCE`` of the
  mean distance from their centroid), its faces face outwards and cover the sphere
  (area at least ``SPHERE_COVER`` of 4 pi R^2). The radius is the one of the sphere of
  the mesh's area, so the part emits the mesh's power;
- convex planar ``polygon`` s: faces grouped by plane and connection, a group whose
  area is its convex hull's becomes one polygon (the Cornell box's lamp is one quad),
  any other face its own triangle;

and stays analytic only if it needs at most ``MAX_OBJECT_PARTS`` parts, and the whole
scene at most ``MAX_PARTS`` (the brightest objects first): the solver evaluates every
part's highlight in closed form on every glossy object it reaches, and each glossy
object's displays draw the brightest ``transport.highlights.MAX_RECEIVER_PARTS`` for
it per pixel. The emitters left over are not lost: the solver gathers their highlights
into the direction grid as it always did.

The scene's delta lights (``Scene.lights``: points, spots, directions) are parts as they
are, one each, and come first within ``MAX_PARTS``: the cheapest to draw (no
quadrature) and the sharpest highlights. One left over is not lost either: the solver
still adds its highlight to the grid in closed form.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull

from radiosity.physics.emitters import MAX_POLYGON_VERTICES, EmitterPart, polygon_normal
from radiosity.scene import geometry

__all__ = ["MAX_OBJECT_PARTS", "MAX_PARTS", "emitter_parts", "object_parts"]

MAX_PARTS = 1024  # analytic parts in a scene; each glossy object draws its brightest (MAX_RECEIVER_PARTS)
MAX_OBJECT_PARTS = 8
SPHERE_TOLERANCE = 0.02  # relative spread of the vertices' distances from the centre
SPHERE_COVER = 0.9
PLANE_TOLERANCE = 1e-6  # relative to the object's size
HULL_TOLERANCE = 1e-6  # relative area difference between a group and its hull


def _sphere(obj):
    """An EmitterPart sphere for ``obj``, or None if it is not one."""
    p = obj.positions
    if len(p) < 12:
        return None
    centre = p.mean(axis=0)
    distance = np.linalg.norm(p - centre, axis=1)
    radius = distance.mean()
    if not radius > 0 or np.ptp(distance) > SPHERE_TOLERANCE * radius:
        return None
    normals, areas = geometry.face_normals(p, obj.faces)
    outward = np.einsum("ij,ij->i", normals, p[obj.faces].mean(axis=1) - centre)
    if (outward <= 0).any():
        return None
    area = float(areas.sum())
    if area < SPHERE_COVER * 4 * math.pi * radius**2:
        return None
    return EmitterPart("sphere", [centre], math.sqrt(area / (4 * math.pi)), obj.material.emission, obj.name)


def _plane_groups(obj):
    """Lists of face indices: faces sharing a plane and connected through edges."""
    p, f = obj.positions, obj.faces
    normals, areas = geometry.face_normals(p, f)
    size = float(np.ptp(p, axis=0).max()) or 1.0
    offsets = np.einsum("ij,ij->i", normals, p[f[:, 0]])
    parent = list(range(len(f)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    edges = {}
    for i, tri in enumerate(f):
        for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            edges.setdefault((min(a, b), max(a, b)), []).append(i)
    for faces in edges.values():
        for j in faces[1:]:
            i = faces[0]
            same = normals[i] @ normals[j] > 1 - 1e-9 and abs(offsets[i] - offsets[j]) <= PLANE_TOLERANCE * size
            if same:
                parent[root(j)] = root(i)
    groups = {}
    for i in range(len(f)):
        if areas[i] > 0:
            groups.setdefault(root(i), []).append(i)
    return list(groups.values()), normals, areas


def _convex_polygon(points, normal, area):
    """The group's outline as a convex polygon (K, 3) counter-clockwise about ``normal``
    when the group fills its convex hull (and K <= MAX_POLYGON_VERTICES), else None."""
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.stack([(points - points[0]) @ u, (points - points[0]) @ v], axis=1)
    try:
        hull = ConvexHull(flat)
    except Exception:  # qhull: flat or degenerate input
        return None
    if abs(hull.volume - area) > HULL_TOLERANCE * area * 10 + 1e-12:  # volume is the 2-d area
        return None
    corners = points[hull.vertices]  # counter-clockwise in (u, v), so about u x v = normal
    # drop vertices on a straight edge
    keep = []
    k = len(corners)
    for i in range(k):
        a, b, c = corners[i - 1], corners[i], corners[(i + 1) % k]
        if np.linalg.norm(np.cross(b - a, c - b)) > 1e-9 * area:
            keep.append(i)
    corners = corners[keep]
    if not 3 <= len(corners) <= MAX_POLYGON_VERTICES:
        return None
    if polygon_normal(corners)[0] @ normal < 0:
        corners = corners[::-1]
    return corners


def object_parts(obj):
    """The EmitterParts of one emitting ``radiosity.scene.model.SceneObject``."""
    sphere = _sphere(obj)
    if sphere is not None:
        return [sphere]
    groups, normals, areas = _plane_groups(obj)
    parts = []
    emission = obj.material.emission
    for group in groups:
        if len(parts) > MAX_OBJECT_PARTS:
            break
        idx = np.unique(obj.faces[group].ravel())
        polygon = None
        if len(group) > 1:
            polygon = _convex_polygon(obj.positions[idx], normals[group[0]], float(areas[group].sum()))
        if polygon is not None:
            parts.append(EmitterPart("polygon", polygon, 0.0, emission, obj.name))
        else:
            parts += [EmitterPart("polygon", obj.positions[obj.faces[i]], 0.0, emission, obj.name) for i in group]
    return parts


def emitter_parts(scene, max_parts=MAX_PARTS, max_object_parts=MAX_OBJECT_PARTS):
    """(parts, names of the objects they come from) of ``scene``'s emitters: its delta
    lights first (``scene.lights``, one part each, in their order), then each emitting
    object that makes at most ``max_object_parts`` parts, brightest (most power) first,
    while the scene's total stays within ``max_parts``."""
    emitters = sorted(scene.emitters, key=lambda o: -float(np.sum(o.emitted_power)))
    parts, names = list(scene.lights[:max_parts]), []
    for obj in emitters:
        mine = object_parts(obj)
        if len(mine) <= max_object_parts and len(parts) + len(mine) <= max_parts:
            parts += mine
            names.append(obj.name)
    return tuple(parts), tuple(names)
