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


def scatter(positions, faces, normals, tangents, n_photons, rng, power=(0.3, 0.3, 0.3)):
    """Photon moments of ``n_photons`` photons of RGB ``power`` each, uniform over the
    mesh's area (each hit weighted by its triangle corners' hat functions, as the
    solver's photon pass adds them); and the irradiance they stand for, per channel."""
    tri = positions[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    hit = rng.choice(len(faces), n_photons, p=area / area.sum())
    r1, r2 = rng.random(n_photons), rng.random(n_photons)
    lam = np.stack([1 - np.sqrt(r1), np.sqrt(r1) * (1 - r2), np.sqrt(r1) * r2], axis=1)
    x = np.einsum("pc,pci->pi", lam, tri[hit])
    s0 = np.zeros((len(positions), 3))
    s1 = np.zeros((len(positions), 3, 2))
    bitangents = np.cross(normals, tangents)
    power = np.asarray(power)
    for corner in range(3):
        vert = faces[hit, corner]
        d = x - positions[vert]
        dt, db = np.sum(d * tangents[vert], axis=1), np.sum(d * bitangents[vert], axis=1)
        np.add.at(s0, vert, lam[:, corner, None] * power)
        np.add.at(s1, vert, (lam[:, corner, None] * power)[:, :, None] * np.stack([dt, db], axis=1)[:, None, :])
    return s0, s1, n_photons * power / area.sum()


def test_kernels_that_catch_too_few_photons_are_widened(rng):
    """A finely meshed plate (12,481 vertices, edges of 1.5 cm) under 300 photons of
    uniform light: a kernel of one ring catches none at 60 % of the vertices, which read
    0 (the living room's sofa at draft). Widened until their supports hold MIN_PHOTONS,
    almost every vertex reads the light, and with each support's vertices counted once
    the relative RMS error is about a support of 16 photons' (1.91 -> 0.35 measured; a
    widened hat function, which counts a neighbour once per path to it, left 0.92), and
    the mean stays the truth's. A radius cap below one more ring changes nothing."""
    positions, faces, normals, tangents = plate(0.015)
    s0, s1, truth = scatter(positions, faces, normals, tangents, 300, rng)
    args = (positions, normals, tangents, faces, s0, s1)
    plain = density.irradiance(*args, rings=1)
    widened = density.irradiance(*args, rings=1, photon_power=0.9)
    assert (plain[:, 0] == 0).mean() > 0.5
    assert (widened[:, 0] == 0).mean() < 0.05
    error = [np.sqrt(np.mean((e[:, 0] / truth[0] - 1) ** 2)) for e in (plain, widened)]
    assert error[1] < 0.45 < 0.55 * error[0], error
    assert abs(widened[:, 0].mean() / truth[0] - 1) < 0.05
    capped = density.irradiance(*args, rings=1, photon_power=0.9, max_radius=0.001)
    assert np.array_equal(capped, plain)
    # plenty of photons: nothing is widened for want of them
    many = scatter(positions, faces, normals, tangents, 400_000, rng)
    dense = (positions, normals, tangents, faces, many[0], many[1])
    assert np.array_equal(density.irradiance(*dense, rings=1, photon_power=0.9), density.irradiance(*dense, rings=1))


def split_at(positions, faces, normals, x):
    """The mesh cut along the line of vertices at ``x`` (as a model's UV islands are):
    the triangles right of it get copies of those vertices."""
    on = np.flatnonzero(np.isclose(positions[:, 0], x))
    copy = {int(v): len(positions) + i for i, v in enumerate(on)}
    right = positions[faces].mean(axis=1)[:, 0] > x
    faces = faces.copy()
    for f in np.flatnonzero(right):
        faces[f] = [copy.get(int(v), int(v)) for v in faces[f]]
    return np.concatenate([positions, positions[on]]), faces, np.concatenate([normals, normals[on]])


def test_a_texture_seam_is_crossed_and_a_crease_is_not(rng, monkeypatch):
    """Vertices at one position with the same normal (a UV seam) are paired; at a crease
    (normals 90 degrees apart) they are not. A plate cut into strips 4.5 cm wide (as a
    model's UV islands cut the living room's cushions into pieces of a median 9
    vertices), under few photons: with the seams crossed its kernels grow as on the
    uncut plate and it reads the light about as well; kept apart, each strip's kernels
    stop at its edges, the strips that caught no photon read 0, and the error is more
    than twice (0.27 and 0.66 measured)."""
    positions, faces, normals, tangents = plate(0.1)
    cut_p, cut_f, cut_n = split_at(positions, faces, normals, 0.5)
    pairs = density.seam_pairs(cut_p, cut_n)
    assert len(pairs) == np.isclose(positions[:, 0], 0.5).sum() > 3
    assert np.array_equal(cut_p[pairs[:, 0]], cut_p[pairs[:, 1]])
    folded = cut_n.copy()
    folded[len(positions):] = [1.0, 0.0, 0.0]  # the copies' normals turned 90 degrees
    assert len(density.seam_pairs(cut_p, folded)) == 0

    positions, faces, normals, tangents = plate(0.015)
    for x in np.unique(np.round(positions[:, 0], 9)):
        if 0 < x < 1 and np.isclose(x % 0.045, 0, atol=0.008):
            positions, faces, normals = split_at(positions, faces, normals, x)
    tangents = geometry.tangents(normals)
    s0, s1, truth = scatter(positions, faces, normals, tangents, 300, rng)
    args = (positions, normals, tangents, faces, s0, s1)

    def reading():
        e = density.irradiance(*args, rings=1, photon_power=0.9)[:, 0]
        return (e == 0).mean(), np.sqrt(np.mean((e / truth[0] - 1) ** 2))

    crossed = reading()
    monkeypatch.setattr(density, "seam_pairs", lambda p, n: np.zeros((0, 2), np.int64))
    apart = reading()
    assert len(positions) > 12481 + 500  # the cuts made copies
    assert crossed[0] < 0.01 < apart[0], (crossed, apart)
    assert crossed[1] < 0.6 * apart[1], (crossed, apart)


@pytest.mark.parametrize("least", [5.0, 60.0, 400.0])
def test_a_sparse_kernel_is_exact_for_linear_irradiance(least):
    """A kernel widened for want of photons is a sum of hat functions, each counted once:
    fed a linear field's exact moments (with a photon power that makes every support
    sparse), every vertex still reads the field exactly, corners and edges included,
    at every support size the photon count asks for."""
    positions, faces, normals, tangents = plate(0.1)

    def field(x):
        return np.stack([2.0 + 3.0 * x[:, 0], 1.0 + 2.0 * x[:, 2], 5.0 - 4.0 * x[:, 0] + x[:, 2]], axis=1)

    s0, s1 = deposit(positions, normals, tangents, faces, field)
    power = float(s0.sum()) / 200.0  # 200 photons over the plate
    estimate = density.irradiance(positions, normals, tangents, faces, s0, s1, rings=1, photon_power=power,
                                  min_photons=least, max_extra_rings=0)
    assert np.allclose(estimate, field(positions), rtol=1e-9, atol=1e-9)


def test_a_sparse_support_is_every_vertex_within_its_rings_once():
    """The sparse kernels' supports against a breadth-first search done by scipy: each
    vertex's moments are the sums of its support's own moments (here S0 = 1 a vertex,
    so the sum counts them: every vertex within r rings, once), and r is the fewest
    rings whose support holds ``least`` photons, capped by the limit."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import shortest_path

    positions, faces, normals, tangents = plate(0.1)
    n = len(positions)
    pairs = density.widening_pairs(positions, normals, tangents, faces)
    indptr, indices = density._adjacency(pairs, n)
    graph = sp.csr_matrix((np.ones(len(indices)), indices, indptr), shape=(n, n))
    hops = shortest_path(graph, unweighted=True, directed=False)
    ones = np.ones((n, 1))
    moments = (ones, np.zeros((n, 1, 2)), np.ones(n), np.zeros((n, 2)), np.zeros((n, 2, 2)))
    photons = np.full(n, 0.5)  # half a photon a vertex
    limit = np.full(n, 6, np.int64)
    limit[0] = 2
    frames = (positions.astype(float), tangents, np.cross(normals, tangents))
    sparse, (s0, *_rest) = density._uniform_supports((indptr, indices), frames, photons, moments, 1, 12.0, limit)
    for i in range(n):
        within = [np.sum(hops[i] <= r) for r in range(7)]
        if 0.5 * within[1] >= 12.0:
            assert not sparse[i]
            continue
        r = next((r for r in range(2, limit[i] + 1) if 0.5 * within[r] >= 12.0), limit[i])
        assert sparse[i] and s0[i, 0] == within[r], (i, r, s0[i, 0], within)
    assert s0[0, 0] == np.sum(hops[0] <= 2)  # a corner capped at two rings
