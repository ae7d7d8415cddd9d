"""Triangle-mesh operations the solver needs: welding, cleaning, crease-split normals,
conforming refinement to a maximum edge length, and tangent frames.

All functions are free functions on numpy arrays:

    positions : (V, 3) float64
    faces     : (F, 3) int64, counter-clockwise seen from the front
    normals   : (V, 3) float64, unit

trimesh supplies the face adjacency; scipy the KD-tree and connected components.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from radiosity.formats.errors import InputError

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


def weld(positions, faces, tol):
    """Merge vertices closer than ``tol``; returns (positions, faces) with faces remapped.

    Positions of a merged group are those of its lowest-index member, so welding is
    exact for points that already coincide.
    """
    n = len(positions)
    if n == 0:
        return positions, faces
    pairs = cKDTree(positions).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return positions, faces
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # representative of each component: its first vertex; keep original order
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    keep = np.sort(first)
    new_index = np.empty(label.max() + 1, dtype=np.int64)
    new_index[label[keep]] = np.arange(len(keep))
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


def corner_angles(positions, faces):
    """Interior angle at each corner, (F, 3) float64."""
    return trimesh.triangles.angles(positions[faces])


def crease_normals(positions, faces, crease_angle_deg):
    """Angle-weighted vertex normals, with vertices split where faces meet at a crease.

    Two faces sharing an edge are smooth across it when their normals differ by less
    than ``crease_angle_deg``. Each vertex is split into one copy per group of its
    faces that are connected through smooth edges, so a cube keeps six flat faces and
    a crease that dies out inside a surface stays sharp only where it is sharp.

    Returns (positions, faces, normals) of the split mesh.
    """
    fn, _ = face_normals(positions, faces)
    weights = corner_angles(positions, faces)  # (F, 3)
    n_faces = len(faces)
    corner_vertex = faces.ravel()
    n_corners = 3 * n_faces

    rows, cols = [], []
    if n_faces > 1:
        adjacency, edges = trimesh.graph.face_adjacency(faces=faces, return_edges=True)
        if len(adjacency):
            cosang = np.einsum("ij,ij->i", fn[adjacency[:, 0]], fn[adjacency[:, 1]])
            smooth = cosang > np.cos(np.radians(crease_angle_deg))
            adjacency, edges = adjacency[smooth], edges[smooth]
            for side in range(2):  # both vertices of the shared edge
                v = edges[:, side]
                k0 = np.argmax(faces[adjacency[:, 0]] == v[:, None], axis=1)
                k1 = np.argmax(faces[adjacency[:, 1]] == v[:, None], axis=1)
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
    return new_positions, group.reshape(-1, 3).astype(np.int64), normals


def _normalize_or(v, fallback):
    """Normalise rows of v; rows of zero length take the matching row of fallback."""
    length = np.linalg.norm(v, axis=1)
    out = fallback.astype(np.float64).copy()
    ok = length > 0
    out[ok] = v[ok] / length[ok, None]
    return out


def refine(positions, faces, max_edge, normals=None, max_triangles=5_000_000):
    """Conforming refinement until no edge is longer than ``max_edge``.

    Longest-edge refinement (Rivara): every edge longer than ``max_edge`` is marked,
    and a triangle with any marked edge also marks its longest edge; marks belong to
    edges, so neighbours always split the same edges and no T-junction appears. A
    triangle then splits by its marked edges: longest edge only, bisection (2); longest
    and one more, 3 triangles; all three, the four similar triangles of midpoint
    subdivision. Angles stay bounded away from zero.

    New vertices interpolate ``normals`` (renormalised), so a tessellated curved
    surface keeps its smooth shading. Returns (positions, faces, normals_or_None).
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
    for _ in range(200):
        edge_vertices = f[:, _EDGE_CORNERS]  # (F, 3, 2)
        sorted_ev = np.sort(edge_vertices, axis=2).reshape(-1, 2)
        unique_edges, inverse = np.unique(sorted_ev, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1, 3)
        length = np.linalg.norm(p[unique_edges[:, 0]] - p[unique_edges[:, 1]], axis=1)
        mark = length > max_edge
        if not mark.any():
            break
        longest = np.argmax(length[inverse], axis=1)
        longest_edge = inverse[np.arange(len(f)), longest]
        while True:  # closure: a triangle with a marked edge marks its longest edge
            touched = mark[inverse].any(axis=1)
            needs = touched & ~mark[longest_edge]
            if not needs.any():
                break
            mark[longest_edge[needs]] = True

        midpoint = np.full(len(unique_edges), -1, dtype=np.int64)
        marked = np.nonzero(mark)[0]
        midpoint[marked] = len(p) + np.arange(len(marked))
        ends = unique_edges[marked]
        p = np.vstack([p, 0.5 * (p[ends[:, 0]] + p[ends[:, 1]])])
        if nrm is not None:
            summed = nrm[ends[:, 0]] + nrm[ends[:, 1]]
            nrm = np.vstack([nrm, _normalize_or(summed, nrm[ends[:, 0]])])

        # rotate every triangle so that its longest edge is edge 0: (a, b) longest
        rot = (np.arange(3)[None, :] + longest[:, None]) % 3
        rows = np.arange(len(f))[:, None]
        a, b, c = f[rows, rot].T
        m0, m1, m2 = midpoint[inverse[rows, rot]].T  # midpoints of (a,b), (b,c), (c,a)
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
        f = np.concatenate(pieces)
    else:  # pragma: no cover - 200 rounds halve any edge far below float precision
        raise RuntimeError("mesh refinement did not converge")
    return p, f, nrm


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


def apply_transform(matrix, positions, faces, normals=None):
    """Transform positions (and normals by the inverse transpose); a mirroring
    transform reverses the winding so fronts stay fronts. Returns (positions, faces, normals)."""
    linear = matrix[:3, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # huge values become inf, which callers refuse
        p = positions @ linear.T + matrix[:3, 3]
        mirrored = np.linalg.det(linear) < 0
    if mirrored:
        faces = faces[:, ::-1].copy()
    if normals is not None:
        n = normals @ np.linalg.inv(linear)
        normals = n / np.linalg.norm(n, axis=1, keepdims=True)
    return p, faces, normals
