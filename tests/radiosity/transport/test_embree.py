"""The Embree wrapper (``radiosity.transport.embree``) on scenes whose answers are known
by hand: the barycentric convention, misses, the occlusion distance, ray-origin
offsets (near the origin and far from it), the triangle index of a merged scene of
several objects, and threads that do not change an answer."""

import numpy as np
import pytest

from radiosity.scene.material_kernels import Material
from radiosity.scene.model import Scene, build_object
from radiosity.transport.embree import MISS, RayTracer, inside_triangle, origin_offset


def tracer_for(positions, faces, threads=1):
    return RayTracer(np.asarray(positions, np.float32), np.asarray(faces, np.int32), threads=threads)


def rays(origins, directions):
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(origins, dtype=np.float64), d.shape)
    return o.astype(np.float32), d.astype(np.float32)


def unit_directions(rng, count, min_cos, normal=(0.0, 0.0, 1.0)):
    """Random unit vectors within the cone cos >= min_cos about ``normal`` (down to grazing)."""
    z = min_cos + (1.0 - min_cos) * rng.random(count) ** 3
    phi = 2 * np.pi * rng.random(count)
    s = np.sqrt(1 - z * z)
    local = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
    n = np.asarray(normal, dtype=np.float64)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(helper, n)
    t /= np.linalg.norm(t)
    return local @ np.stack([t, np.cross(n, t), n])


# -- the barycentric convention ---------------------------------------------------------


def test_hand_computed_hit_on_a_known_triangle():
    # p0 at the origin, p1 on x (length 2), p2 on y (length 3); the ray drops onto (0.5, 0.6, 0)
    tracer = tracer_for([[0, 0, 0], [2, 0, 0], [0, 3, 0]], [[0, 1, 2]])
    hits = tracer.intersect(*rays([0.5, 0.6, 1.5], [0, 0, -1]))
    # (0.5, 0.6) = (1 - u - v) p0 + u p1 + v p2 = (2 u, 3 v): u = 0.25, v = 0.2
    assert hits.triangle[0] == 0
    assert hits.u[0] == pytest.approx(0.25, abs=1e-6) and hits.v[0] == pytest.approx(0.2, abs=1e-6)
    assert hits.t[0] == pytest.approx(1.5, rel=1e-6)
    assert hits.triangle.dtype == np.int32 and hits.u.dtype == hits.v.dtype == hits.t.dtype == np.float32


def test_barycentrics_rebuild_the_hit_point_on_random_triangles(rng):
    corners = rng.normal(size=(200, 3, 3)) * 3
    positions = corners.reshape(-1, 3)
    faces = np.arange(len(positions)).reshape(-1, 3)
    for k in range(len(faces)):
        tracer = tracer_for(corners[k], [[0, 1, 2]])
        u, v = rng.dirichlet([1, 1, 1])[1:] * 0.98 + 0.005
        p0, p1, p2 = corners[k]
        point = (1 - u - v) * p0 + u * p1 + v * p2
        normal = np.cross(p1 - p0, p2 - p0)
        normal /= np.linalg.norm(normal)
        side = 1.0 if k % 2 else -1.0  # from the front and from the back: both sides are hit
        start = point + side * 2.0 * normal + rng.normal(size=3) * 0.3
        hits = tracer.intersect(*rays(start, point - start))
        assert hits.triangle[0] == 0, k
        assert (hits.u[0], hits.v[0]) == pytest.approx((u, v), abs=2e-5), k
        assert hits.t[0] == pytest.approx(np.linalg.norm(point - start), rel=1e-5), k
    assert len(faces) == 200


# -- misses --------------------------------------------------------------------------------


