"""Where a virtual light sits, read from the data.

A highlight seen at vertex v from view w comes from the mirror direction
m = 2 (n . w) n - w. The mirror rays of several vertices that see the same highlight
meet near the light that makes it (``meeting_point``: the point closest to all of them
in least squares); and the solution's own geometry says what one such ray hits
(``first_hits``: the nearest triangle along each ray, brute force in numba, for the few
rays a seed needs). A ray that meets nothing, or rays that are parallel, say the light
is far away: it stays directional.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)

__all__ = ["first_hits", "meeting_point", "mirror"]

AGREE = math.radians(20)  # a ray agrees on a meeting point it points at within this (a grid cell is 10-20 degrees)


def mirror(normals, views):
    """Mirror directions (..., 3) of unit ``views`` about unit ``normals``."""
    normals = np.asarray(normals, np.float64)
    views = np.asarray(views, np.float64)
    m = 2.0 * np.sum(normals * views, axis=-1, keepdims=True) * normals - views
    return m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-300)


def meeting_point(origins, directions, weights=None, min_spread=1e-3, agree=AGREE):
    """The point nearest, in weighted least squares, to the rays (origins (N, 3),
    unit directions (N, 3)) and in front of them; None when the rays are too close to
    parallel to fix a point (the smallest eigenvalue of sum w (I - d d^T), relative to
    the largest, below ``min_spread``), the point lies behind most of them, or the rays
    do not agree on it: less than half of their weight points at it within ``agree``
    (radians). Two bundles of parallel rays (two distant lights' highlights) have a
    least-squares point where they cross, among their origins, that neither points
    at; so have rays in random directions (a noisy residual's peaks).

    Returns (point (3,), spread): spread in [0, 1] says how well the rays pin it down.
    """
    o = np.asarray(origins, np.float64)
    d = np.asarray(directions, np.float64)
    w = np.ones(len(o)) if weights is None else np.asarray(weights, np.float64)
    if len(o) < 2 or not np.isfinite(o).all() or not np.isfinite(d).all():
        return None, 0.0
    projector = np.eye(3)[None] - d[:, :, None] * d[:, None, :]  # (N, 3, 3)
    A = np.einsum("n,nij->ij", w, projector)
    b = np.einsum("n,nij,nj->i", w, projector, o)
    eigenvalues = np.linalg.eigvalsh(A)
    spread = float(eigenvalues[0] / eigenvalues[-1]) if eigenvalues[-1] > 0 else 0.0
    if spread < min_spread:
        return None, spread
    point = np.linalg.solve(A, b)
    to_point = point[None] - o
    along = np.einsum("ni,ni->n", to_point, d)
    if np.sum(w * (along > 0)) < 0.5 * np.sum(w):
        return None, spread
    aligned = along > math.cos(agree) * np.linalg.norm(to_point, axis=1)
    if np.sum(w * aligned) < 0.5 * np.sum(w):
        return None, spread
    return point, spread


@numba.njit(cache=True, nogil=True, parallel=True)
def _hits(origins, directions, tri, t_min, out_t, out_tri):
    n_rays, n_tri = origins.shape[0], tri.shape[0]
    for r in numba.prange(n_rays):
        ox, oy, oz = origins[r, 0], origins[r, 1], origins[r, 2]
        dx, dy, dz = directions[r, 0], directions[r, 1], directions[r, 2]
        best, which = np.inf, -1
        for t in range(n_tri):
            # Moller-Trumbore, both sides; the edges made here, not stored (the scene's
            # triangles are read as they are: no copy of a million of them per ray)
            # (float32 triangles widened first: the same arithmetic as float64 ones)
            ax, ay, az = np.float64(tri[t, 0, 0]), np.float64(tri[t, 0, 1]), np.float64(tri[t, 0, 2])
            e1x = np.float64(tri[t, 1, 0]) - ax
            e1y = np.float64(tri[t, 1, 1]) - ay
            e1z = np.float64(tri[t, 1, 2]) - az
            e2x = np.float64(tri[t, 2, 0]) - ax
            e2y = np.float64(tri[t, 2, 1]) - ay
            e2z = np.float64(tri[t, 2, 2]) - az
            px = dy * e2z - dz * e2y
            py = dz * e2x - dx * e2z
            pz = dx * e2y - dy * e2x
            det = e1x * px + e1y * py + e1z * pz
            if abs(det) < 1e-300:
                continue
            inv = 1.0 / det
            sx, sy, sz = ox - ax, oy - ay, oz - az
            u = (sx * px + sy * py + sz * pz) * inv
            if u < 0.0 or u > 1.0:
                continue
            qx = sy * e1z - sz * e1y
            qy = sz * e1x - sx * e1z
            qz = sx * e1y - sy * e1x
            v = (dx * qx + dy * qy + dz * qz) * inv
            if v < 0.0 or u + v > 1.0:
                continue
            dist = (e2x * qx + e2y * qy + e2z * qz) * inv
            if dist > t_min and dist < best:
                best, which = dist, t
        out_t[r] = best
        out_tri[r] = which


def first_hits(origins, directions, triangles, t_min):
    """Nearest hit along each ray: (distance (N,) with inf for a miss, triangle (N,)
    with -1). triangles (T, 3, 3) world space, float32 or float64 (read in place when
    C-contiguous, as ``mixed.SceneGeometry`` holds them; the arithmetic is float64
    either way); hits nearer than ``t_min`` are ignored (the surface the ray starts on)."""
    tri = np.asarray(triangles)
    tri = np.ascontiguousarray(tri, tri.dtype if tri.dtype in (np.float32, np.float64) else np.float64)
    o = np.ascontiguousarray(origins, np.float64).reshape(-1, 3)
    d = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    out_t = np.empty(len(o))
    out_tri = np.empty(len(o), np.int64)
    if len(tri) == 0:
        out_t[:] = np.inf
        out_tri[:] = -1
        return out_t, out_tri
    _hits(o, d, tri, float(t_min), out_t, out_tri)
    return out_t, out_tri
