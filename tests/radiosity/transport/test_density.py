"""Local linear density estimation: exact for linear irradiance, at edges and corners too."""

import numpy as np
import pytest

from radiosity.scene import geometry
from radiosity.scene.loaders import load_scene
from radiosity.transport import density

# the 4-point rule exact for cubics on a triangle (barycentric points, weights of the area)
RULE_POINTS = np.array([[1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6]])
RULE_WEIGHTS = np.array([-27 / 48, 25 / 48, 25 / 48, 25 / 48])


def deposit(positions, normals, tangents, faces, irradiance_at):
    """Photon moments of a known irradiance field by quadrature on every triangle
    (independent of the kernel-moment formulas): S0_i = int lambda_i E, S1_i = int lambda_i E d.
    For a linear field the integrands are cubic and the rule is exact."""
    s0 = np.zeros((len(positions), 3))
    s1 = np.zeros((len(positions), 3, 2))
    bitangents = np.cross(normals, tangents)
    for f in faces:
        tri = positions[f]
        area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
        x = RULE_POINTS @ tri
        e = irradiance_at(x) * (area * RULE_WEIGHTS)[:, None]
        for corner, vert in enumerate(f):
            lam = RULE_POINTS[:, corner]
            d = x - positions[vert]
            dt, db = d @ tangents[vert], d @ bitangents[vert]
            s0[vert] += lam @ e
            s1[vert, :, 0] += (lam * dt) @ e
            s1[vert, :, 1] += (lam * db) @ e
    return s0, s1


def plate(max_edge):
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0.7], [0, 0, 0.7]], float)
    f = np.array([[0, 2, 1], [0, 3, 2]])
    p, f, _ = geometry.refine(p, f, max_edge)
    normals = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    return p, f, normals, geometry.tangents(normals)


@pytest.mark.parametrize("rings", [0, 1, 2])
def test_linear_irradiance_is_exact_at_every_vertex(rings):
    positions, faces, normals, tangents = plate(0.15)

    def field(x):
        return np.stack([2.0 + 3.0 * x[:, 0], 1.0 + 2.0 * x[:, 2], 5.0 - 4.0 * x[:, 0] + x[:, 2]], axis=1)

    s0, s1 = deposit(positions, normals, tangents, faces, field)
    estimate = density.irradiance(positions, normals, tangents, faces, s0, s1, rings=rings)
    truth = field(positions)
    assert np.allclose(estimate, truth, rtol=1e-9, atol=1e-9), np.abs(estimate / truth - 1).max()
    # the normalised kernel estimate S0 / K0 is biased where the field slopes at the border
    k0, _, _ = density.kernel_moments(positions, normals, tangents, faces)
    corner = np.argmin(positions[:, 0] + positions[:, 2])
    assert abs(s0[corner, 0] / k0[corner] / truth[corner, 0] - 1) > 0.01


def test_constant_irradiance_on_a_curved_surface():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2)
    p, f, n = geometry.crease_normals(np.asarray(sphere.vertices), np.asarray(sphere.faces), 40.0)
    t = geometry.tangents(n)
    s0, s1 = deposit(p, n, t, f, lambda x: np.full((len(x), 3), 7.0))
    estimate = density.irradiance(p, n, t, f, s0, s1, rings=1)
    assert np.allclose(estimate, 7.0, rtol=0.02)


def test_no_photons_gives_zero_and_never_negative():
    positions, faces, normals, tangents = plate(0.3)
    zero = density.irradiance(positions, normals, tangents, faces, np.zeros((len(positions), 3)), np.zeros((len(positions), 3, 2)))
    assert (zero == 0).all()
    # a steep falloff: a linear fit would go below zero beyond it
    s0, s1 = deposit(positions, normals, tangents, faces, lambda x: np.repeat(np.exp(-30 * x[:, :1]), 3, axis=1))
    assert (density.irradiance(positions, normals, tangents, faces, s0, s1) >= 0).all()


