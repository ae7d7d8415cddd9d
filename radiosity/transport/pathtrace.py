"""A path tracer: the ground truth the walkthrough is measured against.

Unidirectional paths from a pinhole camera (``radiosity.files.camera``), next-event estimation on the
emitters and the environment (``radiosity.physics.environment``) combined with BRDF sampling by multiple importance sampling (power
heuristic), and on the delta lights (``radiosity.transport.lights``: points, spots,
directions, which no ray can hit, so their estimate is unweighted), Russian roulette from bounce ``ROULETTE_DEPTH`` on, a box pixel filter
(uniform positions inside the pixel). It reads the same merged scene arrays, BRDF
(``materials``: eval, sample, pdf), Embree wrapper and counter-based random numbers
as the solver, so both see the same scene the same way: one-sided surfaces (backs
absorb and do not emit) but glass, which reflects and refracts on both faces, interpolated shading normals, light that must leave above
both the shading and the true surface.

Work is split into tiles: a run of pixels (row-major) and a run of sample numbers.
Every random number is keyed by (seed, sample number * pixels + pixel, dimension),
so an image depends on the seed and the sample count alone: not on tiles, threads
or passes. A tile is one jitted call that releases the GIL and traces its own rays,
calling Embree directly (``trace_paths``), wavefront-style inside (a loop traces the
paths in flight, a kernel shades their hits and makes the next rays and shadow
rays); a tile per thread, their pixel sums added in tile order.

Rendering is progressive: passes of 1, 1, 2, 4, ... samples per pixel (at most
``MAX_PASS_SAMPLES``), each adding to the running sums; a callback sees the image
after every pass.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.files.errors import InputError
from radiosity.physics.environment import Environment, env_lookup, env_pdf, env_sample
from radiosity.physics.materials import Material
from radiosity.policies.limits import check_seed
from radiosity.scene.columns import KIND, KIND_DIELECTRIC
from radiosity.scene.material_kernels import EMISSION, KD, KS, NCOL, brdf_eval, brdf_pdf, brdf_sample, onb, textured_row
from radiosity.scene.model import Scene, SceneObject
from radiosity.transport.batches import scene_arrays
from radiosity.transport.embree import (
    Hits,
    RayTracer,
    default_threads,
    empty_hits,
    head_hits,
    intersect_rays,
    occluded_rays,
)
from radiosity.transport.lights import arriving, pick_light
from radiosity.transport.rng import STREAM_CAMERA, STREAM_PATH, rand
from radiosity.transport.sampling import (
    barycentric_point,
    glass_bounce,
    hit_texel,
    off_surface,
    pick_emitter,
    roulette,
    shading_normal,
    toward_light_point,
)
from radiosity.transport.threads import Workers, progress_bar, run_ordered

DIMS_PER_BOUNCE = 8  # light pick (1), point on the light (2), BRDF sample (3), roulette (1), spare (1)
MAX_DEPTH = 64  # segments of a path at most; Russian roulette ends nearly all far sooner
ROULETTE_DEPTH = 3  # the first bounce Russian roulette may refuse (the ones before always go on)
TILE_PATHS = 1 << 16  # paths of a tile, about
MIN_TILES = 8  # tiles of a pass at least, so that every thread has work (not a function of threads)
MAX_PASS_SAMPLES = 16  # samples per pixel of one progressive pass, at most
MAX_SPP = 1 << 20


def check_samples(value, flag="--spp", low=1):
    """Refuse (InputError) a sample count that is not a whole number from ``low`` to MAX_SPP."""
    if not (isinstance(value, int | np.integer) and low <= value <= MAX_SPP):
        raise InputError(f"{flag} must be a whole number from {low} to {MAX_SPP:,}, got {value}")


class CameraRays(NamedTuple):
    """A pinhole camera as the kernel reads it: a ray through image point (sx, sy) in
    [-1, 1]^2 (x right, y up) has direction forward + sx * right + sy * up.

    eye, right, up, forward : (3,) float64 (right and up scaled by the half-extents
    of the image plane at distance 1)
    """

    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray


def camera_rays(camera):
    """``CameraRays`` of a ``files.camera.Camera``."""
    right, up, forward = camera.basis
    half_height = math.tan(math.radians(camera.fov_y_deg) / 2)
    half_width = half_height * camera.width / camera.height
    return CameraRays(np.asarray(camera.eye, np.float64), right * half_width, up * half_height, forward)


class Tile(NamedTuple):
    """Pixels first_pixel .. first_pixel + pixels - 1 (row-major) of a width x height
    image, samples first_sample .. first_sample + samples - 1 of each. Path k of the
    tile is pixel first_pixel + k % pixels, sample first_sample + k // pixels."""

    seed: int
    first_pixel: int
    pixels: int
    first_sample: int
    samples: int
    width: int
    height: int