def test_rays_that_hit_nothing_are_misses():
    tracer = tracer_for([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    origins, directions = rays(
        [[0.2, 0.2, 1.0], [0.2, 0.2, 1.0], [2.0, 2.0, -1.0], [0.2, 0.2, 1.0]],
        [[0, 0, 1], [1, 0, 0], [0, 0, 1], [0.5, 0.5, -0.1]],  # away, parallel, beside, past the edge
    )
    hits = tracer.intersect(origins, directions)
    assert (hits.triangle == MISS).all()
    assert not tracer.occluded(origins, directions, np.full(4, 100.0, np.float32)).any()
    empty = tracer.intersect(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32))
    assert all(len(a) == 0 for a in empty)
    assert len(tracer.occluded(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros(0))) == 0


# -- occlusion distance --------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
def test_a_blocker_counts_only_within_the_distance(scale):
    # a square blocker across the z axis at height h; segments from the origin straight up
    h = 1.0 * scale
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * scale + [0, 0, h]
    tracer = tracer_for(quad, [[0, 1, 2], [0, 2, 3]])
    margin = tracer.epsilon  # what the kernels leave between a shadow ray's end and its light
    distances = np.array([h - margin, h + margin, 0.5 * h, 10 * h], dtype=np.float32)
    origins, directions = rays([0, 0, 0], np.tile([0.0, 0.0, 1.0], (4, 1)))
    blocked = tracer.occluded(origins, directions, distances)
    assert blocked.tolist() == [False, True, False, True]
    assert tracer.intersect(origins[:1], directions[:1]).t[0] == pytest.approx(h, rel=1e-6)


# -- ray-origin offsets ----------------------------------------------------------------------


@pytest.mark.parametrize("offset", [0.0, 100.0, 1e4, 1e5])
def test_a_ray_leaving_a_surface_does_not_hit_it_again(rng, offset):
    # a tilted unit square, near the origin or far from it (coarse float32 coordinates there)
    angle = 0.7
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.array([[c, 0, s], [s * s, c, -s * c], [-c * s, s, c * c]])
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) @ rotation.T + offset
    normal = rotation @ [0.0, 0.0, 1.0]
    tracer = tracer_for(square, [[0, 1, 2], [0, 2, 3]])
    assert tracer.epsilon == origin_offset(square.astype(np.float32)) >= 1e-5  # at least the relative offset
    n = 20_000
    uv = rng.random((n, 2)) * 0.98 + 0.01
    points = np.c_[uv, np.zeros(n)] @ rotation.T + offset
    directions = unit_directions(rng, n, 1e-3, normal)  # down to 0.06 degrees above the surface
    origins = (points + tracer.epsilon * normal).astype(np.float32)
    assert (np.abs(origins - points.astype(np.float32)).max(axis=1) > 0).all()  # the offset survives rounding
    hits = tracer.intersect(origins, directions.astype(np.float32))
    assert (hits.triangle == MISS).all()


def test_origin_offset_is_relative_near_the_origin_and_ulp_bound_far_from_it():
    box = np.array([[0, 0, 0], [3, 4, 0]], dtype=np.float32)
    assert origin_offset(box) == pytest.approx(1e-5 * 5.0)
    assert origin_offset(box * 1000) == pytest.approx(1e-5 * 5000.0)  # a scale changes it in proportion
    far = box + np.float32(1e5)
    assert origin_offset(far) == 8 * float(np.spacing(np.float32(1e5 + 4)))


# -- the triangle index of a scene of several objects ---------------------------------------


def test_triangle_index_maps_to_object_and_face():
    white = Material("white", (0.5, 0.5, 0.5))
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    cube_faces = np.array([
        [0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
        [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5],
    ])
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], float)
    quad_faces = np.array([[0, 2, 1], [0, 3, 2]])  # facing +y
    objects = (
        build_object("cube", white, cube + [3, 0, 0], cube_faces, crease_angle_deg=30),
        build_object("floor", white, quad * 2 + [-1, -1, -1], quad_faces),
        build_object("tri", white, [[0, 2, 0], [1, 2, 0], [0, 3, 0]], [[0, 1, 2]]),
    )
    merged = Scene("three", objects).merged()
    tracer = RayTracer(merged.positions, merged.faces, threads=1)
    triangles = merged.positions[merged.faces].astype(np.float64)
    centroids = triangles.mean(axis=1)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # straight down onto each triangle's centroid, from just in front of it
    hits = tracer.intersect((centroids + 0.05 * normals).astype(np.float32), (-normals).astype(np.float32))
    assert np.array_equal(hits.triangle, np.arange(len(merged.faces)))
    for row in range(len(merged.faces)):
        o = objects[merged.triangle_object[row]]
        face = o.faces[merged.triangle_face[row]]
        assert np.allclose(o.positions[face], triangles[row], atol=1e-6)
    assert merged.triangle_object.tolist().count(1) == objects[1].n_triangles
    # and the barycentrics of each centroid are (1/3, 1/3)
    assert np.allclose(hits.u, 1 / 3, atol=1e-5) and np.allclose(hits.v, 1 / 3, atol=1e-5)


# -- threads and bookkeeping ---------------------------------------------------------------------


def test_threads_split_a_batch_without_changing_the_answer(rng):
    positions = rng.normal(size=(300, 3))
    faces = rng.integers(0, len(positions), size=(400, 3))
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    n = 10_000  # above the size at which a batch is split across threads
    origins = (rng.normal(size=(n, 3)) * 2).astype(np.float32)
    directions = unit_directions(rng, n, -1.0).astype(np.float32)
    distances = rng.uniform(0, 3, n).astype(np.float32)
    answers = []
    for threads in (1, 3):
        with tracer_for(positions, faces, threads=threads) as tracer:
            hits = tracer.intersect(origins, directions)
            blocked = tracer.occluded(origins, directions, distances)
            assert tracer.rays_cast == 2 * n
        answers.append((hits, blocked))
    (h1, b1), (h3, b3) = answers
    assert (h1.triangle >= 0).mean() > 0.3 and 0.1 < b1.mean() < 0.9
    for a, b in zip(h1, h3):
        assert np.array_equal(a, b)
    assert np.array_equal(b1, b3)


