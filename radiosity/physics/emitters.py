"""The scene's emitters as the displays draw their glossy reflection ("emitter parts"),
and the one CPU reference of that reflection (solution version 2, docs/formats.md).

A glossy surface (modified Phong: ks, exponent p) at x with unit shading normal n,
seen from the unit direction w (towards the eye), reflects a Lambertian emitter part
of uniform radiance Le as

    E(x, w) = ks (p + 2) / (2 pi) * Le * V * J,
    J       = integral over the part's directions wi of max(0, wi . r)^p max(0, wi . n) dwi

with r = 2 (n . w) n - w the mirror of w, and V in [0, 1] the fraction of the part the
vertex sees (computed by the solver with shadow rays, interpolated like any per-vertex
value). The lobe is symmetric about r, so J is computed in polar coordinates about r
(theta from r, phi about it): for each phi the ray of directions at that azimuth meets
a convex part in one interval [theta1, theta2], and with u = cos^(p+1) theta,

    J = 1 / (p + 1) * integral dphi  integral_{u(theta2)}^{u(theta1)} max(0, wi(theta(u), phi) . n) du.

The u integral is exact for the lobe (u is its cumulative), the cosine at the surface
comes from a 2-point Gauss rule in u, and phi from an N-point rule (``nodes``) over
the azimuths the part covers: Gauss-Legendre after phi = mid + half sin(pi s / 2) (the
interval's ends behave like square roots, which the substitution makes smooth) when r
is outside the part, the periodic midpoint rule over the whole circle when the part
surrounds r. Both converge to the exact J as N grows; ``tests`` measure the error
against brute-force integration (``nodes`` = 8: below 1 % on the cases tested).

Parts
    sphere    a sphere lamp: centre, radius (seen as the cap it subtends)
    polygon   a convex planar polygon of 3 to ``MAX_POLYGON_VERTICES`` vertices,
              counter-clockwise seen from its front (it emits from the front only)
    point     a point light (delta in position): its position and intensity I (W/sr,
              RGB), with an optional spot profile (``SpotProfile``: Mitsuba 3's cone)
    direction a distant light (delta in direction): the unit direction its light
              travels and its irradiance E (on a surface facing it, RGB)

A delta part has no extent: its highlight is the lobe at its one direction wi, exact
and without quadrature (``delta_integral``), J = max(0, wi . r)^p max(0, wi . n) / d^2
times the spot's profile toward x for a point at distance d (Le its intensity), and
J = max(0, wi . r)^p max(0, wi . n) for a direction (wi = -its direction, Le its
irradiance); a delta part is never culled (it costs less than the test).

``highlight_integral`` (numba, scalar) is the reference every display is tested
against; ``emitter_radiance`` evaluates E for many points (parallel); the GLSL in
``display`` and the web page repeat the same arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.files.errors import InputError
from radiosity.physics import ltc
from radiosity.policies.limits import DEFAULT_NODES, MAX_NODES  # noqa: F401 (a part's quadrature)

__all__ = [
    "DEFAULT_NODES",
    "KINDS",
    "MAX_NODES",
    "MAX_POLYGON_VERTICES",
    "DELTA_KINDS",
    "EmitterPart",
    "PackedParts",
    "SpotProfile",
    "emitter_grid",
    "emitter_radiance",
    "delta_integral",
    "highlight_integral",
    "parts_from_meta",
    "pack_parts",
    "spot_angle",
    "spot_falloff",
]

SPHERE = 0
POLYGON = 1
POINT = 2
DIRECTION = 3
KINDS = ("sphere", "polygon", "point", "direction")
DELTA_KINDS = ("point", "direction")  # solution version 4, fit version 5, glTF version 5
AREA_KINDS = ("sphere", "polygon")  # every version since the parts came (solution 2, fit 3, glTF 2)
MAX_POLYGON_VERTICES = 8
MAX_FILE_PARTS = 31  # the parts one object's highlight draws at most: the displays mark its own parts in a 32-bit mask
MAX_SCENE_PARTS = 4096  # a file's parts at most where each object names its own (solution 5, fit 6, glTF 6)
MAX_LIGHTS = 1024  # a scene's delta lights at most (a solution's meta "lights")
UNIT_TOLERANCE = 1e-12  # a direction or a spot's axis this near unit length is kept as given, else normalised
HALF_PI = 0.5 * math.pi
CULL = 1e-4  # a part whose bounding sphere sees the lobe below this fraction of its peak reflects nothing
U_NODE = 0.5 / math.sqrt(3.0)  # 2-point Gauss-Legendre on [0, 1]: 1/2 -+ this, weights 1/2


@dataclass(frozen=True, eq=False)
class SpotProfile:
    """A point light's spot cone, as Mitsuba 3's ``spot`` emitter defines it.

    axis       : (3,) float64 unit: where the spot points (its ``to_world``'s +z)
    cutoff_deg : the cone's half-angle, beyond which it is black (0 < cutoff <= 180)
    beam_deg   : the half-angle of its full-intensity core (0 <= beam <= cutoff)

    The intensity toward a direction at angle theta from the axis is I times
    ``falloff(cos theta)``: 1 inside the beam, (cutoff - theta) / (cutoff - beam)
    across the transition (linear in the angle), 0 at and beyond the cutoff.
    """

    axis: np.ndarray
    cutoff_deg: float
    beam_deg: float

    def __post_init__(self):
        axis = np.asarray(self.axis, np.float64).reshape(3)
        length = float(np.linalg.norm(axis))
        if not (np.isfinite(axis).all() and length > 0):
            raise ValueError("a spot's axis must be a finite, non-zero vector")
        object.__setattr__(self, "axis", axis / length if abs(length - 1) > UNIT_TOLERANCE else axis)
        object.__setattr__(self, "cutoff_deg", float(self.cutoff_deg))
        object.__setattr__(self, "beam_deg", float(self.beam_deg))
        if not 0 < self.cutoff_deg <= 180:
            raise ValueError(f"a spot's cutoff angle must be in (0, 180] degrees, got {self.cutoff_deg:g}")
        if not 0 <= self.beam_deg <= self.cutoff_deg:
            raise ValueError(f"a spot's beam width must be in [0, its cutoff angle {self.cutoff_deg:g}] degrees, "
                             f"got {self.beam_deg:g}")

    @property
    def radians(self):
        """(cutoff, beam) in radians."""
        return math.radians(self.cutoff_deg), math.radians(self.beam_deg)

    def falloff(self, theta_deg):
        """The profile (...) float64 in [0, 1] at the angles ``theta_deg`` (...) from
        the axis, in degrees (``spot_falloff``)."""
        cutoff, beam = self.radians
        t = np.radians(np.asarray(theta_deg, np.float64))
        out = np.array([spot_falloff(float(v), cutoff, beam) for v in t.ravel()])
        return out.reshape(t.shape)

    def solid_angle(self):
        """The integral of the profile over the sphere (sr): 2 pi (1 - (sin c - sin b) / (c - b)),
        2 pi (1 - cos c) for c = b (the power of the spot is I times this)."""
        cutoff, beam = self.radians
        if cutoff - beam < 1e-9:
            return 2 * math.pi * (1 - math.cos(cutoff))
        return 2 * math.pi * (1 - (math.sin(cutoff) - math.sin(beam)) / (cutoff - beam))

    def to_dict(self):
        return {"axis": [float(v) for v in self.axis], "cutoff_deg": self.cutoff_deg, "beam_deg": self.beam_deg}


@dataclass(frozen=True, eq=False)
class EmitterPart:
    """One emitter part.

    kind     : one of KINDS: "sphere", "polygon", "point" or "direction"
    points   : (1, 3) float64, the centre (sphere) or the position (point) or the unit
               direction the light travels (direction), or (K, 3) the vertices
               (polygon, counter-clockwise seen from the front, convex, planar, 3 <= K <= 8)
    radius   : the sphere's radius (0 for the others)
    radiance : (3,) float64, what it emits: the radiance of a sphere or a polygon
               (front only), the intensity of a point (W/sr; a spot's peak), the
               irradiance of a direction (on a surface facing it)
    source   : the name of the object (or the light) it comes from
    spot     : a point's ``SpotProfile``, or None (it lights every way)
    """

    kind: str
    points: np.ndarray
    radius: float
    radiance: np.ndarray
    source: str
    spot: SpotProfile | None = None

    def __post_init__(self):
        put = object.__setattr__
        put(self, "points", np.asarray(self.points, np.float64).reshape(-1, 3))
        put(self, "radiance", np.asarray(self.radiance, np.float64).reshape(3))
        put(self, "radius", float(self.radius))
        if self.kind == "direction" and len(self.points) == 1 and np.isfinite(self.points).all():
            length = float(np.linalg.norm(self.points[0]))
            if length > 0 and abs(length - 1) > UNIT_TOLERANCE:  # a unit one as it is: files read back exactly
                put(self, "points", self.points / length)
        problem = self.problem()
        if problem:
            raise ValueError(f"emitter part of {self.source!r}: {problem}")

    def problem(self):
        """What is wrong with this part (a phrase), or None."""
        if self.kind not in KINDS:
            return f"kind {self.kind!r} is not one of {', '.join(KINDS)}"
        if not (np.isfinite(self.points).all() and np.isfinite(self.radiance).all() and math.isfinite(self.radius)):
            return "has a NaN or infinite number"
        if (self.radiance < 0).any():
            return f"has a negative {self.quantity}"
        if self.spot is not None and self.kind != "point":
            return "only a point light has a spot profile"
        if self.kind in DELTA_KINDS:
            if len(self.points) != 1 or self.radius != 0:
                return f"a {self.kind} has one {'position' if self.kind == 'point' else 'direction'} and no radius"
            if self.kind == "direction" and not np.linalg.norm(self.points[0]) > 0:
                return "a direction must not be zero"
            return None
        if self.kind == "sphere":
            if len(self.points) != 1 or not self.radius > 0:
                return "a sphere has one centre and a radius > 0"
            return None
        if not 3 <= len(self.points) <= MAX_POLYGON_VERTICES:
            return f"a polygon has 3 to {MAX_POLYGON_VERTICES} vertices, not {len(self.points)}"
        normal, area = polygon_normal(self.points)
        if not area > 0:
            return "the polygon has no area"
        q = self.points - self.points[0]
        size = math.sqrt(area)
        if np.abs(q @ normal).max() > 1e-4 * size:
            return "the polygon is not planar"
        for i in range(len(q)):
            a, b, c = self.points[i - 1], self.points[i], self.points[(i + 1) % len(q)]
            if np.cross(b - a, c - b) @ normal < -1e-9 * area:
                return "the polygon is not convex (or not counter-clockwise seen from its front)"
        return None

    @property
    def is_delta(self):
        """A point or a direction: no extent, never seen, only reflected."""
        return self.kind in DELTA_KINDS

    @property
    def quantity(self):
        """The name of what ``radiance`` holds: "radiance", "intensity" or "irradiance"."""
        return {"point": "intensity", "direction": "irradiance"}.get(self.kind, "radiance")

    @property
    def normal(self):
        """Unit front normal of a polygon (zeros for the others)."""
        return polygon_normal(self.points)[0] if self.kind == "polygon" else np.zeros(3)

    @property
    def area(self):
        """Its emitting area (0 for a delta part)."""
        if self.kind == "sphere":
            return 4.0 * math.pi * self.radius**2
        return polygon_normal(self.points)[1] if self.kind == "polygon" else 0.0

    @property
    def centre(self):
        """The centroid of its points (a direction's: the direction itself)."""
        return self.points.mean(axis=0)

    def power(self, radius=None):
        """Power (3,) float64 it emits: pi Le A (a sphere, a polygon), 4 pi I (a point;
        I times ``SpotProfile.solid_angle`` for a spot), E pi R^2 for a direction
        through the disk of radius ``radius`` (the scene's bounding sphere: needed)."""
        if self.kind == "point":
            return self.radiance * (4 * math.pi if self.spot is None else self.spot.solid_angle())
        if self.kind == "direction":
            if radius is None:
                raise ValueError("a direction's power needs the radius of the disk it crosses")
            return self.radiance * math.pi * float(radius) ** 2
        return math.pi * self.radiance * self.area

    def to_dict(self):
        out = {"kind": self.kind, "source": self.source}
        if self.kind == "point":
            out |= {"intensity": [float(v) for v in self.radiance], "position": [float(v) for v in self.points[0]]}
            if self.spot is not None:
                out["spot"] = self.spot.to_dict()
            return out
        if self.kind == "direction":
            return out | {"irradiance": [float(v) for v in self.radiance], "direction": [float(v) for v in self.points[0]]}
        out["radiance"] = [float(v) for v in self.radiance]
        if self.kind == "sphere":
            out |= {"centre": [float(v) for v in self.points[0]], "radius": self.radius}
        else:
            out["vertices"] = self.points.tolist()
        return out


def polygon_normal(points):
    """(unit normal (3,), area) of a planar polygon (K, 3), counter-clockwise seen from
    the normal's side (Newell's method)."""
    p = np.asarray(points, np.float64)
    total = np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
    twice = float(np.linalg.norm(total))
    return (total / twice if twice > 0 else np.zeros(3)), 0.5 * twice


def parts_from_meta(entries, fail, kinds=KINDS, what="emitters", limit=MAX_FILE_PARTS):
    """EmitterParts from the JSON list ``entries`` (meta ``what``); ``fail(message)``
    makes the error to raise (naming the file) for a bad entry; ``kinds``: the kinds
    the file's version holds (``AREA_KINDS`` before the delta parts came); ``limit``:
    the most it may hold."""
    if not isinstance(entries, list):
        raise fail(f"meta '{what}' must be a list of emitter parts")
    if len(entries) > limit:
        raise fail(f"meta '{what}' has {len(entries)} parts; a file holds at most {limit}")
    parts = []
    for i, e in enumerate(entries):
        where = f"meta '{what}' entry {i}"
        if not isinstance(e, dict):
            raise fail(f"{where} must be a JSON object")
        kind = e.get("kind")
        try:
            if kind not in kinds:
                raise fail(f"{where}: kind {kind!r} is not one of {', '.join(kinds)}")
            spot = None
            if kind == "sphere":
                points, radius, value = [e["centre"]], e["radius"], e["radiance"]
            elif kind == "polygon":
                points, radius, value = e["vertices"], 0.0, e["radiance"]
            elif kind == "point":
                points, radius, value = [e["position"]], 0.0, e["intensity"]
                if "spot" in e:
                    spot = _spot_from_meta(e["spot"], where, fail)
            else:
                points, radius, value = [e["direction"]], 0.0, e["irradiance"]
            source = e.get("source", "")
            if not isinstance(source, str):
                raise fail(f"{where}: 'source' must be a string")
            if isinstance(radius, bool) or not isinstance(radius, int | float):
                raise fail(f"{where}: 'radius' must be a number")
            points = np.asarray(points, np.float64)
            value = np.asarray(value, np.float64)
            if points.ndim != 2 or points.shape[1] != 3 or value.shape != (3,):
                raise fail(f"{where}: points must be [x, y, z] triples and the emitted colour [r, g, b]")
            parts.append(EmitterPart(kind, points, float(radius), value, source, spot))
        except KeyError as exc:
            raise fail(f"{where} has no {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise fail(f"{where}: {exc}") from None
    return tuple(parts)


def file_parts(entries, fail, *, delta, own):
    """``parts_from_meta`` of a file's ``emitters`` as its version reads them: ``delta``,
    its version holds delta parts (``KINDS``, else ``AREA_KINDS``); ``own``, its objects
    may name their own parts (up to ``MAX_SCENE_PARTS``, else ``MAX_FILE_PARTS``)."""
    return parts_from_meta(entries, fail, KINDS if delta else AREA_KINDS,
                           limit=MAX_SCENE_PARTS if own else MAX_FILE_PARTS)


def _spot_from_meta(entry, where, fail):
    """The ``SpotProfile`` of a point's "spot" entry."""
    if not isinstance(entry, dict):
        raise fail(f"{where}: 'spot' must be a JSON object")
    numbers = [entry[k] for k in ("cutoff_deg", "beam_deg")]
    if any(isinstance(v, bool) or not isinstance(v, int | float) for v in numbers):
        raise fail(f"{where}: a spot's 'cutoff_deg' and 'beam_deg' must be numbers")
    axis = np.asarray(entry["axis"], np.float64)
    if axis.shape != (3,):
        raise fail(f"{where}: a spot's 'axis' must be [x, y, z]")
    return SpotProfile(axis, *numbers)


class PackedParts:
    """Parts as the kernels and shaders read them.

    kinds (P,) int64 (SPHERE, POLYGON, POINT, DIRECTION); counts (P,) int64 (polygon
    vertices, 1 for the others); points (P, MAX_POLYGON_VERTICES, 3) float64: a
    polygon's vertices, a sphere's centre, a point's position, a direction's unit
    direction of travel in row 0, and for a point, row 1 its spot's axis and row 2
    (cutoff, beam width (radians), 1) for a spot ((pi, pi, 0) for none);
    radius (P,); radiance (P, 3) (a point's intensity, a direction's irradiance)
    """

    def __init__(self, parts):
        p = len(parts)
        self.kinds = np.array([KINDS.index(q.kind) for q in parts], np.int64)
        self.counts = np.array([len(q.points) for q in parts], np.int64)
        self.points = np.zeros((p, MAX_POLYGON_VERTICES, 3))
        for i, q in enumerate(parts):
            self.points[i, : len(q.points)] = q.points
            if q.kind == "point":
                self.points[i, 2] = (math.pi, math.pi, 0.0)
                if q.spot is not None:
                    self.points[i, 1] = q.spot.axis
                    self.points[i, 2] = (*q.spot.radians, 1.0)
        self.radius = np.array([q.radius for q in parts], np.float64)
        self.radiance = np.array([q.radiance for q in parts], np.float64).reshape(p, 3)
        self.sources = [q.source for q in parts]
        # bounding spheres (the culling test, not used for delta parts): a sphere itself;
        # a polygon's centroid and its farthest vertex; a point, radius 0; a direction, 0
        self.bound_centre = np.array(
            [np.zeros(3) if q.kind == "direction" else q.centre for q in parts], np.float64
        ).reshape(p, 3)
        self.bound_radius = np.array(
            [float(np.linalg.norm(q.points - q.centre, axis=1).max()) if q.kind == "polygon" else q.radius
             for q in parts],
            np.float64,
        )

    def arrays(self):
        """The tuple the kernels take: kinds, counts, points, radius, bound_centre,
        bound_radius, radiance."""
        return (self.kinds, self.counts, self.points, self.radius, self.bound_centre, self.bound_radius, self.radiance)

    def __len__(self):
        return len(self.kinds)


def pack_parts(parts):
    return PackedParts(parts)


class Rules(NamedTuple):
    """The Gauss-Legendre rules of ``nodes`` = N (``rules``): sphere nodes (N,) on
    [-1, 1] and their weights (N,), polygon-sector nodes (G,) and weights (G,), G =
    max(2, ceil(N / 2))."""

    sphere_s: np.ndarray
    sphere_w: np.ndarray
    sector_s: np.ndarray
    sector_w: np.ndarray


def rules(nodes):
    """The quadrature ``Rules`` of ``nodes`` = N (1 .. MAX_NODES)."""
    if not (isinstance(nodes, int | np.integer) and 1 <= nodes <= MAX_NODES):
        raise ValueError(f"nodes must be a whole number from 1 to {MAX_NODES}, got {nodes!r}")
    s, w = np.polynomial.legendre.leggauss(int(nodes))
    g_s, g_w = np.polynomial.legendre.leggauss(max(2, -(-int(nodes) // 2)))
    return Rules(s, w, g_s, g_w)


# -- the scalar kernel -------------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _basis(rx, ry, rz):
    """An orthonormal pair (t, b) perpendicular to unit r (Duff et al. 2017)."""
    sign = 1.0 if rz >= 0.0 else -1.0
    a = -1.0 / (sign + rz)
    b = rx * ry * a
    return (1.0 + sign * rx * rx * a, sign * b, -sign * rx), (b, sign + ry * ry * a, -ry)


@numba.njit(cache=True, nogil=True, inline="always")
def _log1m(v):
    """log(1 - v) for 0 <= v < 1, accurate for small v (as the GLSL computes it)."""
    if v < 0.01:
        return -v * (1.0 + v * (0.5 + v * (1.0 / 3.0 + v * 0.25)))
    return math.log(1.0 - v)


@numba.njit(cache=True, nogil=True, inline="always")
def _lobe_cdf(theta, p1):
    """cos^(p1) theta for theta in [0, pi / 2] (1 at 0, 0 at pi / 2), through the
    versine 2 sin^2(theta / 2), which keeps small angles exact."""
    if theta >= HALF_PI:
        return 0.0
    if theta <= 0.0:
        return 1.0
    h = math.sin(0.5 * theta)
    return math.exp(p1 * _log1m(2.0 * h * h))


@numba.njit(cache=True, nogil=True, inline="always")
def _slice(lo, hi, p1, rn, dn):
    """integral over theta in [lo, hi] of cos^p sin max(0, wi . n) dtheta, times (p + 1):
    (u(lo) - u(hi)) times the 2-point Gauss mean in u of the cosine at the surface, where
    cos theta = u^(1 / (p + 1)) and wi . n = cos theta (r . n) + sin theta (d . n)."""
    u1 = _lobe_cdf(lo, p1)
    u2 = _lobe_cdf(hi, p1)
    du = u1 - u2
    if not du > 0.0:
        return 0.0
    mean = 0.0
    for k in range(2):
        u = 0.5 * (u1 + u2) + (U_NODE if k == 0 else -U_NODE) * du
        c = math.exp(math.log(u) / p1) if u > 0.0 else 0.0
        g = c * rn + math.sqrt(max(0.0, 1.0 - c * c)) * dn
        if g > 0.0:
            mean += 0.5 * g
    return du * mean


@numba.njit(cache=True, nogil=True, inline="always")
def _frame(r, n):
    """The lobe's frame about unit r: (t, b) and the normal's components along r, t, b."""
    (tx, ty, tz), (bx, by, bz) = _basis(r[0], r[1], r[2])
    rn = r[0] * n[0] + r[1] * n[1] + r[2] * n[2]
    tn = tx * n[0] + ty * n[1] + tz * n[2]
    bn = bx * n[0] + by * n[1] + bz * n[2]
    return (tx, ty, tz), (bx, by, bz), rn, tn, bn


@numba.njit(cache=True, nogil=True)
def sphere_integral(centre, radius, x, n, r, exponent, rule_s, rule_w):
    """J of a sphere lamp (``centre``, ``radius``) at point x (normal n, mirror
    direction r); ``rule_s``, ``rule_w``: the Gauss-Legendre rule over its azimuths."""
    rx, ry, rz = r[0], r[1], r[2]
    (tx, ty, tz), (bx, by, bz), rn, tn, bn = _frame(r, n)
    p1 = exponent + 1.0
    cx, cy, cz = centre[0] - x[0], centre[1] - x[1], centre[2] - x[2]
    dist = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not dist > radius:
        return 0.0  # inside the lamp
    cx, cy, cz = cx / dist, cy / dist, cz / dist
    sin_beta = radius / dist
    qx, qy, qz = ry * cz - rz * cy, rz * cx - rx * cz, rx * cy - ry * cx
    sin_gamma = math.sqrt(qx * qx + qy * qy + qz * qz)
    gamma = math.atan2(sin_gamma, rx * cx + ry * cy + rz * cz)  # from r to the centre
    beta = math.asin(sin_beta)  # the cap's half-angle
    if gamma - beta >= HALF_PI:
        return 0.0
    full = gamma <= beta  # r inside the cap: every azimuth crosses it
    half = 0.0 if full else math.asin(min(sin_beta / sin_gamma, 1.0))
    mid = math.atan2(cx * bx + cy * by + cz * bz, cx * tx + cy * ty + cz * tz)
    n_phi = rule_s.shape[0]
    total = 0.0
    for k in range(n_phi):
        if full:
            phi = 2.0 * math.pi * (k + 0.5) / n_phi
            weight = 2.0 * math.pi / n_phi
        else:
            phi = mid + half * math.sin(HALF_PI * rule_s[k])
            weight = rule_w[k] * half * HALF_PI * math.cos(HALF_PI * rule_s[k])
        cp, sp = math.cos(phi), math.sin(phi)
        dx, dy, dz = cp * tx + sp * bx, cp * ty + sp * by, cp * tz + sp * bz  # the azimuth's direction
        # c = a r + b d + off e (e = r x d): the azimuth's half great circle meets the cap
        # where cos(theta - delta) >= cos(beta) / rho, rho = |(a, b)|, delta = atan2(b, a)
        a = rx * cx + ry * cy + rz * cz
        b = dx * cx + dy * cy + dz * cz
        ex, ey, ez = ry * dz - rz * dy, rz * dx - rx * dz, rx * dy - ry * dx
        off = ex * cx + ey * cy + ez * cz
        inside = sin_beta * sin_beta - off * off  # = rho^2 - cos^2 beta, without cancellation
        rho = math.sqrt(a * a + b * b)
        if not (inside > 0.0 and rho > 0.0):
            continue
        kappa = math.asin(min(math.sqrt(inside) / rho, 1.0))
        delta = math.atan2(b, a)
        lo = max(0.0, delta - kappa)
        hi = min(HALF_PI, delta + kappa)
        if hi > lo:
            total += weight * _slice(lo, hi, p1, rn, cp * tn + sp * bn)
    return total / p1


@numba.njit(cache=True, nogil=True)
def polygon_integral(count, points, x, n, r, exponent, rule_s, rule_w):
    """J of a convex polygon (``points[:count]``, counter-clockwise seen from its
    emitting front) at point x (normal n, mirror direction r); ``rule_s``, ``rule_w``:
    the Gauss-Legendre rule of each sector between two vertices' azimuths."""
    rx, ry, rz = r[0], r[1], r[2]
    (tx, ty, tz), (bx, by, bz), rn, tn, bn = _frame(r, n)
    p1 = exponent + 1.0
    # behind the polygon's plane: it does not emit towards x
    e1x, e1y, e1z = points[1, 0] - points[0, 0], points[1, 1] - points[0, 1], points[1, 2] - points[0, 2]
    e2x, e2y, e2z = points[2, 0] - points[0, 0], points[2, 1] - points[0, 1], points[2, 2] - points[0, 2]
    fx, fy, fz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    if (x[0] - points[0, 0]) * fx + (x[1] - points[0, 1]) * fy + (x[2] - points[0, 2]) * fz <= 0.0:
        return 0.0
    m = np.empty((MAX_POLYGON_VERTICES, 3))  # edge planes' unit normals: wi . m_i >= 0 inside
    pm = np.empty(MAX_POLYGON_VERTICES)  # their r components
    azimuth = np.empty(MAX_POLYGON_VERTICES + 1)
    ahead = False
    pos = True
    neg = True
    acx = acy = acz = 0.0
    for i in range(count):
        ax, ay, az = points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2]
        ahead = ahead or ax * rx + ay * ry + az * rz > 0.0
        acx, acy, acz = acx + ax, acy + ay, acz + az
        j = i + 1 if i + 1 < count else 0
        gx, gy, gz = points[j, 0] - x[0], points[j, 1] - x[1], points[j, 2] - x[2]
        mx, my, mz = gy * az - gz * ay, gz * ax - gx * az, gx * ay - gy * ax  # a_{i+1} x a_i
        ml = math.sqrt(mx * mx + my * my + mz * mz)
        if ml > 0.0:
            mx, my, mz = mx / ml, my / ml, mz / ml
        m[i, 0], m[i, 1], m[i, 2] = mx, my, mz
        pm[i] = mx * rx + my * ry + mz * rz
        pos = pos and pm[i] >= 0.0
        neg = neg and pm[i] <= 0.0
    if not ahead:
        return 0.0  # entirely at theta >= pi / 2 from r
    # the vertices' azimuths about r, from the centroid's: between two neighbours every
    # azimuth's interval is bounded by the same edges (a smooth integrand), so each such
    # sector gets its own rule; when r (or -r) lies inside, every azimuth crosses the
    # polygon and the last sector wraps round
    ref = math.atan2(acx * bx + acy * by + acz * bz, acx * tx + acy * ty + acz * tz)
    for i in range(count):
        ax, ay, az = points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2]
        d = math.atan2(ax * bx + ay * by + az * bz, ax * tx + ay * ty + az * tz) - ref
        azimuth[i] = d - 2.0 * math.pi * math.floor((d + math.pi) / (2.0 * math.pi))
    for i in range(1, count):  # insertion sort (at most 8)
        v = azimuth[i]
        j = i - 1
        while j >= 0 and azimuth[j] > v:
            azimuth[j + 1] = azimuth[j]
            j -= 1
        azimuth[j + 1] = v
    sectors = count - 1
    if pos or neg:
        azimuth[count] = azimuth[0] + 2.0 * math.pi
        sectors = count
    total = 0.0
    for sector in range(sectors):
        half = 0.5 * (azimuth[sector + 1] - azimuth[sector])
        if not half > 0.0:
            continue
        mid = ref + 0.5 * (azimuth[sector + 1] + azimuth[sector])
        for k in range(rule_s.shape[0]):
            phi = mid + half * rule_s[k]
            cp, sp = math.cos(phi), math.sin(phi)
            dx, dy, dz = cp * tx + sp * bx, cp * ty + sp * by, cp * tz + sp * bz
            # each edge keeps the thetas in [0, pi/2] where cos(t) (r . m) + sin(t) (d . m) >= 0:
            # one interval, as its zeros are pi apart
            lo = 0.0
            hi = HALF_PI
            for i in range(count):
                p_ = pm[i]
                q_ = dx * m[i, 0] + dy * m[i, 1] + dz * m[i, 2]
                if p_ >= 0.0 and q_ >= 0.0:
                    continue
                if p_ < 0.0 and q_ < 0.0:
                    hi = -1.0
                    break
                if p_ >= 0.0:
                    hi = min(hi, math.atan2(p_, -q_))
                else:
                    lo = max(lo, math.atan2(-p_, q_))
            if hi > lo:
                total += rule_w[k] * half * _slice(lo, hi, p1, rn, cp * tn + sp * bn)
    return total / p1


@numba.njit(cache=True, nogil=True, inline="always")
def spot_falloff(theta, cutoff, beam):
    """Mitsuba 3's spot profile (``spot.cpp``, ``falloff_curve``) at the angle theta
    from the spot's axis, its cutoff and beam width (all radians): 0 at and beyond the
    cutoff, 1 within the beam, (cutoff - theta) / (cutoff - beam) between. (Mitsuba
    compares cosines, cos theta > cos(cutoff) and cos theta >= cos(beam): the same
    tests; the angles, from ``spot_angle``, keep single precision exact near the axis.)"""
    if not theta < cutoff:
        return 0.0
    if theta <= beam:
        return 1.0
    return (cutoff - theta) / (cutoff - beam)


@numba.njit(cache=True, nogil=True, inline="always")
def spot_angle(wx, wy, wz, ax, ay, az):
    """The angle (radians) between unit vectors w and a: atan2(|w x a|, w . a), exact
    at small angles where acos(w . a) is not."""
    cx, cy, cz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), wx * ax + wy * ay + wz * az)


@numba.njit(cache=True, nogil=True, inline="always")
def delta_incidence(kind, points, x):
    """Where a delta part's light comes from at point x: (unit direction wi toward it
    (3-tuple), the distance (infinite for a direction; 0: unusable), the factor its
    Le is weighted by: 1 / d^2 times the spot's profile toward x for a point, 1 for a
    direction). ``points``: the part's rows of ``PackedParts.points``."""
    if kind == DIRECTION:
        return (-points[0, 0], -points[0, 1], -points[0, 2]), math.inf, 1.0
    dx, dy, dz = points[0, 0] - x[0], points[0, 1] - x[1], points[0, 2] - x[2]
    d2 = dx * dx + dy * dy + dz * dz
    if not d2 > 0.0:
        return (0.0, 0.0, 1.0), 0.0, 0.0
    dist = math.sqrt(d2)
    wx, wy, wz = dx / dist, dy / dist, dz / dist
    scale = 1.0 / d2
    if points[2, 2] > 0.0:  # a spot: its profile toward x, at -wi from its axis
        scale *= spot_falloff(spot_angle(-wx, -wy, -wz, points[1, 0], points[1, 1], points[1, 2]), points[2, 0], points[2, 1])
    return (wx, wy, wz), dist, scale


@numba.njit(cache=True, nogil=True)
def delta_integral(kind, points, x, n, r, exponent):
    """J of a delta part (POINT or DIRECTION, its rows ``points`` of ``PackedParts``) at
    point x (unit normal n, unit mirror direction r): max(0, wi . r)^p max(0, wi . n)
    times ``delta_incidence``'s factor, exact."""
    (wx, wy, wz), dist, scale = delta_incidence(kind, points, x)
    if not (dist > 0.0 and scale > 0.0):
        return 0.0
    cos_n = wx * n[0] + wy * n[1] + wz * n[2]
    cos_a = wx * r[0] + wy * r[1] + wz * r[2]
    if not (cos_n > 0.0 and cos_a > 0.0):
        return 0.0
    return scale * cos_n * min(cos_a, 1.0) ** exponent


@numba.njit(cache=True, nogil=True)
def highlight_integral(kind, count, points, radius, where, exponent, rule):
    """J (see the module's docstring) of one part (a row of ``PackedParts``: kind,
    vertex count, points, radius) at where = (point x, unit shading normal n, unit
    mirror direction r); exponent p >= 0; ``rule`` : ``Rules``. Returns J >= 0. (No
    culling: ``_culled`` is the displays' and the solver's test of a negligible part.)"""
    x, n, r = where
    if kind >= POINT:
        return delta_integral(kind, points, x, n, r, exponent)
    if kind == SPHERE:
        return sphere_integral(points[0], radius, x, n, r, exponent, rule.sphere_s, rule.sphere_w)
    return polygon_integral(count, points, x, n, r, exponent, rule.sector_s, rule.sector_w)


@numba.njit(cache=True, nogil=True, inline="always")
def _culled(bound_centre, bound_radius, x, r, exponent):
    """True where the lobe about r is below CULL of its peak over the whole bounding
    sphere of a part (its reflection is negligible: 0 by definition)."""
    cx, cy, cz = bound_centre[0] - x[0], bound_centre[1] - x[1], bound_centre[2] - x[2]
    dist = math.sqrt(cx * cx + cy * cy + cz * cz)
    if not dist > bound_radius:
        return False
    qx, qy, qz = r[1] * cz - r[2] * cy, r[2] * cx - r[0] * cz, r[0] * cy - r[1] * cx
    gamma = math.atan2(math.sqrt(qx * qx + qy * qy + qz * qz), r[0] * cx + r[1] * cy + r[2] * cz)
    nearest = gamma - math.asin(bound_radius / dist)
    return nearest > 0.0 and _lobe_cdf(nearest, exponent) < CULL


@numba.njit(cache=True, nogil=True, inline="always")
def _point_radiance(pk, visibility, own, where, material, rule):
    """E (3-tuple) at where = (point x, unit normal n, unit view w), with visibility[i]
    of part i; pk : ``PackedParts.arrays()``; material = (ks, exponent, f0, fresnel,
    code, alpha, table): with ``fresnel`` ks is weighted by Schlick's F(w.n)
    (``emitter_radiance``); code: the lobe's (``ltc.LOBES``; 0: the modified-Phong
    lobe of ``exponent``, else a microfacet lobe of roughness alpha, ``ltc.table()``)."""
    if material[4] != ltc.PHONG:
        return _microfacet_radiance(pk, visibility, own, where, material)
    kinds, counts, points, radius, bound_centre, bound_radius, radiance = pk
    ks, exponent, f0, fresnel = material[0], material[1], material[2], material[3]
    x, n, w = where
    wn = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
    k0, k1, k2 = ks[0], ks[1], ks[2]
    if fresnel:
        x5 = (1.0 - min(max(wn, 0.0), 1.0)) ** 5
        k0, k1, k2 = k0 * (f0[0] + (1.0 - f0[0]) * x5), k1 * (f0[1] + (1.0 - f0[1]) * x5), k2 * (f0[2] + (1.0 - f0[2]) * x5)
    rx, ry, rz = 2.0 * wn * n[0] - w[0], 2.0 * wn * n[1] - w[1], 2.0 * wn * n[2] - w[2]
    rl = math.sqrt(rx * rx + ry * ry + rz * rz)
    e0 = e1 = e2 = 0.0
    if not rl > 0.0:
        return e0, e1, e2
    r = (rx / rl, ry / rl, rz / rl)
    norm = (exponent + 2.0) / (2.0 * math.pi)
    for i in range(kinds.shape[0]):
        v = visibility[i]
        if own[i] or not v > 0.0 or (kinds[i] < POINT and _culled(bound_centre[i], bound_radius[i], x, r, exponent)):
            continue
        j = highlight_integral(kinds[i], counts[i], points[i], radius[i], (x, n, r), exponent, rule) * norm * v
        e0 += j * k0 * radiance[i, 0]
        e1 += j * k1 * radiance[i, 1]
        e2 += j * k2 * radiance[i, 2]
    return e0, e1, e2


@numba.njit(cache=True, nogil=True)
def _microfacet_radiance(pk, visibility, own, where, material):
    """``_point_radiance`` of a microfacet lobe (``radiosity.physics.ltc``): an area
    part's integral by linearly transformed cosines with Schlick's curve through f0
    integrated over the lobe, a delta part's the lobe at its direction with F(wi . h);
    ks the interface's specular reflectance. An area part is culled by ``ltc.culled``."""
    kinds, counts, points, radius, bound_centre, bound_radius, radiance = pk
    ks, f0, code, alpha, table = material[0], material[2], material[4], material[5], material[6]
    x, n, w = where
    wn = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
    e0 = e1 = e2 = 0.0
    if not wn > 0.0:
        return e0, e1, e2
    cell = ltc.cell(table, code, alpha, wn)
    k = (cell[0], cell[1], cell[2], cell[3])
    a0, a1, a2 = (ks[0] * (f0[0] * cell[4] + (1.0 - f0[0]) * cell[5]), ks[1] * (f0[1] * cell[4] + (1.0 - f0[1]) * cell[5]),
                  ks[2] * (f0[2] * cell[4] + (1.0 - f0[2]) * cell[5]))
    t, b = ltc.view_frame(n, w)
    frame = (t, b, (n[0], n[1], n[2]))
    r = (2.0 * wn * n[0] - w[0], 2.0 * wn * n[1] - w[1], 2.0 * wn * n[2] - w[2])
    local = np.empty((ltc.MAX_VERTICES, 3))
    for i in range(kinds.shape[0]):
        v = visibility[i]
        if own[i] or not v > 0.0 or (kinds[i] < POINT and ltc.culled(code, alpha, bound_centre[i], bound_radius[i], x, n, r)):
            continue
        if kinds[i] >= POINT:
            wi, dist, scale = delta_incidence(kinds[i], points[i], x)
            if not (dist > 0.0 and scale > 0.0):
                continue
            value, cih = ltc.lobe_value(code, alpha, wi, w, n)
            s = value * scale * v
            x5 = (1.0 - min(max(cih, 0.0), 1.0)) ** 5
            e0 += s * ks[0] * (f0[0] + (1.0 - f0[0]) * x5) * radiance[i, 0]
            e1 += s * ks[1] * (f0[1] + (1.0 - f0[1]) * x5) * radiance[i, 1]
            e2 += s * ks[2] * (f0[2] + (1.0 - f0[2]) * x5) * radiance[i, 2]
            continue
        if kinds[i] == SPHERE:
            count = ltc.sphere_local(points[i, 0], radius[i], x, frame, local)
        else:
            count = ltc.polygon_local(counts[i], points[i], x, frame, local)
        j = ltc.fan_integral(local, count, k, alpha, code, wn, cell[4]) * v if count else 0.0
        e0 += j * a0 * radiance[i, 0]
        e1 += j * a1 * radiance[i, 1]
        e2 += j * a2 * radiance[i, 2]
    return e0, e1, e2


ROWS = 256  # queries of one task of ``_radiance_many``


@numba.njit(cache=True, nogil=True)
def _radiance_rows(pk, visibility, own, queries, material, rule, out, rows):
    """out[q] = E at queries q = rows[0] .. rows[1] - 1 (``emitter_radiance``): queries
    = (positions, normals, views), material = (ks, exponent, f0, fresnel)."""
    positions, normals, views = queries
    for q in range(rows[0], rows[1]):
        x = (positions[q, 0], positions[q, 1], positions[q, 2])
        n = (normals[q, 0], normals[q, 1], normals[q, 2])
        w = (views[q, 0], views[q, 1], views[q, 2])
        out[q, 0], out[q, 1], out[q, 2] = _point_radiance(pk, visibility[q], own, (x, n, w), material, rule)


@numba.njit(cache=True, nogil=True, parallel=True)
def _radiance_many(pk, visibility, own, queries, material, rule, out):
    """``_radiance_rows`` of every query, ROWS at a time in parallel."""
    count = out.shape[0]
    for task in numba.prange((count + ROWS - 1) // ROWS):
        _radiance_rows(pk, visibility, own, queries, material, rule, out, (task * ROWS, min(count, (task + 1) * ROWS)))


@numba.njit(cache=True, nogil=True)
def _vertex_grid(pk, visibility, own, frame, directions, material, rule, out):
    """out[d] = E at one vertex, frame = (position, unit normal, unit tangent) as
    3-tuples, seen from each local direction d (x tangent, y bitangent, z normal)."""
    x, (nx, ny, nz), (tx, ty, tz) = frame
    bx, by, bz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    for d in range(directions.shape[0]):
        a, b, c = directions[d, 0], directions[d, 1], directions[d, 2]
        wx, wy, wz = a * tx + b * bx + c * nx, a * ty + b * by + c * ny, a * tz + b * bz + c * nz
        wl = math.sqrt(wx * wx + wy * wy + wz * wz)
        out[d, 0], out[d, 1], out[d, 2] = _point_radiance(
            pk, visibility, own, (x, (nx, ny, nz), (wx / wl, wy / wl, wz / wl)), material, rule
        )


@numba.njit(cache=True, nogil=True, parallel=True)
def _radiance_grid(pk, visibility, own, frames, directions, material, rule, out):
    """out[v, d] = E at vertex v seen from its local direction d (``emitter_grid``):
    frames = (positions, normals, tangents), material = (ks, exponent, f0, fresnel)."""
    positions, normals, tangents = frames
    for v in numba.prange(positions.shape[0]):
        frame = (
            (positions[v, 0], positions[v, 1], positions[v, 2]),
            (normals[v, 0], normals[v, 1], normals[v, 2]),
            (tangents[v, 0], tangents[v, 1], tangents[v, 2]),
        )
        _vertex_grid(pk, visibility[v], own, frame, directions, material, rule, out[v])


def _prepare(parts, source, count, visibility):
    packed = parts if isinstance(parts, PackedParts) else PackedParts(parts)
    own = np.array([source is not None and name == source for name in packed.sources], dtype=np.bool_)
    if visibility is None:
        visibility = np.ones((count, len(packed)))
    visibility = np.ascontiguousarray(np.broadcast_to(np.asarray(visibility, np.float64), (count, len(packed))))
    return packed, own, visibility


_NO_TABLE = np.zeros((2, 2, 2, 6))  # a Phong lobe's: the kernels' types stay one


def _material(ks, exponent, fresnel, microfacet):
    """The kernels' material tuple (``_point_radiance``): of the Phong lobe (ks,
    exponent, Schlick's F0 or None), or of ``microfacet`` (a ``Microfacet`` or its dict:
    its own lobe, specular reflectance and normal reflectance; the others ignored)."""
    if microfacet is not None:
        lobe = ltc.highlight_lobe(microfacet)
        return lobe.ks, 0.0, lobe.f0, True, lobe.code, lobe.alpha, ltc.table()
    f0 = np.zeros(3) if fresnel is None else np.asarray(fresnel, np.float64).reshape(3)
    return (np.asarray(ks, np.float64).reshape(3), float(exponent), f0, fresnel is not None, ltc.PHONG, 0.0, _NO_TABLE)


def emitter_radiance(parts, positions, normals, views, ks, exponent, *, visibility=None, nodes=DEFAULT_NODES, source=None,
                     fresnel=None, microfacet=None):
    """E (Q, 3) float64: the glossy reflection of the emitter ``parts`` (a sequence of
    ``EmitterPart`` or a ``PackedParts``) at Q points.

    positions, normals : (Q, 3) world space (normals unit); views : (Q, 3) unit, towards
    the eye; ks : (3,) and exponent p: the surface's modified-Phong specular part;
    visibility : (Q, P) fraction of each part seen (None: all seen); nodes : N of the
    rules; source : the object's own name (its own parts are not reflected);
    fresnel : None, or the surface's Schlick F0 (3,): ks is then weighted by F(w.n), F
    at the highlight's own direction (the mirror of w, where wi.h = w.n);
    microfacet : None, or a ``Microfacet`` (or its dict) whose own lobe reflects the
    parts (``radiosity.physics.ltc``; ks, exponent and fresnel are then its own).
    """
    positions = np.ascontiguousarray(positions, np.float64).reshape(-1, 3)
    q = len(positions)
    packed, own, visibility = _prepare(parts, source, q, visibility)
    out = np.zeros((q, 3))
    material = _material(ks, exponent, fresnel, microfacet)
    if len(packed) and q and np.any(material[0] > 0):
        queries = (
            positions,
            np.ascontiguousarray(normals, np.float64).reshape(-1, 3),
            np.ascontiguousarray(views, np.float64).reshape(-1, 3),
        )
        _radiance_many(packed.arrays(), visibility, own, queries, material, rules(nodes), out)
    return out


def emitter_grid(parts, positions, normals, tangents, directions, ks, exponent, *, visibility=None, nodes=DEFAULT_NODES,
                 source=None, fresnel=None, microfacet=None):
    """E (V, D, 3) float64 at every vertex (positions, unit normals, unit tangents (V, 3))
    seen from every local direction (D, 3) of the solution's grid (x tangent, y
    bitangent = normal x tangent, z normal); the other arguments as ``emitter_radiance``."""
    positions = np.ascontiguousarray(positions, np.float64).reshape(-1, 3)
    directions = np.ascontiguousarray(directions, np.float64).reshape(-1, 3)
    v = len(positions)
    packed, own, visibility = _prepare(parts, source, v, visibility)
    out = np.zeros((v, len(directions), 3))
    material = _material(ks, exponent, fresnel, microfacet)
    if len(packed) and v and np.any(material[0] > 0):
        frames = (
            positions,
            np.ascontiguousarray(normals, np.float64).reshape(-1, 3),
            np.ascontiguousarray(tangents, np.float64).reshape(-1, 3),
        )
        _radiance_grid(packed.arrays(), visibility, own, frames, directions, material, rules(nodes), out)
    return out
