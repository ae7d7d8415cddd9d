"""The emitters' glossy highlights in closed form (radiosity.physics.emitters) against
independent quadratures over the emitter's area or solid angle, closed forms, and the
extremes (exponents 1 to 1e5, a lamp touching the surface, grazing views, radiance 0
and 1e8, tiny and huge scales)."""

import math

import numpy as np
import pytest

from radiosity.files.errors import InputError
from radiosity.physics.emitters import (
    AREA_KINDS,
    EmitterPart,
    PackedParts,
    SpotProfile,
    emitter_grid,
    emitter_radiance,
    highlight_integral,
    parts_from_meta,
    rules,
)


def integral(part, x, n, r, p, nodes=16):
    pk = PackedParts([part])
    where = (np.asarray(x, float), np.asarray(n, float), np.asarray(r, float))
    return highlight_integral(pk.kinds[0], pk.counts[0], pk.points[0], pk.radius[0], where, float(p), rules(nodes))


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def polygon_quadrature(vertices, x, n, r, p, steps=1200):
    """J by the midpoint rule over the polygon's area: dw = cos_light dA / d^2 (a fan of triangles)."""
    q = np.asarray(vertices, float)
    normal = unit(np.cross(q[1] - q[0], q[2] - q[0]))
    g = (np.arange(steps) + 0.5) / steps
    a, b = np.meshgrid(g, g)
    keep = a + b < 1  # the lower triangle of the unit square; weights halve the cell on the diagonal
    weight = np.where(np.isclose(a + b, 1), 0.5, 1.0)[keep] / steps**2
    total = 0.0
    for i in range(1, len(q) - 1):
        e1, e2 = q[i] - q[0], q[i + 1] - q[0]
        area2 = np.linalg.norm(np.cross(e1, e2))
        pts = q[0] + a[keep, None] * e1 + b[keep, None] * e2
        d = pts - x
        dist = np.linalg.norm(d, axis=1)
        w = d / dist[:, None]
        f = np.maximum(w @ r, 0) ** p * np.maximum(w @ n, 0) * np.maximum(-(w @ normal), 0) / dist**2
        total += np.sum(f * weight) * area2
    return total


def sphere_quadrature(centre, radius, x, n, r, p, steps=1500):
    """J by the midpoint rule over the cap the sphere subtends (solid angle, in the cap's frame)."""
    c = np.asarray(centre, float) - x
    d = np.linalg.norm(c)
    c /= d
    beta = math.asin(radius / d)
    t = unit(np.cross(c, [1.0, 0, 0] if abs(c[0]) < 0.9 else [0, 1.0, 0]))
    b = np.cross(c, t)
    # cos(theta) uniform in [cos beta, 1]: equal solid angle per row
    u = (np.arange(steps) + 0.5) / steps
    ct = 1 - u * (1 - math.cos(beta))
    st = np.sqrt(1 - ct**2)
    phi = 2 * np.pi * (np.arange(steps) + 0.5) / steps
    w = (ct[:, None, None] * c + st[:, None, None] * (np.cos(phi)[None, :, None] * t + np.sin(phi)[None, :, None] * b))
    f = np.maximum(w @ r, 0) ** p * np.maximum(w @ n, 0)
    return f.mean() * 2 * np.pi * (1 - math.cos(beta))


def lamp_square(size=0.5, height=1.0, offset=(0.0, 0.0)):
    """A square lamp facing down (-z) at ``height`` above the origin, counter-clockwise seen from below."""
    h = size / 2
    ox, oy = offset
    pts = [[ox - h, oy - h, height], [ox - h, oy + h, height], [ox + h, oy + h, height], [ox + h, oy - h, height]]
    part = EmitterPart("polygon", pts, 0.0, [1.0, 1.0, 1.0], "lamp")
    assert part.normal[2] < -0.99
    return part


