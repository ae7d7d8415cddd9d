"""Reference oracles of the solver's transport kernels: the readable wavefront form of
the physics that ``radiosity.transport.photons.trace_photons`` and
``radiosity.transport.gather.trace_gather`` run fused, for speed, in one loop each.

Here every step is a kernel over a whole batch of rays on records, with named helpers:
emit every photon (``emit_photons``), then per depth trace them all (with embreex or
``RayTracer.intersect``, outside) and deposit and scatter each (``bounce_photons``);
likewise one depth of gather paths (``shade_paths``). The tests hold the product
kernels to these bit for bit (tests/radiosity/transport/test_direct_tracing.py), and
the benchmarks replay the photons' rays through bare Embree with them. The photons' oracle
has every material kind's scattering (through the dispatch) and glass; the gather's has
the Phong kind's glossy hits alone (its microfacet and glass branches are held to their
answers by tests/radiosity/transport/test_microfacet_transport.py and
test_glass_transport.py).

Cached like the product kernels, and as safely: ``radiosity.jit_cache`` stamps these
kernels with the sources of this directory and of radiosity/, every file they inline.
"""

import math
from pathlib import Path

import numba
import numpy as np

import radiosity
from radiosity import jit_cache
from radiosity.scene.columns import KIND, KIND_DIELECTRIC
from radiosity.scene.material_kernels import (
    EMISSION,
    EXPONENT,
    HAS_FRESNEL,
    KD,
    KS,
    brdf_eval,
    brdf_sample,
    deposit_weight,
    diffuse_exitance,
    half_cosine,
    onb,
    phong_lobe,
    schlick,
)
from radiosity.transport.embree import occluded1
from radiosity.transport.lights import arriving, pick_light
from radiosity.transport.records import (
    T_ABSORBED,
    T_BACKFACE,
    T_ESCAPED,
    T_HITS,
    T_INCIDENT,
    T_TERMINATED,
)
from radiosity.transport.rng import STREAM_BOUNCE, STREAM_EMIT, STREAM_GATHER, rand
from radiosity.transport.sampling import (
    barycentric_point,
    cosine_direction,
    facing,
    glass_bounce,
    lerp3,
    off_surface,
    pick_emitter,
    roulette,
    shading_normal,
    toward_light_point,
)

# this file's kernels are stamped with this directory's sources and radiosity's
jit_cache.cover(Path(__file__).parent, inlines_from=(Path(radiosity.__file__).parent,))

# -- photons ------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _albedo(sa, m, cos_theta, c):
    """The true directional albedo of material m at cos_theta, channel c (its table, linearly)."""
    table = sa.albedo_table[m]
    x = min(max(cos_theta, 0.0), 1.0) * (table.shape[0] - 1)
    k = min(int(x), table.shape[0] - 2)
    f = x - k
    return (1.0 - f) * table[k, c] + f * table[k + 1, c]


@numba.njit(cache=True, inline="always")
def _scatter(sa, t, uv, d, rnd):
    """Sample the BRDF at a hit on triangle t (barycentrics uv) reached along d, in the
    shading frame there, with the uniform numbers rnd = (u1, u2, u3) of ``brdf_sample``.

    Returns (wo, wi, pdf, world, ok): wo and wi in the local frame, the mixture pdf,
    the sampled direction in world space, and whether it leaves above both the shading
    and the true (geometric) surface.
    """
    mat = sa.materials[sa.face_material[t]]
    nx, ny, nz = shading_normal(sa, t, uv[0], uv[1], d)
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


@numba.njit(cache=True, inline="always")
def _push_ray(out, i, item, origin, direction, value):
    """Write ray i of ``out`` (``Rays``): id ``item``, its origin, direction and RGB value."""
    out.ids[i] = item
    for c in range(3):
        out.origins[i, c] = origin[c]
        out.directions[i, c] = direction[c]
        out.values[i, c] = value[c]


