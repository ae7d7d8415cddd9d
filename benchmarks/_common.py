"""What every benchmark script records: the machine, and its rows as JSON lines."""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import numpy as np

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
