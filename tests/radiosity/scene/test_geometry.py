"""Mesh operations: refinement, crease normals, welding, cleaning, frames, transforms."""

import numpy as np
import pytest
import trimesh

from radiosity.files.errors import InputError
from radiosity.scene import geometry


def edge_use_counts(faces):
    edges = np.sort(faces[:, geometry._EDGE_CORNERS].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return counts


def unit_cube():
    box = trimesh.creation.box()
    return np.asarray(box.vertices, float), np.asarray(box.faces, np.int64)


@pytest.mark.parametrize("max_edge", [0.9, 0.3, 0.07])
def test_refine_closed_cube_stays_watertight_and_exact(max_edge):
    p, f = unit_cube()
    rp, rf, _ = geometry.refine(p, f, max_edge)
    counts = edge_use_counts(rf)
    assert (counts == 2).all(), "a T-junction or crack: some edge is used by one triangle only"
    lengths = np.linalg.norm(rp[rf] - rp[np.roll(rf, -1, axis=1)], axis=2)
    assert lengths.max() <= max_edge + 1e-12
    _, area = geometry.face_normals(rp, rf)
    assert area.sum() == pytest.approx(6.0, rel=1e-12)
    assert trimesh.Trimesh(rp, rf, process=False).volume == pytest.approx(1.0, rel=1e-12)


def test_refine_keeps_orientation_and_angles():
    p = np.array([[0, 0, 0], [1, 0, 0], [0.3, 0.8, 0]], float)
    f = np.array([[0, 1, 2]])
    rp, rf, _ = geometry.refine(p, f, 0.05)
    n, _ = geometry.face_normals(rp, rf)
    assert np.allclose(n, [0, 0, 1])  # all still counter-clockwise seen from +z
    start = np.degrees(geometry.corner_angles(p, f).min())
    final = np.degrees(geometry.corner_angles(rp, rf).min())
    assert final >= start / 2 - 1e-9, (start, final)  # longest-edge bisection bounds angles


def test_refine_interpolates_normals_and_leaves_short_edges_alone():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    normals = np.array([[0, 0, 1], [1, 0, 0], [0, 0, 1]], float)
    rp, rf, rn = geometry.refine(p, f, 0.75, normals=normals)
    assert np.allclose(np.linalg.norm(rn, axis=1), 1.0)
    mid = np.nonzero(np.all(np.isclose(rp, [0.5, 0, 0]), axis=1))[0]
    assert len(mid) == 1 and np.allclose(rn[mid[0]], np.array([1, 0, 1]) / np.sqrt(2))
    same_p, same_f, _ = geometry.refine(p, f, 10.0)
    assert np.array_equal(same_p, p) and np.array_equal(same_f, f)


def test_refine_refuses_absurd_sizes():
    p, f = unit_cube()
    with pytest.raises(InputError, match="triangles"):
        geometry.refine(p, f, 1e-4)
    with pytest.raises(InputError, match="positive"):
        geometry.refine(p, f, 0.0)


def test_crease_normals_split_a_cube_but_not_a_sphere():
    p, f = unit_cube()
    cp, cf, cn = geometry.crease_normals(p, f, 40.0)
    assert len(cp) == 24  # each corner split into its three faces
    assert np.allclose(np.abs(cn).max(axis=1), 1.0)  # every normal is axis-aligned
    fn, _ = geometry.face_normals(cp, cf)
    assert np.allclose(np.einsum("fkj,fj->fk", cn[cf], fn), 1.0)

    sphere = trimesh.creation.icosphere(subdivisions=3)
    sp, sf, sn = geometry.crease_normals(np.asarray(sphere.vertices), np.asarray(sphere.faces), 40.0)
    assert len(sp) == len(sphere.vertices)
    radial = sp / np.linalg.norm(sp, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.einsum("ij,ij->i", sn, radial).clip(-1, 1))).max() < 1.0


@pytest.mark.parametrize("threshold, vertices", [(40.0, 4), (20.0, 6)])
def test_crease_threshold_on_a_hinge(threshold, vertices):
    bend = np.radians(30.0)  # the two faces' normals differ by 30 degrees
    p = np.array([[0, 0, 0], [0, 1, 0], [-1, 0, 0], [np.cos(bend), 0, np.sin(bend)]], float)
    f = np.array([[0, 1, 2], [0, 3, 1]])
    cp, _, cn = geometry.crease_normals(p, f, threshold)
    assert len(cp) == vertices
    assert np.allclose(np.linalg.norm(cn, axis=1), 1.0)


def test_weld_and_remove_degenerate():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-12, 0, 0], [2, 2, 0], [3, 3, 0]], float)
    f = np.array([[0, 1, 2], [3, 2, 1], [0, 4, 5], [1, 1, 2]])
    wp, wf = geometry.weld(p, f, 1e-9)
    assert len(wp) == 5 and wf[1, 0] == 0
    cp, cf, dropped = geometry.remove_degenerate(wp, wf)
    assert dropped == 2  # the collinear one and the one with a repeated vertex
    assert len(cf) == 2 and len(cp) == 3