@numba.njit(cache=True)
def emit_photons(sa, seed, first_id, total, out):
    """Emit photons first_id .. first_id + len(out.ids) - 1 of ``total`` into ``out``
    (``Rays``): a triangle in proportion to its power, a uniform point on it, a
    cosine-distributed direction about its front. Each carries pi Le / (total * area
    pdf), so the batch's power sums to the emitters' power in expectation."""
    for i in range(len(out.ids)):
        pid = first_id + i
        tri = pick_emitter(sa.emit_cdf, sa.emit_triangles, rand(seed, STREAM_EMIT, pid, 0))
        s = math.sqrt(rand(seed, STREAM_EMIT, pid, 1))
        u = s * (1.0 - rand(seed, STREAM_EMIT, pid, 2))
        v = s - u
        point = barycentric_point(sa, tri, u, v)
        g = sa.face_normals[tri]
        lx, ly, lz = cosine_direction(rand(seed, STREAM_EMIT, pid, 3), rand(seed, STREAM_EMIT, pid, 4))
        tx, ty, tz, bx, by, bz = onb(g[0], g[1], g[2])
        direction = (lx * tx + ly * bx + lz * g[0], lx * ty + ly * by + lz * g[1], lx * tz + ly * bz + lz * g[2])
        m = sa.face_material[tri]
        scale = math.pi / (total * sa.emit_area_pdf[tri])
        power = (
            sa.materials[m, EMISSION] * scale,
            sa.materials[m, EMISSION + 1] * scale,
            sa.materials[m, EMISSION + 2] * scale,
        )
        _push_ray(out, i, pid, off_surface(point, g, sa.epsilon), direction, power)


@numba.njit(cache=True, inline="always")
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


@numba.njit(cache=True)
def bounce_photons(sa, batch, depth, photons, hits, acc, out):
    """Deposit each photon of ``batch`` (``PhotonBatch``: its seed and max_depth) at
    ``depth`` where it landed and scatter it on; returns the survivors' count.

    photons : ``Rays`` in flight (values: power); hits : their ``embree.Hits``;
    acc : the batch's ``PhotonTally``; out : ``Rays`` receiving the survivors.
    """
    seed, max_depth = batch.seed, batch.max_depth
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
        m = sa.face_material[t]
        if sa.materials[m, KIND] >= KIND_DIELECTRIC:  # glass, either face: no deposit, on through it
            base = depth * 8
            weight, origin, direction, _ = glass_bounce(
                (sa.positions, sa.normals, sa.faces, sa.face_normals), sa.epsilon, sa.materials[m],
                (t, np.float64(hits.u[k]), np.float64(hits.v[k])), d,
                (rand(seed, STREAM_BOUNCE, pid, base), rand(seed, STREAM_BOUNCE, pid, base + 1),
                 rand(seed, STREAM_BOUNCE, pid, base + 2)), False)
            scattered = (power[0] * weight[0], power[1] * weight[1], power[2] * weight[2])
            for c in range(3):
                tally[T_ABSORBED + c] += power[c] - scattered[c]
            if depth + 1 >= max_depth:
                for c in range(3):
                    tally[T_TERMINATED + c] += scattered[c]
                continue
            survives, carried = roulette(
                scattered, max(power[0], power[1], power[2]), rand(seed, STREAM_BOUNCE, pid, base + 3)
            )
            if survives:
                _push_ray(out, n_out, pid, origin, direction, carried)
                n_out += 1
            continue
        if d[0] * g[0] + d[1] * g[1] + d[2] * g[2] >= 0.0:
            for c in range(3):
                tally[T_BACKFACE + c] += power[c]
            continue
        uk, vk = np.float64(hits.u[k]), np.float64(hits.v[k])
        point = barycentric_point(sa, t, uk, vk)
        deposited = power
        if sa.materials[m, HAS_FRESNEL] > 0.0:
            n = facing(lerp3(sa.normals, sa.faces[t, 0], sa.faces[t, 1], sa.faces[t, 2], 1.0 - uk - vk, uk, vk), d, g)
            fw = deposit_weight(sa.materials[m], -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2]))
            deposited = (power[0] * fw, power[1] * fw, power[2] * fw)
        _deposit(sa, t, point, (1.0 - uk - vk, uk, vk), deposited, acc)
        for c in range(3):
            tally[T_INCIDENT + c] += power[c]

        base = depth * 8
        rnd = (
            rand(seed, STREAM_BOUNCE, pid, base),
            rand(seed, STREAM_BOUNCE, pid, base + 1),
            rand(seed, STREAM_BOUNCE, pid, base + 2),
        )
        wo, wi, pdf, direction, ok = _scatter(sa, t, (uk, vk), d, rnd)
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
        survives, carried = roulette(
            scattered, max(power[0], power[1], power[2]), rand(seed, STREAM_BOUNCE, pid, base + 3)
        )
        if not survives:
            continue
        _push_ray(out, n_out, pid, off_surface(point, (g[0], g[1], g[2]), sa.epsilon), direction, carried)
        n_out += 1
    return n_out


