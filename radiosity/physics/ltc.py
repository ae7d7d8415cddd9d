"""A microfacet lobe's highlight of an emitter in closed form: linearly transformed
cosines (Heitz, Dupuy, Hill and Neubelt 2016), the CPU reference both displays' GLSL
repeats (``display/shaders/ltc.glsl``) and the solver's grids use.

A microfacet material (GGX or Beckmann, roughness alpha; ``radiosity.physics.materials.
Microfacet``) at x with unit normal n, seen from w, reflects a Lambertian emitter part
of radiance Le as

    E = ks (F0 norm + (1 - F0) schlick) Le V I,

I the integral over the part of the cosine distribution transformed by the cell's M
(``radiosity/scene/ltc_fit.py`` fits it to the lobe D G1 G1 / (4 cos theta_o) times the
cosine, without Fresnel; ``norm`` and ``schlick`` are the lobe's integrals, plain and
weighted by (1 - wi.h)^5, so Schlick's curve through the material's exact normal
reflectance F0 is integrated over the lobe), V the fraction of the part the vertex
sees. I of a polygon: its vertices mapped by M^-1 in the frame (t, b, n) where w lies in
the tn plane, the polygon clipped to the mapped cosine's horizon edge by edge (no
vertex list: the displays' shaders hold none), and the edge sum (1 / 2 pi) |sum_k
theta_k (v_k x v_k+1).z / |v_k x v_k+1||, theta_k = atan2(|v_k x v_k+1|, v_k . v_k+1)
(exact for small edges). (The mapped horizon is the surface's where the lobe is not
tilted; at grazing views a little of the fit's mass below the surface's horizon counts,
as in Heitz et al.'s own implementation.) Where the lobe's shape and the fit's differ (a
Beckmann lobe's lighter tail, the grazing views), I is corrected towards the lobe's own
integral: the polygon is cut into the fan of triangles from its representative direction
(M f, f its vector form factor) to each edge, and each triangle's integral weighed by the
lobe over the fit's density at the triangle's own representative direction
(``fan_integral``). A sphere
is its visible cap, a regular ``SPHERE_SIDES``-gon of the same area across the cone
that bounds the cap (its solid angle the cap's to 1 % up to a half-angle of 60
degrees). A delta part's highlight is the lobe at its one direction, with Schlick's
F at wi.h: ks F D G1 G1 / (4 cos theta_o) times its incidence factor.

The table: per distribution (GGX, Beckmann), cells over sqrt(alpha) in
[sqrt(``ALPHA_MIN``), 1] and sqrt(1 - cos theta_o) in [0, 1], each (k00, k02, k20, k22,
norm, schlick), read bilinearly: M^-1 is proportional to diag(1 / alpha, 1 / alpha, 1)
K with K = [[k00, 0, k02], [0, 1, 0], [k20, 0, k22]] (``radiosity.scene.ltc_fit``).
A roughness above 1 reads the cells at 1 (the lobes the collection's scenes use are
all below it). Smith's G1 of Beckmann is Walter et al.'s rational form (within 0.35 %
of the exact one), as the GLSL has no erf.
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.materials import Microfacet

__all__ = ["ALPHA_MIN", "LOBES", "SPHERE_SIDES", "HighlightLobe", "highlight_lobe", "lobe_albedo", "lobe_code", "table", "table_texture",
           "normal_reflectance"]

LOBES = ("phong", "ggx", "beckmann")  # a highlight's lobe: its code is the index
PHONG, GGX, BECKMANN = 0, 1, 2
ALPHA_MIN = 1e-4
SPHERE_SIDES = 12
SPHERE_SCALE = math.sqrt(2.0 * math.pi / (SPHERE_SIDES * math.sin(2.0 * math.pi / SPHERE_SIDES)))
MAX_VERTICES = 12  # a polygon's vertices at most here (a sphere's regular polygon; a part's, at most 8)
MAX_RATIO = 3.0  # the lobe over the fit at most (near the transformed horizon the fit's density goes to 0)
CULL = 1e-4  # a part where the distribution is below this fraction of its peak reflects nothing (``culled``)
TABLE_FILE = Path(__file__).resolve().parent / "data" / "ltc.npz"


def lobe_code(distribution):
    """The lobe's code (``LOBES``) of a distribution name; ValueError for another."""
    if distribution not in LOBES[1:]:
        raise ValueError(f"a highlight's distribution must be one of {', '.join(LOBES[1:])}, got {distribution!r}")
    return LOBES.index(distribution)


