"""The solver's photon phase: one jitted kernel traces a batch of photons from their
emission to their end, calling Embree directly and releasing the GIL, and adds their
incident power to the density moments of the vertices around each hit.

The photons of a batch go in waves of ``batch.wave``: the rays of a wave's photons at
one depth are traced one after another, then their hits are shaded one after another,
each hit's triangle and vertices asked of the cache a few hits ahead (PREFETCH_AHEAD).
So Embree runs with its own data in cache, and the shading does not wait for memory at
every hit (on a large mesh the hits' data is not in cache).

The readable wavefront form of the same physics (emit every photon, then per depth
trace them all and bounce them) is the tests' oracle (tests/oracles/wavefront.py): each
photon's rays and deposits are the same bit for bit, and only the order in which a
batch's deposits are summed depends on the wave size (tests check both).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.environment import env_lookup, env_sample
from radiosity.scene.columns import KIND, KIND_DIELECTRIC
from radiosity.scene.material_kernels import (
    EMISSION,
    HAS_FRESNEL,
    KD,
    NCOL,
    brdf_eval,
    brdf_sample,
    deposit_weight,
    diffuse_exitance,
    onb,
    textured_row,
)
from radiosity.transport.embree import intersect1, new_rayhit
from radiosity.transport.lights import emit_delta, pick_light
from radiosity.transport.records import (
    T_ABSORBED,
    T_BACKFACE,
    T_ESCAPED,
    T_HITS,
    T_INCIDENT,
    T_TERMINATED,
)
from radiosity.transport.rng import PHOTON_DIMS_PER_BOUNCE, STREAM_BOUNCE, STREAM_EMIT, rand
from radiosity.transport.sampling import (
    cosine_direction,
    facing,
    glass_bounce,
    hit_texel,
    lerp3,
    pick_emitter,
    prefetch_row,
    roulette,
)

PREFETCH_AHEAD = 4  # hits ahead whose data the wave's shading loop asks the cache for


@numba.njit(cache=True, nogil=True, inline="always")
def _prefetch_hit(t, faces, face_normals, face_material, positions, moment0, moment1):
    """Ask the cache for what shading a hit on triangle t waits for most: the
    triangle's rows, and its vertices' positions and density moments (their indices
    are read, so ``faces`` should be asked first)."""
    if t < 0:
        return
    prefetch_row(face_normals, t)
    prefetch_row(face_material, t)
    for j in range(3):
        vert = faces[t, j]
        prefetch_row(positions, vert)
        prefetch_row(moment0, vert)
        prefetch_row(moment1, vert)


@numba.njit(cache=True, nogil=True, inline="always")
def _go_on(wave, survivors, pid, scattered, reference, u, origin, direction):
    """Russian roulette (``sampling.roulette``) on a photon's ``scattered`` power against
    its power before the bounce (``reference``); a survivor goes on from slot
    ``survivors`` of the wave's buffers (ids, power, ray), which is at most the photon's
    own: it is read already. Returns the survivors' count."""
    ids, power, ray = wave
    survives, carried = roulette(scattered, reference, u)
    if not survives:
        return survivors
    ids[survivors] = pid
    for c in range(3):
        power[survivors, c] = carried[c]
        ray[survivors, c] = origin[c]
        ray[survivors, 3 + c] = direction[c]
    return survivors + 1


@numba.njit(cache=True, nogil=True, inline="always")
def _environment_photon(env, total_share, u):
    """(power, origin, direction) of a photon from the environment ``env`` (``EnvArrays``):
    a direction w towards it drawn from it (u[0], u[1]; density p(w)), a point on the disk
    of the scene's bounding sphere facing w (u[2], u[3]) pushed out by R along w, the
    photon going along -w with L(w) pi R^2 / (``total_share`` p(w)); nothing where p = 0."""
    (wx, wy, wz), pdf = env_sample(env.rotation, env.row_cdf, env.column_cdf, env.cell_pdf, u[0], u[1])
    le = env_lookup(env.pixels, env.rotation, wx, wy, wz) if pdf > 0.0 else (0.0, 0.0, 0.0)
    scale = math.pi * env.radius * env.radius / (total_share * pdf) if pdf > 0.0 else 0.0
    ox, oy, _ = cosine_direction(u[2], u[3])
    tx, ty, tz, bx, by, bz = onb(wx, wy, wz)
    centre, radius = env.center, env.radius
    origin = (centre[0] + radius * (ox * tx + oy * bx + wx), centre[1] + radius * (ox * ty + oy * by + wy),
              centre[2] + radius * (ox * tz + oy * bz + wz))
    return (le[0] * scale, le[1] * scale, le[2] * scale), origin, (-wx, -wy, -wz)


