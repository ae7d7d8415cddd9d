"""Irradiance at every vertex from photon hits: local linear density estimation.

Walter et al. (1997) fit, at each vertex, a linear function to the photon density
with a kernel, which removes the boundary bias of a plain kernel estimate (that reads
1/2 of the truth on an edge and 1/4 in a corner, exactly where mesh vertices sit).
Here the kernel of vertex i is its hat function lambda_i (1 at the vertex, 0 at the
far edges of its triangles, the finite-element basis of the mesh), so

    E(x) ~ a + g . (x - x_i)       minimises  integral lambda_i (E_true - E)^2 dA

and its normal equations need only

    photon moments (streamed, additive over batches):
        S0 = sum_hits power * lambda_i(hit),   S1 = sum_hits power * lambda_i(hit) * d
    kernel moments (exact, from the mesh):
        K0 = integral lambda_i dA,  K1 = integral lambda_i d dA,  K2 = integral lambda_i d d^T dA

with d = x - x_i in vertex i's tangent plane. [K0 K1^T; K1 K2] [a; g] = [S0; S1] gives
a = E(x_i): exact for irradiance that varies linearly, at edges and corners too. At a
vertex inside a symmetric fan K1 = 0 and a = S0 / K0, the normalised kernel estimate.
Vertices split at creases have their own hat functions, so each side of an edge gets
its own light.
"""

from __future__ import annotations

import numba
import numpy as np

from radiosity.formats.presets import MAX_SPARSE_RINGS, MIN_PHOTONS
from radiosity.scene.geometry import unique_edges

_CONDITION_LIMIT = 1e-3  # below this (relative) Schur complement, fall back to S0 / K0
SEAM_COSINE = 0.9  # vertices at one position with normals this alike are one surface (``seam_pairs``)


def kernel_moments(positions, normals, tangents, faces):
    """K0 (V,), K1 (V, 2), K2 (V, 2, 2) float64 of each vertex's hat function.

    For a triangle (p0, p1, p2) with e1 = p1 - p0, e2 = p2 - p0 seen from corner p0:
    integral lambda0 = A/3, integral lambda0 (x - p0) = A/12 (e1 + e2), and
    integral lambda0 (x - p0)(x - p0)^T = A/30 (e1 e1^T + e2 e2^T) + A/60 (e1 e2^T + e2 e1^T).
    Offsets are expressed in the tangent frame (t, n x t) of the corner's vertex.
    """
    n_vertices = len(positions)
    bitangents = np.cross(normals, tangents)
    tri = positions[faces]  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    k0 = np.zeros(n_vertices)
    k1 = np.zeros((n_vertices, 2))
    k2 = np.zeros((n_vertices, 2, 2))
    for corner in range(3):
        vert = faces[:, corner]
        frame = np.stack([tangents[vert], bitangents[vert]], axis=1)  # (F, 2, 3)
        e1 = np.einsum("fij,fj->fi", frame, tri[:, (corner + 1) % 3] - tri[:, corner])
        e2 = np.einsum("fij,fj->fi", frame, tri[:, (corner + 2) % 3] - tri[:, corner])
        np.add.at(k0, vert, area / 3.0)
        np.add.at(k1, vert, (area / 12.0)[:, None] * (e1 + e2))
        outer = (
            (area / 30.0)[:, None, None] * (e1[:, :, None] * e1[:, None, :] + e2[:, :, None] * e2[:, None, :])
            + (area / 60.0)[:, None, None] * (e1[:, :, None] * e2[:, None, :] + e2[:, :, None] * e1[:, None, :])
        )
        np.add.at(k2, vert, outer)
    return k0, k1, k2


def seam_pairs(positions, normals, alike=SEAM_COSINE):
    """(S, 2) int64: pairs of distinct vertices at the same position whose normals are
    within acos(``alike``) of each other: one surface split by its texture coordinates
    (a model's UV islands), not at a crease. Rings of neighbours (``widen``) cross such
    a seam through them. The living room's sofa cushions are 1,801 pieces of a median
    9 vertices; a kernel could not grow beyond its piece."""
    if len(positions) == 0:
        return np.zeros((0, 2), np.int64)
    _, group, counts = np.unique(positions, axis=0, return_inverse=True, return_counts=True)
    group = group.reshape(-1)
    shared = np.flatnonzero(counts[group] > 1)
    if not len(shared):
        return np.zeros((0, 2), np.int64)
    order = shared[np.argsort(group[shared], kind="stable")]
    first = np.r_[0, np.flatnonzero(np.diff(group[order])) + 1]
    pairs = []
    for start, stop in zip(first, np.r_[first[1:], len(order)]):
        members = order[start:stop]
        a, b = np.triu_indices(len(members), 1)
        pairs.append(np.stack([members[a], members[b]], axis=1))
    pairs = np.concatenate(pairs)
    cosine = np.einsum("pi,pi->p", normals[pairs[:, 0]], normals[pairs[:, 1]])
    return pairs[cosine > alike].astype(np.int64)