@cache
def table():
    """(2, S, S, 6) float64: the GGX then the Beckmann cells (read once)."""
    with np.load(TABLE_FILE) as data:
        out = np.stack([data["ggx"], data["beckmann"]]).astype(np.float64)
    if out.ndim != 4 or out.shape[1] != out.shape[2] or out.shape[3] != 6 or not np.isfinite(out).all():
        raise RuntimeError(f"{TABLE_FILE} is not a table of linearly transformed cosines")
    return np.ascontiguousarray(out)


def table_texture():
    """The table as the GLSL reads it: (2 S, 2 S, 4) float32, row l S + i (distribution
    l, alpha cell i), texels 2 j (k00, k02, k20, k22) and 2 j + 1 (norm, schlick, 0, 0)."""
    t = table()
    s = t.shape[1]
    out = np.zeros((2 * s, s, 2, 4), np.float32)
    out[..., 0, :] = t[..., :4].reshape(2 * s, s, 4)
    out[..., 1, :2] = t[..., 4:].reshape(2 * s, s, 2)
    return out.reshape(2 * s, 2 * s, 4)


def normal_reflectance(microfacet):
    """(3,) float64: the exact Fresnel reflectance at normal incidence of a ``Microfacet``
    (a plastic's ((eta - 1) / (eta + 1))^2, a conductor's ((eta - 1)^2 + k^2) / ((eta +
    1)^2 + k^2)), the F0 of the highlights' Schlick curve."""
    eta = np.asarray(microfacet.eta, np.float64)
    k = np.asarray(microfacet.k, np.float64)
    return ((eta - 1.0) ** 2 + k * k) / ((eta + 1.0) ** 2 + k * k)


class HighlightLobe(NamedTuple):
    """What draws a microfacet material's highlights: ks (3,) its specular reflectance,
    f0 (3,) its exact normal reflectance, code its lobe's (``LOBES``), alpha its roughness."""

    ks: np.ndarray
    f0: np.ndarray
    code: int
    alpha: float


def highlight_lobe(microfacet):
    """The ``HighlightLobe`` of a ``Microfacet`` (or its ``to_dict``)."""
    mf = microfacet if isinstance(microfacet, Microfacet) else Microfacet.from_dict(microfacet)
    return HighlightLobe(np.asarray(mf.specular_reflectance, np.float64), normal_reflectance(mf),
                         lobe_code(mf.distribution), float(mf.alpha))


def lobe_albedo(microfacet, cos_theta):
    """(N, 3) float64: the directional albedo of a ``Microfacet``'s specular lobe (without
    ks) seen at cos theta_o = ``cos_theta`` (N,): F0 norm + (1 - F0) schlick from the
    table's cells (the highlights' Fresnel, ``normal_reflectance``), what its
    reflection of distant surroundings keeps."""
    mf = microfacet if isinstance(microfacet, Microfacet) else Microfacet.from_dict(microfacet)
    f0 = normal_reflectance(mf)
    ltc, code = table(), lobe_code(mf.distribution)
    cells = np.array([cell(ltc, code, mf.alpha, float(c))[4:] for c in np.asarray(cos_theta, np.float64).ravel()])
    return cells[:, :1] * f0 + cells[:, 1:] * (1.0 - f0)


@numba.njit(cache=True, nogil=True, inline="always")
def cell(ltc, lobe, alpha, cos_o):
    """The bilinear read (k00, k02, k20, k22, norm, schlick) of ``lobe`` (GGX or
    BECKMANN) at roughness alpha, cos theta_o."""
    size = ltc.shape[1]
    lo = math.sqrt(ALPHA_MIN)
    u = (math.sqrt(min(max(alpha, ALPHA_MIN), 1.0)) - lo) / (1.0 - lo) * (size - 1)
    v = math.sqrt(max(0.0, 1.0 - min(max(cos_o, 0.0), 1.0))) * (size - 1)
    i = min(int(u), size - 2)
    j = min(int(v), size - 2)
    fu, fv = u - i, v - j
    d = lobe - 1
    c0, c1, c2, c3 = ltc[d, i, j], ltc[d, i, j + 1], ltc[d, i + 1, j], ltc[d, i + 1, j + 1]
    gu, gv = 1.0 - fu, 1.0 - fv
    return (gu * (gv * c0[0] + fv * c1[0]) + fu * (gv * c2[0] + fv * c3[0]),
            gu * (gv * c0[1] + fv * c1[1]) + fu * (gv * c2[1] + fv * c3[1]),
            gu * (gv * c0[2] + fv * c1[2]) + fu * (gv * c2[2] + fv * c3[2]),
            gu * (gv * c0[3] + fv * c1[3]) + fu * (gv * c2[3] + fv * c3[3]),
            gu * (gv * c0[4] + fv * c1[4]) + fu * (gv * c2[4] + fv * c3[4]),
            gu * (gv * c0[5] + fv * c1[5]) + fu * (gv * c2[5] + fv * c3[5]))


