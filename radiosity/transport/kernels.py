"""numba kernels of the solver: photon emission and scattering, density deposits, and
the vertex gather. Orchestration (batches, threads) is in ``solve``.

A photon batch (``trace_photons``) and a gather block (``trace_gather``) each run as
one jitted call that releases the GIL and traces its rays itself, calling Embree
directly (``embree.intersect1`` / ``occluded1``: no Python between rays); batches and
blocks run a thread each. A photon batch goes in waves of PHOTON_WAVE photons
(``_trace_photon_waves``): a wave's rays of one depth, then their hits, the hits'
data asked of the cache a few hits ahead; ``emit_photons`` and ``bounce_photons`` are
the same steps on whole batches, for tests. A gather block goes wavefront-style: one
kernel makes rays, a loop traces them, the next kernel reads the hits. Every random number comes
from a counter-based hash of (seed, stream, item, dimension), so a result depends on
the seed and the item's index only, never on how work is split into batches or
threads.

Kernels take named tuples of arrays, never long lists of them:

    SceneArrays   the merged scene (vertex and triangle indices of ``Scene.merged()``)
    Rays          a batch of rays with an RGB value each: photons or gather paths
    embree.Hits   where each ray of a batch landed (triangle, t, u, v)
    PhotonTally   a photon batch's additive accumulators (density moments, energy tally)
    GatherBlock   a block of glossy vertices and how they are sampled (seed, counts)
    LightSamples  the light samples (shadow rays) of a gather block
    GatherSamples the gather rays of a gather block and the radiance they bring back
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from radiosity.formats.directions import hemisphere_to_square_nb
from radiosity.scene.materials import (
    EMISSION,
    EXPONENT,
    KD,
    KS,
    brdf_eval,
    brdf_sample,
    onb,
    phong_lobe,
)
from radiosity.transport.embree import head_hits, intersect1, intersect_rays, new_rayhit, occluded1

STREAM_EMIT, STREAM_BOUNCE, STREAM_LIGHT, STREAM_GATHER = 1, 2, 3, 4
# tally slots of a photon batch (RGB triples, then counts)
T_ESCAPED, T_ABSORBED, T_INCIDENT, T_BACKFACE, T_TERMINATED = 0, 3, 6, 9, 12
T_HITS, T_LENGTH = 15, 16
LOBE_CUTOFF = 1e-3  # gather: lobe values below this fraction of the peak are skipped (<= 0.1 % of its energy)
LOBE_TABLE = 2048  # entries of the cos^n table
# the concentric map shrinks no angle by more than 0.73 (square max-norm units per radian
# at least 1 / 0.73, measured over 2e6 random pairs; tests check it): 0.7 leaves a margin
SQUARE_PER_RADIAN = 1.0 / 0.7
PHOTON_WAVE = 1024  # photons traced together by trace_photons: a wave's rays, then its hits
PREFETCH_AHEAD = 4  # hits ahead whose data the wave's shading loop asks the cache for
LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709: the gather's noise is measured in luminance

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_INV_2_53 = 1.0 / 9007199254740992.0


class SceneArrays(NamedTuple):
    """The merged scene as the kernels read it.

    positions      : (N, 3) float64   vertex positions
    normals        : (N, 3) float64   unit shading normals
    tangents       : (N, 3) float64   unit tangents (the frames of the density moments)
    faces          : (T, 3) int64
    face_normals   : (T, 3) float64   unit geometric normals (the front side)
    face_material  : (T,) int64       row of ``materials``
    materials      : (M, NCOL) float64, see ``materials.pack_materials``
    albedo_table   : (M, A, 3) float64 true directional albedo at cos theta = k / (A - 1)
    emit_cdf       : (E,) float64     cumulative probability over emitting triangles
    emit_triangles : (E,) int64
    emit_area_pdf  : (T,) float64     density per unit area of choosing a point on a triangle
    epsilon        : float            ray-origin offset, scene units
    direct_cdf, direct_triangles, direct_area_pdf : the same over the emitters whose direct
                     glossy highlight the gather estimates (its vertices' light samples and
                     the emission its rays find on their first segment); the others'
                     (analytic emitter parts, ``radiosity.scene.emitters``) the solver adds
                     in closed form. The same arrays as emit_* when every emitter is gathered.
    """

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    faces: np.ndarray
    face_normals: np.ndarray
    face_material: np.ndarray
    materials: np.ndarray
    albedo_table: np.ndarray
    emit_cdf: np.ndarray
    emit_triangles: np.ndarray
    emit_area_pdf: np.ndarray
    epsilon: float
    direct_cdf: np.ndarray
    direct_triangles: np.ndarray
    direct_area_pdf: np.ndarray


class Rays(NamedTuple):
    """A batch of rays, each carrying an RGB value: photons (power) or gather paths
    (throughput). Kernels write the rays that go on into another ``Rays``.

    ids        : (R,) int64      photon id, or gather sample index within its block
    values     : (R, 3) float64  power (photons) or throughput (gather paths)
    origins    : (R, 3) float32  already offset off the surface they leave
    directions : (R, 3) float32  unit
    """

    ids: np.ndarray
    values: np.ndarray
    origins: np.ndarray
    directions: np.ndarray


def empty_rays(count):
    """Uninitialised ``Rays`` for ``count`` rays."""
    return Rays(
        ids=np.empty(count, dtype=np.int64),
        values=np.empty((count, 3)),
        origins=np.empty((count, 3), dtype=np.float32),
        directions=np.empty((count, 3), dtype=np.float32),
    )


class PhotonTally(NamedTuple):
    """What a photon batch accumulates; every field is additive over batches.

    moment0 : (N, 3) float64     sum of power * lambda_j per vertex j (density moments)
    moment1 : (N, 3, 2) float64  sum of power * lambda_j * (x - p_j) in vertex j's tangent frame
    tally   : (T_LENGTH,) float64 energy bookkeeping, slots T_*
    """

    moment0: np.ndarray
    moment1: np.ndarray
    tally: np.ndarray


def empty_tally(n_vertices):
    """A zeroed ``PhotonTally`` for a scene of ``n_vertices`` vertices."""
    return PhotonTally(np.zeros((n_vertices, 3)), np.zeros((n_vertices, 3, 2)), np.zeros(T_LENGTH))


class GatherBlock(NamedTuple):
    """A block of glossy vertices and how each is sampled.

    seed      : int           the solve's seed
    vertices  : (B,) int64    merged-scene vertex indices
    n_light   : int           light samples (shadow rays) per vertex
    strata    : int           gather rays per vertex: strata^2, stratified
    max_depth : int           segments of a gather path at most
    lobe_light: bool          sample the light at the glossy hits of gather paths
                              (``shade_paths``); False finds it by the lobe alone,
                              as before: the same expected value, more noise (for tests)
    measure_noise: bool       also measure each vertex's variance (``gather_outputs``);
                              the extra passes of ``regather`` need none
    """

    seed: int
    vertices: np.ndarray
    n_light: int
    strata: int
    max_depth: int
    lobe_light: bool = True
    measure_noise: bool = True


class LightSamples(NamedTuple):
    """The light samples of a gather block, ``n_light`` per vertex, vertex-major.

    origins, directions : (L, 3) float32  shadow rays (direction: the vertex normal where unused)
    distances           : (L,) float32    to the sampled light point (0 where unused)
    wi                  : (L, 3) float64  direction to the light in the vertex's local frame
    radiance            : (L, 3) float64  emitted radiance of the sampled light
    pdf                 : (L,) float64    solid-angle density, 0 for a sample that cannot contribute
    visible             : (L,) bool       the shadow ray reaches the light (filled in by the tracer)
    """

    origins: np.ndarray
    directions: np.ndarray
    distances: np.ndarray
    wi: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray
    visible: np.ndarray


def empty_light_samples(count):
    """``LightSamples`` for ``count`` samples: pdf, wi and radiance zero, none visible."""
    return LightSamples(
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        distances=np.empty(count, np.float32),
        wi=np.zeros((count, 3)),
        radiance=np.zeros((count, 3)),
        pdf=np.zeros(count),
        visible=np.zeros(count, dtype=bool),
    )


class GatherSamples(NamedTuple):
    """The gather rays of a block, strata^2 per vertex, vertex-major.

    origins, directions : (G, 3) float32  the first segment of each gather path
    wi                  : (G, 3) float64  its direction in the vertex's local frame
    incoming            : (G, 3) float64  radiance arriving along it (accumulated by ``shade_paths``)
    """

    origins: np.ndarray
    directions: np.ndarray
    wi: np.ndarray
    incoming: np.ndarray


def empty_gather_samples(count):
    """``GatherSamples`` for ``count`` rays, nothing arrived yet (incoming zero)."""
    return GatherSamples(
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        wi=np.empty((count, 3)),
        incoming=np.zeros((count, 3)),
    )


# -- random numbers -------------------------------------------------------------------


@numba.njit(inline="always")
def _mix(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True, nogil=True)
def rand(seed, stream, item, dim):
    """A uniform number in [0, 1) determined by (seed, stream, item, dim) alone."""
    z = _mix(np.uint64(seed) * _GOLDEN + np.uint64(stream))
    z = _mix(z ^ (np.uint64(item) * _GOLDEN))
    z = _mix(z + np.uint64(dim) * _M1)
    return float(z >> np.uint64(11)) * _INV_2_53


@intrinsic
def _prefetch_row(typingctx, array, row):
    """Ask the cache for row ``row`` of ``array`` (its first line), for reading, and
    return at once (LLVM's ``llvm.prefetch``): a hint that changes no value."""
    if not isinstance(array, types.Array) or not isinstance(row, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0])
        stride = cgutils.unpack_tuple(builder, data.strides)[0]
        index = context.cast(builder, args[1], signature.args[1], types.intp)
        address = builder.gep(builder.bitcast(data.data, ir.IntType(8).as_pointer()), [builder.mul(index, stride)])
        i32 = ir.IntType(32)
        prefetch = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [address.type, i32, i32, i32]), "llvm.prefetch.p0"
        )
        # read (0), keep in every level (3), data cache (1)
        builder.call(prefetch, [address, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(array, row), codegen


# -- small geometry helpers -----------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _search_cdf(cdf, u):
    """np.searchsorted(cdf, u, side="right") by hand: numba's, for one number, allocates."""
    lo, hi = 0, len(cdf)
    while lo < hi:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(cache=True, nogil=True, inline="always")
def _pick_emitter(sa, u):
    """The emitter triangle whose slot of the power CDF holds u."""
    return sa.emit_triangles[min(_search_cdf(sa.emit_cdf, u), len(sa.emit_triangles) - 1)]


@numba.njit(cache=True, nogil=True, inline="always")
def _lerp3(a, i0, i1, i2, w, u, v):
    """w a[i0] + u a[i1] + v a[i2] of the rows of a (N, 3), as a 3-tuple: a point or a
    normal inside a triangle from its corners' values and barycentrics."""
    return (
        w * a[i0, 0] + u * a[i1, 0] + v * a[i2, 0],
        w * a[i0, 1] + u * a[i1, 1] + v * a[i2, 1],
        w * a[i0, 2] + u * a[i1, 2] + v * a[i2, 2],
    )


@numba.njit(cache=True, nogil=True, inline="always")
def _facing(n, d, g):
    """The interpolated normal n normalised, where it faces the ray arriving along d;
    else the geometric normal g (which then faces it): the shading normal at a hit."""
    length = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    if length > 0.0 and (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) < 0.0:
        return n[0] / length, n[1] / length, n[2] / length
    return g[0], g[1], g[2]


@numba.njit(cache=True, nogil=True, inline="always")
def _barycentric_point(sa, tri, u, v):
    return _lerp3(sa.positions, sa.faces[tri, 0], sa.faces[tri, 1], sa.faces[tri, 2], 1.0 - u - v, u, v)


@numba.njit(cache=True, nogil=True, inline="always")
def _shading_normal(sa, tri, u, v, d):
    """Interpolated shading normal at a hit reached along direction d = (dx, dy, dz),
    or the geometric one where the interpolated normal would put the incoming ray's
    side behind the surface (``_facing``)."""
    n = _lerp3(sa.normals, sa.faces[tri, 0], sa.faces[tri, 1], sa.faces[tri, 2], 1.0 - u - v, u, v)
    g = sa.face_normals[tri]
    return _facing(n, d, (g[0], g[1], g[2]))


@numba.njit(cache=True, nogil=True, inline="always")
def _interpolate3(values, sa, tri, u, v, c):
    i0, i1, i2 = sa.faces[tri, 0], sa.faces[tri, 1], sa.faces[tri, 2]
    return (1.0 - u - v) * values[i0, c] + u * values[i1, c] + v * values[i2, c]


@numba.njit(cache=True, nogil=True, inline="always")
def _albedo(sa, m, cos_theta, c):
    table = sa.albedo_table[m]
    x = min(max(cos_theta, 0.0), 1.0) * (table.shape[0] - 1)
    k = min(int(x), table.shape[0] - 2)
    f = x - k
    return (1.0 - f) * table[k, c] + f * table[k + 1, c]


@numba.njit(cache=True, nogil=True, inline="always")
def _cosine_direction(u1, u2):
    """Cosine-weighted direction about +z from the concentric map of (u1, u2)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0, 1.0
    if abs(a) > abs(b):
        r, phi = a, 0.25 * math.pi * b / a
    else:
        r, phi = b, 0.5 * math.pi - 0.25 * math.pi * a / b
    x, y = r * math.cos(phi), r * math.sin(phi)
    return x, y, math.sqrt(max(0.0, 1.0 - x * x - y * y))


@numba.njit(cache=True, nogil=True, inline="always")
def _scatter(sa, t, u, v, d, rnd):
    """Sample the BRDF at a hit on triangle t reached along d = (dx, dy, dz), in the
    shading frame there, with the uniform numbers rnd = (u1, u2, u3) of ``brdf_sample``.

    Returns (wo, wi, pdf, world, ok): wo and wi in the local frame, the mixture pdf,
    the sampled direction in world space (3-tuples), and whether it leaves above both
    the shading and the true (geometric) surface.
    """
    mat = sa.materials[sa.face_material[t]]
    nx, ny, nz = _shading_normal(sa, t, u, v, d)
    tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
    dx, dy, dz = d
    wox = -(dx * tx + dy * ty + dz * tz)
    woy = -(dx * bx + dy * by + dz * bz)
    woz = -(dx * nx + dy * ny + dz * nz)
    wix, wiy, wiz, pdf = brdf_sample(mat, wox, woy, woz, rnd[0], rnd[1], rnd[2])
    ox = wix * tx + wiy * bx + wiz * nx
    oy = wix * ty + wiy * by + wiz * ny
    oz = wix * tz + wiy * bz + wiz * nz
    g = sa.face_normals[t]
    ok = wiz > 0.0 and pdf > 0.0 and ox * g[0] + oy * g[1] + oz * g[2] > 0.0
    return (wox, woy, woz), (wix, wiy, wiz), pdf, (ox, oy, oz), ok


@numba.njit(cache=True, nogil=True, inline="always")
def _roulette(value, reference, u):
    """Russian roulette on a path's RGB weight ``value`` after a bounce.

    The path survives with probability q = min(1, max(value) / reference) (0 if
    reference <= 0), decided by the uniform number u, and then carries value / q: the
    estimate stays unbiased and a surviving weight stays about ``reference`` (the
    photon's power before the bounce; 1 for gather throughput). Returns (survives,
    the surviving weight as an RGB tuple).
    """
    survive = min(1.0, max(value[0], value[1], value[2]) / reference) if reference > 0.0 else 0.0
    if survive <= 0.0 or u >= survive:
        return False, (0.0, 0.0, 0.0)
    return True, (value[0] / survive, value[1] / survive, value[2] / survive)


@numba.njit(cache=True, nogil=True, inline="always")
def _push_ray(out, i, item, point, g, epsilon, direction, value):
    """Write ray i of ``out`` (``Rays``): id ``item``, origin ``point`` offset by
    ``epsilon`` along the front normal g, ``direction`` and its RGB ``value``."""
    out.ids[i] = item
    for c in range(3):
        out.origins[i, c] = point[c] + epsilon * g[c]
        out.directions[i, c] = direction[c]
        out.values[i, c] = value[c]


# -- photons --------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def emit_photons(sa, seed, first_id, total, out):
    """Emit photons first_id .. first_id + len(out.ids) - 1 of ``total`` into ``out``
    (``Rays``): a triangle in proportion to its power, a uniform point on it, a
    cosine-distributed direction about its front. Each carries pi Le / (total * area
    pdf), so the batch's power sums to the emitters' power in expectation."""
    for i in range(len(out.ids)):
        pid = first_id + i
        tri = _pick_emitter(sa, rand(seed, STREAM_EMIT, pid, 0))
        s = math.sqrt(rand(seed, STREAM_EMIT, pid, 1))
        u = s * (1.0 - rand(seed, STREAM_EMIT, pid, 2))
        v = s - u
        point = _barycentric_point(sa, tri, u, v)
        g = sa.face_normals[tri]
        lx, ly, lz = _cosine_direction(rand(seed, STREAM_EMIT, pid, 3), rand(seed, STREAM_EMIT, pid, 4))
        tx, ty, tz, bx, by, bz = onb(g[0], g[1], g[2])
        direction = (lx * tx + ly * bx + lz * g[0], lx * ty + ly * by + lz * g[1], lx * tz + ly * bz + lz * g[2])
        m = sa.face_material[tri]
        scale = math.pi / (total * sa.emit_area_pdf[tri])
        power = (
            sa.materials[m, EMISSION] * scale,
            sa.materials[m, EMISSION + 1] * scale,
            sa.materials[m, EMISSION + 2] * scale,
        )
        _push_ray(out, i, pid, point, g, sa.epsilon, direction, power)


@numba.njit(cache=True, nogil=True, inline="always")
def _deposit(sa, t, point, lam, power, acc):
    """Add a photon's incident power to the density moments of triangle t's vertices."""
    x, y, z = point
    for j in range(3):
        vert = sa.faces[t, j]
        ox = x - sa.positions[vert, 0]
        oy = y - sa.positions[vert, 1]
        oz = z - sa.positions[vert, 2]
        tn = sa.tangents[vert]
        nn = sa.normals[vert]
        bx = nn[1] * tn[2] - nn[2] * tn[1]
        by = nn[2] * tn[0] - nn[0] * tn[2]
        bz = nn[0] * tn[1] - nn[1] * tn[0]
        along_t = ox * tn[0] + oy * tn[1] + oz * tn[2]
        along_b = ox * bx + oy * by + oz * bz
        for c in range(3):
            w = power[c] * lam[j]
            acc.moment0[vert, c] += w
            acc.moment1[vert, c, 0] += w * along_t
            acc.moment1[vert, c, 1] += w * along_b


@numba.njit(cache=True, nogil=True)
def bounce_photons(sa, seed, depth, max_depth, photons, hits, acc, out):
    """Deposit each photon where it landed and scatter it on; returns the survivors' count.

    photons : ``Rays`` in flight (values: power); hits : their ``embree.Hits``;
    acc : the batch's ``PhotonTally``; out : ``Rays`` receiving the survivors.

    At a front-face hit the incident power is added to the density moments of the
    triangle's three vertices: moment0[j] += power * lambda_j and moment1[j] += power *
    lambda_j * (x - p_j) in vertex j's tangent frame (lambda_j the barycentric weight,
    the hat function of vertex j). The photon then scatters by BRDF sampling with
    Russian roulette that keeps its power about constant. Backs absorb.

    ``acc.tally`` gains escaped power, the expected absorbed power (incident * (1 -
    true albedo)), incident power, back-face and forced-termination losses, and the
    hit count: emitted = escaped + absorbed + backface + terminated in expectation,
    which tests check.
    """
    tally = acc.tally
    n_out = 0
    for k in range(len(photons.ids)):
        t = hits.triangle[k]
        pid = photons.ids[k]
        power = (photons.values[k, 0], photons.values[k, 1], photons.values[k, 2])
        if t < 0:
            for c in range(3):
                tally[T_ESCAPED + c] += power[c]
            continue
        tally[T_HITS] += 1.0
        d = (photons.directions[k, 0], photons.directions[k, 1], photons.directions[k, 2])
        g = sa.face_normals[t]
        if d[0] * g[0] + d[1] * g[1] + d[2] * g[2] >= 0.0:
            for c in range(3):
                tally[T_BACKFACE + c] += power[c]
            continue
        uk, vk = np.float64(hits.u[k]), np.float64(hits.v[k])
        point = _barycentric_point(sa, t, uk, vk)
        _deposit(sa, t, point, (1.0 - uk - vk, uk, vk), power, acc)
        for c in range(3):
            tally[T_INCIDENT + c] += power[c]

        m = sa.face_material[t]
        base = depth * 8
        rnd = (
            rand(seed, STREAM_BOUNCE, pid, base),
            rand(seed, STREAM_BOUNCE, pid, base + 1),
            rand(seed, STREAM_BOUNCE, pid, base + 2),
        )
        wo, wi, pdf, direction, ok = _scatter(sa, t, uk, vk, d, rnd)
        for c in range(3):
            tally[T_ABSORBED + c] += power[c] * (1.0 - _albedo(sa, m, wo[2], c))
        if depth + 1 >= max_depth:
            for c in range(3):
                tally[T_TERMINATED + c] += power[c] * _albedo(sa, m, wo[2], c)
            continue
        if not ok:
            continue  # below the shading or the true surface: absorbed
        fr, fg, fb = brdf_eval(sa.materials[m], wi[0], wi[1], wi[2], wo[0], wo[1], wo[2])
        scale = wi[2] / pdf
        scattered = (power[0] * fr * scale, power[1] * fg * scale, power[2] * fb * scale)
        survives, carried = _roulette(
            scattered, max(power[0], power[1], power[2]), rand(seed, STREAM_BOUNCE, pid, base + 3)
        )
        if not survives:
            continue
        _push_ray(out, n_out, pid, point, g, sa.epsilon, direction, carried)
        n_out += 1
    return n_out


# -- gather ---------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True, inline="always")
def _emitter_sample(emit_cdf, emit_triangles, emit_area_pdf, positions, faces, face_normals, epsilon, point, g, u0, u1, u2):
    """A light sample seen from ``point`` (a hit, front normal g): an emitter triangle
    chosen in proportion to power by u0 and a point area-uniform on it by (u1, u2),
    both offset by epsilon off their fronts. Returns (triangle, its area density (0:
    none to draw), origin, unit direction to the light point (3-tuples), distance (0:
    unusable), cosine at the light)."""
    tri = emit_triangles[min(_search_cdf(emit_cdf, u0), len(emit_triangles) - 1)]
    area_pdf = emit_area_pdf[tri]
    eps = epsilon
    ox, oy, oz = point[0] + eps * g[0], point[1] + eps * g[1], point[2] + eps * g[2]
    if area_pdf <= 0.0:
        return tri, 0.0, (ox, oy, oz), (0.0, 0.0, 0.0), 0.0, 0.0
    r = math.sqrt(u1)
    u = r * (1.0 - u2)
    v = r - u
    qx, qy, qz = _lerp3(positions, faces[tri, 0], faces[tri, 1], faces[tri, 2], 1.0 - u - v, u, v)
    gl0, gl1, gl2 = face_normals[tri, 0], face_normals[tri, 1], face_normals[tri, 2]
    dx, dy, dz = qx + eps * gl0 - ox, qy + eps * gl1 - oy, qz + eps * gl2 - oz
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if dist <= 0.0:
        return tri, area_pdf, (ox, oy, oz), (0.0, 0.0, 0.0), 0.0, 0.0
    dx, dy, dz = dx / dist, dy / dist, dz / dist
    return tri, area_pdf, (ox, oy, oz), (dx, dy, dz), dist, -(dx * gl0 + dy * gl1 + dz * gl2)


@numba.njit(cache=True, nogil=True, inline="always")
def _toward_emitter(sa, point, g, u0, u1, u2):
    """``_emitter_sample`` on the scene's arrays."""
    return _emitter_sample(
        sa.emit_cdf, sa.emit_triangles, sa.emit_area_pdf, sa.positions, sa.faces, sa.face_normals, sa.epsilon,
        point, g, u0, u1, u2,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def make_gather_rays(sa, block, light, samples):
    """Rays for the vertices of one ``GatherBlock``: ``block.n_light`` light samples
    (shadow rays, into ``light``: ``LightSamples``) and ``block.strata``^2 stratified
    cosine-weighted gather rays (into ``samples``: ``GatherSamples``) per vertex.
    Directions are also kept in the vertex's local frame (x tangent, y bitangent,
    z normal).

    light.pdf is the solid-angle density of the light sample, 0 for a sample that
    cannot contribute (behind the vertex or seeing the light's back).
    """
    seed, n_light, strata = block.seed, block.n_light, block.strata
    n_gather = strata * strata
    for b in range(len(block.vertices)):
        vert = block.vertices[b]
        px, py, pz = sa.positions[vert, 0], sa.positions[vert, 1], sa.positions[vert, 2]
        nx, ny, nz = sa.normals[vert, 0], sa.normals[vert, 1], sa.normals[vert, 2]
        tx, ty, tz = sa.tangents[vert, 0], sa.tangents[vert, 1], sa.tangents[vert, 2]
        bx, by, bz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
        ox, oy, oz = px + sa.epsilon * nx, py + sa.epsilon * ny, pz + sa.epsilon * nz
        for m in range(n_light):
            i = b * n_light + m
            item = vert * n_light + m
            tri, area_pdf, _, (dx, dy, dz), dist, cos_light = _emitter_sample(
                sa.direct_cdf, sa.direct_triangles, sa.direct_area_pdf, sa.positions, sa.faces, sa.face_normals,
                sa.epsilon,
                (px, py, pz),
                (nx, ny, nz),
                rand(seed, STREAM_LIGHT, item, 0),
                rand(seed, STREAM_LIGHT, item, 1),
                rand(seed, STREAM_LIGHT, item, 2),
            )
            light.origins[i, 0], light.origins[i, 1], light.origins[i, 2] = ox, oy, oz
            light.pdf[i] = 0.0
            light.distances[i] = 0.0
            light.directions[i, 0], light.directions[i, 1], light.directions[i, 2] = nx, ny, nz
            wz = dx * nx + dy * ny + dz * nz
            if area_pdf <= 0.0 or dist <= 0.0 or cos_light <= 0.0 or wz <= 0.0:
                continue
            light.directions[i, 0], light.directions[i, 1], light.directions[i, 2] = dx, dy, dz
            light.distances[i] = dist
            light.wi[i, 0] = dx * tx + dy * ty + dz * tz
            light.wi[i, 1] = dx * bx + dy * by + dz * bz
            light.wi[i, 2] = wz
            light.pdf[i] = area_pdf * dist * dist / cos_light
            mat = sa.face_material[tri]
            for c in range(3):
                light.radiance[i, c] = sa.materials[mat, EMISSION + c]
        for k in range(n_gather):
            i = b * n_gather + k
            item = vert * n_gather + k
            kx, ky = k % strata, k // strata
            lx, ly, lz = _cosine_direction(
                (kx + rand(seed, STREAM_GATHER, item, 0)) / strata,
                (ky + rand(seed, STREAM_GATHER, item, 1)) / strata,
            )
            samples.wi[i, 0], samples.wi[i, 1], samples.wi[i, 2] = lx, ly, lz
            samples.directions[i, 0] = lx * tx + ly * bx + lz * nx
            samples.directions[i, 1] = lx * ty + ly * by + lz * ny
            samples.directions[i, 2] = lx * tz + ly * bz + lz * nz
            samples.origins[i, 0], samples.origins[i, 1], samples.origins[i, 2] = ox, oy, oz


@numba.njit(cache=True, nogil=True)
def shade_paths(rt, rayhit, sa, irradiance, block, depth, paths, path_pdf, hits, samples, out, out_pdf):
    """Radiance arriving along gather paths; returns (the number of paths that go on,
    the shadow rays traced).

    rt, rayhit : the scene (``embree.Embree``) and a ray-hit record for the shadow rays;
    paths : ``Rays`` in flight (values: throughput) at segment ``depth``, and path_pdf
    (their count,) the density with which the previous vertex's lobe sampled their
    direction (unused at depth 0); hits : their ``embree.Hits``; samples : the block's
    ``GatherSamples``; out, out_pdf : receive the paths that go on.

    ``samples.incoming[paths.ids[k]]`` gains throughput * (emitted + diffusely
    reflected radiance) at each path's hit. The emitted part is weighted by the
    balance heuristic against the light sample that saw it too: on the first segment
    (depth 0) the ``block.n_light`` light samples of the vertex (the gather ray's
    density is cos / pi, its cosine at the vertex being ``samples.wi[id, 2]``), later
    the previous vertex's light sample (the ray's density path_pdf). The diffuse part
    is kd / pi times the irradiance interpolated at the hit. At a glossy surface the
    path goes on through the specular lobe (the diffuse lobe's light is in the
    irradiance), with Russian roulette, so light that passes from glossy to glossy is
    not lost.

    There a light sample also catches the emitters the lobe reflects (without it, a
    lamp seen in a glossy neighbour was found only by chance and made the heavy-tailed
    outliers that showed as blotches): a point on an emitter (``_emitter_sample``,
    numbers from ``STREAM_GATHER + 2``) and its shadow ray, weighted by the balance
    heuristic against the lobe's continuation: f_s cos / (p_light + p_lobe), with f_s =
    ks (n + 2) / (2 pi) cos^n alpha and p_lobe = (n + 1) / (2 pi) cos^n alpha, alpha
    measured from the mirror direction. Directions the continuation cannot produce
    (below the shading or the true surface) are skipped by both.

    ``paths.ids`` index the block's gather samples (vertex ``block.vertices[id //
    n_gather]``, sample ``id % n_gather``), which also key the random numbers.
    """
    return _shade_loop(
        # the call's own copy of the small material table: a row of it per hit (a
        # reference-count update) that threads must not share
        rt, rayhit, sa.positions, sa.normals, sa.faces, sa.face_normals, sa.face_material, sa.materials.copy(),
        sa.emit_cdf, sa.emit_triangles, sa.emit_area_pdf, sa.direct_area_pdf, sa.epsilon, irradiance,
        block.seed, block.n_light, block.strata * block.strata, block.max_depth, block.vertices, block.lobe_light,
        depth, paths.ids, paths.values, paths.origins, paths.directions, path_pdf,
        hits.triangle, hits.u, hits.v, samples.wi, samples.incoming,
        out.ids, out.values, out.origins, out.directions, out_pdf,
    )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _shade_loop(
    rt, rayhit, positions, normals, faces, face_normals, face_material, materials, emit_cdf, emit_triangles,
    emit_area_pdf, direct_area_pdf, epsilon, irradiance, seed, n_light, n_gather, max_depth, vertices, lobe_light, depth,
    ids, values, origins, directions, path_pdf, triangle, hit_u, hit_v, sample_wi, incoming,
    out_ids, out_values, out_origins, out_directions, out_pdf,
):  # fmt: skip
    """``shade_paths`` on the arrays one by one (as ``_trace_photon_waves``: a named tuple
    handed to an inlined helper costs a reference-count update of each of its arrays),
    with the same arithmetic in the same order."""
    n_out = 0
    shadow = 0
    has_lights = len(emit_triangles) > 0 and lobe_light
    for k in range(len(ids)):
        t = triangle[k]
        if t < 0:
            continue
        d = (directions[k, 0], directions[k, 1], directions[k, 2])
        gx, gy, gz = face_normals[t, 0], face_normals[t, 1], face_normals[t, 2]
        if d[0] * gx + d[1] * gy + d[2] * gz >= 0.0:
            continue
        uk, vk = np.float64(hit_u[k]), np.float64(hit_v[k])
        w = 1.0 - uk - vk
        i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
        px, py, pz = _lerp3(positions, i0, i1, i2, w, uk, vk)
        m = face_material[t]
        target = ids[k]
        weight = 1.0
        if depth == 0 and emit_area_pdf[t] > 0.0 and direct_area_pdf[t] <= 0.0:
            weight = 0.0  # an analytic emitter part: its direct highlight is added in closed form
        elif emit_area_pdf[t] > 0.0 and (depth > 0 or n_light > 0):
            cos_light = -(d[0] * gx + d[1] * gy + d[2] * gz)
            ex, ey, ez = px - origins[k, 0], py - origins[k, 1], pz - origins[k, 2]
            dist = math.sqrt(ex * ex + ey * ey + ez * ez)
            if depth == 0:
                p_light = direct_area_pdf[t] * dist * dist / cos_light
                p_gather = sample_wi[target, 2] / math.pi
                weight = n_gather * p_gather / (n_gather * p_gather + n_light * p_light)
            elif lobe_light:
                p_light = emit_area_pdf[t] * dist * dist / cos_light
                weight = path_pdf[k] / (path_pdf[k] + p_light)
        for c in range(3):
            e = w * irradiance[i0, c] + uk * irradiance[i1, c] + vk * irradiance[i2, c]
            radiance = weight * materials[m, EMISSION + c] + materials[m, KD + c] / math.pi * e
            incoming[target, c] += values[k, c] * radiance
        ks0, ks1, ks2 = materials[m, KS], materials[m, KS + 1], materials[m, KS + 2]
        if max(ks0, ks1, ks2) <= 0.0 or depth + 1 >= max_depth:
            continue
        item = (vertices[target // n_gather] * n_gather + target % n_gather) * max_depth + depth
        nx, ny, nz = _facing(_lerp3(normals, i0, i1, i2, w, uk, vk), d, (gx, gy, gz))
        exponent = materials[m, EXPONENT]
        if has_lights:
            # the light sample at the glossy hit
            tri, area_pdf, (ox, oy, oz), (dx, dy, dz), dist, cos_light = _emitter_sample(
                emit_cdf, emit_triangles, emit_area_pdf, positions, faces, face_normals, epsilon,
                (px, py, pz), (gx, gy, gz),
                rand(seed, STREAM_GATHER + 2, item, 0),
                rand(seed, STREAM_GATHER + 2, item, 1),
                rand(seed, STREAM_GATHER + 2, item, 2),
            )  # fmt: skip
            if area_pdf > 0.0 and dist > 0.0:
                cos_i = dx * nx + dy * ny + dz * nz
                if cos_light > 0.0 and cos_i > 0.0 and dx * gx + dy * gy + dz * gz > 0.0:
                    dn = d[0] * nx + d[1] * ny + d[2] * nz
                    cos_alpha = dx * (d[0] - 2.0 * dn * nx) + dy * (d[1] - 2.0 * dn * ny) + dz * (d[2] - 2.0 * dn * nz)
                    if cos_alpha > 0.0:
                        lobe = phong_lobe(min(cos_alpha, 1.0), exponent)
                        if lobe > 0.0:
                            shadow += 1
                            if not occluded1(rt, rayhit, ox, oy, oz, dx, dy, dz, dist):
                                p_light = area_pdf * dist * dist / cos_light
                                p_lobe = (exponent + 1.0) / (2.0 * math.pi) * lobe
                                scale = (exponent + 2.0) / (2.0 * math.pi) * lobe * cos_i / (p_light + p_lobe)
                                lm = face_material[tri]
                                incoming[target, 0] += values[k, 0] * (ks0 * materials[lm, EMISSION] * scale)
                                incoming[target, 1] += values[k, 1] * (ks1 * materials[lm, EMISSION + 1] * scale)
                                incoming[target, 2] += values[k, 2] * (ks2 * materials[lm, EMISSION + 2] * scale)
        # the lobe's continuation (``_scatter`` with u1 = 0: the specular lobe; the diffuse
        # lobe's light is in the irradiance)
        tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
        wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
        woy = -(d[0] * bx + d[1] * by + d[2] * bz)
        woz = -(d[0] * nx + d[1] * ny + d[2] * nz)
        wix, wiy, wiz, pdf = brdf_sample(
            materials[m], wox, woy, woz, 0.0, rand(seed, STREAM_GATHER + 1, item, 0), rand(seed, STREAM_GATHER + 1, item, 1)
        )
        sx = wix * tx + wiy * bx + wiz * nx
        sy = wix * ty + wiy * by + wiz * ny
        sz = wix * tz + wiy * bz + wiz * nz
        if not (wiz > 0.0 and pdf > 0.0 and sx * gx + sy * gy + sz * gz > 0.0):
            continue
        # specular lobe sampled exactly: f_s cos / pdf_s = ks (n + 2) / (n + 1) cos
        lobe_weight = (exponent + 2.0) / (exponent + 1.0) * wiz
        q0, q1, q2 = values[k, 0] * ks0 * lobe_weight, values[k, 1] * ks1 * lobe_weight, values[k, 2] * ks2 * lobe_weight
        survives, carried = _roulette((q0, q1, q2), 1.0, rand(seed, STREAM_GATHER + 1, item, 2))
        if not survives:
            continue
        cos_alpha = min(max(-wix * wox - wiy * woy + wiz * woz, 0.0), 1.0)
        out_pdf[n_out] = (exponent + 1.0) / (2.0 * math.pi) * phong_lobe(cos_alpha, exponent)
        out_ids[n_out] = target
        out_origins[n_out, 0] = px + epsilon * gx
        out_origins[n_out, 1] = py + epsilon * gy
        out_origins[n_out, 2] = pz + epsilon * gz
        out_directions[n_out, 0], out_directions[n_out, 1], out_directions[n_out, 2] = sx, sy, sz
        out_values[n_out, 0], out_values[n_out, 1], out_values[n_out, 2] = carried
        n_out += 1
    return n_out, shadow


@numba.njit(cache=True, nogil=True, inline="always")
def _variance_sum(moments, n_light, n_gather):
    """sum over directions of S2 - S1^2 / m of each group (light samples, gather rays)
    from ``moments`` (4, D): light S1, S2, gather S1, S2."""
    total = 0.0
    for d in range(moments.shape[1]):
        if n_light > 0:
            total += max(moments[1, d] - moments[0, d] * moments[0, d] / n_light, 0.0)
        if n_gather > 0:
            total += max(moments[3, d] - moments[2, d] * moments[2, d] / n_gather, 0.0)
    return total


@numba.njit(cache=True, nogil=True)
def gather_outputs(mat, emission, diffuse_radiance, light, samples, directions, out, variance):
    """Outgoing radiance of a block of B vertices in every direction of an n x n grid.

    out[b, d] = emission + diffuse_radiance[b] + the specular lobe's integral of the
    incoming light for wo = directions[d], estimated from the vertex's light samples
    (balance-heuristic weighted against the gather rays) and its gather rays, all
    shared by every direction d.

    Each sample adds ks (n + 2) / (2 pi) cos^n(alpha) times its weight to the grid
    directions within its lobe, alpha measured from its mirror direction; directions
    where the lobe is below LOBE_CUTOFF of its peak are skipped (that loses at most
    LOBE_CUTOFF of the lobe's energy). The cells to visit come from the grid's square:
    the concentric map never shrinks angles by more than SQUARE_PER_RADIAN, so a
    window of that many square units per radian of lobe holds every cell that
    matters. cos^n comes from a table over the lobe's range of cos alpha, linearly
    interpolated (relative error ~1e-6 whatever n).

    mat : (NCOL,) the object's material row; emission : (3,); diffuse_radiance :
    (B, 3) kd E / pi; light : ``LightSamples`` (B * n_light, its ``wi``, ``radiance``,
    ``pdf`` and ``visible`` read); samples : ``GatherSamples`` (B * n_gather, its ``wi``
    and ``incoming`` read); directions : (n^2, 3) local, ``directions.grid_directions``;
    out : (B, n^2, 3) float64; variance : (B,) float64 (or empty: not measured), receives each vertex's
    sum over directions of the variance of the luminance (``LUMINANCE``) of out[b, d],
    estimated from the spread of its samples: a group of m samples (light, gather)
    whose terms x_s sum to S1 and their squares to S2 adds S2 - S1^2 / m (samples that
    brought nothing count as zeros). Stratification makes the true variance lower.
    """
    n_blocks = out.shape[0]
    n_light = light.pdf.shape[0] // n_blocks if n_blocks > 0 else 0
    n_gather = samples.wi.shape[0] // n_blocks if n_blocks > 0 else 0
    grid_n = int(round(math.sqrt(directions.shape[0])))
    n = mat[EXPONENT]
    norm = (n + 2.0) / (2.0 * math.pi)
    cos_min = math.exp(math.log(LOBE_CUTOFF) / n) if n > 1e-9 else 0.0
    half = math.acos(cos_min) * SQUARE_PER_RADIAN
    table = np.empty(LOBE_TABLE)
    step = (1.0 - cos_min) / (LOBE_TABLE - 1)
    for k in range(LOBE_TABLE):
        table[k] = phong_lobe(cos_min + k * step, n)
    inv_step = 1.0 / step
    n_samples = n_light + n_gather
    mirror = np.empty((n_samples, 3))
    weight = np.empty((n_samples, 3))
    n_dirs = directions.shape[0]
    moments = np.empty((4, n_dirs))  # light S1, S2, gather S1, S2 of luminance
    lum_ks = (LUMINANCE[0] * mat[KS], LUMINANCE[1] * mat[KS + 1], LUMINANCE[2] * mat[KS + 2])
    measure = variance.shape[0] > 0
    for b in range(n_blocks):
        used = 0
        for m in range(n_light):
            i = b * n_light + m
            p = light.pdf[i]
            if p <= 0.0 or not light.visible[i]:
                continue
            wz = light.wi[i, 2]
            p_gather = wz / math.pi
            scale = wz / (p * n_light) * (n_light * p / (n_light * p + n_gather * p_gather))
            mirror[used, 0], mirror[used, 1], mirror[used, 2] = -light.wi[i, 0], -light.wi[i, 1], wz
            for c in range(3):
                weight[used, c] = scale * light.radiance[i, c]
            used += 1
        used_light = used
        for k in range(n_gather):
            i = b * n_gather + k
            incoming = samples.incoming
            if incoming[i, 0] == 0.0 and incoming[i, 1] == 0.0 and incoming[i, 2] == 0.0:
                continue
            wi = samples.wi
            mirror[used, 0], mirror[used, 1], mirror[used, 2] = -wi[i, 0], -wi[i, 1], wi[i, 2]
            for c in range(3):
                weight[used, c] = math.pi / n_gather * incoming[i, c]
            used += 1
        acc = out[b]
        acc[:, :] = 0.0
        moments[:, :] = 0.0
        for s in range(used):
            s1 = moments[0] if s < used_light else moments[2]
            s2 = moments[1] if s < used_light else moments[3]
            y = norm * (lum_ks[0] * weight[s, 0] + lum_ks[1] * weight[s, 1] + lum_ks[2] * weight[s, 2])
            rx, ry, rz = mirror[s, 0], mirror[s, 1], mirror[s, 2]
            sa_, sb_ = hemisphere_to_square_nb(rx, ry, rz)
            i_lo = max(0, int(math.floor((sa_ - half + 1.0) * 0.5 * grid_n - 0.5)))
            i_hi = min(grid_n - 1, int(math.ceil((sa_ + half + 1.0) * 0.5 * grid_n - 0.5)))
            j_lo = max(0, int(math.floor((sb_ - half + 1.0) * 0.5 * grid_n - 0.5)))
            j_hi = min(grid_n - 1, int(math.ceil((sb_ + half + 1.0) * 0.5 * grid_n - 0.5)))
            w0, w1, w2 = weight[s, 0], weight[s, 1], weight[s, 2]
            for j in range(j_lo, j_hi + 1):
                for i in range(i_lo, i_hi + 1):
                    d = j * grid_n + i
                    cos_alpha = rx * directions[d, 0] + ry * directions[d, 1] + rz * directions[d, 2]
                    if cos_alpha <= cos_min:
                        continue
                    x = min((cos_alpha - cos_min) * inv_step, LOBE_TABLE - 1.0)
                    k = min(int(x), LOBE_TABLE - 2)
                    lobe = table[k] + (x - k) * (table[k + 1] - table[k])
                    acc[d, 0] += lobe * w0
                    acc[d, 1] += lobe * w1
                    acc[d, 2] += lobe * w2
                    if measure:
                        x = lobe * y
                        s1[d] += x
                        s2[d] += x * x
        if measure:
            variance[b] = _variance_sum(moments, n_light, n_gather)
        for d in range(acc.shape[0]):
            for c in range(3):
                acc[d, c] = emission[c] + diffuse_radiance[b, c] + norm * mat[KS + c] * acc[d, c]


# -- whole batches, tracing their own rays ----------------------------------------------


@numba.njit(cache=True, nogil=True)
def _head(rays, n):
    """The first n rays of ``rays`` (``Rays``), as views."""
    return Rays(rays.ids[:n], rays.values[:n], rays.origins[:n], rays.directions[:n])


@numba.njit(cache=True, nogil=True)
def trace_photons(rt, sa, seed, first_id, count, total, max_depth, acc, wave=PHOTON_WAVE):
    """Trace photons first_id .. first_id + count - 1 of ``total`` to the end through
    the scene ``rt`` (``embree.Embree``), adding to ``acc`` (``PhotonTally``). Returns
    the rays traced.

    ``wave`` photons at a time (``_trace_photon_waves``): the rays of a wave's photons
    at one depth are traced one after another, then their hits are shaded one after
    another, each hit's triangle and vertices asked of the cache a few hits ahead. So
    Embree runs with its own data in cache, and the shading does not wait for memory
    at every hit (on a large mesh the hits' data is not in cache).

    Each photon's rays and deposits are those of the wavefront form (``emit_photons``,
    then per depth every photon in flight traced and ``bounce_photons``, which tests
    check bit for bit, photon by photon and wave by wave); only the order in which the
    photons' deposits are summed depends on ``wave`` (wave by wave, depth by depth
    within a wave), which moves the batch's sums by float rounding.
    """
    return _trace_photon_waves(
        # the batch's own copy of the small material table: the loop takes a row of it
        # per bounce (a reference-count update), which threads must not share
        rt, sa.positions, sa.normals, sa.tangents, sa.faces, sa.face_normals, sa.face_material, sa.materials.copy(),
        sa.albedo_table, sa.emit_cdf, sa.emit_triangles, sa.emit_area_pdf, sa.epsilon,
        seed, first_id, count, total, max_depth, acc.moment0, acc.moment1, acc.tally, max(1, min(wave, count)),
    )  # fmt: skip


@numba.njit(cache=True, nogil=True, inline="always")
def _prefetch_hit(t, faces, face_normals, face_material, positions, moment0, moment1):
    """Ask the cache for what shading a hit on triangle t waits for most: the
    triangle's rows, and its vertices' positions and density moments (their indices
    are read, so ``faces`` should be asked first)."""
    if t < 0:
        return
    _prefetch_row(face_normals, t)
    _prefetch_row(face_material, t)
    for j in range(3):
        vert = faces[t, j]
        _prefetch_row(positions, vert)
        _prefetch_row(moment0, vert)
        _prefetch_row(moment1, vert)


@numba.njit(cache=True, nogil=True)
def _trace_photon_waves(
    rt, positions, normals, tangents, faces, face_normals, face_material, materials, albedo_table, emit_cdf,
    emit_triangles, emit_area_pdf, epsilon, seed, first_id, count, total, max_depth, moment0, moment1, tally, wave,
):  # fmt: skip
    """``trace_photons`` on the scene's arrays one by one: the loops index them with
    scalars (a ``SceneArrays`` handed to an inlined helper costs a reference-count
    update, an atomic operation, of each of its arrays: the wavefront kernels made
    dozens per bounce), and find the emitter by their own binary search
    (``np.searchsorted`` of one number allocates). The arithmetic is that of
    ``emit_photons`` and ``bounce_photons``, operation for operation; the survivors of
    a depth are packed to the front of the wave's buffers in order, as
    ``bounce_photons`` packs them. ``wave`` = 1 follows one photon at a time. The
    prefetches (``_prefetch_hit``, PREFETCH_AHEAD hits ahead, the triangle's vertex
    indices twice as far) change no value."""
    rayhit = new_rayhit()
    n_emitters = len(emit_triangles)
    n_albedo = albedo_table.shape[1]
    ids = np.empty(wave, np.int64)
    power = np.empty((wave, 3))
    ray = np.empty((wave, 6), np.float32)  # origin, direction: float32, as a ``Rays`` stores them
    hit_triangle = np.empty(wave, np.int64)
    hit_uv = np.empty((wave, 2), np.float32)
    rays = 0
    for first in range(first_id, first_id + count, wave):
        n = min(wave, first_id + count - first)
        # -- emission (emit_photons) --
        for i in range(n):
            pid = first + i
            u0 = rand(seed, STREAM_EMIT, pid, 0)
            tri = emit_triangles[min(_search_cdf(emit_cdf, u0), n_emitters - 1)]
            s = math.sqrt(rand(seed, STREAM_EMIT, pid, 1))
            u = s * (1.0 - rand(seed, STREAM_EMIT, pid, 2))
            v = s - u
            px, py, pz = _lerp3(positions, faces[tri, 0], faces[tri, 1], faces[tri, 2], 1.0 - u - v, u, v)
            gx, gy, gz = face_normals[tri, 0], face_normals[tri, 1], face_normals[tri, 2]
            lx, ly, lz = _cosine_direction(rand(seed, STREAM_EMIT, pid, 3), rand(seed, STREAM_EMIT, pid, 4))
            tx, ty, tz, bx, by, bz = onb(gx, gy, gz)
            m = face_material[tri]
            scale = math.pi / (total * emit_area_pdf[tri])
            ids[i] = pid
            power[i, 0] = materials[m, EMISSION] * scale
            power[i, 1] = materials[m, EMISSION + 1] * scale
            power[i, 2] = materials[m, EMISSION + 2] * scale
            ray[i, 0] = px + epsilon * gx
            ray[i, 1] = py + epsilon * gy
            ray[i, 2] = pz + epsilon * gz
            ray[i, 3] = lx * tx + ly * bx + lz * gx
            ray[i, 4] = lx * ty + ly * by + lz * gy
            ray[i, 5] = lx * tz + ly * bz + lz * gz
        for depth in range(max_depth):
            if n == 0:
                break
            # -- the wave's rays, one after another --
            for k in range(n):
                r = ray[k]
                t, _, hu, hv = intersect1(rt, rayhit, r[0], r[1], r[2], r[3], r[4], r[5])
                hit_triangle[k] = t
                hit_uv[k, 0], hit_uv[k, 1] = hu, hv
            rays += n
            # -- their hits (bounce_photons), survivors packed to the front --
            for k in range(min(n, 2 * PREFETCH_AHEAD)):
                if hit_triangle[k] >= 0:
                    _prefetch_row(faces, hit_triangle[k])
            survivors = 0
            for k in range(n):
                if k + 2 * PREFETCH_AHEAD < n and hit_triangle[k + 2 * PREFETCH_AHEAD] >= 0:
                    _prefetch_row(faces, hit_triangle[k + 2 * PREFETCH_AHEAD])
                if k + PREFETCH_AHEAD < n:
                    _prefetch_hit(
                        hit_triangle[k + PREFETCH_AHEAD], faces, face_normals, face_material, positions, moment0, moment1
                    )
                pid = ids[k]
                p0, p1, p2 = power[k, 0], power[k, 1], power[k, 2]
                t = hit_triangle[k]
                if t < 0:
                    tally[T_ESCAPED] += p0
                    tally[T_ESCAPED + 1] += p1
                    tally[T_ESCAPED + 2] += p2
                    continue
                tally[T_HITS] += 1.0
                dx, dy, dz = np.float64(ray[k, 3]), np.float64(ray[k, 4]), np.float64(ray[k, 5])
                gx, gy, gz = face_normals[t, 0], face_normals[t, 1], face_normals[t, 2]
                if dx * gx + dy * gy + dz * gz >= 0.0:
                    tally[T_BACKFACE] += p0
                    tally[T_BACKFACE + 1] += p1
                    tally[T_BACKFACE + 2] += p2
                    continue
                u, v = np.float64(hit_uv[k, 0]), np.float64(hit_uv[k, 1])
                w = 1.0 - u - v
                i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
                px, py, pz = _lerp3(positions, i0, i1, i2, w, u, v)
                # deposit (_deposit)
                for j in range(3):
                    vert = faces[t, j]
                    lam = w if j == 0 else (u if j == 1 else v)
                    ex = px - positions[vert, 0]
                    ey = py - positions[vert, 1]
                    ez = pz - positions[vert, 2]
                    t0, t1, t2 = tangents[vert, 0], tangents[vert, 1], tangents[vert, 2]
                    n0, n1, n2 = normals[vert, 0], normals[vert, 1], normals[vert, 2]
                    cx = n1 * t2 - n2 * t1
                    cy = n2 * t0 - n0 * t2
                    cz = n0 * t1 - n1 * t0
                    along_t = ex * t0 + ey * t1 + ez * t2
                    along_b = ex * cx + ey * cy + ez * cz
                    for c in range(3):
                        wc = (p0 if c == 0 else (p1 if c == 1 else p2)) * lam
                        moment0[vert, c] += wc
                        moment1[vert, c, 0] += wc * along_t
                        moment1[vert, c, 1] += wc * along_b
                tally[T_INCIDENT] += p0
                tally[T_INCIDENT + 1] += p1
                tally[T_INCIDENT + 2] += p2
                m = face_material[t]
                base = depth * 8
                r0 = rand(seed, STREAM_BOUNCE, pid, base)
                r1 = rand(seed, STREAM_BOUNCE, pid, base + 1)
                r2 = rand(seed, STREAM_BOUNCE, pid, base + 2)
                # scatter (_scatter): the shading frame, then brdf_sample
                nx, ny, nz = _facing(_lerp3(normals, i0, i1, i2, w, u, v), (dx, dy, dz), (gx, gy, gz))
                tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
                wox = -(dx * tx + dy * ty + dz * tz)
                woy = -(dx * bx + dy * by + dz * bz)
                woz = -(dx * nx + dy * ny + dz * nz)
                mat = materials[m]
                wix, wiy, wiz, pdf = brdf_sample(mat, wox, woy, woz, r0, r1, r2)
                sx = wix * tx + wiy * bx + wiz * nx
                sy = wix * ty + wiy * by + wiz * ny
                sz = wix * tz + wiy * bz + wiz * nz
                ok = wiz > 0.0 and pdf > 0.0 and sx * gx + sy * gy + sz * gz > 0.0
                # albedo (_albedo)
                xa = min(max(woz, 0.0), 1.0) * (n_albedo - 1)
                ka = min(int(xa), n_albedo - 2)
                fa = xa - ka
                a0 = (1.0 - fa) * albedo_table[m, ka, 0] + fa * albedo_table[m, ka + 1, 0]
                a1 = (1.0 - fa) * albedo_table[m, ka, 1] + fa * albedo_table[m, ka + 1, 1]
                a2 = (1.0 - fa) * albedo_table[m, ka, 2] + fa * albedo_table[m, ka + 1, 2]
                tally[T_ABSORBED] += p0 * (1.0 - a0)
                tally[T_ABSORBED + 1] += p1 * (1.0 - a1)
                tally[T_ABSORBED + 2] += p2 * (1.0 - a2)
                if depth + 1 >= max_depth:
                    tally[T_TERMINATED] += p0 * a0
                    tally[T_TERMINATED + 1] += p1 * a1
                    tally[T_TERMINATED + 2] += p2 * a2
                    continue
                if not ok:
                    continue  # below the shading or the true surface: absorbed
                fr, fg, fb = brdf_eval(mat, wix, wiy, wiz, wox, woy, woz)
                scale = wiz / pdf
                q0, q1, q2 = p0 * fr * scale, p1 * fg * scale, p2 * fb * scale
                # Russian roulette (_roulette)
                reference = max(p0, p1, p2)
                survive = min(1.0, max(q0, q1, q2) / reference) if reference > 0.0 else 0.0
                if survive <= 0.0 or rand(seed, STREAM_BOUNCE, pid, base + 3) >= survive:
                    continue
                # the survivor goes on from slot ``survivors`` <= k: photon k is read already
                ids[survivors] = pid
                power[survivors, 0], power[survivors, 1], power[survivors, 2] = q0 / survive, q1 / survive, q2 / survive
                ray[survivors, 0] = px + epsilon * gx
                ray[survivors, 1] = py + epsilon * gy
                ray[survivors, 2] = pz + epsilon * gz
                ray[survivors, 3], ray[survivors, 4], ray[survivors, 5] = sx, sy, sz
                survivors += 1
            n = survivors
    return rays


@numba.njit(cache=True, nogil=True)
def trace_gather(rt, sa, irradiance, block, light, samples, paths, spare, pdfs, hits):
    """Trace the light samples and gather paths of a ``GatherBlock`` through the scene
    ``rt`` (``embree.Embree``): fills ``light`` (``LightSamples``) and ``samples``
    (``GatherSamples``, their ``incoming`` radiance) for ``gather_outputs``.

    paths, spare : ``Rays``, pdfs : (2, count) float64 and hits : ``embree.Hits`` of the
    block's gather-ray count, the wavefront's buffers. Returns (rays traced, of which
    shadow rays).
    """
    make_gather_rays(sa, block, light, samples)
    rayhit = new_rayhit()
    shadow = 0
    for i in range(len(light.pdf)):
        if light.pdf[i] > 0.0:
            o, d = light.origins, light.directions
            light.visible[i] = not occluded1(
                rt, rayhit, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], light.distances[i]
            )
            shadow += 1
    n = len(samples.wi)
    for k in range(n):
        paths.ids[k] = k
        for c in range(3):
            paths.values[k, c] = 1.0
            paths.origins[k, c] = samples.origins[k, c]
            paths.directions[k, c] = samples.directions[k, c]
    rays = shadow
    pdf, spare_pdf = pdfs[0], pdfs[1]
    for depth in range(block.max_depth):
        if n == 0:
            break
        intersect_rays(rt, paths.origins, paths.directions, hits, 0, n)
        m, traced = shade_paths(
            rt, rayhit, sa, irradiance, block, depth, _head(paths, n), pdf[:n], head_hits(hits, n), samples, spare,
            spare_pdf,
        )
        rays += n + traced
        shadow += traced
        paths, spare = spare, paths
        pdf, spare_pdf = spare_pdf, pdf
        n = m
    return rays, shadow