# -- the ray-hit record the kernels pass to Embree ------------------------------------------------


def test_the_rayhit_record_is_aligned_and_one_record_seen_two_ways():
    from radiosity.transport import embree

    for _ in range(20):  # allocations land on different addresses
        floats, ints = embree.new_rayhit()
        assert floats.ctypes.data % embree.RAYHIT_ALIGN == 0 and floats.ctypes.data == ints.ctypes.data
        assert floats.dtype == np.float32 and ints.dtype == np.int32 and len(floats) == embree.RAYHIT_WORDS
    # RTCRayHit: 12 words of ray, then Ng, u, v, primID, geomID, instID
    assert (embree.TFAR, embree.HIT_U, embree.PRIM_ID, embree.GEOM_ID, embree.INST_ID) == (8, 15, 17, 18, 19)
    assert embree.RAYHIT_WORDS * 4 >= 96  # room for instPrimID in builds with instance arrays


def test_the_library_is_the_one_inside_the_embreex_wheel():
    from radiosity.transport import embree

    path = embree.library_path()
    assert "embreex" in path and "libembree4" in path


def test_dropping_a_tracer_does_not_wait_for_its_threads():
    """``__del__`` (which the garbage collector may run in any thread, a pool thread or
    one holding a lock the pool wants) stops the pool without waiting for a query still
    running; ``close()`` called by the owner waits."""
    import threading
    import time

    tracer = tracer_for([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], threads=2)
    release = threading.Event()
    running = tracer._pool.submit(release.wait, 30)
    start = time.perf_counter()
    tracer.__del__()
    assert time.perf_counter() - start < 5 and not running.done()
    release.set()
    assert running.result(timeout=30) is True
    other = tracer_for([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], threads=2)
    done = other._pool.submit(time.sleep, 0.3)
    other.close()
    assert done.done()


# -- barycentrics inside the triangle ---------------------------------------------------


def test_inside_triangle_moves_a_rounding_over_the_edge_back_and_leaves_the_inside_alone(rng):
    f32 = np.float32
    over = (f32(0.3), f32(np.nextafter(f32(0.7), f32(1))))  # u + v a float32 rounding above 1
    assert float(over[0]) + float(over[1]) > 1.0
    for u, v in [over, (f32(0.5), f32(0.5000001)), (f32(-1e-9), f32(0.4)), (f32(0.2), f32(-0.0)),
                 (f32(1.0000001), f32(0.0)), (f32(0.99999994), f32(1e-7))]:
        iu, iv = inside_triangle(u, v)
        assert float(np.float32(iu)) == iu and float(np.float32(iv)) == iv  # float32 values
        assert iu >= 0 and iv >= 0 and float(iu) + float(iv) <= 1.0
        assert abs(float(iu) - max(float(u), 0.0)) < 1e-6 and abs(float(iv) - max(float(v), 0.0)) < 1e-6
    inside = rng.random((2000, 2)).astype(np.float32) * f32(0.5)
    for u, v in inside:
        assert inside_triangle(u, v) == (u, v)


def test_hits_along_a_shared_edge_weigh_no_corner_negatively(rng):
    # rays at the diagonal of a quad (two triangles sharing it), slanted and far from the origin:
    # Embree's rounded u and v can sum above 1 there; the interpolation weights w = 1 - u - v must not go negative
    corners = np.array([[0, 0, 0], [1, 0, 0.3], [1, 1, 0.7], [0, 1, 0.4]], np.float64) * 7.3 + [101.7, -55.2, 13.1]
    tracer = tracer_for(corners, [[0, 1, 2], [0, 2, 3]])
    t = rng.random(20000)
    on_edge = corners[0] + t[:, None] * (corners[2] - corners[0])
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    normal /= np.linalg.norm(normal)
    origins = (on_edge + 3.0 * normal + rng.normal(scale=1e-6, size=on_edge.shape)).astype(np.float32)
    hits = tracer.intersect(origins, np.broadcast_to(-normal, origins.shape).astype(np.float32))
    hit = hits.triangle != MISS
    assert hit.mean() > 0.99
    u, v = hits.u[hit].astype(np.float64), hits.v[hit].astype(np.float64)
    assert (u >= 0).all() and (v >= 0).all() and (1.0 - u - v >= 0).all()