def test_refined_vertices_keep_their_small_kernels():
    """Where the mesh was refined (along a shadow edge, say), a vertex's kernel is its
    hat widened by ``rings`` rings of its own small triangles: the extra rings a weak fit
    gets are judged against vertices of the same mesh size, so fine vertices are not
    all widened back across the edge they resolve."""
    positions, faces, normals, tangents = plate(0.05)
    density_field = np.where(np.abs(positions[:, 0] - 0.5) < 0.05, 1 / 0.0125, 0.0)  # a narrow band
    positions, faces, normals = geometry.refine_density(positions, faces, density_field, normals=normals)
    tangents = geometry.tangents(normals)
    edges = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    length = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    assert length.max() / length.min() > 4  # graded: coarse plate, fine band
    # photons at one vertex in the middle of the fine band
    source = np.argmin(np.sum((positions - [0.5, 0, 0.35]) ** 2, axis=1))
    s0 = np.zeros((len(positions), 3))
    s1 = np.zeros((len(positions), 3, 2))
    s0[source] = 1.0
    seen = density.irradiance(positions, normals, tangents, faces, s0, s1, rings=1)[:, 0] > 0
    # graph distance from the source
    hops = np.full(len(positions), -1)
    hops[source] = 0
    for step in range(1, 8):
        near = hops[edges] == step - 1
        for a, b in ((0, 1), (1, 0)):
            reach = edges[near[:, a], b]
            hops[reach[hops[reach] < 0]] = step
    assert seen[hops == 1].all()
    assert not seen[(hops < 0) | (hops > 2)].any()  # at most one extra ring, and only for a few
    # as on a uniform mesh, where about half the vertices are below the median; judged
    # against the whole mesh's median (the rule before), every fine vertex here was widened
    assert seen[hops == 2].mean() < 0.6


def _widen_with_numpy(positions, normals, tangents, faces, moments, rings):
    """``widen`` as numpy array operations (np.add.at over the pairs): the reference
    for the jitted loop."""
    target, source, rotate, delta = density.widening_pairs(positions, normals, tangents, faces)
    n_vertices = len(positions)
    for _ in range(rings):
        s0, s1, k0, k1, k2 = moments
        r_s1 = np.einsum("pij,pcj->pci", rotate, s1[source])
        r_k1 = np.einsum("pij,pj->pi", rotate, k1[source])
        r_k2 = np.einsum("pij,pjk,plk->pil", rotate, k2[source], rotate)
        k0_j = k0[source]
        terms = (
            s0[source],
            r_s1 + delta[:, None, :] * s0[source][:, :, None],
            k0_j,
            r_k1 + delta * k0_j[:, None],
            r_k2
            + r_k1[:, :, None] * delta[:, None, :]
            + delta[:, :, None] * r_k1[:, None, :]
            + k0_j[:, None, None] * delta[:, :, None] * delta[:, None, :],
        )
        widened = []
        for term in terms:
            total = np.zeros((n_vertices,) + term.shape[1:])
            np.add.at(total, target, term)
            widened.append(total)
        moments = tuple(widened)
    return moments


@pytest.mark.parametrize("channels", [1, 3])
def test_the_widening_loop_matches_the_array_formulas(rng, channels):
    # the same sums in the same order; the frame rotation R K2 R^T may round differently
    obj = next(o for o in load_scene("cornell-teapot").refined(60.0).objects if o.name == "teapot")
    p, n, t, f = obj.positions, obj.normals, obj.tangents, obj.faces
    moments = (rng.uniform(0, 1, (len(p), channels)), rng.normal(size=(len(p), channels, 2)))
    moments = moments + density.kernel_moments(p, n, t, f)
    expected = _widen_with_numpy(p, n, t, f, moments, 2)
    got = density.widen(p, n, t, f, moments, 2)
    for a, b in zip(got, expected):
        assert a.shape == b.shape
        assert np.allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(b).max())
    assert all(np.array_equal(a, b) for a, b in zip(got[:4], expected[:4]))