def widening_pairs(positions, normals, tangents, faces):
    """What ``widen`` adds up: (target, source, rotate, delta), one row per pair of a
    vertex i (target) and itself or a neighbour j (source): a vertex sharing a triangle
    edge with it, or one at its position across a texture seam (``seam_pairs``).
    ``rotate`` (P, 2, 2) takes j-frame coordinates to i's frame, ``delta`` (P, 2) is
    x_j - x_i in i's frame. Depends on the mesh only: compute it once for every
    ``widen`` of a mesh."""
    edges = unique_edges(faces)
    edges = np.concatenate([edges.reshape(-1, 2), seam_pairs(positions, normals)])
    n_vertices = len(positions)
    target = np.concatenate([np.arange(n_vertices), edges[:, 0], edges[:, 1]])
    source = np.concatenate([np.arange(n_vertices), edges[:, 1], edges[:, 0]])
    bitangents = np.cross(normals, tangents)
    frame_i = np.stack([tangents[target], bitangents[target]], axis=1)  # (P, 2, 3)
    frame_j = np.stack([tangents[source], bitangents[source]], axis=1)
    rotate = np.einsum("pik,pjk->pij", frame_i, frame_j)  # j-frame coordinates -> i-frame
    delta = np.einsum("pik,pk->pi", frame_i, positions[source] - positions[target])
    return target.astype(np.int64), source.astype(np.int64), rotate, delta


def widen(positions, normals, tangents, faces, moments, rings=1, pairs=None):
    """Widen every vertex's kernel by ``rings`` rings of neighbours.

    The widened kernel of vertex i is the sum of the hat functions of i and of the
    vertices sharing a triangle with it (applied ``rings`` times). Photon and kernel
    moments of a sum are sums of moments, each shifted from vertex j's frame to
    vertex i's: an offset d_j seen from j is R d_j + delta seen from i, with R the
    2x2 change of tangent frame and delta = x_j - x_i in i's frame. So widening costs
    no photon work and keeps the fit exact for linearly varying irradiance, while
    every vertex (corners above all, whose own hat covers one small triangle) sees
    several times the photons.

    moments = (S0 (V,C), S1 (V,C,2), K0 (V,), K1 (V,2), K2 (V,2,2)); returns the widened
    tuple. ``pairs``: ``widening_pairs`` of the mesh, if already at hand.
    """
    if pairs is None:
        pairs = widening_pairs(positions, normals, tangents, faces)
    for _ in range(rings):
        moments = _widen_once(tuple(pairs), tuple(np.ascontiguousarray(m, dtype=np.float64) for m in moments))
    return moments