@numba.njit(cache=True, nogil=True, inline="always")
def view_frame(n, w):
    """(t, b): unit tangents with w in the (t, n) plane on t's side (any pair when w is n)."""
    wn = w[0] * n[0] + w[1] * n[1] + w[2] * n[2]
    tx, ty, tz = w[0] - wn * n[0], w[1] - wn * n[1], w[2] - wn * n[2]
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    if not tl > 1e-12:
        sign = 1.0 if n[2] >= 0.0 else -1.0
        a = -1.0 / (sign + n[2])
        c = n[0] * n[1] * a
        tx, ty, tz = 1.0 + sign * n[0] * n[0] * a, sign * c, -sign * n[0]
        tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / tl, ty / tl, tz / tl
    return (tx, ty, tz), (n[1] * tz - n[2] * ty, n[2] * tx - n[0] * tz, n[0] * ty - n[1] * tx)


@numba.njit(cache=True, nogil=True, inline="always")
def _mapped(x, y, z, k, a):
    """alpha M^-1 (x, y, z), normalised (the cell's K = (k00, k02, k20, k22), a = alpha)."""
    px, py, pz = k[0] * x + k[1] * z, y, a * (k[2] * x + k[3] * z)
    length = math.sqrt(px * px + py * py + pz * pz)
    if length > 0.0:
        return px / length, py / length, pz / length
    return px, py, pz


@numba.njit(cache=True, nogil=True, inline="always")
def _edge(a, b):
    """One edge's term theta (a x b) / |a x b| of the vector form factor (a, b unit)."""
    cx, cy, cz = a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not s > 0.0:
        return 0.0, 0.0, 0.0
    theta = math.atan2(s, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / s
    return theta * cx, theta * cy, theta * cz


@numba.njit(cache=True, nogil=True, inline="always")
def _crossing(a, b):
    """Where the segment a b meets z = 0 (a and b on either side), normalised."""
    s = a[2] / (a[2] - b[2])
    x, y = a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])
    length = math.sqrt(x * x + y * y)
    return (x / length, y / length, 0.0) if length > 0.0 else (x, y, 0.0)


@numba.njit(cache=True, nogil=True, inline="always")
def _clip_edge(prev, cur, state):
    """One edge prev -> cur (mapped) of a polygon clipped edge by edge to z >= 0: state =
    (its form factor so far (3-tuple), where it left, where it came back, crossings)
    updated with the edge's part above (as display/shaders/ltc.glsl's ltc_clip_edge)."""
    f, leave, enter, crossed = state
    above_a, above_b = prev[2] >= 0.0, cur[2] >= 0.0
    if above_a and above_b:
        e = _edge(prev, cur)
    elif above_a:
        leave = _crossing(prev, cur)
        e = _edge(prev, leave)
        crossed += 1
    elif above_b:
        enter = _crossing(prev, cur)
        e = _edge(enter, cur)
        crossed += 1
    else:
        e = (0.0, 0.0, 0.0)
    return (f[0] + e[0], f[1] + e[1], f[2] + e[2]), leave, enter, crossed


@numba.njit(cache=True, nogil=True, inline="always")
def _closed(state):
    """The clipped polygon's vector form factor: the edge along the horizon added where it
    crossed, over 2 pi, oriented so that z >= 0."""
    (fx, fy, fz), leave, enter, crossed = state
    if crossed == 2:
        e = _edge(leave, enter)
        fx, fy, fz = fx + e[0], fy + e[1], fz + e[2]
    scale = (1.0 if fz >= 0.0 else -1.0) / (2.0 * math.pi)
    return fx * scale, fy * scale, fz * scale


_START = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0)  # ``_clip_edge``'s state before any edge