N_UP = np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("p", [1.0, 8.0, 120.0, 1000.0, 10000.0])
@pytest.mark.parametrize("aim", ["inside", "edge", "outside"])
def test_polygon_highlight_against_quadrature_over_its_area(p, aim):
    lamp = lamp_square(0.6, 1.0, (0.1, -0.05))
    x = np.array([0.05, 0.02, 0.0])
    to_centre = unit(lamp.centre - x)
    # aim the mirror direction at the lamp's centre, its edge, or beside it
    sideways = {"inside": 0.0, "edge": 0.28, "outside": 0.45}[aim]
    r = unit(to_centre + [sideways, 0.0, 0.0])
    expected = polygon_quadrature(lamp.points, x, N_UP, r, p)
    got = integral(lamp, x, N_UP, r, p)
    # relative to the value, and to the lobe's whole integral for far tails
    assert got == pytest.approx(expected, rel=0.005 if p <= 1000 else 0.01, abs=1e-4 * 2 * np.pi / (p + 1))


@pytest.mark.parametrize("p", [1.0, 8.0, 120.0, 1000.0, 10000.0])
@pytest.mark.parametrize("radius, aim", [(0.05, 0.0), (0.2, 0.5), (0.2, 1.5), (0.5, 0.9)])
def test_sphere_highlight_against_quadrature_over_its_cap(p, radius, aim):
    centre = np.array([0.3, -0.2, 1.5])
    x = np.zeros(3)
    c = unit(centre - x)
    beta = math.asin(radius / np.linalg.norm(centre - x))
    # aim r off the centre by ``aim`` cap radii
    side = unit(np.cross(c, [0, 1.0, 0]))
    r = unit(math.cos(aim * beta) * c + math.sin(aim * beta) * side)
    expected = sphere_quadrature(centre, radius, x, N_UP, r, p)
    got = integral(EmitterPart("sphere", [centre], radius, [1, 1, 1], "s"), x, N_UP, r, p)
    assert got == pytest.approx(expected, rel=0.005 if p <= 1000 else 0.01, abs=1e-4 * 2 * np.pi / (p + 1))


def test_the_default_rule_is_within_one_percent_and_more_nodes_converge():
    lamp = lamp_square(0.6, 1.0)
    x = np.array([0.2, 0.1, 0.0])
    r = unit(lamp.centre - x + [0.1, 0.05, 0.0])
    expected = polygon_quadrature(lamp.points, x, N_UP, r, 60.0)
    errors = [abs(integral(lamp, x, N_UP, r, 60.0, nodes) / expected - 1) for nodes in (2, 4, 8, 16, 32)]
    assert errors[2] < 0.01  # the default, 8
    assert errors[-1] < 0.002 and errors[-1] < errors[0]


def test_closed_form_cap_straight_above():
    # r = n = the direction of the sphere's centre: J = 2 pi (1 - cos^(p + 2) beta) / (p + 2);
    # exact in the lobe, the surface's cosine cos theta = u^(1 / (p + 1)) by the 2-point rule in u
    # (exact for p = 0, within 1e-3 otherwise)
    for p in (0.0, 1.0, 50.0, 5000.0):
        beta = 0.3
        centre = [0, 0, 1 / math.sin(beta)]
        got = integral(EmitterPart("sphere", [centre], 1.0, [1, 1, 1], "s"), np.zeros(3), N_UP, N_UP, p, nodes=8)
        assert got == pytest.approx(2 * np.pi * (1 - math.cos(beta) ** (p + 2)) / (p + 2), rel=1e-6 if p == 0 else 1e-3)


def test_exponent_zero_seen_along_the_normal_is_the_projected_solid_angle():
    # p = 0 and r = n: the lobe is the whole upper hemisphere, J = irradiance / L (Lambert)
    from analytic import polygon_irradiance

    lamp = lamp_square(0.8, 0.5, (0.3, 0.1))
    x = np.array([[0.05, -0.1, 0.0]])
    expected = polygon_irradiance(x, N_UP, lamp.points, 1.0)[0]
    assert integral(lamp, x[0], N_UP, N_UP, 0.0, nodes=32) == pytest.approx(expected, rel=2e-3)


