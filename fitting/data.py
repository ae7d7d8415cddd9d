"""A solution object as the fitter sees it, and how fit errors are measured.

Every (vertex, direction) sample of the solution is weighted by the vertex's area
(a third of its triangles') times the direction's solid angle (the grid is
equal-area, so the same for every direction): the error of a fit is then an integral
over the surface and the hemisphere, not a count of samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class FitData:
    """radiance : (V, D, 3) float64, the solution's outgoing radiance
    views    : (V, D, 3) float64, world-space unit directions towards the eye
    normals  : (V, 3) float64, world-space unit normals
    weights  : (V, D) float64, area x solid angle, summing to 1
    positions: (V, 3) float64, world-space vertex positions (None: not known; point
               lights need them)
    """

    radiance: np.ndarray
    views: np.ndarray
    normals: np.ndarray
    weights: np.ndarray
    positions: np.ndarray | None = None

    @property
    def n_vertices(self):
        return self.radiance.shape[0]

    @property
    def n_directions(self):
        return self.radiance.shape[1]

    def vertices(self, idx):
        """The same data at the vertices ``idx`` (an index array), weights as they are."""
        return FitData(radiance=np.ascontiguousarray(self.radiance[idx]), views=np.ascontiguousarray(self.views[idx]),
                       normals=np.ascontiguousarray(self.normals[idx]), weights=np.ascontiguousarray(self.weights[idx]),
                       positions=None if self.positions is None else np.ascontiguousarray(self.positions[idx]))


def vertex_areas(positions, faces):
    """(V,) float64: a third of the area of every triangle around each vertex."""
    tri = np.asarray(positions, np.float64)[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    out = np.zeros(len(positions))
    np.add.at(out, np.asarray(faces).ravel(), np.repeat(area / 3.0, 3))
    return out


def object_areas(obj):
    """(V,) each vertex's area (``vertex_areas``), ones where the object has none: the
    weights ``fit_data`` and a fit's blocks use."""
    area = vertex_areas(obj.positions, obj.faces)
    return area if area.sum() > 0 else np.ones_like(area)

def fit_data(obj, vertices=slice(None), area=None):
    """The FitData of a ``radiosity.files.solution.ObjectSolution``, or of its
    ``vertices`` alone (a slice: a block of a large object, or every k-th vertex).

    area : (V,) every vertex's area (``vertex_areas``), if already known. A block's
    weights are those of the whole object (summing to 1 over all vertices, so that sums
    over blocks add up); a strided subset's (step > 1) are scaled to sum to 1 over it.
    """
    sl = vertices if isinstance(vertices, slice) else slice(None)
    normals = np.asarray(obj.normals[sl], np.float64)
    tangents = np.asarray(obj.tangents[sl], np.float64)
    bitangents = np.cross(normals, tangents)
    local = np.asarray(obj.directions, np.float64)
    views = (
        local[None, :, 0:1] * tangents[:, None, :]
        + local[None, :, 1:2] * bitangents[:, None, :]
        + local[None, :, 2:3] * normals[:, None, :]
    )
    views /= np.linalg.norm(views, axis=2, keepdims=True)
    if area is None:
        area = object_areas(obj)
    if area.sum() <= 0:
        area = np.ones_like(area)
    total = area.sum() if (sl.step or 1) == 1 else area[sl].sum()
    if not total > 0:
        area, total = np.ones_like(area), float(len(area[sl]))
    weights = np.broadcast_to(area[sl, None], views.shape[:2]) / (total * views.shape[1])
    return FitData(
        radiance=np.asarray(obj.radiance[sl], np.float64),
        views=views,
        normals=normals,
        weights=np.ascontiguousarray(weights),
        positions=np.asarray(obj.positions[sl], np.float64),
    )


