"""More gather passes where the gather is noisy, decided without biasing the answer.

At draft a glossy vertex's outgoing radiance comes from a few hundred gather rays,
and the gather's noise is heavy-tailed: a ray that finds a small bright thing (a
glossy path to the lamp) makes one vertex an outlier, which the linear interpolation
spreads over its triangles, a bright X or rectangle on the satin block. More rays
everywhere cost what the whole gather costs; this module spends an extra budget
where the noise is.

Every glossy vertex is gathered once (pass 0). ``gather_outputs`` also returns, per
vertex, the variance of that estimate (the spread of its samples, in luminance,
summed over the direction grid), and from it each vertex gets its relative noise

    r_u = variance_u / sum_d (luminance_u,d^2 + floor^2)

(the floor, ``FLOOR`` times the object's median level, keeps black directions from
asking for rays). A vertex's number of passes P_v follows from the noise of its
*neighbours*, never its own: R_v is the mean of r_u over the vertices within
``RINGS`` rings of v, v excluded, and P_v = ceil(R_v / tolerance^2) (capped at
``MAX_PASSES``), so that its relative standard error R_v / P_v falls to the
tolerance. The final value is the plain mean of its P_v passes, each with its own
random numbers (``pass_seed``).

Why neighbours: a vertex whose own samples decided how many more it gets would keep
its outliers' company selectively (a high outlier asks for more passes and is
diluted, a low one is not), which biases the mean. P_v is computed from pass 0 of
the other vertices, independent of v's own samples, so each of v's passes is an
unbiased estimate and so is their mean, for any P_v. The variance is a property of
where a vertex is and what it sees, smooth across the surface, so the neighbours'
noise predicts v's. The one link left is the budget: when the planned passes exceed
``budget`` x the vertex count, the tolerance is raised (bisection) until they fit, a
single number set by every vertex of the object at once.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from radiosity.scene.geometry import unique_edges
from radiosity.transport.gather import LUMINANCE as _LUMINANCE

LUMINANCE = np.array(_LUMINANCE)
RINGS = 2  # neighbours pooled for a vertex's noise
FLOOR = 0.05  # of the object's median level: directions darker than this do not ask for rays
MAX_PASSES = 16  # at most 4x less noise than pass 0


def pass_seed(seed, k):
    """The seed of gather pass ``k`` (0: the solve's own), in [0, 2^63): a hash of
    (seed, k), so passes have independent counter-based random numbers."""
    if k == 0:
        return int(seed)
    z = (int(seed) * 0x9E3779B97F4A7C15 + k * 0xBF58476D1CE4E5B9) % 2**64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) % 2**64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) % 2**64
    return (z ^ (z >> 31)) >> 1


def relative_noise(radiance, variance):
    """r_v (V,): each vertex's gather variance ``variance`` (V,) relative to its
    radiance (V, D, 3) squared, summed over the directions, with the floor."""
    lum = radiance @ LUMINANCE  # (V, D)
    level = np.sqrt(np.mean(lum * lum, axis=1))
    floor = FLOOR * float(np.median(level)) if len(level) else 0.0
    denominator = np.sum(lum * lum, axis=1) + lum.shape[1] * floor * floor
    return np.where(denominator > 0, variance / np.where(denominator > 0, denominator, 1.0), 0.0)


def neighbour_noise(faces, n_vertices, r, rings=RINGS):
    """R_v (V,): the mean of ``r`` over the vertices within ``rings`` rings of v, v
    itself excluded (an isolated vertex gets the object's mean)."""
    edges = unique_edges(faces) if len(faces) else np.zeros((0, 2), dtype=np.int64)
    ones = np.ones(len(edges))
    a = sp.coo_matrix((ones, (edges[:, 0], edges[:, 1])), shape=(n_vertices, n_vertices)).tocsr()
    a = ((a + a.T) > 0).astype(np.float64)
    reach = a.copy()
    for _ in range(rings - 1):
        reach = ((reach + reach @ a) > 0).astype(np.float64)
    reach.setdiag(0.0)
    reach.eliminate_zeros()
    count = np.asarray(reach.sum(axis=1)).ravel()
    total = reach @ r
    fallback = float(np.mean(r)) if len(r) else 0.0
    return np.where(count > 0, total / np.maximum(count, 1.0), fallback)


def plan_passes(predicted, tolerance, budget, max_passes=MAX_PASSES):
    """Passes per vertex (V,) int and the tolerance used: ceil(predicted / tol^2),
    between 1 and ``max_passes``, with tol raised from ``tolerance`` until the extra
    passes are at most ``budget`` x V (``budget`` 0: one pass everywhere)."""
    n = len(predicted)

    def passes(tol):
        want = np.ceil(predicted / (tol * tol) - 1e-9)
        return np.clip(np.nan_to_num(want, nan=1.0), 1, max_passes).astype(np.int64)

    if n == 0 or budget <= 0 or tolerance <= 0:
        return np.ones(n, dtype=np.int64), float(tolerance)
    allowed = budget * n
    p = passes(tolerance)
    if (p - 1).sum() <= allowed:
        return p, float(tolerance)
    lo, hi = float(tolerance), float(tolerance)
    while (passes(hi) - 1).sum() > allowed:
        lo, hi = hi, hi * 2.0
    for _ in range(40):  # log-space bisection: the largest spend within the budget
        mid = float(np.sqrt(lo * hi))
        if (passes(mid) - 1).sum() > allowed:
            lo = mid
        else:
            hi = mid
    return passes(hi), hi
