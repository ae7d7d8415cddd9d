"""The Utah teapot tessellation: welded seams, a closed body, outward fronts, sane poles."""

import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from radiosity.scene import geometry, teapot


def boundary_edges(faces):
    edges = np.sort(faces[:, geometry._EDGE_CORNERS].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return unique[counts == 1], counts


def loops(edges, n_vertices):
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_vertices,) * 2)
    _, label = connected_components(graph, directed=False)
    return [np.unique(edges[label[edges[:, 0]] == k]) for k in np.unique(label[edges[:, 0]])]


@pytest.mark.parametrize("resolution", [3, 8, 14])
def test_seams_welded_and_only_the_tube_ends_open(resolution):
    p, f = teapot.tessellate(resolution)
    assert cKDTree(p).query_pairs(1e-6).__len__() == 0, "a seam was not welded"
    boundary, counts = boundary_edges(f)
    assert counts.max() == 2, "non-manifold edge"
    ends = loops(boundary, len(p))
    assert len(ends) == 4  # both ends of the handle and of the spout
    for loop in ends:
        # every open end is outside the body's radius (handle at -x, spout at +x)
        assert np.abs(p[loop, 0]).min() > 1.4
    tip = max(ends, key=lambda loop: p[loop, 0].mean())
    assert p[tip, 0].mean() > 2.7 and np.allclose(p[tip, 1], 2.4, atol=0.05)


def test_body_with_lid_is_closed_and_faces_out():
    p, f = teapot.tessellate(8)
    mesh = trimesh.Trimesh(p, f, process=False)
    assert mesh.is_winding_consistent
    # the component with the most faces is body + rim + bottom + ring + lid
    graph = coo_matrix(
        (np.ones(len(mesh.face_adjacency)), tuple(mesh.face_adjacency.T)), shape=(len(f), len(f))
    )
    _, label = connected_components(graph, directed=False)
    body = trimesh.Trimesh(p, f[label == np.bincount(label).argmax()], process=False)
    assert body.is_watertight
    assert body.volume > 0  # fronts out
    # a closed body: about the volume of a solid of revolution of radius ~2, height ~3
    assert 20 < body.volume < 30
    lo, hi = p.min(axis=0), p.max(axis=0)
    assert np.allclose([lo[1], hi[1]], [0.0, 3.15]) and hi[0] > 3.4 and lo[0] == pytest.approx(-3.0)


def test_pole_normals_and_outward_body_normals():
    p, f = teapot.tessellate(8)
    cp, cf, cn = geometry.crease_normals(p, f, 40.0)
    top, bottom = np.argmax(cp[:, 1]), np.argmin(cp[:, 1])
    assert np.allclose(cp[top], [0, 3.15, 0]) and np.allclose(cn[top], [0, 1, 0], atol=1e-9)
    assert np.allclose(cp[bottom], [0, 0, 0]) and np.allclose(cn[bottom], [0, -1, 0], atol=1e-9)
    # on the body's side wall the normal points away from the axis
    radial = np.hypot(cp[:, 0], cp[:, 2])
    side = (radial > 1.55) & (cp[:, 1] > 0.5) & (cp[:, 1] < 2.2) & (np.abs(cp[:, 0]) < 1.4)
    assert side.sum() > 20
    outward = np.einsum("ij,ij->i", cn[side][:, [0, 2]], cp[side][:, [0, 2]] / radial[side, None])
    assert outward.min() > 0.5


def test_resolution_controls_the_triangle_count():
    counts = [len(teapot.tessellate(r)[1]) for r in (4, 8)]
    assert counts == [32 * 2 * 16, 32 * 2 * 64]  # pole triangles collapse, the lid ring replaces them
    with pytest.raises(ValueError):
        teapot.tessellate(1)
