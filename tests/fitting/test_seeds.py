"""Seeds of positional lights: mirror rays, their meeting point, what they hit."""

import numpy as np

from fitting.seeds import first_hits, meeting_point, mirror


def test_mirror_about_the_normal():
    n = np.array([0.0, 0.0, 1.0])
    w = np.array([0.6, 0.0, 0.8])
    np.testing.assert_allclose(mirror(n, w), [-0.6, 0.0, 0.8])


def test_rays_from_a_plane_meet_at_the_light(rng):
    light = np.array([0.3, -0.2, 2.0])
    origins = np.column_stack([rng.uniform(-1, 1, 30), rng.uniform(-1, 1, 30), np.zeros(30)])
    dirs = light - origins
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    dirs += rng.normal(scale=1e-3, size=dirs.shape)  # noisy peaks
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    point, spread = meeting_point(origins, dirs)
    assert spread > 0.01 and np.linalg.norm(point - light) < 0.02


def test_parallel_rays_say_directional(rng):
    origins = rng.uniform(-1, 1, (20, 3))
    dirs = np.tile([0.0, 0.6, 0.8], (20, 1))
    point, spread = meeting_point(origins, dirs)
    assert point is None and spread < 1e-3


def test_two_bundles_of_parallel_rays_do_not_make_a_point(rng):
    """Two distant lights' highlights on a plane: each vertex's strongest ray points at
    one or the other. Their least-squares point lies among the origins, where the
    bundles cross, and no ray points at it: no point light."""
    origins = np.column_stack([rng.uniform(-1, 1, 40), rng.uniform(-1, 1, 40), np.zeros(40)])
    a, b = np.array([0.6, 0.2, 0.77]), np.array([-0.5, -0.4, 0.77])
    dirs = np.where((np.arange(40) % 2 == 0)[:, None], a / np.linalg.norm(a), b / np.linalg.norm(b))
    point, spread = meeting_point(origins, dirs)
    assert point is None and spread > 1e-3  # not parallel: refused because no ray points at it


def test_rays_in_random_directions_do_not_make_a_point(rng):
    origins = np.column_stack([rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50), np.zeros(50)])
    dirs = rng.normal(size=(50, 3))
    dirs[:, 2] = np.abs(dirs[:, 2])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    point, _ = meeting_point(origins, dirs)
    assert point is None


def test_a_point_behind_the_rays_is_refused():
    origins = np.array([[-1.0, 0, 0], [1.0, 0, 0]])
    dirs = np.array([[-0.6, 0.8, 0], [0.6, 0.8, 0]])  # diverging: they meet behind
    point, _ = meeting_point(origins, dirs)
    assert point is None


def test_first_hits_on_a_quad():
    quad = np.array([[[-1, -1, 2], [1, -1, 2], [1, 1, 2]], [[-1, -1, 2], [1, 1, 2], [-1, 1, 2]]], float)
    origins = np.array([[0.2, 0.3, 0.0], [0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    dirs = np.array([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 1.0], [0, 0, 1.0]])
    t, tri = first_hits(origins, dirs, quad, t_min=1e-6)
    assert t[0] == np.float64(2.0) and tri[0] in (0, 1)
    assert np.isinf(t[1]) and np.isinf(t[2]) and tri[1] == tri[2] == -1
    assert np.isinf(t[3])  # starting on the quad: ignored within t_min


def test_first_hits_are_the_nearest_of_every_triangle(rng):
    """Against an independent answer: each ray's hits on every triangle found by solving
    o + t d = a + u (b - a) + v (c - a) with numpy's linear solver; the scene given as
    float32 and as a strided view, which are read as the float64 array they equal."""
    tri = rng.uniform(-3, 3, (400, 3, 3)).astype(np.float32).astype(np.float64)  # float32 values
    origins = rng.uniform(-1, 1, (40, 3))
    dirs = rng.normal(size=(40, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    answers = [first_hits(origins, dirs, given, t_min=1e-9)
               for given in (tri, np.asfortranarray(tri), tri.astype(np.float32))]
    for t, which in answers[1:]:  # float32 triangles are read as the float64 values they are
        assert np.array_equal(t, answers[0][0]) and np.array_equal(which, answers[0][1])
    for t, which in answers[:1]:
        for r in range(len(origins)):
            m = np.stack([np.broadcast_to(dirs[r], e1.shape), -e1, -e2], axis=2)  # (T, 3, 3) unknowns (t, u, v)
            tuv = np.linalg.solve(m, (a - origins[r])[:, :, None])[:, :, 0]
            ok = (tuv[:, 0] > 1e-9) & (tuv[:, 1] >= 0) & (tuv[:, 2] >= 0) & (tuv.sum(axis=1) - tuv[:, 0] <= 1)
            if ok.any():
                k = np.flatnonzero(ok)[np.argmin(tuv[ok, 0])]
                assert which[r] == k and np.isclose(t[r], tuv[k, 0], rtol=1e-9)
            else:
                assert which[r] == -1 and np.isinf(t[r])
    assert (which >= 0).sum() > 10  # most rays hit something
