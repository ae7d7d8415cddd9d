"""Triangle-mesh operations the solver needs: welding, cleaning, crease-split normals,
conforming refinement (to a maximum edge length, or of chosen edges), and tangent frames.

All functions are free functions on numpy arrays:

    positions : (V, 3) float64
    faces     : (F, 3) int64, counter-clockwise seen from the front
    normals   : (V, 3) float64, unit

trimesh supplies the face adjacency; scipy the KD-tree and connected components.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from radiosity.files.errors import InputError

_LOG_TINY_DET = math.log(1e-300)  # a transform whose |det| is below 1e-300 is singular

# corner k of a face starts edge k, which runs to corner (k + 1) % 3
_EDGE_CORNERS = np.array([[0, 1], [1, 2], [2, 0]])


def face_normals(positions, faces):
    """Unit geometric normals (F, 3) and areas (F,) of the triangles."""
    tri = positions[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    twice_area = np.linalg.norm(cross, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = cross / twice_area[:, None]
    unit[twice_area == 0] = 0.0
    return unit, 0.5 * twice_area


def weld(positions, faces, tol, uvs=None):
    """Merge vertices closer than ``tol``; returns (positions, faces) with faces remapped.

    Positions of a merged group are those of its lowest-index member, so welding is
    exact for points that already coincide. With texture coordinates ``uvs`` (V, 2),
    only vertices whose uvs also agree (within ``tol`` relative to 1) merge, so a
    texture's seam keeps a copy of each vertex per side; returns (positions, faces, uvs).
    """
    n = len(positions)
    points = positions
    if uvs is not None:
        uvs = np.asarray(uvs, dtype=np.float64)
        extent = float(np.ptp(positions, axis=0).max()) if n else 0.0
        points = np.hstack([positions, uvs * max(extent, np.finfo(float).tiny)])
    if n == 0:
        return (positions, faces) if uvs is None else (positions, faces, uvs)
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return (positions, faces) if uvs is None else (positions, faces, uvs)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # representative of each component: its first vertex; keep original order
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    keep = np.sort(first)
    new_index = np.empty(label.max() + 1, dtype=np.int64)
    new_index[label[keep]] = np.arange(len(keep))
    if uvs is not None:
        return positions[keep], new_index[label][faces], uvs[keep]
    return positions[keep], new_index[label][faces]


def remove_degenerate(positions, faces, rel_area=1e-14):
    """Drop triangles with a repeated vertex or (near) zero area, and unused vertices.

    ``rel_area`` is relative to the squared diagonal of the mesh's bounding box, so
    the test does not depend on the scene's units. Returns (positions, faces, dropped).
    """
    if len(faces) == 0:
        return positions[:0], faces, 0
    repeated = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    )
    diag2 = float(np.sum(np.ptp(positions, axis=0) ** 2))
    _, area = face_normals(positions, faces)
    good = ~repeated & (area > rel_area * diag2)
    dropped = int(len(faces) - good.sum())
    positions, faces = compact(positions, faces[good])
    return positions, faces, dropped


def compact(positions, faces, *attributes):
    """Remove vertices no face uses; returns (positions, faces, *attributes)."""
    used = np.zeros(len(positions), dtype=bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    out = (positions[used], remap[faces].astype(np.int64))
    return out + tuple(a[used] for a in attributes)


def _sorted_pairs(pairs):
    """(K, 2) rows (a, b) as (min, max): ``np.sort(pairs, axis=1)``, faster."""
    return np.stack([np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])], axis=1)


def unique_pairs(pairs, return_inverse=False):
    """``np.unique(pairs, axis=0)`` (and its inverse, 1-D) of (K, 2) non-negative
    integers, several times faster: each pair as one int64 key, a * n + b, sorts
    exactly as the pairs do lexicographically."""
    pairs = np.asarray(pairs)
    if not len(pairs):
        out = pairs.reshape(0, 2)
        return (out, np.zeros(0, dtype=np.int64)) if return_inverse else out
    n = int(pairs.max()) + 1
    key = pairs[:, 0].astype(np.int64) * n + pairs[:, 1]
    if return_inverse:
        key, inverse = np.unique(key, return_inverse=True)
    else:
        key = np.unique(key)
    out = np.stack([key // n, key % n], axis=1).astype(pairs.dtype, copy=False)
    return (out, inverse.reshape(-1)) if return_inverse else out


def unique_edges(faces):
    """(E, 2) int: every edge of a triangle mesh once, as (smaller, larger) vertex index,
    sorted."""
    return unique_pairs(_sorted_pairs(np.asarray(faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)))


def corner_angles(positions, faces):
    """Interior angle at each corner, (F, 3) float64."""
    return trimesh.triangles.angles(positions[faces])


def crease_normals(positions, faces, crease_angle_deg, uvs=None):
    """Angle-weighted vertex normals, with vertices split where faces meet at a crease.

    Two faces sharing an edge are smooth across it when their normals differ by less
    than ``crease_angle_deg``. Each vertex is split into one copy per group of its
    faces that are connected through smooth edges, so a cube keeps six flat faces and
    a crease that dies out inside a surface stays sharp only where it is sharp.

    Returns (positions, faces, normals) of the split mesh. With texture coordinates
    ``uvs`` (V, 2), faces are smooth across a texture's seam too (vertices at the same
    position, other uvs: their normals are the same), each copy keeps its uvs, and
    (positions, faces, normals, uvs) are returned.
    """
    fn, _ = face_normals(positions, faces)
    linked = faces if uvs is None else position_labels(positions)[faces]  # what "shares an edge" means
    weights = corner_angles(positions, faces)  # (F, 3)
    n_faces = len(faces)
    corner_vertex = faces.ravel()
    n_corners = 3 * n_faces

    rows, cols = [], []
    if n_faces > 1:
        adjacency, edges = trimesh.graph.face_adjacency(faces=linked, return_edges=True)
        if len(adjacency):
            cosang = np.einsum("ij,ij->i", fn[adjacency[:, 0]], fn[adjacency[:, 1]])
            smooth = cosang > np.cos(np.radians(crease_angle_deg))
            adjacency, edges = adjacency[smooth], edges[smooth]
            for side in range(2):  # both vertices of the shared edge
                v = edges[:, side]
                k0 = np.argmax(linked[adjacency[:, 0]] == v[:, None], axis=1)
                k1 = np.argmax(linked[adjacency[:, 1]] == v[:, None], axis=1)
                rows.append(3 * adjacency[:, 0] + k0)
                cols.append(3 * adjacency[:, 1] + k1)
    if rows:
        rows, cols = np.concatenate(rows), np.concatenate(cols)
    else:
        rows = cols = np.zeros(0, dtype=np.int64)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_corners, n_corners))
    n_groups, group = connected_components(graph, directed=False)

    new_positions = np.empty((n_groups, 3))
    new_positions[group] = positions[corner_vertex]
    summed = np.zeros((n_groups, 3))
    np.add.at(summed, group, (weights[:, :, None] * fn[:, None, :]).reshape(-1, 3))
    normals = _normalize_or(summed, np.repeat(fn, 3, axis=0)[np.unique(group, return_index=True)[1]])
    if uvs is None:
        return new_positions, group.reshape(-1, 3).astype(np.int64), normals
    # a smooth group may hold corners of several copies of a point (a seam): one vertex per copy
    copies, copy = unique_pairs(np.stack([group, corner_vertex], axis=1), return_inverse=True)
    return (positions[copies[:, 1]], copy.reshape(-1, 3).astype(np.int64), normals[copies[:, 0]],
            np.asarray(uvs, dtype=np.float64)[copies[:, 1]])


def _normalize_or(v, fallback):
    """Normalise rows of v; rows of zero length take the matching row of fallback."""
    length = np.linalg.norm(v, axis=1)
    out = fallback.astype(np.float64).copy()
    ok = length > 0
    out[ok] = v[ok] / length[ok, None]
    return out


def refine(positions, faces, max_edge, normals=None, max_triangles=5_000_000, uvs=None):
    """Conforming refinement until no edge is longer than ``max_edge``.

    Longest-edge refinement (Rivara): every edge longer than ``max_edge`` is marked,
    and a triangle with any marked edge also marks its longest edge; marks belong to
    edges, so neighbours always split the same edges and no T-junction appears. A
    triangle then splits by its marked edges: longest edge only, bisection (2); longest
    and one more, 3 triangles; all three, the four similar triangles of midpoint
    subdivision. Angles stay bounded away from zero.

    New vertices interpolate ``normals`` (renormalised), so a tessellated curved
    surface keeps its smooth shading. Returns (positions, faces, normals_or_None), and
    with texture coordinates ``uvs`` (V, 2) also the new vertices' (interpolated
    linearly, each copy of a seam's edge its own): (positions, faces, normals, uvs).
    """
    if not max_edge > 0:
        raise InputError(f"max edge length must be positive, got {max_edge}")
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    nrm = None if normals is None else np.asarray(normals, dtype=np.float64)
    _, area = face_normals(p, f)
    with np.errstate(over="ignore", divide="ignore"):  # extreme max_edge: an estimate of 0 or inf
        estimate = len(f) + 2.3 * area.sum() / (np.sqrt(3) / 4 * np.float64(max_edge) ** 2)
    if estimate > max_triangles:
        raise InputError(
            f"refining to a maximum edge of {max_edge:g} would make about {estimate:.3g} "
            f"triangles (limit {max_triangles:.3g}); choose a larger maximum edge"
        )
    labels = position_labels(p)
    attributes = () if uvs is None else (np.asarray(uvs, dtype=np.float64),)
    for _ in range(200):
        edges = _edge_tables(f, labels)
        length = np.linalg.norm(p[edges.index_edges[:, 0]] - p[edges.index_edges[:, 1]], axis=1)
        mark = np.zeros(len(edges.geometric), dtype=bool)
        mark[edges.geometric_of[length > max_edge]] = True
        if not mark.any():
            break
        p, f, nrm, labels, attributes = _split_marked(p, f, nrm, labels, edges, mark, attributes)
    else:  # pragma: no cover - 200 rounds halve any edge far below float precision
        raise RuntimeError("mesh refinement did not converge")
    return (p, f, nrm) if uvs is None else (p, f, nrm, attributes[0])


def position_labels(positions):
    """(V,) int64: one label per distinct position, so the copies of a vertex split at
    a crease (same point, other normal) share it."""
    p = np.asarray(positions)
    if not len(p):
        return np.zeros(0, dtype=np.int64)
    # the inverse of np.unique(p, axis=0), without its sort of rows as records: rows in
    # lexicographic order, a new label wherever a row differs from the one before
    order = np.lexsort(p.T[::-1])
    rows = p[order]
    new = np.empty(len(p), dtype=bool)
    new[0] = False
    np.any(rows[1:] != rows[:-1], axis=1, out=new[1:])
    labels = np.empty(len(p), dtype=np.int64)
    labels[order] = np.cumsum(new)
    return labels


class _Edges(NamedTuple):
    """The edges of a mesh, by vertex indices and by position.

    index_edges : (E, 2) int64, sorted vertex pairs, each once
    index_of    : (F, 3) int64, edge k of each face (corners k, k + 1) in index_edges
    geometric   : (G, 2) int64, sorted position-label pairs: an edge and its copies
                  across a crease are one geometric edge
    geometric_of: (E,) int64, the geometric edge of each index edge
    """

    index_edges: np.ndarray
    index_of: np.ndarray
    geometric: np.ndarray
    geometric_of: np.ndarray


def _edge_tables(faces, labels):
    sorted_ev = _sorted_pairs(faces[:, _EDGE_CORNERS].reshape(-1, 2))
    index_edges, index_of = unique_pairs(sorted_ev, return_inverse=True)
    geometric, geometric_of = unique_pairs(_sorted_pairs(labels[index_edges]), return_inverse=True)
    return _Edges(index_edges, index_of.reshape(-1, 3), geometric, geometric_of.reshape(-1))


def _split_marked(p, f, nrm, labels, edges, mark, attributes=()):
    """One round of conforming longest-edge refinement of the marked geometric edges.

    Closure (Rivara): a triangle with a marked edge also marks its longest edge, until
    nothing changes; marks belong to geometric edges, so the faces on both sides of an
    edge, and the copies of an edge split at a crease, split the same edges and no
    T-junction appears. Each marked index edge gets a midpoint (a crease's copies one
    each, with their own interpolated normals). Returns (positions, faces, normals,
    labels, attributes) of the refined mesh; ``attributes`` are per-vertex arrays whose
    midpoint values are the means of the edge's ends.
    """
    length = np.linalg.norm(p[edges.index_edges[:, 0]] - p[edges.index_edges[:, 1]], axis=1)
    face_geometric = edges.geometric_of[edges.index_of]  # (F, 3)
    longest = np.argmax(length[edges.index_of], axis=1)
    rows1 = np.arange(len(f))
    longest_edge = face_geometric[rows1, longest]
    mark = mark.copy()
    while True:  # closure: a triangle with a marked edge marks its longest edge
        touched = mark[face_geometric].any(axis=1)
        needs = touched & ~mark[longest_edge]
        if not needs.any():
            break
        mark[longest_edge[needs]] = True

    midpoint = np.full(len(edges.index_edges), -1, dtype=np.int64)
    marked = np.nonzero(mark[edges.geometric_of])[0]
    midpoint[marked] = len(p) + np.arange(len(marked))
    ends = edges.index_edges[marked]
    p = np.vstack([p, 0.5 * (p[ends[:, 0]] + p[ends[:, 1]])])
    # a midpoint's label: one per marked geometric edge, after the existing labels
    geo_marked, geo_label = np.unique(edges.geometric_of[marked], return_inverse=True)
    labels = np.concatenate([labels, labels.max(initial=-1) + 1 + geo_label.reshape(-1)])
    if nrm is not None:
        summed = nrm[ends[:, 0]] + nrm[ends[:, 1]]
        nrm = np.vstack([nrm, _normalize_or(summed, nrm[ends[:, 0]])])
    attributes = tuple(np.concatenate([a, 0.5 * (a[ends[:, 0]] + a[ends[:, 1]])]) for a in attributes)

    # rotate every triangle so that its longest edge is edge 0: (a, b) longest
    rot = (np.arange(3)[None, :] + longest[:, None]) % 3
    rows = rows1[:, None]
    a, b, c = f[rows, rot].T
    m0, m1, m2 = midpoint[edges.index_of[rows, rot]].T  # midpoints of (a,b), (b,c), (c,a)
    s0, s1, s2 = m0 >= 0, m1 >= 0, m2 >= 0
    pieces = [np.stack([a, b, c], 1)[~s0]]
    only0 = s0 & ~s1 & ~s2
    pieces += [np.stack(t, 1)[only0] for t in ((a, m0, c), (m0, b, c))]
    with01 = s0 & s1 & ~s2
    pieces += [np.stack(t, 1)[with01] for t in ((a, m0, c), (m0, b, m1), (m0, m1, c))]
    with02 = s0 & ~s1 & s2
    pieces += [np.stack(t, 1)[with02] for t in ((a, m0, m2), (m0, c, m2), (m0, b, c))]
    red = s0 & s1 & s2
    pieces += [np.stack(t, 1)[red] for t in ((a, m0, m2), (m0, b, m1), (m2, m1, c), (m0, m1, m2))]
    return p, np.concatenate(pieces), nrm, labels, attributes


def split_edges(positions, faces, edges, normals=None, uvs=None):
    """Conforming refinement that splits the given edges (and whatever the closure needs).

    edges : (K, 2) int vertex pairs of edges of ``faces`` (either order); pairs that are
    not edges of the mesh are ignored. One round of longest-edge refinement
    (``_split_marked``): each given edge, its copies across a crease (same positions,
    other vertices) and, by closure, the longest edge of every triangle that has a
    split edge, get their midpoint. New vertices interpolate ``normals`` (renormalised).
    Returns (positions, faces, normals_or_None); nothing marked: the inputs unchanged.
    With texture coordinates ``uvs`` (V, 2), interpolated linearly, also them:
    (positions, faces, normals, uvs).
    """
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    nrm = None if normals is None else np.asarray(normals, dtype=np.float64)
    attributes = () if uvs is None else (np.asarray(uvs, dtype=np.float64),)
    edges = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)

    def result():
        return (p, f, nrm) if uvs is None else (p, f, nrm, attributes[0])

    if not len(edges) or not len(f):
        return result()
    labels = position_labels(p)
    table = _edge_tables(f, labels)
    key_wanted = edges[:, 0] * len(p) + edges[:, 1]
    key_have = table.index_edges[:, 0] * len(p) + table.index_edges[:, 1]
    found = np.isin(key_have, key_wanted)
    if not found.any():
        return result()
    mark = np.zeros(len(table.geometric), dtype=bool)
    mark[table.geometric_of[found]] = True
    p, f, nrm, _, attributes = _split_marked(p, f, nrm, labels, table, mark, attributes)
    return result()


def refine_density(positions, faces, density, normals=None, max_vertices=None, max_rounds=12, uvs=None):
    """Conforming refinement to a size field: edges no longer than 1 / density.

    density : (V,) float64 >= 0, the wanted edges per unit length at each vertex (0:
    leave alone). An edge is split while its length times the mean density of its ends
    exceeds 1; a midpoint gets that mean, so the field is interpolated linearly along
    the edges and the refinement grades from fine to coarse without spreading further.
    Each round is one ``_split_marked`` (closure included, so the mesh stays conforming,
    also across creases). ``max_vertices``: stop before a round that would go beyond it
    (the mesh of the last round within it is returned). Returns (positions, faces,
    normals_or_None), and with texture coordinates ``uvs`` (V, 2) (interpolated
    linearly) also them: (positions, faces, normals, uvs).
    """
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    nrm = None if normals is None else np.asarray(normals, dtype=np.float64)
    rho = np.asarray(density, dtype=np.float64)
    if rho.shape != (len(p),) or not np.all(rho >= 0):
        raise ValueError("density must be (V,) and >= 0")
    labels = position_labels(p)
    attributes = (rho,) if uvs is None else (rho, np.asarray(uvs, dtype=np.float64))
    for _ in range(max_rounds):
        edges = _edge_tables(f, labels)
        ends = edges.index_edges
        length = np.linalg.norm(p[ends[:, 0]] - p[ends[:, 1]], axis=1)
        want = length * 0.5 * (rho[ends[:, 0]] + rho[ends[:, 1]]) > 1.0
        if not want.any():
            break
        mark = np.zeros(len(edges.geometric), dtype=bool)
        mark[edges.geometric_of[want]] = True
        new = _split_marked(p, f, nrm, labels, edges, mark, attributes)
        if max_vertices is not None and len(new[0]) > max_vertices:
            break
        p, f, nrm, labels, attributes = new
        rho = attributes[0]
    return (p, f, nrm) if uvs is None else (p, f, nrm, attributes[1])


def tangents(normals):
    """Unit tangents (V, 3) orthogonal to ``normals``: world +x projected into the
    tangent plane, or world +z where the normal is within ~25 degrees of +-x.

    The choice is per vertex and deterministic; a vertex's direction grid is read in
    its own frame, so the frame need not be continuous across the surface.
    """
    n = np.asarray(normals, dtype=np.float64)
    ref = np.zeros_like(n)
    near_x = np.abs(n[:, 0]) > 0.9
    ref[~near_x, 0] = 1.0
    ref[near_x, 2] = 1.0
    t = ref - np.einsum("ij,ij->i", ref, n)[:, None] * n
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def transform_matrix(scale=1.0, rotate_deg=(0.0, 0.0, 0.0), translate=(0.0, 0.0, 0.0)):
    """4x4 matrix: scale, then rotate about x, then y, then z (degrees), then translate."""
    s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,))
    m = np.diag(np.append(s, 1.0))
    for axis, deg in zip("xyz", rotate_deg):
        direction = {"x": [1, 0, 0], "y": [0, 1, 0], "z": [0, 0, 1]}[axis]
        m = trimesh.transformations.rotation_matrix(np.radians(deg), direction) @ m
    m[:3, 3] += np.asarray(translate, dtype=np.float64)
    return m


def singular(linear):
    """Whether a transform's 3x3 ``linear`` part is singular (|det| < 1e-300) or not finite.
    Judged on the determinant's logarithm: a huge scale's determinant would overflow,
    yet it is a transform (the coordinates it makes are refused, by size, elsewhere)."""
    if not np.isfinite(linear).all():
        return True
    sign, log_det = np.linalg.slogdet(linear)
    return bool(sign == 0 or log_det < _LOG_TINY_DET)


def apply_transform(matrix, positions, faces, normals=None):
    """Transform positions (and normals by the inverse transpose); a mirroring
    transform reverses the winding so fronts stay fronts. Returns (positions, faces, normals)."""
    linear = matrix[:3, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # huge values become inf, which callers refuse
        p = positions @ linear.T + matrix[:3, 3]
        mirrored = np.linalg.slogdet(linear)[0] < 0
    if mirrored:
        faces = faces[:, ::-1].copy()
    if normals is not None:
        n = normals @ np.linalg.inv(linear)
        normals = n / np.linalg.norm(n, axis=1, keepdims=True)
    return p, faces, normals