@numba.njit(cache=True, nogil=True)
def _widen_once(pairs, moments):
    """One ring of ``widen``: every moment of i gains those of each of its ``pairs``'
    sources j, moved into i's frame (in the order of the pairs, as np.add.at adds).
    pairs = (target, source, rotate, delta); moments = (s0, s1, k0, k1, k2)."""
    target, source, rotate, delta = pairs
    s0, s1, k0, k1, k2 = moments
    n_vertices, n_channels = s0.shape
    out_s0 = np.zeros((n_vertices, n_channels))
    out_s1 = np.zeros((n_vertices, n_channels, 2))
    out_k0 = np.zeros(n_vertices)
    out_k1 = np.zeros((n_vertices, 2))
    out_k2 = np.zeros((n_vertices, 2, 2))
    for p in range(len(target)):
        i, j = target[p], source[p]
        r00, r01, r10, r11 = rotate[p, 0, 0], rotate[p, 0, 1], rotate[p, 1, 0], rotate[p, 1, 1]
        d0, d1 = delta[p, 0], delta[p, 1]
        for c in range(n_channels):
            s0j = s0[j, c]
            out_s0[i, c] += s0j
            out_s1[i, c, 0] += (r00 * s1[j, c, 0] + r01 * s1[j, c, 1]) + d0 * s0j
            out_s1[i, c, 1] += (r10 * s1[j, c, 0] + r11 * s1[j, c, 1]) + d1 * s0j
        k0j = k0[j]
        rk0 = r00 * k1[j, 0] + r01 * k1[j, 1]
        rk1 = r10 * k1[j, 0] + r11 * k1[j, 1]
        out_k0[i] += k0j
        out_k1[i, 0] += rk0 + d0 * k0j
        out_k1[i, 1] += rk1 + d1 * k0j
        # R K2_j R^T, then the shift: + rk d^T + d rk^T + k0 d d^T
        for a in range(2):
            ra0, ra1 = rotate[p, a, 0], rotate[p, a, 1]
            rka = rk0 if a == 0 else rk1
            da = d0 if a == 0 else d1
            for b in range(2):
                rb0, rb1 = rotate[p, b, 0], rotate[p, b, 1]
                rkb = rk0 if b == 0 else rk1
                db = d0 if b == 0 else d1
                rkr = (
                    ra0 * k2[j, 0, 0] * rb0 + ra0 * k2[j, 0, 1] * rb1 + ra1 * k2[j, 1, 0] * rb0 + ra1 * k2[j, 1, 1] * rb1
                )
                out_k2[i, a, b] += rkr + rka * db + da * rkb + k0j * da * db
    return out_s0, out_s1, out_k0, out_k1, out_k2


def _fit(moments):
    """Local linear fits: (irradiance (V, 3) >= 0, Schur complement (V,)).

    The Schur complement K0 - K1^T K2^-1 K1 is the fit's effective kernel mass: the
    variance of the fitted value goes as its inverse. Where the fit is ill-conditioned
    (a support of slivers along one line) the normalised estimate S0 / K0 is used and
    the returned mass is that of the constant fit, K0, scaled down by the condition limit.
    """
    moment0, moment1, k0, k1, k2 = moments
    estimate = np.zeros_like(moment0)
    has_area = k0 > 0
    estimate[has_area] = moment0[has_area] / k0[has_area, None]
    det = k2[:, 0, 0] * k2[:, 1, 1] - k2[:, 0, 1] * k2[:, 1, 0]
    scale = np.maximum(k2[:, 0, 0] + k2[:, 1, 1], 1e-300)
    ok = has_area & (det > 1e-9 * scale**2)
    inv = np.zeros_like(k2)
    inv[ok, 0, 0] = k2[ok, 1, 1] / det[ok]
    inv[ok, 1, 1] = k2[ok, 0, 0] / det[ok]
    inv[ok, 0, 1] = -k2[ok, 0, 1] / det[ok]
    inv[ok, 1, 0] = -k2[ok, 1, 0] / det[ok]
    # a = (S0 - K1^T K2^-1 S1) / (K0 - K1^T K2^-1 K1)
    k2inv_k1 = np.einsum("vij,vj->vi", inv, k1)
    schur = k0 - np.einsum("vi,vi->v", k1, k2inv_k1)
    ok &= schur > _CONDITION_LIMIT * k0
    fitted = (moment0 - np.einsum("vi,vci->vc", k2inv_k1, moment1)) / np.where(ok, schur, 1.0)[:, None]
    estimate[ok] = fitted[ok]
    mass = np.where(ok, schur, _CONDITION_LIMIT * k0)
    return np.maximum(estimate, 0.0), mass


def local_scale(positions, faces):
    """(V,) mean squared length of the edges at each vertex: the area a vertex's
    kernel would cover inside the mesh, up to a constant, at that vertex's mesh size."""
    edges = unique_edges(faces)
    length2 = np.sum((positions[edges[:, 0]] - positions[edges[:, 1]]) ** 2, axis=1)
    total = np.zeros(len(positions))
    count = np.zeros(len(positions))
    for side in range(2):
        np.add.at(total, edges[:, side], length2)
        np.add.at(count, edges[:, side], 1.0)
    return total / np.maximum(count, 1.0)