@numba.njit(cache=True, nogil=True, inline="always")
def _surface_photon(mesh, epsilon, tri, u):
    """(origin, direction) of a photon leaving emitter triangle ``tri`` of mesh =
    (positions, faces, face_normals): a uniform point on it (u[0], u[1]) pushed
    ``epsilon`` off its front, a cosine-distributed direction about its normal (u[2], u[3])."""
    positions, faces, face_normals = mesh
    s = math.sqrt(u[0])
    a = s * (1.0 - u[1])
    b = s - a
    px, py, pz = lerp3(positions, faces[tri, 0], faces[tri, 1], faces[tri, 2], 1.0 - a - b, a, b)
    gx, gy, gz = face_normals[tri, 0], face_normals[tri, 1], face_normals[tri, 2]
    lx, ly, lz = cosine_direction(u[2], u[3])
    tx, ty, tz, bx, by, bz = onb(gx, gy, gz)
    return ((px + epsilon * gx, py + epsilon * gy, pz + epsilon * gz),
            (lx * tx + ly * bx + lz * gx, lx * ty + ly * by + lz * gy, lx * tz + ly * bz + lz * gz))


@numba.njit(cache=True, nogil=True, inline="always")
def _deposit(moments, frame, t, point, barycentric, power):
    """Add ``power`` arriving at ``point`` of triangle t to the density moments =
    (moment0, moment1) of its three vertices: moment0[j] += power lambda_j and
    moment1[j] += power lambda_j (x - p_j) in vertex j's tangent frame (frame =
    (positions, normals, tangents, faces); barycentric = (w, u, v), lambda_j the hat
    function of vertex j)."""
    moment0, moment1 = moments
    positions, normals, tangents, faces = frame
    px, py, pz = point
    for j in range(3):
        vert = faces[t, j]
        lam = barycentric[j]
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
            wc = power[c] * lam
            moment0[vert, c] += wc
            moment1[vert, c, 0] += wc * along_t
            moment1[vert, c, 1] += wc * along_b


@numba.njit(cache=True, nogil=True, inline="always")
def _true_albedo(albedo_table, m, cosine):
    """Material m's true albedo (RGB) towards a view of this cosine, interpolated in its
    table (``albedo_table[m]``, cosines 0..1 evenly)."""
    n_albedo = albedo_table.shape[1]
    xa = min(max(cosine, 0.0), 1.0) * (n_albedo - 1)
    ka = min(int(xa), n_albedo - 2)
    fa = xa - ka
    return ((1.0 - fa) * albedo_table[m, ka, 0] + fa * albedo_table[m, ka + 1, 0],
            (1.0 - fa) * albedo_table[m, ka, 1] + fa * albedo_table[m, ka + 1, 1],
            (1.0 - fa) * albedo_table[m, ka, 2] + fa * albedo_table[m, ka + 1, 2])