class Paths(NamedTuple):
    """Paths in flight.

    ids        : (R,) int64      path index within the tile
    throughput : (R, 3) float64
    origins    : (R, 3) float32  already offset off the surface they leave
    directions : (R, 3) float32  unit
    last_pdf   : (R,) float64    solid-angle density of the BRDF sample that made this
                                 segment; 0 for a camera ray (emission seen by it counts in full)
    """

    ids: np.ndarray
    throughput: np.ndarray
    origins: np.ndarray
    directions: np.ndarray
    last_pdf: np.ndarray


def empty_paths(count):
    return Paths(
        ids=np.empty(count, np.int64),
        throughput=np.empty((count, 3)),
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        last_pdf=np.empty(count),
    )


class ShadowRays(NamedTuple):
    """Next-event estimates waiting for their shadow ray.

    ids        : (S,) int64     path index within the tile
    origins    : (S, 3) float32
    directions : (S, 3) float32 unit, toward the sampled point on a light
    distances  : (S,) float32   to that point (offset off the light)
    values     : (S, 3) float64 what the path gains if the point is visible
    """

    ids: np.ndarray
    origins: np.ndarray
    directions: np.ndarray
    distances: np.ndarray
    values: np.ndarray


def empty_shadow_rays(count):
    return ShadowRays(
        ids=np.empty(count, np.int64),
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        distances=np.empty(count, np.float32),
        values=np.empty((count, 3)),
    )


class TileBuffers(NamedTuple):
    """The buffers a tile's paths swap between, one row per path: the paths in flight
    and those going on (``Paths``), the light samples waiting for their shadow rays
    (``ShadowRays``), where the paths in flight landed (``embree.Hits``) and which
    shadow rays were blocked ((count,) bool)."""

    paths: Paths
    spare: Paths
    shadow: ShadowRays
    hits: Hits
    blocked: np.ndarray


def empty_tile_buffers(count):
    """``TileBuffers`` for ``count`` paths."""
    return TileBuffers(
        empty_paths(count), empty_paths(count), empty_shadow_rays(count), empty_hits(count), np.empty(count, dtype=bool)
    )


# -- kernels ------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _key(tile, k):
    """The random-number key of path k of a tile: sample * pixels of the image + pixel."""
    pixel = tile.first_pixel + k % tile.pixels
    sample = tile.first_sample + k // tile.pixels
    return sample * (tile.width * tile.height) + pixel