# -- gather -------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _emission_weight(sa, block, depth, d, point, t, before):
    """The balance-heuristic weight of the emission a gather path finds at triangle t:
    against the vertex's light samples on the first segment, the previous glossy
    hit's light sample later; before = (the density with which the path's direction
    was sampled: the gather ray's cos / pi, later the lobe's; the segment's origin).
    d is the direction of travel; 0 for an analytic emitter part's direct highlight."""
    if depth == 0 and sa.emit_area_pdf[t] > 0.0 and sa.direct_area_pdf[t] <= 0.0:
        return 0.0
    if not (sa.emit_area_pdf[t] > 0.0 and (depth > 0 or block.n_light > 0)):
        return 1.0
    g = sa.face_normals[t]
    cos_light = -(d[0] * g[0] + d[1] * g[1] + d[2] * g[2])
    ex, ey, ez = point[0] - before[1][0], point[1] - before[1][1], point[2] - before[1][2]
    dist = math.sqrt(ex * ex + ey * ey + ez * ez)
    n_gather = block.strata * block.strata
    if depth == 0:
        p_light = sa.direct_area_pdf[t] * dist * dist / cos_light
        return n_gather * before[0] / (n_gather * before[0] + block.n_light * p_light)
    if block.lobe_light:
        p_light = sa.emit_area_pdf[t] * dist * dist / cos_light
        return before[0] / (before[0] + p_light)
    return 1.0