def test_tangents_are_unit_and_orthogonal_everywhere():
    rng = np.random.default_rng(7)
    n = rng.normal(size=(1000, 3))
    n = np.vstack([n, np.eye(3), -np.eye(3), [[0.9, 0.43588989, 0]]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t = geometry.tangents(n)
    assert np.allclose(np.linalg.norm(t, axis=1), 1.0)
    assert np.abs(np.einsum("ij,ij->i", t, n)).max() < 1e-12


def test_mirroring_transform_keeps_fronts_outward():
    p, f = unit_cube()
    m = geometry.transform_matrix(scale=[-2, 1, 1], rotate_deg=[10, 20, 30], translate=[5, 6, 7])
    tp, tf, _ = geometry.apply_transform(m, p, f)
    assert trimesh.Trimesh(tp, tf, process=False).volume == pytest.approx(2.0)
    assert np.allclose(tp.mean(axis=0), [5, 6, 7])


def test_rotation_order_is_x_then_y_then_z():
    m = geometry.transform_matrix(rotate_deg=[90, 90, 0])
    # x first: +y -> +z; then y: +z -> +x
    assert np.allclose(m[:3, :3] @ [0, 1, 0], [1, 0, 0], atol=1e-12)


def welded_edge_counts(positions, faces):
    """Edge use counts after merging the copies of a vertex split at a crease."""
    labels = geometry.position_labels(positions)
    return edge_use_counts(labels[faces])


def test_split_edges_keeps_a_crease_split_cube_closed_and_exact():
    p, f = unit_cube()
    cp, cf, cn = geometry.crease_normals(p, f, 40.0)
    # an edge on the crease between two faces: its copy on the other face splits too
    labels = geometry.position_labels(cp)
    ev = np.sort(cf[:, geometry._EDGE_CORNERS].reshape(-1, 2), axis=1)
    crease = next(e for e in ev if (np.sort(labels[ev], axis=1) == np.sort(labels[e])).all(axis=1).sum() == 2)
    rp, rf, rn = geometry.split_edges(cp, cf, [crease], normals=cn)
    assert len(rf) > len(cf)
    assert (welded_edge_counts(rp, rf) == 2).all(), "a T-junction or crack across the crease"
    _, area = geometry.face_normals(rp, rf)
    assert area.sum() == pytest.approx(6.0, rel=1e-12)
    assert trimesh.Trimesh(rp, rf, process=False).volume == pytest.approx(1.0, rel=1e-12)
    # new vertices are copies per side, each with its own face's (flat) normal
    fn, _ = geometry.face_normals(rp, rf)
    assert np.allclose(rn[rf[:, 0]], fn) and np.allclose(rn[rf[:, 1]], fn) and np.allclose(rn[rf[:, 2]], fn)
    midpoint = 0.5 * (cp[crease[0]] + cp[crease[1]])
    assert np.isclose(rp, midpoint).all(axis=1).sum() == 2
    # nothing to split: the mesh unchanged
    same = geometry.split_edges(cp, cf, np.zeros((0, 2), int), normals=cn)
    assert np.array_equal(same[0], cp) and np.array_equal(same[1], cf)


def test_refine_density_grades_conforms_and_keeps_the_budget():
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 3, 2]])
    p, f, _ = geometry.refine(p, f, 0.25)
    normals = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    normals[p[:, 0] > 0.6] = np.array([0.0, 1.0, 0.2]) / np.hypot(1, 0.2)
    density = np.where(np.abs(p[:, 0] - 0.5) < 0.2, 1 / 0.04, 0.0)  # edges of 0.04 near x = 0.5
    rp, rf, rn = geometry.refine_density(p, f, density, normals=normals)
    assert len(rp) > 3 * len(p)
    counts = welded_edge_counts(rp, rf)
    assert set(np.unique(counts)) == {1, 2}
    edges = np.sort(rf[:, geometry._EDGE_CORNERS].reshape(-1, 2), axis=1)
    unique, use = np.unique(edges, axis=0, return_counts=True)
    lengths = np.linalg.norm(rp[unique[:, 0]] - rp[unique[:, 1]], axis=1)
    assert lengths[use == 1].sum() == pytest.approx(4.0, rel=1e-12)  # open edges: the border alone
    _, area = geometry.face_normals(rp, rf)
    assert area.sum() == pytest.approx(1.0, rel=1e-12)
    mid = 0.5 * (rp[unique[:, 0]] + rp[unique[:, 1]])
    assert lengths[np.abs(mid[:, 0] - 0.5) < 0.05].max() <= 0.04 * 1.5  # fine where asked
    assert lengths[np.abs(mid[:, 0] - 0.5) > 0.45].min() > 0.1  # untouched far away
    assert np.allclose(np.linalg.norm(rn, axis=1), 1.0)
    fn, _ = geometry.face_normals(rp, rf)
    assert (fn[:, 1] > 0.99).all()  # orientation kept
    # a budget: the last round within it
    capped = geometry.refine_density(p, f, density, max_vertices=len(rp) - 1)
    assert len(p) < len(capped[0]) < len(rp)
    with pytest.raises(ValueError):
        geometry.refine_density(p, f, -density)