@numba.njit(cache=True, nogil=True)
def start_paths(cam, tile, out):
    """Camera rays of every path of ``tile`` into ``out`` (``Paths``): a uniform point
    inside the pixel (the box filter), throughput 1, last_pdf 0."""
    for k in range(tile.pixels * tile.samples):
        pixel = tile.first_pixel + k % tile.pixels
        key = _key(tile, k)
        px = pixel % tile.width
        py = pixel // tile.width
        sx = 2.0 * (px + rand(tile.seed, STREAM_CAMERA, key, 0)) / tile.width - 1.0
        sy = 1.0 - 2.0 * (py + rand(tile.seed, STREAM_CAMERA, key, 1)) / tile.height
        dx = cam.forward[0] + sx * cam.right[0] + sy * cam.up[0]
        dy = cam.forward[1] + sx * cam.right[1] + sy * cam.up[1]
        dz = cam.forward[2] + sx * cam.right[2] + sy * cam.up[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        out.ids[k] = k
        for c in range(3):
            out.origins[k, c] = cam.eye[c]
            out.throughput[k, c] = 1.0
        out.directions[k, 0] = dx / length
        out.directions[k, 1] = dy / length
        out.directions[k, 2] = dz / length
        out.last_pdf[k] = 0.0


@numba.njit(cache=True, nogil=True, inline="always")
def _in_frame(shading, dx, dy, dz):
    """Direction (dx, dy, dz) in the shading frame ``shading`` = (t, b, n), 9 floats."""
    tx, ty, tz, bx, by, bz, nx, ny, nz = shading
    return dx * tx + dy * ty + dz * tz, dx * bx + dy * by + dz * bz, dx * nx + dy * ny + dz * nz


@numba.njit(cache=True, nogil=True, inline="always")
def _light_sample(sa, point, g, shading, wo, mat, rnd, throughput):
    """Next-event estimate at ``point`` (front normal g, shading frame ``shading`` =
    (t, b, n) as a 9-tuple, outgoing ``wo`` local), with the uniform numbers rnd = (u0,
    u1, u2): the environment with probability ``sa.env.light_share``
    (``_environment_sample``), else a point on an emitter chosen in proportion to
    power, its contribution weighted by the power heuristic against BRDF sampling. Returns (whether it can
    contribute, the shadow ray's origin, direction and length, the RGB value it adds
    to the path where the ray reaches the light)."""
    nothing = (False, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    share = sa.env.light_share
    u0 = rnd[0]
    if u0 < share:
        return _environment_sample(sa.env, off_surface(point, g, sa.epsilon), g, shading, wo, mat, rnd, throughput)
    delta_share = sa.lights.light_share
    if delta_share > 0.0:
        if u0 < share + delta_share:
            return _delta_sample(sa, off_surface(point, g, sa.epsilon), g, shading, wo, mat,
                                 min((u0 - share) / delta_share, 1.0), throughput)
        u0 = (u0 - share - delta_share) / (1.0 - share - delta_share)
    elif share > 0.0:
        u0 = (u0 - share) / (1.0 - share)
    tri = pick_emitter(sa.emit_cdf, sa.emit_triangles, u0)
    area_pdf = sa.emit_area_pdf[tri]
    if area_pdf <= 0.0:
        return nothing
    origin = off_surface(point, g, sa.epsilon)
    (dx, dy, dz), dist, cos_light = toward_light_point(
        sa.positions, sa.faces, sa.face_normals, sa.epsilon, tri, origin, (rnd[1], rnd[2])
    )
    if dist <= 0.0:
        return nothing
    if cos_light <= 0.0 or dx * g[0] + dy * g[1] + dz * g[2] <= 0.0:
        return nothing
    wix, wiy, wiz = _in_frame(shading, dx, dy, dz)
    if wiz <= 0.0:
        return nothing
    p_light = area_pdf * dist * dist / cos_light
    if share > 0.0 or delta_share > 0.0:
        p_light *= 1.0 - share - delta_share
    p_brdf = brdf_pdf(mat, wo[0], wo[1], wo[2], wix, wiy, wiz)
    ratio = p_brdf / p_light
    weight = 1.0 / (1.0 + ratio * ratio)  # the power heuristic, written so that no square overflows
    f = brdf_eval(mat, wix, wiy, wiz, wo[0], wo[1], wo[2])
    le = sa.materials[sa.face_material[tri]]
    scale = weight * wiz / p_light
    value = (
        throughput[0] * f[0] * le[EMISSION] * scale,
        throughput[1] * f[1] * le[EMISSION + 1] * scale,
        throughput[2] * f[2] * le[EMISSION + 2] * scale,
    )
    return True, origin, (dx, dy, dz), dist, value


@numba.njit(cache=True, nogil=True, inline="always")
def _delta_sample(sa, origin, g, shading, wo, mat, u, throughput):
    """``_light_sample``'s estimate when it picks the delta lights (with probability
    sa.lights.light_share): one chosen by power with the uniform number u, its shadow
    ray from ``origin`` (off the surface) to it (``sa.epsilon`` short of a point), and
    f cos I profile / d^2 (E for a direction) over the probability of the choice."""
    nothing = (False, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    lights = sa.lights
    j = pick_light(lights.cdf, u)
    (dx, dy, dz), dist, le = arriving(lights, j, origin)
    if not (dist > sa.epsilon and max(le[0], le[1], le[2]) > 0.0) or dx * g[0] + dy * g[1] + dz * g[2] <= 0.0:
        return nothing
    wix, wiy, wiz = _in_frame(shading, dx, dy, dz)
    if wiz <= 0.0:
        return nothing
    f = brdf_eval(mat, wix, wiy, wiz, wo[0], wo[1], wo[2])
    scale = wiz / (lights.light_share * lights.pick[j])
    value = (
        throughput[0] * f[0] * le[0] * scale,
        throughput[1] * f[1] * le[1] * scale,
        throughput[2] * f[2] * le[2] * scale,
    )
    return True, origin, (dx, dy, dz), dist - sa.epsilon, value


@numba.njit(cache=True, nogil=True, inline="always")
def _environment_sample(env, origin, g, shading, wo, mat, rnd, throughput):
    """``_light_sample``'s estimate when it picks the environment (``env``:
    ``EnvArrays``, chosen with probability env.light_share): a direction drawn from it
    by (rnd[1], rnd[2]) (``environment.env_sample``), the shadow ray from ``origin``
    (off the surface) unbounded, weighted by the power heuristic against BRDF sampling."""
    nothing = (False, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))
    (dx, dy, dz), pdf = env_sample(env.rotation, env.row_cdf, env.column_cdf, env.cell_pdf, rnd[1], rnd[2])
    if pdf <= 0.0 or dx * g[0] + dy * g[1] + dz * g[2] <= 0.0:
        return nothing
    wix, wiy, wiz = _in_frame(shading, dx, dy, dz)
    if wiz <= 0.0:
        return nothing
    p_light = env.light_share * pdf
    p_brdf = brdf_pdf(mat, wo[0], wo[1], wo[2], wix, wiy, wiz)
    ratio = p_brdf / p_light
    weight = 1.0 / (1.0 + ratio * ratio)
    f = brdf_eval(mat, wix, wiy, wiz, wo[0], wo[1], wo[2])
    le = env_lookup(env.pixels, env.rotation, dx, dy, dz)
    scale = weight * wiz / p_light
    value = (
        throughput[0] * f[0] * le[0] * scale,
        throughput[1] * f[1] * le[1] * scale,
        throughput[2] * f[2] * le[2] * scale,
    )
    return True, origin, (dx, dy, dz), math.inf, value


@numba.njit(cache=True, nogil=True, inline="always")
def _escaped(env, paths, k, radiance):
    """Path k of ``paths`` left the scene: its path gains the environment's radiance
    along its direction, weighted by the power heuristic against the light sample its
    last vertex made (in full for a camera ray, or where the environment is not sampled)."""
    dx, dy, dz = np.float64(paths.directions[k, 0]), np.float64(paths.directions[k, 1]), np.float64(paths.directions[k, 2])
    le = env_lookup(env.pixels, env.rotation, dx, dy, dz)
    weight = 1.0
    p_brdf = paths.last_pdf[k]
    if p_brdf > 0.0 and env.light_share > 0.0:
        ratio = env.light_share * env_pdf(env.rotation, env.cell_pdf, dx, dy, dz) / p_brdf
        weight = 1.0 / (1.0 + ratio * ratio)
    path = paths.ids[k]
    for c in range(3):
        radiance[path, c] += weight * paths.throughput[k, c] * le[c]


@numba.njit(cache=True, nogil=True, inline="always")
def _through_glass(sa, tile, depth, at, mat, d, out, n_out):
    """Path k of ``at`` = (paths, hits, k) met glass (either face): it goes on reflected or refracted
    (``sampling.glass_bounce``, radiance's 1 / eta^2), with Russian roulette from bounce
    ROULETTE_DEPTH on; no light sample is made there, so an emitter it meets next counts
    in full (last_pdf 0). Returns the paths going on."""
    paths, hits, k = at
    path = paths.ids[k]
    key = _key(tile, path)
    base = depth * DIMS_PER_BOUNCE
    rnd = (rand(tile.seed, STREAM_PATH, key, base + 3), rand(tile.seed, STREAM_PATH, key, base + 4),
           rand(tile.seed, STREAM_PATH, key, base + 5))
    weight, origin, direction, _ = glass_bounce(
        (sa.positions, sa.normals, sa.faces, sa.face_normals), sa.epsilon, mat,
        (hits.triangle[k], np.float64(hits.u[k]), np.float64(hits.v[k])), d, rnd, True)
    carried = (paths.throughput[k, 0] * weight[0], paths.throughput[k, 1] * weight[1],
               paths.throughput[k, 2] * weight[2])
    if depth + 1 >= ROULETTE_DEPTH:
        survives, carried = roulette(carried, 1.0, rand(tile.seed, STREAM_PATH, key, base + 6))
        if not survives:
            return n_out
    if carried[0] <= 0.0 and carried[1] <= 0.0 and carried[2] <= 0.0:
        return n_out
    out.ids[n_out] = path
    for c in range(3):
        out.origins[n_out, c] = origin[c]
        out.directions[n_out, c] = direction[c]
        out.throughput[n_out, c] = carried[c]
    out.last_pdf[n_out] = 0.0
    return n_out + 1


@numba.njit(cache=True, nogil=True)
def shade(sa, tile, depth, paths, hits, radiance, shadow, out):
    """One bounce of the paths in flight; returns (shadow rays written, paths going on).

    paths : ``Paths`` at segment ``depth``; hits : their ``embree.Hits``;
    radiance : (tile paths, 3) float64, each path's radiance so far (emission seen is
    added here, light samples once their shadow rays are traced: ``add_visible``);
    shadow : ``ShadowRays`` receiving the light samples; out : ``Paths`` going on.

    At a front-facing hit: emission, weighted by the power heuristic against the light
    sample the previous vertex made (in full for camera rays); then, unless the path
    has reached MAX_DEPTH segments, one light sample and one BRDF sample (the path's
    bounce depth + 1), which from bounce ROULETTE_DEPTH on must survive Russian roulette
    on its throughput. Glass (either face) reflects or refracts the path on
(``_through_glass``). Other back faces end the path (backs absorb); so do misses, which
    see the environment (``_escaped``; the background is black without one). On a textured
    triangle the diffuse colour is kd * texture(uv at the hit) (``textured_row``), for
    the light sample, the BRDF sample and the roulette alike.
    """
    seed = tile.seed
    n_shadow = 0
    n_out = 0
    row = np.empty(NCOL)  # a textured hit's material row
    env = sa.env
    env_share = env.light_share
    delta_share = sa.lights.light_share
    for k in range(len(paths.ids)):
        t = hits.triangle[k]
        if t < 0:
            if env.active:
                _escaped(env, paths, k, radiance)
            continue
        d = (np.float64(paths.directions[k, 0]), np.float64(paths.directions[k, 1]), np.float64(paths.directions[k, 2]))
        g = sa.face_normals[t]
        mat = sa.materials[sa.face_material[t]]
        if mat[KIND] >= KIND_DIELECTRIC:
            if depth + 1 < MAX_DEPTH:
                n_out = _through_glass(sa, tile, depth, (paths, hits, k), mat, d, out, n_out)
            continue
        cos_in = -(d[0] * g[0] + d[1] * g[1] + d[2] * g[2])
        if cos_in <= 0.0:
            continue
        path = paths.ids[k]
        key = _key(tile, path)
        throughput = (paths.throughput[k, 0], paths.throughput[k, 1], paths.throughput[k, 2])
        emits = mat[EMISSION] > 0.0 or mat[EMISSION + 1] > 0.0 or mat[EMISSION + 2] > 0.0
        if emits:
            weight = 1.0
            p_brdf = paths.last_pdf[k]
            if p_brdf > 0.0:
                dist = np.float64(hits.t[k])
                ratio = sa.emit_area_pdf[t] * dist * dist / cos_in / p_brdf  # p_light / p_brdf
                if env_share > 0.0 or delta_share > 0.0:
                    ratio *= 1.0 - env_share - delta_share
                weight = 1.0 / (1.0 + ratio * ratio)
            for c in range(3):
                radiance[path, c] += weight * throughput[c] * mat[EMISSION + c]
        if depth + 1 >= MAX_DEPTH:
            continue
        if max(mat[KD], mat[KD + 1], mat[KD + 2], mat[KS], mat[KS + 1], mat[KS + 2]) <= 0.0:
            continue  # a pure emitter (or black): reflects nothing
        uk, vk = np.float64(hits.u[k]), np.float64(hits.v[k])
        texture = sa.face_texture[t]
        if texture >= 0:
            mat = textured_row(mat, hit_texel(sa, texture, t, uk, vk), row)
        point = barycentric_point(sa, t, uk, vk)
        nx, ny, nz = shading_normal(sa, t, uk, vk, d)
        tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
        wo = (
            -(d[0] * tx + d[1] * ty + d[2] * tz),
            -(d[0] * bx + d[1] * by + d[2] * bz),
            -(d[0] * nx + d[1] * ny + d[2] * nz),
        )
        base = depth * DIMS_PER_BOUNCE
        shading = (tx, ty, tz, bx, by, bz, nx, ny, nz)
        rnd = (rand(seed, STREAM_PATH, key, base), rand(seed, STREAM_PATH, key, base + 1), rand(seed, STREAM_PATH, key, base + 2))
        ok, origin, direction, dist, value = _light_sample(sa, point, g, shading, wo, mat, rnd, throughput)
        if ok:
            shadow.ids[n_shadow] = path
            shadow.distances[n_shadow] = dist
            for c in range(3):
                shadow.origins[n_shadow, c] = origin[c]
                shadow.directions[n_shadow, c] = direction[c]
                shadow.values[n_shadow, c] = value[c]
            n_shadow += 1
        wix, wiy, wiz, pdf = brdf_sample(
            mat, wo[0], wo[1], wo[2],
            rand(seed, STREAM_PATH, key, base + 3),
            rand(seed, STREAM_PATH, key, base + 4),
            rand(seed, STREAM_PATH, key, base + 5),
        )
        direction = (wix * tx + wiy * bx + wiz * nx, wix * ty + wiy * by + wiz * ny, wix * tz + wiy * bz + wiz * nz)
        if wiz <= 0.0 or pdf <= 0.0 or direction[0] * g[0] + direction[1] * g[1] + direction[2] * g[2] <= 0.0:
            continue  # below the shading or the true surface: absorbed
        f = brdf_eval(mat, wix, wiy, wiz, wo[0], wo[1], wo[2])
        scale = wiz / pdf
        carried = (throughput[0] * f[0] * scale, throughput[1] * f[1] * scale, throughput[2] * f[2] * scale)
        if depth + 1 >= ROULETTE_DEPTH:
            survives, carried = roulette(carried, 1.0, rand(seed, STREAM_PATH, key, base + 6))
            if not survives:
                continue
        if carried[0] <= 0.0 and carried[1] <= 0.0 and carried[2] <= 0.0:
            continue
        out.ids[n_out] = path
        for c in range(3):
            out.origins[n_out, c] = point[c] + sa.epsilon * g[c]
            out.directions[n_out, c] = direction[c]
            out.throughput[n_out, c] = carried[c]
        out.last_pdf[n_out] = pdf
        n_out += 1
    return n_shadow, n_out


@numba.njit(cache=True, nogil=True)
def add_visible(shadow, blocked, radiance):
    """Add the light samples whose shadow rays reached the light to their paths."""
    for s in range(len(blocked)):
        if not blocked[s]:
            path = shadow.ids[s]
            for c in range(3):
                radiance[path, c] += shadow.values[s, c]


@numba.njit(cache=True, nogil=True)
def pixel_sums(tile, radiance, total, squares):
    """Add every path's radiance (and its square) to its pixel, in sample order:
    total, squares : (tile.pixels, 3) float64."""
    for k in range(radiance.shape[0]):
        p = k % tile.pixels
        for c in range(3):
            x = radiance[k, c]
            total[p, c] += x
            squares[p, c] += x * x


@numba.njit(cache=True, nogil=True)
def _head_paths(paths, n):
    return Paths(paths.ids[:n], paths.throughput[:n], paths.origins[:n], paths.directions[:n], paths.last_pdf[:n])


@numba.njit(cache=True, nogil=True)
def _head_shadow(shadow, n):
    return ShadowRays(shadow.ids[:n], shadow.origins[:n], shadow.directions[:n], shadow.distances[:n], shadow.values[:n])


@numba.njit(cache=True, nogil=True)
def trace_paths(rt, sa, cam, tile, buffers, radiance):
    """Trace every path of ``tile`` to its end through the scene ``rt``
    (``embree.Embree``), adding each path's radiance to ``radiance`` (tile paths, 3).

    buffers : ``TileBuffers`` of the tile's path count. Per bounce: every path in flight
    traced, ``shade``, the light samples' shadow rays traced, ``add_visible``.
    Returns (rays traced, of which shadow rays).
    """
    paths, spare, shadow, hits, blocked = buffers
    n = tile.pixels * tile.samples
    start_paths(cam, tile, paths)
    rays = 0
    shadow_rays = 0
    for depth in range(MAX_DEPTH):
        if n == 0:
            break
        intersect_rays(rt, paths.origins, paths.directions, hits, 0, n)
        live = _head_paths(paths, n)
        rays += n
        n_shadow, n = shade(sa, tile, depth, live, head_hits(hits, n), radiance, shadow, spare)
        if n_shadow:
            occluded_rays(rt, shadow.origins, shadow.directions, shadow.distances, blocked, 0, n_shadow)
            add_visible(_head_shadow(shadow, n_shadow), blocked[:n_shadow], radiance)
            rays += n_shadow
            shadow_rays += n_shadow
        paths, spare = spare, paths
    return rays, shadow_rays


# -- orchestration --------------------------------------------------------------------------


def trace_tile(tracer, sa, cam, tile):
    """Pixel sums of one tile: (tile, total (pixels, 3), squares (pixels, 3)) float64.
    Its rays are traced in one jitted call (``trace_paths``, which releases the GIL)
    and counted on ``tracer``."""
    n = tile.pixels * tile.samples
    radiance = np.zeros((n, 3))
    rays, shadow_rays = trace_paths(tracer.embree, sa, cam, tile, empty_tile_buffers(n), radiance)
    tracer.count(rays, shadow_rays)
    total = np.zeros((tile.pixels, 3))
    squares = np.zeros((tile.pixels, 3))
    pixel_sums(tile, radiance, total, squares)
    return tile, total, squares


def pass_plan(spp):
    """Samples per pixel of each progressive pass: 1, 1, 2, 4, ... up to
    MAX_PASS_SAMPLES each, summing to ``spp``."""
    plan, done = [], 0
    while done < spp:
        step = min(max(1, done), MAX_PASS_SAMPLES, spp - done)
        plan.append(step)
        done += step
    return plan


def tiles(seed, width, height, first_sample, samples):
    """The tiles of one pass: runs of pixels holding about TILE_PATHS paths."""
    n_pixels = width * height
    per_tile = max(1, min(TILE_PATHS // samples, -(-n_pixels // MIN_TILES)))
    return [
        Tile(seed, start, min(per_tile, n_pixels - start), first_sample, samples, width, height)
        for start in range(0, n_pixels, per_tile)
    ]


@dataclass(frozen=True)
class PathTraced:
    """A path-traced image and what it cost.

    radiance       : (H, W, 3) float32 linear radiance, row 0 at the top, background the
                     scene's environment (0 without one)
    standard_error : (H, W, 3) float32 the Monte Carlo standard error of each pixel's mean
    spp            : samples per pixel
    stats          : JSON-ready: seed, threads, spp, paths, rays (closest-hit and shadow),
                     shadow_rays (of those, occlusion queries), seconds, rays_per_s, paths_per_s
    """

    radiance: np.ndarray
    standard_error: np.ndarray
    spp: int
    stats: dict = field(default_factory=dict)


def _image(total, squares, spp, width, height):
    mean = total / spp
    variance = np.maximum(squares / spp - mean * mean, 0.0) / max(spp - 1, 1)
    shape = (height, width, 3)
    return mean.reshape(shape).astype(np.float32), np.sqrt(variance).reshape(shape).astype(np.float32)


class PathTracer:
    """Path-traces a scene (``Scene``) from cameras; build once, render many views.

    threads: worker threads (default: one per core); the image does not depend on it.
    microfacet_models: False renders every microfacet material as its Phong stand-in (what
    the solver and the displays evaluate), to measure what the stand-in costs.
    """

    def __init__(self, scene, threads=None, microfacet_models=True):
        self.scene = scene
        self.threads = threads or default_threads()
        merged = scene.merged()
        self.tracer = RayTracer(merged.positions, merged.faces, threads=1, cutout=merged.cutout)
        self.arrays = scene_arrays(scene, merged, self.tracer.epsilon, microfacet_models=microfacet_models)

    def close(self):
        self.tracer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def render(self, camera, spp, seed=1, progress=False, callback=None, first_sample=0):
        """Path-trace ``camera``'s image with ``spp`` samples per pixel; ``PathTraced``.

        callback(spp_so_far, PathTraced) runs after every progressive pass (the time it
        takes is not counted in the stats' seconds). Samples
        first_sample .. first_sample + spp - 1 of each pixel are traced: two renders of
        disjoint ranges are independent, and together make the render of both.
        """
        check_samples(spp)
        check_samples(first_sample, "first sample", low=0)
        check_seed(seed)
        width, height = camera.width, camera.height
        n_pixels = width * height
        cam = camera_rays(camera)
        total = np.zeros((n_pixels, 3))
        squares = np.zeros((n_pixels, 3))
        bar = progress_bar(progress)(total=spp * n_pixels, desc="path tracing", unit="path")
        rays_before = (self.tracer.rays_cast, self.tracer.shadow_rays_cast)
        clock = [time.perf_counter(), 0.0]  # start, time spent in the callback
        done = 0
        try:
            with ThreadPoolExecutor(self.threads) as pool:
                workers = Workers(pool, self.threads, self.tracer, self.arrays, seed)
                for samples in pass_plan(spp):
                    jobs = tiles(seed, width, height, first_sample + done, samples)

                    def combine(result):
                        tile, tile_total, tile_squares = result
                        sl = slice(tile.first_pixel, tile.first_pixel + tile.pixels)
                        total[sl] += tile_total
                        squares[sl] += tile_squares

                    run_ordered(
                        workers,
                        lambda tile: trace_tile(self.tracer, self.arrays, cam, tile),
                        jobs,
                        combine,
                        bar,
                        [t.pixels * t.samples for t in jobs],
                    )
                    done += samples
                    if callback is not None:
                        paused = time.perf_counter()
                        callback(done, self._result(total, squares, done, camera, seed, clock, rays_before))
                        clock[1] += time.perf_counter() - paused
        finally:
            bar.close()
        return self._result(total, squares, spp, camera, seed, clock, rays_before)

    def _result(self, total, squares, spp, camera, seed, clock, rays_before):
        seconds = time.perf_counter() - clock[0] - clock[1]
        rays = self.tracer.rays_cast - rays_before[0]
        shadow_rays = self.tracer.shadow_rays_cast - rays_before[1]
        paths = spp * camera.width * camera.height
        radiance, error = _image(total, squares, spp, camera.width, camera.height)
        stats = {
            "seed": int(seed),
            "threads": self.threads,
            "spp": int(spp),
            "paths": int(paths),
            "rays": int(rays),
            "shadow_rays": int(shadow_rays),
            "seconds": round(seconds, 4),
            "rays_per_s": rays / seconds if seconds > 0 else 0.0,
            "paths_per_s": paths / seconds if seconds > 0 else 0.0,
        }
        return PathTraced(radiance, error, int(spp), stats)


def scene_of_solution(solution):
    """The ``Scene`` a solution's meshes, materials, textures, environment and delta
    lights make (what its displays show)."""
    objects = []
    for o in solution.objects:
        m = o.material
        material = Material(
            name=o.name, diffuse=m["diffuse"], specular=m["specular"], exponent=m["exponent"], emission=m["emission"],
            fresnel=m.get("fresnel"), microfacet=m.get("microfacet"), glass=m.get("glass"),
        )
        objects.append(
            SceneObject(
                name=o.name,
                material=material,
                positions=o.positions.astype(np.float64),
                normals=o.normals.astype(np.float64),
                tangents=o.tangents.astype(np.float64),
                faces=o.faces.astype(np.int64),
                uvs=None if o.textured is None else o.textured.uvs.astype(np.float64),
                texture=None if o.textured is None else o.textured.texture,
                opacity=None if o.textured is None else o.textured.opacity,
            )
        )
    env = solution.environment
    if env is not None:
        env = Environment(env.image, env.scale, env.rotation, env.constant, env.source)
    return Scene(name=solution.scene or "solution", objects=tuple(objects), camera=solution.camera, environment=env,
                 lights=solution.lights)