@numba.njit(cache=True, nogil=True)
def polygon_cosine(local, count, k, alpha):
    """The vector form factor (3-tuple; its z is I) of the polygon local[:count] (its
    vertices relative to the shading point, in the frame (t, b, n)) under the cell's K =
    (k00, k02, k20, k22) and roughness alpha: each vertex mapped by alpha M^-1 and
    normalised, the polygon clipped to the transformed cosine's horizon edge by edge (an
    edge's part above it, and the one edge along it from where the polygon leaves to where
    it comes back), the sum of the edges' terms over 2 pi, oriented so that z >= 0. (0, 0,
    0) where nothing is above."""
    a = max(alpha, ALPHA_MIN)
    first = _mapped(local[0, 0], local[0, 1], local[0, 2], k, a)
    prev = first
    state = _START
    for i in range(count):
        cur = first if i + 1 == count else _mapped(local[i + 1, 0], local[i + 1, 1], local[i + 1, 2], k, a)
        state = _clip_edge(prev, cur, state)
        prev = cur
    return _closed(state)


@numba.njit(cache=True, nogil=True, inline="always")
def triangle_cosine(p, q, r, k, alpha):
    """``polygon_cosine`` of the triangle (p, q, r) (3-tuples), without a vertex array."""
    a = max(alpha, ALPHA_MIN)
    mp, mq, mr = _mapped(p[0], p[1], p[2], k, a), _mapped(q[0], q[1], q[2], k, a), _mapped(r[0], r[1], r[2], k, a)
    return _closed(_clip_edge(mr, mp, _clip_edge(mq, mr, _clip_edge(mp, mq, _START))))


@numba.njit(cache=True, nogil=True, inline="always")
def representative(f, k, alpha):
    """The unit direction (3-tuple, in the frame (t, b, n)) a vector form factor f of the
    transformed space stands for: M f normalised; (0, 0, 0) where f is 0."""
    fl = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    det = k[0] * k[3] - k[1] * k[2]
    if not (fl > 0.0 and det > 0.0):
        return 0.0, 0.0, 0.0
    a = max(alpha, ALPHA_MIN)
    px, pz = a * f[0] / fl, f[2] / fl  # M u = K^-1 diag(alpha, alpha, 1) u, up to scale
    wx, wy, wz = (k[3] * px - k[1] * pz) / det, a * f[1] / fl, (-k[2] * px + k[0] * pz) / det
    wl = math.sqrt(wx * wx + wy * wy + wz * wz)
    return wx / wl, wy / wl, wz / wl


@numba.njit(cache=True, nogil=True)
def lobe_ratio(f, k, lobe, alpha, cos_o, norm):
    """T / (norm D) at a polygon's representative direction (``representative`` of its
    vector form factor f), where T is the lobe times the cosine (``lobe_value``) and D
    the transformed cosine's density, at most ``MAX_RATIO``; 1 where f is 0."""
    wx, wy, wz = representative(f, k, alpha)
    if not (norm > 0.0 and (wx != 0.0 or wy != 0.0 or wz != 0.0)):
        return 1.0
    a = max(alpha, ALPHA_MIN)
    det = k[0] * k[3] - k[1] * k[2]
    # A w = diag(1 / alpha, 1 / alpha, 1) K w: its length, and D = (A w).z / |A w| / pi |det A| / |A w|^3
    ax, ay, az = (k[0] * wx + k[1] * wz) / a, wy / a, k[2] * wx + k[3] * wz
    al = math.sqrt(ax * ax + ay * ay + az * az)
    if not (az > 0.0 and al > 0.0):
        return 1.0
    density = az / al / math.pi * (det / (a * a)) / (al * al * al)
    so = math.sqrt(max(0.0, 1.0 - cos_o * cos_o))
    value, _ = lobe_value(lobe, alpha, (wx, wy, wz), (so, 0.0, cos_o), (0.0, 0.0, 1.0))
    return min(value / (norm * density), MAX_RATIO)