def test_a_polygon_seen_from_behind_or_below_the_horizon_reflects_nothing():
    lamp = lamp_square(0.5, 1.0)
    above = np.array([0.0, 0.0, 2.0])  # behind its emitting front
    assert integral(lamp, above, -N_UP, -N_UP, 10.0) == 0.0
    # entirely below the surface's horizon: n points away from it
    assert integral(lamp, np.zeros(3), -N_UP, unit([0.1, 0, 1]), 10.0) == 0.0


@pytest.mark.parametrize("p", [1.0, 1e5])
def test_extremes_stay_finite_and_continuous(p):
    # a sharp lobe sweeping across a sphere's edge: finite, non-negative, no jump
    centre = np.array([0.0, 0.0, 2.0])
    sphere = EmitterPart("sphere", [centre], 0.1, [1, 1, 1], "s")
    beta = math.asin(0.1 / 2.0)
    angles = np.linspace(0.0, 2.5 * beta, 400)
    values = np.array([integral(sphere, np.zeros(3), N_UP, [math.sin(a), 0, math.cos(a)], p) for a in angles])
    assert np.isfinite(values).all() and (values >= 0).all()
    assert np.abs(np.diff(values)).max() < 0.2 * values.max()
    # a lamp touching the surface (the sphere tangent to the plane at x's side)
    touching = EmitterPart("sphere", [[0.3, 0.0, 0.1]], 0.1, [1, 1, 1], "s")
    for r in ([0.9, 0, 0.1], [0, 0, 1], [0.99, 0, 0.01]):
        v = integral(touching, np.zeros(3), N_UP, unit(r), p)
        assert math.isfinite(v) and v >= 0
    # inside the lamp: nothing
    assert integral(touching, np.array([0.3, 0.0, 0.1]), N_UP, N_UP, p) == 0.0


def test_grazing_views_and_scale_invariance():
    lamp = lamp_square(0.5, 1.0)
    x = np.array([0.1, 0.0, 0.0])
    for grazing in (1e-3, 1e-6, 0.0):
        w = unit([1.0, 0.0, grazing])
        out = emitter_radiance([lamp], x[None], N_UP[None], w[None], [1, 1, 1], 100.0)
        assert np.isfinite(out).all() and (out >= 0).all()
    r = unit(lamp.centre - x + [0.05, 0.02, 0.0])
    base = integral(lamp, x, N_UP, r, 300.0)
    for scale in (1e-6, 1e6):
        big = EmitterPart("polygon", lamp.points * scale, 0.0, [1, 1, 1], "lamp")
        assert integral(big, x * scale, N_UP, r, 300.0) == pytest.approx(base, rel=1e-6)


def test_radiance_is_linear_in_the_lamp_and_the_visibility_and_skips_its_own_parts():
    x = np.array([[0.0, 0.0, 0.0]])
    w = unit([0.2, 0.1, 1.0])[None]
    r = 2 * N_UP * (N_UP @ w[0]) - w[0]
    lamp = EmitterPart("polygon", lamp_square(0.4, 1.0, (r[0] / r[2], r[1] / r[2])).points, 0.0, [1e8, 0.0, 2.0], "lamp")
    ks = np.array([0.5, 0.5, 0.25])
    e = emitter_radiance([lamp], x, N_UP[None], w, ks, 40.0)
    j = integral(lamp, x[0], N_UP, r, 40.0, nodes=8)
    expected = ks * (40.0 + 2) / (2 * np.pi) * lamp.radiance * j
    assert e[0] == pytest.approx(expected, rel=1e-12)
    assert e[0, 1] == 0.0 and np.isfinite(e).all()
    half = emitter_radiance([lamp], x, N_UP[None], w, ks, 40.0, visibility=[[0.5]])
    assert half[0] == pytest.approx(0.5 * e[0], rel=1e-12)
    assert not emitter_radiance([lamp], x, N_UP[None], w, ks, 40.0, source="lamp").any()


