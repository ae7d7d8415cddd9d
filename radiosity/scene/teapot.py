"""The Utah teapot (Newell 1975) tessellated from its 32 bicubic Bezier patches.

The patches are evaluated on a ``resolution x resolution`` grid each, the seams are
welded, the triangles that collapse at the lid and bottom poles are dropped (so the
pole vertex's normal averages a full fan and points straight up or down), and the
gap the original data leaves between the lid (radius 1.3) and the rim (radius 1.4)
at height 2.4 is closed with a flat ring, so the body with its lid is a closed
surface. The spout is open at its tip, like the real one; the handle's and the
spout's other ends lie inside the body.

The result is in the data's units with +y up (the data has +z up), the bottom on
y = 0, the spout towards +x and the handle towards -x; fronts face outward.
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources
from math import comb

import numpy as np

from radiosity.scene import geometry

LID_RING_HEIGHT = 2.4  # the lid's lower edge and the rim's inner edge, in the data's z
LID_RADIUS, RIM_INNER_RADIUS = 1.3, 1.4


@lru_cache(maxsize=1)
def _patch_data():
    data = json.loads(resources.files("radiosity.scene").joinpath("data/teapot.json").read_text())
    control = np.asarray(data["control_points"], dtype=np.float64)
    patches = np.asarray(data["patches"], dtype=np.int64)
    return control[patches].reshape(-1, 4, 4, 3)  # (32, 4, 4, 3), z up


def _bernstein(t):
    return np.stack([comb(3, k) * t**k * (1 - t) ** (3 - k) for k in range(4)], axis=1)


def _patch_grids(resolution):
    """Every patch evaluated on a (resolution + 1)^2 grid: (surface (P, r+1, r+1, 3) z
    up, the triangles of one patch's grid (2 r^2, 3), outward)."""
    if int(resolution) != resolution or resolution < 2:
        raise ValueError(f"teapot resolution must be an integer >= 2, got {resolution}")
    resolution = int(resolution)
    control = _patch_data()
    basis = _bernstein(np.linspace(0.0, 1.0, resolution + 1))
    surface = np.einsum("ui,vj,pijk->puvk", basis, basis, control)  # (P, r+1, r+1, 3)
    grid = np.arange((resolution + 1) ** 2).reshape(resolution + 1, resolution + 1)
    a, b = grid[:-1, :-1].ravel(), grid[1:, :-1].ravel()
    c, d = grid[1:, 1:].ravel(), grid[:-1, 1:].ravel()
    return surface, np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)])  # outward


def _welded(resolution):
    """The patches welded into one surface, the lid's gap closed: (positions, faces,
    the number of faces the closing ring added at the end), z up."""
    surface, quad_tris = _patch_grids(resolution)
    per_patch = surface.shape[1] * surface.shape[2]
    faces = np.concatenate([quad_tris + i * per_patch for i in range(len(surface))])
    positions = surface.reshape(-1, 3)
    extent = float(np.ptp(positions, axis=0).max())
    positions, faces = geometry.weld(positions, faces, 1e-9 * extent)
    positions, faces, _ = geometry.remove_degenerate(positions, faces)
    before = len(faces)
    positions, faces = _close_lid_gap(positions, faces)
    return positions, faces, len(faces) - before


def _y_up(positions):
    """z up -> y up: (x, y, z) -> (x, z, -y), a proper rotation (winding unchanged)."""
    return np.stack([positions[:, 0], positions[:, 2], -positions[:, 1]], axis=1)


def tessellate(resolution=8):
    """Teapot surface: (positions (V, 3) float64, faces (F, 3) int64), y up, fronts out.

    ``resolution`` is the number of segments along each side of each patch
    (2 x resolution^2 triangles per patch before the poles collapse).
    """
    positions, faces, _ = _welded(resolution)
    return _y_up(positions), faces


def tessellate_with_uvs(resolution=8):
    """The teapot with texture coordinates: (positions, faces, uvs (V, 2) float64), y
    up, the same triangles as ``tessellate`` (in another order, each patch's vertices
    its own: a patch's edge is a texture seam).

    Each patch maps the whole image: patch parameters (s, t) (the data's two
    directions) as u = 1 - t, v = 1 - s, which on the body puts the image upright
    (v up) and, on every patch, unmirrored seen from outside (its triangles
    counter-clockwise in (u, v) as in space). The flat ring closing the lid's gap
    gets a planar map: u = (x + 1.5) / 3, v = (1.5 - z) / 3 in the y-up frame (seen
    from above with -z up, as the built-in quad).
    """
    surface, quad_tris = _patch_grids(resolution)
    n = surface.shape[1]
    per_patch = n * n
    s, t = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
    patch_uvs = np.stack([1.0 - t.ravel(), 1.0 - s.ravel()], axis=1)
    faces = np.concatenate([quad_tris + i * per_patch for i in range(len(surface))])
    positions = surface.reshape(-1, 3)
    uvs = np.tile(patch_uvs, (len(surface), 1))
    # drop the triangles the poles collapse (two corners at one point)
    corners = positions[faces]
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    extent = float(np.ptp(positions, axis=0).max())
    faces = faces[area > 1e-14 * extent * extent]
    welded, welded_faces, ring_count = _welded(resolution)
    ring = welded_faces[len(welded_faces) - ring_count:]
    ring_positions = welded[ring].reshape(-1, 3)
    ring_y_up = _y_up(ring_positions)
    ring_uvs = np.stack([(ring_y_up[:, 0] + 1.5) / 3.0, (1.5 - ring_y_up[:, 2]) / 3.0], axis=1)
    positions = np.concatenate([positions, ring_positions])
    faces = np.concatenate([faces, len(uvs) + np.arange(3 * ring_count).reshape(-1, 3)])
    uvs = np.concatenate([uvs, ring_uvs])
    positions, faces, uvs = geometry.weld(positions, faces, 1e-9 * extent, uvs=uvs)
    positions, faces, uvs = geometry.compact(positions, faces, uvs)
    return _y_up(positions), faces, uvs


def _close_lid_gap(positions, faces):
    """Join the lid's lower boundary loop to the rim's inner loop with a flat ring."""
    edges = np.sort(faces[:, geometry._EDGE_CORNERS].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = np.unique(unique[counts == 1])
    p = positions[boundary]
    radius = np.hypot(p[:, 0], p[:, 1])
    on_plane = np.abs(p[:, 2] - LID_RING_HEIGHT) < 1e-6
    lid = boundary[on_plane & (np.abs(radius - LID_RADIUS) < 0.02)]
    rim = boundary[on_plane & (np.abs(radius - RIM_INNER_RADIUS) < 0.02)]
    if len(lid) != len(rim) or len(lid) < 3:
        raise RuntimeError("teapot data: lid and rim boundary loops do not match")
    lid = lid[np.argsort(np.arctan2(positions[lid, 1], positions[lid, 0]))]
    rim = rim[np.argsort(np.arctan2(positions[rim, 1], positions[rim, 0]))]
    lid_next, rim_next = np.roll(lid, -1), np.roll(rim, -1)
    # counter-clockwise seen from +z (above): the ring's front faces up
    ring = np.concatenate(
        [np.stack([lid, rim, rim_next], 1), np.stack([lid, rim_next, lid_next], 1)]
    )
    return positions, np.concatenate([faces, ring])
