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

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.policies.presets import MAX_SPARSE_RINGS, MIN_PHOTONS
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
    out = _zero_moments(moments)
    for p in range(len(target)):
        shift = (rotate[p, 0, 0], rotate[p, 0, 1], rotate[p, 1, 0], rotate[p, 1, 1], delta[p, 0], delta[p, 1])
        _add_shifted(out, target[p], moments, source[p], shift)
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True, nogil=True, inline="always")
def _zero_moments(moments):
    """Zero moments shaped as ``moments`` (s0, s1, k0, k1, k2)."""
    n_vertices, n_channels = moments[0].shape
    return (np.zeros((n_vertices, n_channels)), np.zeros((n_vertices, n_channels, 2)), np.zeros(n_vertices),
            np.zeros((n_vertices, 2)), np.zeros((n_vertices, 2, 2)))


@numba.njit(cache=True, nogil=True, inline="always")
def _add_shifted(out, i, moments, j, shift):
    """Add vertex j's moments to vertex i's in ``out``, moved into i's frame: an offset
    d_j seen from j is R d_j + delta seen from i (shift = (R00, R01, R10, R11, delta0,
    delta1)); K2 becomes R K2_j R^T + rk delta^T + delta rk^T + k0 delta delta^T."""
    s0, s1, k0, k1, k2 = moments
    out_s0, out_s1, out_k0, out_k1, out_k2 = out
    r00, r01, r10, r11, d0, d1 = shift
    for c in range(s0.shape[1]):
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
    for a in range(2):
        ra0 = r00 if a == 0 else r10
        ra1 = r01 if a == 0 else r11
        rka = rk0 if a == 0 else rk1
        da = d0 if a == 0 else d1
        for b in range(2):
            rb0 = r00 if b == 0 else r10
            rb1 = r01 if b == 0 else r11
            rkb = rk0 if b == 0 else rk1
            db = d0 if b == 0 else d1
            rkr = ra0 * k2[j, 0, 0] * rb0 + ra0 * k2[j, 0, 1] * rb1 + ra1 * k2[j, 1, 0] * rb0 + ra1 * k2[j, 1, 1] * rb1
            out_k2[i, a, b] += rkr + rka * db + da * rkb + k0j * da * db


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

    And where the kernel's support holds fewer than ``min_photons`` photons (its photon
    power over one photon's, ``photon_power``: the RGB sum a photon carries; 0 leaves
    this out), the vertex gets a kernel of another shape (``_uniform_supports``): every
    vertex within r rings of it counted once, r grown a ring at a time until the support
    holds ``min_photons`` photons, up to ``max_sparse_rings`` more rings and while the
    support (rings times the local edge length) stays within ``max_radius``. A widened
    hat function would not do: it counts a neighbour once for every path to it, so its
    weight piles up at the centre (a binomial of about sqrt(r) rings), and a support of
    16 photons reads with the noise of a few. A finely modelled object (the living
    room's sofa cushions: 18,108 vertices, edges of 6 mm, about 350 photons at draft)
    was drawn as black patches with bright blots; over a uniform support of 16 photons
    it reads the light within their noise.
    """
    moments = (moment0, moment1) + kernel_moments(positions, normals, tangents, faces)
    pairs = widening_pairs(positions, normals, tangents, faces)
    base = moments
    moments = widen(positions, normals, tangents, faces, moments, rings, pairs)
    estimate, mass = _fit(moments)
    scale = np.maximum(local_scale(positions, faces), 1e-300)
    mass = mass / scale
    target = np.median(mass) if len(mass) else 0.0
    weak = mass < target
    edge = np.sqrt(scale)

    if photon_power > 0 and min_photons > 0 and len(positions):
        # rings a sparse kernel may reach: its extra rings, and its support's radius within max_radius
        reach = np.floor(np.minimum(max_radius / edge, float(rings + max_sparse_rings)))
        limit = np.maximum(reach, rings).astype(np.int64)
        adjacency = _adjacency(pairs, len(positions))
        bitangents = np.cross(normals, tangents)
        frames = (np.asarray(positions, np.float64), np.asarray(tangents, np.float64), bitangents)
        sparse, uniform = _uniform_supports(
            adjacency, frames, base[0].sum(axis=1) / photon_power,
            tuple(np.ascontiguousarray(m, dtype=np.float64) for m in base), rings, float(min_photons), limit,
        )
        if sparse.any():
            estimate[sparse] = _fit(tuple(m[sparse] for m in uniform))[0]
        weak &= ~sparse
    for extra in range(1, max_extra_rings + 1):
        if not weak.any():
            break
        moments = widen(positions, normals, tangents, faces, moments, 1, pairs)
        wider, wider_mass = _fit(moments)
        estimate[weak] = wider[weak]
        weak &= wider_mass / scale < target
    return estimate


def _adjacency(pairs, n):
    """(indptr (V + 1,), indices) int64: each vertex's neighbours, a ring of ``widen``
    (the sources j != i of ``widening_pairs``' rows), as a CSR adjacency."""
    target, source = pairs[0], pairs[1]
    other = target != source
    target, source = target[other], source[other]
    order = np.argsort(target, kind="stable")
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(target, minlength=n), out=indptr[1:])
    return indptr, source[order].astype(np.int64)


@numba.njit(cache=True, nogil=True)
def _uniform_supports(adjacency, frames, photons, moments, rings, least, limit):
    """The sparse vertices and their uniform kernels' moments.

    A vertex is sparse where the vertices within ``rings`` rings of it (a set, found
    breadth first over ``adjacency``) hold fewer than ``least`` photons (``photons``
    (V,): each vertex's share of the photon hits, whose hat weights sum to 1) and it may
    take at least one ring more. Its support then grows a ring at a time until it holds
    ``least``, or reaches ``limit[i]`` rings, or the whole of its piece of mesh. Its moments are those of the
    sum of the hat functions of its support's vertices, each counted once (so a
    uniform kernel inside the support, falling to 0 across its last ring), moved into
    its own frame as ``_widen_once`` moves a neighbour's: the local linear fit over
    them (``_fit``) is exact for linear irradiance as before.

    frames = (positions, tangents, bitangents) (V, 3) float64 each;
    moments = (s0 (V,C), s1 (V,C,2), k0 (V,), k1 (V,2), k2 (V,2,2)) of the hat functions.
    Returns (sparse (V,) bool, the moments' tuple, zero where not sparse)."""
    indptr, indices = adjacency
    positions, tangents, bitangents = frames
    n = len(photons)
    sparse = np.zeros(n, np.bool_)
    out = _zero_moments(moments)
    stamp = np.full(n, -1, np.int64)
    support = np.empty(n, np.int64)
    for i in range(n):
        stamp[i] = i
        support[0] = i
        size, ring_start, count, ring = 1, 0, photons[i], 0
        while ring < limit[i] and (ring < rings or count < least):
            ring_stop = size
            for a in range(ring_start, ring_stop):
                v = support[a]
                for p in range(indptr[v], indptr[v + 1]):
                    w = indices[p]
                    if stamp[w] != i:
                        stamp[w] = i
                        support[size] = w
                        size += 1
                        count += photons[w]
            ring += 1
            if size == ring_stop:  # the whole piece
                break
            ring_start = ring_stop
        if ring <= rings:  # enough photons, or no ring more to take: the widened hat function stays
            continue
        sparse[i] = True
        t, b, xi = tangents[i], bitangents[i], positions[i]
        for a in range(size):
            j = support[a]
            tj, bj, xj = tangents[j], bitangents[j], positions[j]
            x = (xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2])
            shift = (_dot3(t, tj), _dot3(t, bj), _dot3(b, tj), _dot3(b, bj), _dot3(t, x), _dot3(b, x))
            _add_shifted(out, i, moments, j, shift)
    return sparse, out