@numba.njit(cache=True, nogil=True, inline="always")
def _fan_centre(local, count, c):
    """The fan's centre: c where it lies inside the polygon local[:count] (seen from the
    point: on one side of every edge's plane), else the mean of the vertices' directions
    (a polygon mostly clipped away has a form factor too small to point anywhere)."""
    pos = True
    neg = True
    mx = my = mz = 0.0
    for i in range(count):
        j = i + 1 if i + 1 < count else 0
        ax, ay, az = local[i, 0], local[i, 1], local[i, 2]
        bx, by, bz = local[j, 0], local[j, 1], local[j, 2]
        side = c[0] * (ay * bz - az * by) + c[1] * (az * bx - ax * bz) + c[2] * (ax * by - ay * bx)
        pos = pos and side >= 0.0
        neg = neg and side <= 0.0
        length = math.sqrt(ax * ax + ay * ay + az * az)
        if length > 0.0:
            mx, my, mz = mx + ax / length, my + ay / length, mz + az / length
    if pos or neg:
        return c
    length = math.sqrt(mx * mx + my * my + mz * mz)
    return (mx / length, my / length, mz / length) if length > 0.0 else c


@numba.njit(cache=True, nogil=True)
def fan_integral(local, count, k, alpha, lobe, cos_o, norm):
    """I of the polygon local[:count] (relative to the point, in the frame (t, b, n)),
    its transformed cosine's integral corrected towards the lobe's own: the polygon cut
    into the fan of triangles from its representative direction (``_fan_centre``) to each edge, each
    triangle's integral times ``lobe_ratio`` at its own representative direction (where
    the fit's shape and the lobe's differ, a Beckmann lobe's lighter tail, a grazing view,
    each part of the polygon is weighed by the lobe there)."""
    f = polygon_cosine(local, count, k, alpha)
    if not f[2] > 0.0:
        return 0.0
    c = _fan_centre(local, count, representative(f, k, alpha))
    total = 0.0
    for i in range(count):
        j = i + 1 if i + 1 < count else 0
        ft = triangle_cosine(c, (local[i, 0], local[i, 1], local[i, 2]), (local[j, 0], local[j, 1], local[j, 2]), k, alpha)
        if ft[2] > 0.0:
            total += ft[2] * lobe_ratio(ft, k, lobe, alpha, cos_o, norm)
    # the triangles' integrals sum to the polygon's, each ratio at most MAX_RATIO: where a sliver
    # along the horizon leaves rounding to decide an edge's side, the bound holds the sum
    return min(total, MAX_RATIO * f[2])


@numba.njit(cache=True, nogil=True, inline="always")
def _to_local(vx, vy, vz, frame):
    (tx, ty, tz), (bx, by, bz), (nx, ny, nz) = frame
    return vx * tx + vy * ty + vz * tz, vx * bx + vy * by + vz * bz, vx * nx + vy * ny + vz * nz


@numba.njit(cache=True, nogil=True)
def polygon_local(count, points, x, frame, local):
    """A convex polygon's vertices (``points[:count]``, counter-clockwise seen from its
    emitting front) relative to x in the frame (t, b, n) (``view_frame``) into local; its
    vertex count, 0 seen from behind."""
    e1x, e1y, e1z = points[1, 0] - points[0, 0], points[1, 1] - points[0, 1], points[1, 2] - points[0, 2]
    e2x, e2y, e2z = points[2, 0] - points[0, 0], points[2, 1] - points[0, 1], points[2, 2] - points[0, 2]
    fx, fy, fz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    if (x[0] - points[0, 0]) * fx + (x[1] - points[0, 1]) * fy + (x[2] - points[0, 2]) * fz <= 0.0:
        return 0
    for i in range(count):
        local[i, 0], local[i, 1], local[i, 2] = _to_local(
            points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2], frame)
    return count


@numba.njit(cache=True, nogil=True)
def sphere_local(centre, radius, x, frame, local):
    """A sphere lamp's visible cap as seen from x, into local: the regular
    ``SPHERE_SIDES``-gon of the same area across the cone that bounds it, in the frame (t,
    b, n); its vertex count, 0 from inside the lamp."""
    cx, cy, cz = _to_local(centre[0] - x[0], centre[1] - x[1], centre[2] - x[2], frame)
    dist = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not dist > radius:
        return 0
    cx, cy, cz = cx / dist, cy / dist, cz / dist
    sin_beta = radius / dist
    spread = sin_beta / math.sqrt(max(1e-30, 1.0 - sin_beta * sin_beta)) * SPHERE_SCALE  # tan(beta), scaled
    sign = 1.0 if cz >= 0.0 else -1.0
    a = -1.0 / (sign + cz)
    c = cx * cy * a
    ux, uy, uz = 1.0 + sign * cx * cx * a, sign * c, -sign * cx
    vx, vy, vz = c, sign + cy * cy * a, -cy
    for i in range(SPHERE_SIDES):
        phi = 2.0 * math.pi * i / SPHERE_SIDES
        cp, sp = math.cos(phi) * spread, math.sin(phi) * spread
        local[i, 0], local[i, 1], local[i, 2] = cx + cp * ux + sp * vx, cy + cp * uy + sp * vy, cz + cp * uz + sp * vz
    return SPHERE_SIDES