def test_grid_and_points_agree():
    lamp = lamp_square(0.5, 1.0)
    sphere = EmitterPart("sphere", [[0.4, 0.2, 0.8]], 0.15, [2.0, 1.0, 0.5], "ball")
    parts = [lamp, sphere]
    positions = np.array([[0.0, 0.0, 0.0], [0.2, -0.1, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], unit([0.1, 0.0, 1.0])])
    tangents = np.array([[1.0, 0.0, 0.0], unit(np.cross([0, 1.0, 0], normals[1]))])
    from radiosity.physics.directions import grid_directions

    dirs = grid_directions(6)
    grid = emitter_grid(parts, positions, normals, tangents, dirs, [0.6] * 3, 80.0, visibility=[[1.0, 0.5], [0.2, 1.0]])
    for v in range(2):
        b = np.cross(normals[v], tangents[v])
        world = dirs @ np.stack([tangents[v], b, normals[v]])
        points = emitter_radiance(parts, np.repeat(positions[v:v + 1], len(dirs), 0), np.repeat(normals[v:v + 1], len(dirs), 0),
                                  world, [0.6] * 3, 80.0, visibility=np.array([[1.0, 0.5], [0.2, 1.0]])[v])
        np.testing.assert_allclose(grid[v], points, rtol=1e-12, atol=1e-300)


def test_parts_are_checked_and_read_back():
    with pytest.raises(ValueError, match="not convex"):
        EmitterPart("polygon", [[0, 0, 0], [1, 0, 0], [0.2, 0.2, 0], [0, 1, 0]], 0, [1, 1, 1], "x")
    with pytest.raises(ValueError, match="not planar"):
        EmitterPart("polygon", [[0, 0, 0], [1, 0, 0], [1, 1, 0.3], [0, 1, 0]], 0, [1, 1, 1], "x")
    with pytest.raises(ValueError, match="radius"):
        EmitterPart("sphere", [[0, 0, 0]], 0.0, [1, 1, 1], "x")
    parts = [lamp_square(), EmitterPart("sphere", [[1, 2, 3]], 0.5, [1, 2, 3], "ball")]

    def fail(message):
        return InputError(f"file: {message}")

    back = parts_from_meta([p.to_dict() for p in parts], fail)
    for a, b in zip(parts, back):
        assert a.kind == b.kind and a.source == b.source and a.radius == b.radius
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.radiance, b.radiance)
    for bad, words in (
        ([{"kind": "cone"}], "kind 'cone'"),
        ([{"kind": "sphere", "centre": [0, 0, 0], "radiance": [1, 1, 1]}], "no 'radius'"),
        ([{"kind": "sphere", "centre": [0, 0], "radius": 1, "radiance": [1, 1, 1]}], "triples"),
        ([{"kind": "polygon", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "radiance": [-1, 1, 1]}], "negative"),
        ("parts", "must be a list"),
    ):
        with pytest.raises(InputError, match=words):
            parts_from_meta(bad, fail)


# -- delta parts: a point (with a spot's profile) and a direction ---------------------------------


