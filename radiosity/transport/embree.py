"""The only module that touches Embree (through embreex).

``RayTracer`` holds one Embree scene built from a ``MergedMesh`` and answers batched
closest-hit and occlusion queries. embreex's ``EmbreeScene.run`` releases the GIL, so
a batch is split into one chunk per thread and the chunks run concurrently. Embree's
tnear is fixed at 0: callers offset their ray origins (see ``RayTracer.epsilon``).

The BVH is built on the first query; the constructor makes that query itself, from
the calling thread, so that later concurrent queries find it built.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

MISS = -1
RELATIVE_EPSILON = 1e-5  # ray-origin offset, as a fraction of the scene's bounding-box diagonal
OFFSET_ULPS = 8  # ... and at least this many float32 spacings of the largest coordinate


class Hits(NamedTuple):
    """Closest hits of a batch of N rays (``RayTracer.intersect``).

    triangle : (N,) int32    row of the tracer's ``faces``; MISS (-1) where nothing is hit
    t        : (N,) float32  distance along the (unit) direction to the hit
    u, v     : (N,) float32  barycentrics: the hit is (1 - u - v) p0 + u p1 + v p2
    """

    triangle: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray


def default_threads():
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def origin_offset(positions):
    """How far off a surface a ray must start (scene units) not to hit it again.

    RELATIVE_EPSILON of the bounding-box diagonal, and at least OFFSET_ULPS float32
    spacings at the largest coordinate: a scene far from the origin has coarse
    single-precision coordinates, and an offset below their spacing would round away.
    """
    positions = np.asarray(positions, dtype=np.float64)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    relative = RELATIVE_EPSILON * float(np.linalg.norm(hi - lo))
    spacing = float(np.spacing(np.float32(np.abs(positions).max())))
    return max(relative, OFFSET_ULPS * spacing)


class RayTracer:
    """Closest-hit and shadow queries against one triangle mesh.

    positions : (N, 3) float32 and faces : (T, 3) int32 of the merged scene mesh.
    The triangle index returned is the row of ``faces``; u and v are Embree's
    barycentrics (the hit is (1 - u - v) p0 + u p1 + v p2 of that row's vertices).
    Triangles are hit from both sides. ``epsilon`` is the ray-origin offset callers
    must apply (``origin_offset``).
    """

    def __init__(self, positions, faces, threads=None):
        triangles = np.ascontiguousarray(positions[faces], dtype=np.float32)
        self.n_triangles = len(triangles)
        self.threads = threads or default_threads()
        self.epsilon = origin_offset(positions)
        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = TriangleMesh(self._scene, triangles)
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        probe = np.zeros((1, 3), dtype=np.float32)
        self._scene.run(probe, probe + np.float32([0, 0, 1]), output=1)  # builds the BVH here
        self.rays_cast = 0  # every query's rays
        self.shadow_rays_cast = 0  # of which occlusion queries

    def close(self):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _chunks(self, n):
        k = self.threads if (self._pool is not None and n >= 4096) else 1
        bounds = np.linspace(0, n, k + 1).astype(int)
        return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]

    def _map(self, fn, n):
        chunks = self._chunks(n)
        if len(chunks) == 1:
            return [fn(chunks[0])]
        return list(self._pool.map(fn, chunks))

    def intersect(self, origins, directions):
        """Closest hits of rays (origins, directions: (N, 3) float32; directions unit).

        Returns ``Hits`` (triangle (N,) int32, MISS where nothing is hit; t, u, v (N,)
        float32).
        """
        n = len(origins)
        triangle = np.empty(n, dtype=np.int32)
        t = np.empty(n, dtype=np.float32)
        u = np.empty(n, dtype=np.float32)
        v = np.empty(n, dtype=np.float32)
        if n == 0:
            return Hits(triangle, t, u, v)
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)

        def run(chunk):
            out = self._scene.run(origins[chunk], directions[chunk], output=1)
            triangle[chunk] = out["primID"]
            t[chunk] = out["tfar"]
            u[chunk] = out["u"]
            v[chunk] = out["v"]

        self._map(run, n)
        self.rays_cast += n
        return Hits(triangle, t, u, v)

    def occluded(self, origins, directions, distances):
        """Whether each segment origin + s * direction, 0 < s < distance, hits anything.

        Returns (N,) bool.
        """
        n = len(origins)
        blocked = np.empty(n, dtype=bool)
        if n == 0:
            return blocked
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)
        distances = np.ascontiguousarray(distances, dtype=np.float32)

        def run(chunk):
            out = self._scene.run(origins[chunk], directions[chunk], dists=distances[chunk].copy(), query="OCCLUDED")
            blocked[chunk] = out != MISS

        self._map(run, n)
        self.rays_cast += n
        self.shadow_rays_cast += n
        return blocked
