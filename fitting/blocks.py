"""A glossy object's samples (vertex x direction) a bounded number at a time.

The fit of one glossy object is in two steps, so that its memory does not grow with
the object beyond its input radiance (float32, as the solution file holds it) and its
stored model (per-vertex coefficients):

- **the search** (``--model auto``'s comparison of candidate models, the probe's texels,
  the lights' placement and refinement) runs on every k-th vertex, at most
  ``search_samples`` samples (``search_slice``): the object's whole working set of
  the search, float64, held for that subset alone;
- **the per-vertex coefficients** of the model chosen, and its error measures, are
  then solved on every vertex, a block of at most ``block_samples`` samples at a time
  (``vertex_blocks``): the normal equations of each vertex are the sums over its own
  directions, so a block holds its vertices' samples and nothing else.

An object of at most ``search_samples`` samples is fitted in one piece, as before:
the same model, bit for bit. The grids the solver writes hold at most 128 x 128
directions, so a block always holds whole vertices (``vertex_blocks`` gives two
vertices a block where one alone exceeds the budget).
"""

from __future__ import annotations

import math

import numpy as np

from radiosity.policies.presets import DEFAULT_QUALITY, PRESETS

__all__ = ["BLOCK_SAMPLES", "SEARCH_SAMPLES", "object_mean", "search_slice", "vertex_blocks"]

SEARCH_SAMPLES = PRESETS[DEFAULT_QUALITY].fit_search_samples  # the search's samples (draft: the teapot's every 4th vertex)
BLOCK_SAMPLES = 1 << 18  # the per-vertex pass's samples a block (about 0.3 GB of working arrays)


def search_slice(n_vertices, n_directions, search_samples=SEARCH_SAMPLES):
    """slice(0, V, k): every k-th vertex, k the least keeping the subset within
    ``search_samples`` samples (k = 1: the whole object), at least two vertices."""
    step = max(1, math.ceil(n_vertices * n_directions / max(int(search_samples), 1)))
    return slice(0, n_vertices, max(1, min(step, (n_vertices - 1) // 2 + (n_vertices == 1))))


def vertex_blocks(n_vertices, n_directions, block_samples=BLOCK_SAMPLES):
    """Consecutive slices of vertices, each of at most ``block_samples`` samples, and of
    at least two vertices (a trailing one joins the block before): the kernels read loss
    weights of one vertex, (1, D, 3), as the linear loss's placeholder (1, 1, 1)."""
    block = max(2, int(block_samples) // max(n_directions, 1))
    starts = list(range(0, n_vertices, block))
    if len(starts) > 1 and n_vertices - starts[-1] == 1:
        starts.pop()
    return [slice(first, starts[i + 1] if i + 1 < len(starts) else n_vertices) for i, first in enumerate(starts)]


def object_mean(radiance, area, block_samples=BLOCK_SAMPLES):
    """sum w L / 3 over the whole object (w = area x solid angle, summing to 1), from
    its radiance (V, D, 3) (float32 as stored), a block at a time: the relative loss's
    and the perceptual error's scale (``loss.loss_weights``, ``data.ErrorSums``)."""
    v, d = radiance.shape[:2]
    total = 0.0
    for sl in vertex_blocks(v, d, block_samples):
        total += float(np.dot(area[sl], np.asarray(radiance[sl], np.float64).sum(axis=(1, 2))))
    return total / (max(float(area.sum()), 1e-300) * d * 3.0)