def delta_reference(x, n, w, lobe, part, fresnel=None):
    """f_s(wi, w) Le cos / d^2 (E cos for a direction) by numpy: the modified-Phong lobe
    = (ks, p) about the mirror of w, ks weighted by Schlick's F(n . w); a spot's profile
    by its angle from acos (float64). ``part``: (kind, its point or direction, Le,
    None or (axis, cutoff, beam))."""
    kind, where, le, spot = part
    ks, p = lobe
    if kind == "direction":
        wi, scale = -unit(where), 1.0
    else:
        to = np.asarray(where, float) - x
        d = np.linalg.norm(to)
        wi, scale = to / d, 1 / d**2
        if spot is not None:
            axis, cutoff, beam = unit(spot[0]), spot[1], spot[2]
            theta = math.degrees(math.acos(np.clip(-wi @ axis, -1, 1)))
            scale *= 1.0 if theta <= beam else (max(cutoff - theta, 0.0) / (cutoff - beam))
    r = 2 * (n @ w) * n - w
    k = np.asarray(ks, float)
    if fresnel is not None:
        k = k * (np.asarray(fresnel) + (1 - np.asarray(fresnel)) * (1 - np.clip(n @ w, 0, 1)) ** 5)
    return k * (p + 2) / (2 * np.pi) * max(wi @ r, 0) ** p * max(wi @ n, 0) * scale * np.asarray(le, float)


@pytest.mark.parametrize("fresnel", [None, (0.04, 0.3, 0.9)])
def test_delta_parts_highlights_against_numpy(fresnel):
    """A point, a spot (inside its beam, across its transition, outside its cone) and a
    direction: E at random points and views against the formula in numpy."""
    rng = np.random.default_rng(3)
    spot = ([0.2, -1.0, 0.1], 30.0, 18.0)
    parts = [
        EmitterPart("point", [[0.3, 1.2, -0.2]], 0.0, [3.0, 2.0, 1.0], "bulb"),
        EmitterPart("point", [[-0.1, 1.5, 0.3]], 0.0, [5.0, 5.0, 2.0], "torch", SpotProfile(*spot)),
        EmitterPart("direction", [[0.4, -1.0, 0.3]], 0.0, [1.0, 0.8, 0.5], "sun"),
    ]
    ks, p = np.array([0.6, 0.5, 0.4]), 25.0
    x = np.column_stack([rng.uniform(-1, 1, 400), np.zeros(400), rng.uniform(-1, 1, 400)])
    n = np.tile([0.0, 1.0, 0.0], (400, 1))
    w = np.array([unit(v) for v in rng.normal(size=(400, 3)) * [1, 0.2, 1] + [0, 1.0, 0]])
    got = emitter_radiance(parts, x, n, w, ks, p, fresnel=None if fresnel is None else np.array(fresnel))
    described = [("point", parts[0].points[0], parts[0].radiance, None),
                 ("point", parts[1].points[0], parts[1].radiance, spot),
                 ("direction", parts[2].points[0], parts[2].radiance, None)]
    want = np.array([sum(delta_reference(x[i], n[i], w[i], (ks, p), part, fresnel) for part in described)
                     for i in range(400)])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-300)
    # the spot's three regions are all among the points
    angles = np.degrees(np.arccos(np.clip(((x - parts[1].points[0]) / np.linalg.norm(x - parts[1].points[0], axis=1)[:, None])
                                          @ unit(spot[0]), -1, 1)))
    assert (angles < 18).sum() > 10 and ((angles > 18) & (angles < 30)).sum() > 10 and (angles > 30).sum() > 10
    # visibility scales, a part's own object skips it, one part alone is its term alone
    half = emitter_radiance(parts, x, n, w, ks, p, visibility=[0.5, 0.5, 0.5],
                            fresnel=None if fresnel is None else np.array(fresnel))
    np.testing.assert_allclose(half, 0.5 * got, rtol=1e-12)
    alone = emitter_radiance(parts, x, n, w, ks, p, source="torch", fresnel=None if fresnel is None else np.array(fresnel))
    assert np.abs(alone - got).max() > 0 and np.all(alone <= got + 1e-15)