class ErrorSums:
    """``relative_error`` and ``perceptual_error`` of an approximation added up a block
    of vertices at a time (the sums of every block, in block order: the same bits for
    the same blocks). ``mean``: the whole object's weighted mean radiance (one number)."""

    def __init__(self, mean):
        self.mean = float(mean)
        self.num = self.den = self.seen_num = self.seen_den = 0.0
        self.worst, self.worst_index = 0.0, 0

    def add(self, data, approximation, first=0):
        """Vertices ``first``.. of the object: their ``data`` and ``approximation``."""
        diff = np.sum((approximation - data.radiance) ** 2, axis=2)
        size = np.sum(data.radiance**2, axis=2)
        num, den = np.sum(data.weights * diff, axis=1), np.sum(data.weights * size, axis=1)
        self.num += float(num.sum())
        self.den += float(den.sum())
        with np.errstate(divide="ignore", invalid="ignore"):
            per_vertex = np.sqrt(np.where(den > 0, num / den, np.where(num > 0, np.inf, 0.0)))
        if len(per_vertex) and per_vertex.max() > self.worst:
            self.worst, self.worst_index = float(per_vertex.max()), first + int(np.argmax(per_vertex))
        if self.mean > 0:
            w = data.weights[:, :, None]
            a = np.maximum(approximation / self.mean, 0.0) ** GAMMA
            b = np.maximum(data.radiance / self.mean, 0.0) ** GAMMA
            self.seen_num += float(np.sum(w * (a - b) ** 2))
            self.seen_den += float(np.sum(w * b**2))
        elif np.any(approximation):
            self.seen_num = np.inf

    def relative(self):
        """As ``relative_error`` returns it, of everything added."""
        total = (np.sqrt(self.num / self.den) if self.den > 0 else (0.0 if self.num == 0 else np.inf))
        return {"relative_rms": float(total), "worst_vertex": self.worst, "worst_vertex_index": self.worst_index}

    def perceptual(self):
        """As ``perceptual_error`` returns it, of everything added."""
        if not self.mean > 0:
            return 0.0 if self.seen_num == 0 else float("inf")
        return float(np.sqrt(self.seen_num / self.seen_den)) if self.seen_den > 0 else 0.0


def relative_error(data, approximation):
    """Error of an approximation (V, D, 3) of ``data.radiance``.

    Returns {"relative_rms": sqrt(sum w |a - L|^2 / sum w |L|^2) over everything,
    "worst_vertex": the largest per-vertex value of the same ratio, "worst_vertex_index"}.
    Zero data give 0 for a zero approximation.
    """
    diff = np.sum((approximation - data.radiance) ** 2, axis=2)
    size = np.sum(data.radiance**2, axis=2)
    per_vertex_num = np.sum(data.weights * diff, axis=1)
    per_vertex_den = np.sum(data.weights * size, axis=1)
    total_num, total_den = per_vertex_num.sum(), per_vertex_den.sum()
    total = np.sqrt(total_num / total_den) if total_den > 0 else (0.0 if total_num == 0 else np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        per_vertex = np.sqrt(np.where(per_vertex_den > 0, per_vertex_num / per_vertex_den, np.where(per_vertex_num > 0, np.inf, 0.0)))
    worst = int(np.argmax(per_vertex)) if len(per_vertex) else 0
    return {
        "relative_rms": float(total),
        "worst_vertex": float(per_vertex[worst]) if len(per_vertex) else 0.0,
        "worst_vertex_index": worst,
    }


GAMMA = 1.0 / 2.2  # the display's: what a viewer sees of radiance, roughly


def perceptual_error(data, approximation):
    """The relative RMS error of an approximation (V, D, 3) of ``data.radiance`` in a
    space nearer what a viewer sees: both scaled by the object's mean radiance (an
    exposure) and raised to the display's gamma 1 / 2.2, so that a dim reflection's
    error counts about as the eye weighs it, not as its square in radiance."""
    w = data.weights[:, :, None]
    mean = float(np.sum(w * data.radiance) / max(float(w.sum()), 1e-300) / 3.0)
    if not mean > 0:
        return 0.0 if not np.any(approximation) else float("inf")
    a = np.maximum(approximation / mean, 0.0) ** GAMMA
    b = np.maximum(data.radiance / mean, 0.0) ** GAMMA
    return float(np.sqrt(np.sum(w * (a - b) ** 2) / np.sum(w * b**2)))
