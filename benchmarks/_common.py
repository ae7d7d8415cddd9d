"""What every benchmark script records: the machine, and its rows as JSON lines."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numba
import numpy as np

from radiosity.transport.embree import intersect1, new_rayhit

RESULTS = Path(__file__).resolve().parent / "results"


def machine():
    return {"cores": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version()}


class Recorder:
    """Rows of one benchmark run: each printed as it comes, all saved at the end."""

    def __init__(self, **context):
        self.context = machine() | context
        self.rows = []

    def __call__(self, row):
        row = self.context | row
        self.rows.append(row)
        print(json.dumps(row), flush=True)
        return row

    def save(self, name):
        RESULTS.mkdir(exist_ok=True)
        with open(RESULTS / name, "w") as f:
            for row in self.rows:
                f.write(json.dumps(row) + "\n")


def incoherent_rays(merged, n_rays, epsilon, seed=0):
    """(origins, directions) float32 (n, 3) of rays like photons and bounces: origins
    uniform on random triangles of ``merged`` (a ``MergedMesh``), offset ``epsilon``
    off their front, directions uniform over the front hemisphere."""
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, len(merged.faces), n_rays)
    bary = rng.random((n_rays, 2))
    flip = bary.sum(axis=1) > 1
    bary[flip] = 1 - bary[flip]
    p = merged.positions.astype(np.float64)[merged.faces[tri]]
    points = p[:, 0] + bary[:, :1] * (p[:, 1] - p[:, 0]) + bary[:, 1:] * (p[:, 2] - p[:, 0])
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where((np.einsum("ij,ij->i", d, normal) < 0)[:, None], -d, d)
    return (points + epsilon * normal).astype(np.float32), d.astype(np.float32)


class Limit:
    """The fastest this machine traces incoherent rays through Embree: jitted loops of
    single-ray queries (``embree.intersect1``) over the same rays, either a thread per
    core each running one nogil loop over its chunk (``RayTracer.intersect``) or a numba
    ``prange`` loop; ``rates()`` times both, the limit is the faster.

    scene : a ``Scene`` (its merged mesh is traced); n_rays incoherent rays (origins on
    the surfaces, directions over the front hemisphere: ``incoherent_rays``).
    """

    def __init__(self, scene, n_rays, threads):
        from radiosity.transport.embree import RayTracer

        merged = scene.merged()
        self.threads = threads
        self.tracer = RayTracer(merged.positions, merged.faces, threads=threads)
        self.origins, self.directions = incoherent_rays(merged, n_rays, self.tracer.epsilon)
        self.n = n_rays
        self.triangle = np.empty(n_rays, np.int32)
        self.rates()  # compile, warm caches

    def rates(self):
        """{"threads": rays/s, "prange": rays/s, "limit": the larger} of one pass each."""
        t = time.perf_counter()
        hits = self.tracer.intersect(self.origins, self.directions)
        threads = self.n / (time.perf_counter() - t)
        previous = numba.get_num_threads()
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        try:
            t = time.perf_counter()
            _trace_prange(self.tracer.embree, self.origins, self.directions, self.threads * 16, self.triangle)
            prange = self.n / (time.perf_counter() - t)
        finally:
            numba.set_num_threads(previous)
        assert np.array_equal(hits.triangle, self.triangle)  # the same rays, the same answers
        return {"threads": threads, "prange": prange, "limit": max(threads, prange)}

    def close(self):
        self.tracer.close()


@numba.njit(cache=True, parallel=True)
def _trace_prange(rt, origins, directions, chunks, triangle):
    n = origins.shape[0]
    for c in numba.prange(chunks):
        rayhit = new_rayhit()
        for k in range(c * n // chunks, (c + 1) * n // chunks):
            o, d = origins[k], directions[k]
            triangle[k] = intersect1(rt, rayhit, o[0], o[1], o[2], d[0], d[1], d[2])[0]