def irradiance(positions, normals, tangents, faces, moment0, moment1, rings=1, max_extra_rings=3, *,
               photon_power=0.0, min_photons=MIN_PHOTONS, max_sparse_rings=MAX_SPARSE_RINGS, max_radius=np.inf):
    """Vertex irradiance (V, 3) of one object from its photon moments.

    Each vertex's kernel is its hat function widened by ``rings`` rings, and by up to
    ``max_extra_rings`` more where its fit is weaker than a typical vertex's of the
    same mesh size (the Schur complement over the squared local edge length, below the
    median): a corner extrapolates a linear fit from a one-sided support, and without
    more photons its estimate would be several times noisier than the interior's.
    Widening there roughly equalises the variance. The comparison is at the vertex's
    own mesh size so that where the mesh was refined (along a shadow edge, say) the
    small kernels are not widened back across the edge they resolve: rings are
    topological, so the support shrinks with the triangles.

    And where the kernel holds fewer than ``min_photons`` photons (its photon power over
    one photon's, ``photon_power``: the RGB sum a photon carries; 0 leaves this out), it
    is widened a ring at a time, up to ``max_sparse_rings`` more, while its support
    (rings times the local edge length) stays within ``max_radius``. A finely modelled
    object (the living room's sofa: cushions of 18,108 vertices, edges of 6 mm) has
    kernels so small that at draft most of them catch no photon at all, and the sofa
    was drawn in black-and-white speckle: a kernel of one photon reads 0 or several
    times the truth. A kernel that holds a few photons reads the light, at the cost of
    a support a few rings wider on such a mesh only.
    """
    moments = (moment0, moment1) + kernel_moments(positions, normals, tangents, faces)
    pairs = widening_pairs(positions, normals, tangents, faces)
    moments = widen(positions, normals, tangents, faces, moments, rings, pairs)
    estimate, mass = _fit(moments)
    scale = np.maximum(local_scale(positions, faces), 1e-300)
    mass = mass / scale
    target = np.median(mass) if len(mass) else 0.0
    weak = mass < target
    edge = np.sqrt(scale)

    # the photons in each support, counted only where they are asked about
    count = _PhotonCount(pairs, moment0, photon_power, rings) if photon_power > 0 and min_photons > 0 else None
    sparse = count.fewer(min_photons) if count is not None else np.zeros(len(positions), bool)
    for extra in range(1, max(max_extra_rings, max_sparse_rings) + 1):
        weak &= extra <= max_extra_rings
        sparse &= (extra <= max_sparse_rings) & ((rings + extra) * edge <= max_radius)
        wanted = weak | sparse
        if not wanted.any():
            break
        moments = widen(positions, normals, tangents, faces, moments, 1, pairs)
        wider, wider_mass = _fit(moments)
        estimate[wanted] = wider[wanted]
        weak &= wider_mass / scale < target
        if sparse.any():
            sparse &= count.grow(sparse).fewer(min_photons)
    return estimate


class _PhotonCount:
    """The photons in each vertex's kernel support: the vertices within r rings of it
    (a set: a widened kernel counts a neighbour's photons once for every path to it, 7^r
    times at most, so its moments do not count photons), each holding its share of the
    photons that hit its triangles (a hit's hat weights sum to 1). Counted for the
    vertices still asked about only, a ring at a time, as a sparse matrix of their
    supports (rows) over the vertices."""

    def __init__(self, pairs, moment0, photon_power, rings):
        import scipy.sparse as sp

        n = len(moment0)
        self.photons = moment0.sum(axis=1) / photon_power
        target, source = pairs[0], pairs[1]  # self pairs and both directions of every edge
        self.adjacency = sp.csr_matrix((np.ones(len(target), np.float32), (target, source)), shape=(n, n))
        self.rows = np.arange(n)
        self.support = sp.identity(n, np.float32, format="csr")
        for _ in range(rings):
            self._ring()

    def _ring(self):
        self.support = self.support @ self.adjacency
        self.support.data[:] = 1.0

    def grow(self, asked):
        """One ring more for the vertices ``asked`` (bool (V,)); the others are let go."""
        keep = asked[self.rows]
        self.rows, self.support = self.rows[keep], self.support[keep]
        self._ring()
        return self

    def fewer(self, least):
        """(V,) bool: the vertices counted whose support holds fewer than ``least`` photons."""
        out = np.zeros(len(self.adjacency.indptr) - 1, bool)
        if len(self.rows):
            out[self.rows] = self.support @ self.photons < least
        return out