@numba.njit(cache=True)
def shade_paths(tracing, sa, irradiance, block, depth, wave, samples, out):
    """Radiance arriving along one depth of a gather block's paths; returns (the number
    of paths that go on, the shadow rays traced).

    tracing : (the scene ``embree.Embree``, a ray-hit record) for the glossy hits'
    shadow rays; wave : (``Rays`` in flight, values: throughput; their lobe densities;
    their ``embree.Hits``); samples : the block's ``GatherSamples``; out : (``Rays``,
    densities) receiving the paths that go on. What each path adds and how it goes on:
    ``radiosity.transport.gather.trace_gather``.
    """
    rt, rayhit = tracing
    paths, path_pdf, hits = wave
    out_rays, out_pdf = out
    n_gather = block.strata * block.strata
    n_out = 0
    shadow = 0
    for k in range(len(paths.ids)):
        t = hits.triangle[k]
        if t < 0:
            continue
        d = (paths.directions[k, 0], paths.directions[k, 1], paths.directions[k, 2])
        g = (sa.face_normals[t, 0], sa.face_normals[t, 1], sa.face_normals[t, 2])
        if d[0] * g[0] + d[1] * g[1] + d[2] * g[2] >= 0.0:
            continue
        uk, vk = np.float64(hits.u[k]), np.float64(hits.v[k])
        point = barycentric_point(sa, t, uk, vk)
        m = sa.face_material[t]
        target = paths.ids[k]
        p_before = samples.wi[target, 2] / math.pi if depth == 0 else path_pdf[k]
        origin = (paths.origins[k, 0], paths.origins[k, 1], paths.origins[k, 2])
        weight = _emission_weight(sa, block, depth, d, point, t, (p_before, origin))
        i0, i1, i2 = sa.faces[t, 0], sa.faces[t, 1], sa.faces[t, 2]
        fresnel = sa.materials[m, HAS_FRESNEL] > 0.0
        n = facing(lerp3(sa.normals, i0, i1, i2, 1.0 - uk - vk, uk, vk), d, g)
        kd_scale = diffuse_exitance(sa.materials[m], -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2])) if fresnel else 1.0
        for c in range(3):
            e = (1.0 - uk - vk) * irradiance[i0, c] + uk * irradiance[i1, c] + vk * irradiance[i2, c]
            kd = sa.materials[m, KD + c] * kd_scale if fresnel else sa.materials[m, KD + c]
            radiance = weight * sa.materials[m, EMISSION + c] + kd / math.pi * e
            samples.incoming[target, c] += paths.values[k, c] * radiance
        ks = (sa.materials[m, KS], sa.materials[m, KS + 1], sa.materials[m, KS + 2])
        if max(ks[0], ks[1], ks[2]) <= 0.0 or depth + 1 >= block.max_depth:
            continue
        item = (block.vertices[target // n_gather] * n_gather + target % n_gather) * block.max_depth + depth
        exponent = sa.materials[m, EXPONENT]
        if len(sa.emit_triangles) > 0 and block.lobe_light:
            shadow += _glossy_light_sample(
                (rt, rayhit), sa, (point, g, n, d), (exponent, ks, sa.materials[m]), _light_numbers(block.seed, item),
                paths.values[k], samples.incoming[target],
            )  # fmt: skip
        if len(sa.lights.kinds) > 0:
            shadow += _glossy_delta_sample(
                (rt, rayhit), sa, (point, g, n, d), (exponent, ks, sa.materials[m]),
                rand(block.seed, STREAM_GATHER + 3, item, 0), paths.values[k], samples.incoming[target],
            )  # fmt: skip
        nx, ny, nz = n
        tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
        wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
        woy = -(d[0] * bx + d[1] * by + d[2] * bz)
        woz = -(d[0] * nx + d[1] * ny + d[2] * nz)
        wix, wiy, wiz, pdf = brdf_sample(
            sa.materials[m], wox, woy, woz, 0.0,
            rand(block.seed, STREAM_GATHER + 1, item, 0), rand(block.seed, STREAM_GATHER + 1, item, 1),
        )  # fmt: skip
        sx = wix * tx + wiy * bx + wiz * nx
        sy = wix * ty + wiy * by + wiz * ny
        sz = wix * tz + wiy * bz + wiz * nz
        if not (wiz > 0.0 and pdf > 0.0 and sx * g[0] + sy * g[1] + sz * g[2] > 0.0):
            continue
        lobe_weight = (exponent + 2.0) / (exponent + 1.0) * wiz
        if fresnel:
            f = schlick(sa.materials[m], half_cosine(wix * wox + wiy * woy + wiz * woz))
            ks = (ks[0] * f[0], ks[1] * f[1], ks[2] * f[2])
        q = (
            paths.values[k, 0] * ks[0] * lobe_weight,
            paths.values[k, 1] * ks[1] * lobe_weight,
            paths.values[k, 2] * ks[2] * lobe_weight,
        )
        survives, carried = roulette(q, 1.0, rand(block.seed, STREAM_GATHER + 1, item, 2))
        if not survives:
            continue
        cos_alpha = min(max(-wix * wox - wiy * woy + wiz * woz, 0.0), 1.0)
        out_pdf[n_out] = (exponent + 1.0) / (2.0 * math.pi) * phong_lobe(cos_alpha, exponent)
        _push_ray(out_rays, n_out, target, off_surface(point, g, sa.epsilon), (sx, sy, sz), carried)
        n_out += 1
    return n_out, shadow


@numba.njit(cache=True, inline="always")
def _light_numbers(seed, item):
    """The three numbers of the light sample at a glossy hit."""
    return (
        rand(seed, STREAM_GATHER + 2, item, 0),
        rand(seed, STREAM_GATHER + 2, item, 1),
        rand(seed, STREAM_GATHER + 2, item, 2),
    )


@numba.njit(cache=True, inline="always")
def _glossy_light_sample(tracing, sa, where, lobe, rnd, throughput, incoming):
    """The light sample at a glossy hit where = (point, g, shading normal n, arrival
    direction d), for lobe = (exponent, ks, the material row: its Fresnel): adds its balance-heuristic-weighted
    contribution to ``incoming`` (3,) when its shadow ray is clear; returns the shadow
    rays traced (0 or 1)."""
    rt, rayhit = tracing
    point, g, n, d = where
    exponent, ks, mat = lobe
    tri = pick_emitter(sa.emit_cdf, sa.emit_triangles, rnd[0])
    area_pdf = sa.emit_area_pdf[tri]
    if area_pdf <= 0.0:
        return 0
    origin = off_surface(point, g, sa.epsilon)
    (dx, dy, dz), dist, cos_light = toward_light_point(
        sa.positions, sa.faces, sa.face_normals, sa.epsilon, tri, origin, (rnd[1], rnd[2])
    )
    if dist <= 0.0:
        return 0
    nx, ny, nz = n
    cos_i = dx * nx + dy * ny + dz * nz
    if not (cos_light > 0.0 and cos_i > 0.0 and dx * g[0] + dy * g[1] + dz * g[2] > 0.0):
        return 0
    dn = d[0] * nx + d[1] * ny + d[2] * nz
    cos_alpha = dx * (d[0] - 2.0 * dn * nx) + dy * (d[1] - 2.0 * dn * ny) + dz * (d[2] - 2.0 * dn * nz)
    if cos_alpha <= 0.0:
        return 0
    value = phong_lobe(min(cos_alpha, 1.0), exponent)
    if value <= 0.0:
        return 0
    if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist):
        p_light = area_pdf * dist * dist / cos_light
        p_lobe = (exponent + 1.0) / (2.0 * math.pi) * value
        scale = (exponent + 2.0) / (2.0 * math.pi) * value * cos_i / (p_light + p_lobe)
        lm = sa.face_material[tri]
        if mat[HAS_FRESNEL] > 0.0:
            f = schlick(mat, half_cosine(-(dx * d[0] + dy * d[1] + dz * d[2])))
            ks = (ks[0] * f[0], ks[1] * f[1], ks[2] * f[2])
        for c in range(3):
            incoming[c] += throughput[c] * (ks[c] * sa.materials[lm, EMISSION + c] * scale)
    return 1


@numba.njit(cache=True, inline="always")
def _glossy_delta_sample(tracing, sa, where, lobe, u, throughput, incoming):
    """The delta light's sample at a glossy hit where = (point, g, shading normal n,
    arrival direction d): light j of ``sa.lights`` chosen by power with the uniform
    number u, adding f_s cos I / d^2 (E for a direction) over the probability of the
    choice to ``incoming`` (3,) when its shadow ray is clear; returns the shadow rays
    traced (0 or 1)."""
    rt, rayhit = tracing
    point, g, n, d = where
    exponent, ks, mat = lobe
    lights = sa.lights
    j = pick_light(lights.cdf, u)
    origin = off_surface(point, g, sa.epsilon)
    (dx, dy, dz), dist, le = arriving(lights, j, origin)
    nx, ny, nz = n
    cos_i = dx * nx + dy * ny + dz * nz
    if not (dist > sa.epsilon and max(le[0], le[1], le[2]) > 0.0 and cos_i > 0.0
            and dx * g[0] + dy * g[1] + dz * g[2] > 0.0):
        return 0
    dn = d[0] * nx + d[1] * ny + d[2] * nz
    cos_alpha = dx * (d[0] - 2.0 * dn * nx) + dy * (d[1] - 2.0 * dn * ny) + dz * (d[2] - 2.0 * dn * nz)
    value = phong_lobe(min(cos_alpha, 1.0), exponent) if cos_alpha > 0.0 else 0.0
    if value <= 0.0:
        return 0
    if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist - sa.epsilon):
        scale = (exponent + 2.0) / (2.0 * math.pi) * value * cos_i / lights.pick[j]
        f = (1.0, 1.0, 1.0)
        if mat[HAS_FRESNEL] > 0.0:
            f = schlick(mat, half_cosine(-(dx * d[0] + dy * d[1] + dz * d[2])))
        for c in range(3):
            incoming[c] += throughput[c] * (ks[c] * f[c] * le[c] * scale)
    return 1