@numba.njit(cache=True, nogil=True)
def trace_photons(rt, sa, batch, acc):
    """Trace the photons of ``batch`` (``PhotonBatch``) to their end through the scene
    ``rt`` (``embree.Embree``) and ``sa`` (``SceneArrays``), adding to ``acc``
    (``PhotonTally``). Returns the rays traced.

    Each photon: an emitter triangle in proportion to its power, a uniform point on
    it, a cosine-distributed direction about its front, carrying pi Le / (total *
    area pdf), so a pass's power sums to the emitters' power in expectation. Or, with
    probability ``sa.env.photon_share`` (the environment's share of the power), the
    environment's: a direction w drawn from it (``environment.env_sample``, density
    p(w)), a uniform point on the disk of the scene's bounding sphere (centre c,
    radius R) facing w, the photon starting at that point pushed out by R along w and
    going along -w, carrying L(w) pi R^2 / (total * share * p(w)). Or, with
    probability ``sa.lights.photon_share``, a delta light's (``lights.emit_delta``: one
    chosen by power, from its position or the disk facing its direction). At a
    front-face hit its incident power is added to the density moments of the
    triangle's three vertices (times ``materials.deposit_weight``: 1 without Fresnel):
    moment0[j] += power * lambda_j and moment1[j] += power
    * lambda_j * (x - p_j) in vertex j's tangent frame (lambda_j the barycentric
    weight, the hat function of vertex j). It then scatters by BRDF sampling with
    Russian roulette that keeps its power about constant. Backs absorb. On a textured
    triangle the diffuse colour is kd * texture(uv at the hit) (``textured_row``) for
    the scattering and the absorbed-power tally alike.

    ``acc.tally`` gains escaped power, the expected absorbed power (incident * (1 -
    true albedo)), incident power, back-face and forced-termination losses, and the
    hit count: emitted = escaped + absorbed + backface + terminated in expectation,
    which tests check.

    The records are unpacked into locals once: the loops index arrays with scalars (a
    record handed to an inlined helper costs a reference-count update of each of its
    arrays), and the batch works on its own copy of the small material table (a row
    of it per bounce, a reference-count update that threads must not share). The
    survivors of a depth are packed to the front of the wave's buffers in order.
    ``batch.wave`` = 1 follows one photon at a time. The prefetches
    (``_prefetch_hit``, PREFETCH_AHEAD hits ahead, the triangle's vertex indices twice
    as far) change no value.
    """
    positions, normals, tangents, faces = sa.positions, sa.normals, sa.tangents, sa.faces
    face_normals, face_material, materials = sa.face_normals, sa.face_material, sa.materials.copy()
    albedo_table, emit_cdf, emit_triangles, emit_area_pdf = sa.albedo_table, sa.emit_cdf, sa.emit_triangles, sa.emit_area_pdf
    epsilon = sa.epsilon
    env = sa.env
    env_share = env.photon_share
    lights = sa.lights
    lights_share = lights.photon_share
    seed, first_id, count, total, max_depth = batch.seed, batch.first_id, batch.count, batch.total, batch.max_depth
    wave = max(1, min(batch.wave, count))
    moment0, moment1, tally = acc.moment0, acc.moment1, acc.tally
    rayhit = new_rayhit()
    ids = np.empty(wave, np.int64)
    power = np.empty((wave, 3))
    ray = np.empty((wave, 6), np.float32)  # origin, direction: float32, as a ``Rays`` stores them
    hit_triangle = np.empty(wave, np.int64)
    hit_uv = np.empty((wave, 2), np.float32)
    row = np.empty(NCOL)  # a textured hit's material row
    rays = 0
    for first in range(first_id, first_id + count, wave):
        n = min(wave, first_id + count - first)
        # -- emission --
        for i in range(n):
            pid = first + i
            u0 = rand(seed, STREAM_EMIT, pid, 0)
            ids[i] = pid
            if u0 < env_share:  # from the environment
                carried, origin, direction = _environment_photon(
                    env, total * env_share, (rand(seed, STREAM_EMIT, pid, 1), rand(seed, STREAM_EMIT, pid, 2),
                                             rand(seed, STREAM_EMIT, pid, 3), rand(seed, STREAM_EMIT, pid, 4)))
            elif lights_share > 0.0 and (u0 < env_share + lights_share or lights.only):
                # from a delta light, chosen by power
                j = pick_light(lights.cdf, min((u0 - env_share) / lights_share, 1.0))
                origin, direction, carried = emit_delta(
                    lights, j, (rand(seed, STREAM_EMIT, pid, 1), rand(seed, STREAM_EMIT, pid, 2)),
                    1.0 / (total * lights_share * lights.pick[j]),
                )  # fmt: skip
            else:
                # from an emitting triangle, chosen by power
                if env_share > 0.0 or lights_share > 0.0:
                    u0 = (u0 - env_share - lights_share) / (1.0 - env_share - lights_share)
                tri = pick_emitter(emit_cdf, emit_triangles, u0)
                origin, direction = _surface_photon(
                    (positions, faces, face_normals), epsilon, tri,
                    (rand(seed, STREAM_EMIT, pid, 1), rand(seed, STREAM_EMIT, pid, 2),
                     rand(seed, STREAM_EMIT, pid, 3), rand(seed, STREAM_EMIT, pid, 4)))
                m = face_material[tri]
                scale = math.pi / (total * emit_area_pdf[tri])
                if env_share > 0.0 or lights_share > 0.0:
                    scale /= 1.0 - env_share - lights_share
                carried = (materials[m, EMISSION] * scale, materials[m, EMISSION + 1] * scale,
                           materials[m, EMISSION + 2] * scale)
            for c in range(3):
                power[i, c] = carried[c]
                ray[i, c] = origin[c]
                ray[i, 3 + c] = direction[c]
        for depth in range(max_depth):
            if n == 0:
                break
            # -- the wave's rays, one after another --
            for k in range(n):
                r = ray[k]
                t, _, hu, hv = intersect1(rt, rayhit, (r[0], r[1], r[2]), (r[3], r[4], r[5]))
                hit_triangle[k] = t
                hit_uv[k, 0], hit_uv[k, 1] = hu, hv
            rays += n
            # -- their hits, survivors packed to the front --
            for k in range(min(n, 2 * PREFETCH_AHEAD)):
                if hit_triangle[k] >= 0:
                    prefetch_row(faces, hit_triangle[k])
            survivors = 0
            for k in range(n):
                if k + 2 * PREFETCH_AHEAD < n and hit_triangle[k + 2 * PREFETCH_AHEAD] >= 0:
                    prefetch_row(faces, hit_triangle[k + 2 * PREFETCH_AHEAD])
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
                m = face_material[t]
                if materials[m, KIND] >= KIND_DIELECTRIC:
                    # glass, either face: no deposit, reflected or refracted on
                    base = depth * PHOTON_DIMS_PER_BOUNCE
                    weight, origin, direction, _ = glass_bounce(
                        (positions, normals, faces, face_normals), epsilon, materials[m],
                        (t, np.float64(hit_uv[k, 0]), np.float64(hit_uv[k, 1])), (dx, dy, dz),
                        (rand(seed, STREAM_BOUNCE, pid, base), rand(seed, STREAM_BOUNCE, pid, base + 1),
                         rand(seed, STREAM_BOUNCE, pid, base + 2)), False)
                    q0, q1, q2 = p0 * weight[0], p1 * weight[1], p2 * weight[2]
                    tally[T_ABSORBED] += p0 - q0
                    tally[T_ABSORBED + 1] += p1 - q1
                    tally[T_ABSORBED + 2] += p2 - q2
                    if depth + 1 >= max_depth:
                        tally[T_TERMINATED] += q0
                        tally[T_TERMINATED + 1] += q1
                        tally[T_TERMINATED + 2] += q2
                        continue
                    survivors = _go_on((ids, power, ray), survivors, pid, (q0, q1, q2), max(p0, p1, p2),
                                       rand(seed, STREAM_BOUNCE, pid, base + 3), origin, direction)
                    continue
                if dx * gx + dy * gy + dz * gz >= 0.0:
                    tally[T_BACKFACE] += p0
                    tally[T_BACKFACE + 1] += p1
                    tally[T_BACKFACE + 2] += p2
                    continue
                u, v = np.float64(hit_uv[k, 0]), np.float64(hit_uv[k, 1])
                w = 1.0 - u - v
                i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
                px, py, pz = lerp3(positions, i0, i1, i2, w, u, v)
                # the shading frame
                nx, ny, nz = facing(lerp3(normals, i0, i1, i2, w, u, v), (dx, dy, dz), (gx, gy, gz))
                if materials[m, HAS_FRESNEL] > 0.0:
                    # a Fresnel surface's estimate counts what its diffuse part lets in
                    fw = deposit_weight(materials[m], -(dx * nx + dy * ny + dz * nz))
                    d0, d1, d2 = p0 * fw, p1 * fw, p2 * fw
                else:
                    d0, d1, d2 = p0, p1, p2
                _deposit((moment0, moment1), (positions, normals, tangents, faces), t, (px, py, pz), (w, u, v),
                         (d0, d1, d2))
                tally[T_INCIDENT] += p0
                tally[T_INCIDENT + 1] += p1
                tally[T_INCIDENT + 2] += p2
                base = depth * PHOTON_DIMS_PER_BOUNCE
                r0 = rand(seed, STREAM_BOUNCE, pid, base)
                r1 = rand(seed, STREAM_BOUNCE, pid, base + 1)
                r2 = rand(seed, STREAM_BOUNCE, pid, base + 2)
                # scatter: brdf_sample in the shading frame
                tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
                wox = -(dx * tx + dy * ty + dz * tz)
                woy = -(dx * bx + dy * by + dz * bz)
                woz = -(dx * nx + dy * ny + dz * nz)
                mat = materials[m]
                texture = sa.face_texture[t]
                tex0, tex1, tex2 = 1.0, 1.0, 1.0
                if texture >= 0:
                    tex0, tex1, tex2 = hit_texel(sa, texture, t, u, v)
                    mat = textured_row(mat, (tex0, tex1, tex2), row)
                wix, wiy, wiz, pdf = brdf_sample(mat, wox, woy, woz, r0, r1, r2)
                sx = wix * tx + wiy * bx + wiz * nx
                sy = wix * ty + wiy * by + wiz * ny
                sz = wix * tz + wiy * bz + wiz * nz
                ok = wiz > 0.0 and pdf > 0.0 and sx * gx + sy * gy + sz * gz > 0.0
                # the true albedo, interpolated in its table
                a0, a1, a2 = _true_albedo(albedo_table, m, woz)
                if texture >= 0:  # the diffuse part of the albedo is kd (kd b(cos) with Fresnel): kd * texel instead
                    b = diffuse_exitance(materials[m], woz)
                    a0 += b * materials[m, KD] * (tex0 - 1.0)
                    a1 += b * materials[m, KD + 1] * (tex1 - 1.0)
                    a2 += b * materials[m, KD + 2] * (tex2 - 1.0)
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
                survivors = _go_on((ids, power, ray), survivors, pid, (q0, q1, q2), max(p0, p1, p2),
                                   rand(seed, STREAM_BOUNCE, pid, base + 3),
                                   (px + epsilon * gx, py + epsilon * gy, pz + epsilon * gz), (sx, sy, sz))
            n = survivors
    return rays