def test_delta_parts_are_exact_behind_below_and_at_the_light():
    """Nothing from behind the surface or below the lobe's horizon; a point exactly at x
    gives nothing (not a NaN); huge and tiny distances stay finite."""
    n = np.array([[0.0, 0.0, 1.0]])
    w = np.array([[0.0, 0.0, 1.0]])
    below = EmitterPart("point", [[0.0, 0.0, -1.0]], 0.0, [1.0, 1.0, 1.0], "under")
    at = EmitterPart("point", [[0.0, 0.0, 0.0]], 0.0, [1.0, 1.0, 1.0], "at")
    up = EmitterPart("direction", [[0.0, 0.0, 1.0]], 0.0, [1.0, 1.0, 1.0], "from below")  # travels up: lights the back
    e = emitter_radiance([below, at, up], [[0.0, 0.0, 0.0]], n, w, [0.5] * 3, 10.0)
    assert np.all(e == 0)
    for d in (1e-6, 1e6):
        far = EmitterPart("point", [[0.0, 0.0, d]], 0.0, [1.0, 1.0, 1.0], "lamp")
        e = emitter_radiance([far], [[0.0, 0.0, 0.0]], n, w, [0.5] * 3, 10.0)
        assert e[0, 0] == pytest.approx(0.5 * 12 / (2 * np.pi) / d**2, rel=1e-12)


def test_delta_parts_are_checked_and_read_back_in_the_versions_that_hold_them():
    def fail(message):
        return InputError(f"file: {message}")

    spot = EmitterPart("point", [[1, 2, 3]], 0.0, [4, 5, 6], "torch", SpotProfile([0, 0, -2], 25, 10))
    sun = EmitterPart("direction", [[0, -3, 4]], 0.0, [1, 1, 1], "sun")
    assert sun.points[0].tolist() == [0, -0.6, 0.8]  # unit
    assert spot.to_dict() == {"kind": "point", "source": "torch", "intensity": [4, 5, 6], "position": [1, 2, 3],
                              "spot": {"axis": [0, 0, -1], "cutoff_deg": 25, "beam_deg": 10}}
    assert sun.to_dict() == {"kind": "direction", "source": "sun", "irradiance": [1, 1, 1], "direction": [0, -0.6, 0.8]}
    back = parts_from_meta([spot.to_dict(), sun.to_dict()], fail)
    assert [b.to_dict() for b in back] == [spot.to_dict(), sun.to_dict()]
    assert spot.power() == pytest.approx(np.array([4, 5, 6]) * spot.spot.solid_angle())
    assert sun.power(2.0) == pytest.approx(np.pi * 4 * np.ones(3))
    with pytest.raises(InputError, match="kind 'point' is not one of sphere, polygon"):
        parts_from_meta([spot.to_dict()], fail, AREA_KINDS)
    with pytest.raises(ValueError, match="beam width"):
        SpotProfile([0, 0, 1], 10, 12)
    with pytest.raises(ValueError, match="cutoff angle"):
        SpotProfile([0, 0, 1], 0, 0)
    with pytest.raises(ValueError, match="only a point light has a spot"):
        EmitterPart("direction", [[0, 0, 1]], 0.0, [1, 1, 1], "x", SpotProfile([0, 0, 1], 10, 5))
    for bad, words in (
        ([{"kind": "point", "position": [0, 0, 0]}], "no 'intensity'"),
        ([{"kind": "point", "position": [0, 0, 0], "intensity": [1, 1, 1], "spot": {"axis": [0, 0, 1]}}],
         "no 'cutoff_deg'"),
        ([{"kind": "point", "position": [0, 0, 0], "intensity": [1, 1, 1],
           "spot": {"axis": [0, 0, 0], "cutoff_deg": 10, "beam_deg": 5}}], "axis"),
        ([{"kind": "direction", "direction": [0, 0, 0], "irradiance": [1, 1, 1]}], "must not be zero"),
        ([{"kind": "direction", "direction": [0, 0, 1], "irradiance": [1, -1, 1]}], "negative irradiance"),
    ):
        with pytest.raises(InputError, match=words):
            parts_from_meta(bad, fail)