CULL_ALPHA = 0.5  # below it both distributions fall monotonically from the normal: a part may be culled


@numba.njit(cache=True, nogil=True)
def culled(lobe, alpha, bound_centre, bound_radius, x, n, r):
    """True where a part (its bounding sphere) reflects nothing worth drawing: it lies
    wholly below the surface's tangent plane, or (alpha < ``CULL_ALPHA``) every direction
    towards it is at delta >= 2 theta from the mirror direction r where D(theta) is below
    ``CULL`` of D's peak (reflecting wo about a normal turned by theta turns wi by at
    most 2 theta: so no half vector of the part is nearer the normal than delta / 2)."""
    cx, cy, cz = bound_centre[0] - x[0], bound_centre[1] - x[1], bound_centre[2] - x[2]
    if cx * n[0] + cy * n[1] + cz * n[2] < -bound_radius:
        return True
    if not alpha < CULL_ALPHA:
        return False
    dist = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not dist > bound_radius:
        return False
    qx, qy, qz = r[1] * cz - r[2] * cy, r[2] * cx - r[0] * cz, r[0] * cy - r[1] * cx
    nearest = math.atan2(math.sqrt(qx * qx + qy * qy + qz * qz), r[0] * cx + r[1] * cy + r[2] * cz) - math.asin(
        bound_radius / dist)
    if not nearest > 0.0:
        return False
    return ndf(lobe, alpha, math.cos(min(0.5 * nearest, 0.5 * math.pi))) < CULL * ndf(lobe, alpha, 1.0)


@numba.njit(cache=True, nogil=True, inline="always")
def ndf(lobe, alpha, cos_h):
    """D(h) of GGX or Beckmann at cos_h; 0 for cos_h <= 0."""
    if cos_h <= 0.0:
        return 0.0
    c2 = min(cos_h * cos_h, 1.0)
    a2 = alpha * alpha
    if lobe == GGX:
        t = a2 * c2 + 1.0 - c2
        return a2 / (math.pi * t * t)
    return math.exp(-(1.0 - c2) / (c2 * a2)) / (math.pi * a2 * c2 * c2)


@numba.njit(cache=True, nogil=True, inline="always")
def smith_g1(lobe, alpha, cos_v, cos_vh):
    """Smith's G1 (Beckmann's by Walter et al.'s rational form); 0 where v sees the
    microfacet's back."""
    if cos_v * cos_vh <= 0.0:
        return 0.0
    c2 = min(cos_v * cos_v, 1.0)
    s2 = 1.0 - c2
    if s2 <= 0.0:
        return 1.0
    if lobe == GGX:
        return 2.0 / (1.0 + math.sqrt(1.0 + alpha * alpha * s2 / c2))
    a = math.sqrt(c2 / s2) / alpha
    if a >= 1.6:
        return 1.0
    return (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)


@numba.njit(cache=True, nogil=True)
def lobe_value(lobe, alpha, wi, w, n):
    """(D G1 G1 / (4 cos theta_o) at unit wi toward the light, w toward the eye, n the
    normal (the lobe times cos theta_i, without Fresnel); wi . h). 0 below either horizon."""
    ci = wi[0] * n[0] + wi[1] * n[1] + wi[2] * n[2]
    co = w[0] * n[0] + w[1] * n[1] + w[2] * n[2]
    if not (ci > 0.0 and co > 0.0):
        return 0.0, 1.0
    hx, hy, hz = wi[0] + w[0], wi[1] + w[1], wi[2] + w[2]
    hl = math.sqrt(hx * hx + hy * hy + hz * hz)
    if not hl > 0.0:
        return 0.0, 1.0
    hx, hy, hz = hx / hl, hy / hl, hz / hl
    cih = wi[0] * hx + wi[1] * hy + wi[2] * hz
    coh = w[0] * hx + w[1] * hy + w[2] * hz
    ch = hx * n[0] + hy * n[1] + hz * n[2]
    g = smith_g1(lobe, alpha, ci, cih) * smith_g1(lobe, alpha, co, coh)
    return ndf(lobe, alpha, ch) * g / (4.0 * co), cih
