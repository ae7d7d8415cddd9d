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


def vertex_areas(positions, faces):
    """(V,) float64: a third of the area of every triangle around each vertex."""
    tri = np.asarray(positions, np.float64)[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    out = np.zeros(len(positions))
    np.add.at(out, np.asarray(faces).ravel(), np.repeat(area / 3.0, 3))
    return out


def fit_data(obj):
    """The FitData of a ``radiosity.formats.solution.ObjectSolution``."""
    normals = np.asarray(obj.normals, np.float64)
    tangents = np.asarray(obj.tangents, np.float64)
    bitangents = np.cross(normals, tangents)
    local = np.asarray(obj.directions, np.float64)
    views = (
        local[None, :, 0:1] * tangents[:, None, :]
        + local[None, :, 1:2] * bitangents[:, None, :]
        + local[None, :, 2:3] * normals[:, None, :]
    )
    views /= np.linalg.norm(views, axis=2, keepdims=True)
    area = vertex_areas(obj.positions, obj.faces)
    if area.sum() <= 0:
        area = np.ones_like(area)
    weights = np.broadcast_to(area[:, None], views.shape[:2]) / (area.sum() * views.shape[1])
    return FitData(
        radiance=np.asarray(obj.radiance, np.float64),
        views=views,
        normals=normals,
        weights=np.ascontiguousarray(weights),
        positions=np.asarray(obj.positions, np.float64),
    )


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
