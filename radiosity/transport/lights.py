"""Delta lights in the transport kernels: points (with an optional spot profile) and
directions (``Scene.lights``, ``radiosity.physics.emitters`` parts of kind "point" and
"direction"). Nothing can hit them: they light the scene through their photons and
through next-event estimates (the gather's at glossy hits of its paths, the path
tracer's at every hit), and the solver adds their direct glossy highlights in closed
form (``transport.highlights``).

    light_arrays   the ``records.LightArrays`` of a scene's lights (``no_lights``: none)
    emit_delta     a photon from light j: where it starts, where it goes, its power
    pick_light     light j of a uniform number, by power
    arriving       the light from light j at a point: direction, distance, RGB

A point emits from its position, uniformly over the sphere, or, outside the scene's
bounding sphere (a lamp by the camera, a street light), uniformly over the cone that
holds that sphere (``reach``: the rest of its light leaves the scene without meeting
anything, and counts as escaped at once, ``unreached``); a spot uniformly over its
cone, each photon weighted by the profile there; a direction from a uniform point of
the disk of the scene's bounding sphere facing it, as the environment's photons do.
Each photon carries its light's share of the pass's power, so a pass's photons sum to
the power the lights send into the scene in expectation (``photon_power``; ``power``
is all they emit: 4 pi I for a point, I times the profile's solid angle for a spot,
E pi R^2 for a direction through the disk of radius R). Lights are chosen by that
power, for their photons and their light samples alike.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.cdf import search_cdf
from radiosity.physics.emitters import DIRECTION, PackedParts, delta_incidence, spot_falloff
from radiosity.scene.material_kernels import onb
from radiosity.transport.records import LightArrays
from radiosity.transport.sampling import cosine_direction

__all__ = ["arriving", "emit_delta", "light_arrays", "no_lights", "photon_power", "pick_light", "power", "reach",
           "unreached"]

WHOLE_SPHERE = (0.0, 0.0, 1.0, -1.0)  # a cone of every direction


def power(lights, radius):
    """The RGB power (3,) float64 of ``lights`` (delta ``EmitterPart`` s), a direction's
    through the disk of ``radius``."""
    return sum((light.power(radius) for light in lights), np.zeros(3))


def reach(light, center, radius):
    """(axis x, y, z, cos of the half-angle): the cone a point light (no spot) sends its
    photons into, the one that holds the bounding sphere (center, radius) from outside
    it, else every direction (``WHOLE_SPHERE``, as for a spot or a direction)."""
    if light.kind != "point" or light.spot is not None:
        return WHOLE_SPHERE
    to = np.asarray(center, np.float64) - light.points[0]
    distance = float(np.linalg.norm(to))
    if not distance > radius * (1 + 1e-6):
        return WHOLE_SPHERE
    return (*(to / distance), math.sqrt(1.0 - (radius / distance) ** 2))


def photon_power(light, center, radius):
    """The RGB power (3,) float64 ``light`` sends into the bounding sphere (center,
    radius), as its photons carry it: I 2 pi (1 - cos) over a point's ``reach``, else
    all of it (``EmitterPart.power``)."""
    cone = reach(light, center, radius)
    if cone[3] == -1.0:
        return light.power(radius)
    return light.radiance * 2 * math.pi * (1 - cone[3])


def unreached(lights, center, radius):
    """The RGB power (3,) float64 of ``lights`` their photons do not carry: it leaves the
    scene without meeting it (``reach``)."""
    return sum((light.power(radius) - photon_power(light, center, radius) for light in lights), np.zeros(3))


def no_lights():
    """``LightArrays`` of a scene without delta lights (never picked)."""
    return LightArrays(np.zeros(0, np.int64), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 4)), np.zeros(0),
                       np.zeros(0), 0.0, 0.0, False, np.zeros(3), 0.0)


def light_arrays(lights, center, radius, photon_share, light_share, only):
    """``LightArrays`` of ``lights`` (delta ``EmitterPart`` s, at least one) in a scene
    whose bounding sphere is (center, radius): each chosen in proportion to the power
    it sends into the scene (``photon_power``, the sum of its RGB), photons with
    probability ``photon_share`` and the path tracer's light samples with
    ``light_share``; ``only``: the scene has no emitting triangle."""
    packed = PackedParts(lights)
    weights = np.array([float(photon_power(light, center, radius).sum()) for light in lights])
    if not weights.sum() > 0:
        weights = np.ones(len(lights))  # all black: any will do, each brings nothing
    pick = weights / weights.sum()
    cdf = np.cumsum(pick)
    cdf[-1] = 1.0
    cones = np.array([reach(light, center, radius) for light in lights], np.float64).reshape(len(lights), 4)
    return LightArrays(
        packed.kinds.copy(), np.ascontiguousarray(packed.points[:, :3]), packed.radiance.copy(), cones, cdf, pick,
        float(photon_share), float(light_share), bool(only), np.asarray(center, np.float64).reshape(3), float(radius),
    )  # fmt: skip


@numba.njit(cache=True, nogil=True, inline="always")
def pick_light(cdf, u):
    """The light whose slot of ``cdf`` holds the uniform number u."""
    return min(search_cdf(cdf, u), len(cdf) - 1)


@numba.njit(cache=True, nogil=True, inline="always")
def emit_delta(lights, j, rnd, weight):
    """A photon of light j of ``lights`` (``LightArrays``) from the uniform numbers rnd
    = (u1, u2): (origin (3-tuple), unit direction, power (RGB 3-tuple)); ``weight`` is
    1 / (photons of the pass * the probability that this photon is light j's)."""
    kind = lights.kinds[j]
    q = lights.points[j]
    value = lights.values[j]
    if kind == DIRECTION:
        dx, dy, dz = q[0, 0], q[0, 1], q[0, 2]
        ox, oy, _ = cosine_direction(rnd[0], rnd[1])  # a uniform point of the unit disk
        tx, ty, tz, bx, by, bz = onb(dx, dy, dz)
        r, c = lights.radius, lights.center
        origin = (c[0] + r * (ox * tx + oy * bx - dx), c[1] + r * (ox * ty + oy * by - dy),
                  c[2] + r * (ox * tz + oy * bz - dz))  # fmt: skip
        scale = math.pi * r * r * weight
        return origin, (dx, dy, dz), (value[0] * scale, value[1] * scale, value[2] * scale)
    origin = (q[0, 0], q[0, 1], q[0, 2])
    phi = 2.0 * math.pi * rnd[1]
    if q[2, 2] > 0.0:  # a spot: uniform over its cone, weighted by the profile
        cos_cut = math.cos(q[2, 0])
        cos_t = 1.0 - rnd[0] * (1.0 - cos_cut)
        ax, ay, az = q[1, 0], q[1, 1], q[1, 2]
        solid = 2.0 * math.pi * (1.0 - cos_cut)
        falloff = spot_falloff(math.acos(cos_t), q[2, 0], q[2, 1])
    else:  # uniform over the cone that holds the scene (every direction from inside it)
        cone = lights.cones[j]
        cos_t = 1.0 - rnd[0] * (1.0 - cone[3])
        ax, ay, az = cone[0], cone[1], cone[2]
        solid = 2.0 * math.pi * (1.0 - cone[3])
        falloff = 1.0
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    tx, ty, tz, bx, by, bz = onb(ax, ay, az)
    lx, ly = sin_t * math.cos(phi), sin_t * math.sin(phi)
    direction = (lx * tx + ly * bx + cos_t * ax, lx * ty + ly * by + cos_t * ay, lx * tz + ly * bz + cos_t * az)
    scale = solid * falloff * weight
    return origin, direction, (value[0] * scale, value[1] * scale, value[2] * scale)


@numba.njit(cache=True, nogil=True, inline="always")
def arriving(lights, j, x):
    """The light of light j of ``lights`` arriving at point x (3-tuple): (unit direction
    toward it, its distance (infinite for a direction; 0: none arrives), the RGB
    irradiance on a surface facing it: I profile / d^2, or E)."""
    wi, dist, scale = delta_incidence(lights.kinds[j], lights.points[j], x)
    value = lights.values[j]
    return wi, dist, (value[0] * scale, value[1] * scale, value[2] * scale)
