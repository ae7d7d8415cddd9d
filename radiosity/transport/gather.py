"""The solver's gather phase: the outgoing radiance of a block of glossy vertices in
every direction of their grid, from light samples and gather paths traced by one
jitted kernel (``trace_gather``, calling Embree directly and releasing the GIL) and
summed over each sample's Phong lobe by ``gather_outputs``.

A gather block goes wavefront-style inside ``trace_gather``: its rays are made
(``make_gather_rays``), its light samples' shadow rays traced, then per depth every
path in flight is traced and its hit shaded. The readable form of the shading, on
records (``shade_paths``), is the tests' oracle (tests/oracles/wavefront.py), which the kernel
matches bit for bit.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.directions import square_boundary_nb
from radiosity.physics.environment import env_lookup
from radiosity.scene.columns import KIND, KIND_DIELECTRIC, KIND_PHONG, MF_ALPHA, MF_DISTRIBUTION, MF_GGX
from radiosity.scene.material_kernels import (
    EMISSION,
    EXPONENT,
    HAS_FRESNEL,
    KD,
    KS,
    brdf_sample,
    diffuse_exitance,
    half_cosine,
    onb,
    phong_lobe,
    schlick,
    specular_eval,
    specular_pdf,
    specular_sample,
)
from radiosity.scene.microfacet_kernels import interface_fresnel, smith_g1
from radiosity.transport.embree import intersect_rays, new_rayhit, occluded1
from radiosity.transport.lights import arriving, pick_light
from radiosity.transport.rng import (
    STREAM_GATHER,
    STREAM_GATHER_DELTA,
    STREAM_GATHER_LIGHT,
    STREAM_LIGHT,
    STREAM_LOBE,
    rand,
)
from radiosity.transport.sampling import (
    cosine_direction,
    facing,
    glass_bounce,
    hit_texel,
    lerp3,
    off_surface,
    pick_emitter,
    roulette,
    toward_light_point,
)

LOBE_CUTOFF = 1e-3  # gather: lobe values below this fraction of the peak are skipped (<= 0.1 % of its energy)
LOBE_TABLE = 2048  # entries of the cos^n table
# a lobe this wide (radians from its axis to LOBE_CUTOFF; Phong exponents below about 26)
# visits every cell: its window (``lobe_window``) would save too few to pay for itself
WHOLE_GRID_CONE = 0.7
WINDOW_MARGIN = 1e-9  # square units around a lobe's window: rounding in the map and the grid's directions
_PI_OVER_4 = math.pi / 4.0
LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709: the gather's noise is measured in luminance


@numba.njit(cache=True, nogil=True)
def make_gather_rays(sa, block, light, samples):
    """Rays for the vertices of one ``GatherBlock``: ``block.n_light`` light samples
    (shadow rays, into ``light``: ``LightSamples``) and ``block.strata``^2 stratified
    cosine-weighted gather rays (into ``samples``: ``GatherSamples``) per vertex.
    Directions are also kept in the vertex's local frame (x tangent, y bitangent,
    z normal).

    light.pdf is the solid-angle density of the light sample, 0 for a sample that
    cannot contribute (behind the vertex or seeing the light's back). The light samples
    pick among the gathered emitters (``sa.direct_*``: the analytic parts' highlights are
    the solver's, in closed form).
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
            light.origins[i, 0], light.origins[i, 1], light.origins[i, 2] = ox, oy, oz
            light.pdf[i] = 0.0
            light.distances[i] = 0.0
            light.directions[i, 0], light.directions[i, 1], light.directions[i, 2] = nx, ny, nz
            tri = pick_emitter(sa.direct_cdf, sa.direct_triangles, rand(seed, STREAM_LIGHT, item, 0))
            area_pdf = sa.direct_area_pdf[tri]
            if area_pdf <= 0.0:
                continue
            (dx, dy, dz), dist, cos_light = toward_light_point(
                sa.positions, sa.faces, sa.face_normals, sa.epsilon, tri, (ox, oy, oz),
                (rand(seed, STREAM_LIGHT, item, 1), rand(seed, STREAM_LIGHT, item, 2)),
            )  # fmt: skip
            wz = dx * nx + dy * ny + dz * nz
            if dist <= 0.0 or cos_light <= 0.0 or wz <= 0.0:
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
            lx, ly, lz = cosine_direction(
                (kx + rand(seed, STREAM_GATHER, item, 0)) / strata,
                (ky + rand(seed, STREAM_GATHER, item, 1)) / strata,
            )
            samples.wi[i, 0], samples.wi[i, 1], samples.wi[i, 2] = lx, ly, lz
            samples.directions[i, 0] = lx * tx + ly * bx + lz * nx
            samples.directions[i, 1] = lx * ty + ly * by + lz * ny
            samples.directions[i, 2] = lx * tz + ly * bz + lz * nz
            samples.origins[i, 0], samples.origins[i, 1], samples.origins[i, 2] = ox, oy, oz


@numba.njit(cache=True, nogil=True, inline="always")
def _light_visibility(rt, rayhit, light):
    """Trace the shadow ray of every light sample that found an emitter (``light.pdf``
    > 0), setting ``light.visible``; returns their count."""
    shadow = 0
    lo, ld = light.origins, light.directions
    for i in range(len(light.pdf)):
        if light.pdf[i] > 0.0:
            light.visible[i] = not occluded1(
                rt, rayhit, (lo[i, 0], lo[i, 1], lo[i, 2]), (ld[i, 0], ld[i, 1], ld[i, 2]), light.distances[i]
            )
            shadow += 1
    return shadow


@numba.njit(cache=True, nogil=True, inline="always")
def _first_segments(samples, paths):
    """Every gather ray of ``samples`` as a path of throughput 1 in ``paths`` (path k the
    gather sample k); returns their count."""
    n = len(samples.wi)
    for k in range(n):
        paths.ids[k] = k
        for c in range(3):
            paths.values[k, c] = 1.0
            paths.origins[k, c] = samples.origins[k, c]
            paths.directions[k, c] = samples.directions[k, c]
    return n


@numba.njit(cache=True, nogil=True)
def trace_gather(rt, sa, irradiance, block, light, samples, buffers):
    """Trace the light samples and gather paths of a ``GatherBlock`` through the scene
    ``rt`` (``embree.Embree``): fills ``light`` (``LightSamples``) and ``samples``
    (``GatherSamples``, the radiance arriving along each gather ray) for
    ``gather_outputs``. ``buffers`` : ``PathBuffers`` of the block's gather-ray count.
    Returns (rays traced, of which shadow rays).

    Per depth, every path in flight is traced, and at its hit ``samples.incoming[id]``
    gains throughput * (emitted + diffusely reflected radiance). The emitted part is
    weighted by the balance heuristic against the light sample that saw it too: on the
    first segment (depth 0) the ``block.n_light`` light samples of the vertex (the
    gather ray's density is cos / pi, its cosine at the vertex being
    ``samples.wi[id, 2]``), later the previous vertex's light sample (the ray's density
    the lobe's). The diffuse part is kd / pi times the irradiance interpolated at the
    hit (kd * texture(uv at the hit) on a textured triangle). At a glossy surface the path goes on through the specular lobe (the diffuse
    lobe's light is in the irradiance), with Russian roulette, so light that passes
    from glossy to glossy is not lost. A path that leaves the scene brings the
    environment's radiance along its direction (``sa.env``; nothing without one): the
    light samples never pick the environment, so it counts in full. Glass (either face)
    passes a path on, reflected or refracted (``sampling.glass_bounce``), with no light
    sample there: the emission it meets next counts in full.

    There a light sample also catches the emitters the lobe reflects (without it, a
    lamp seen in a glossy neighbour was found only by chance and made the heavy-tailed
    outliers that showed as blotches): a point on an emitter (numbers from
    ``STREAM_GATHER_LIGHT``) and its shadow ray, weighted by the balance heuristic against
    the lobe's continuation: f_s cos / (p_light + p_lobe), with f_s = ks (n + 2) / (2 pi)
    cos^n alpha and p_lobe = (n + 1) / (2 pi) cos^n alpha, alpha measured from the
    mirror direction. Directions the continuation cannot produce (below the shading or
    the true surface) are skipped by both. ``block.lobe_light`` False leaves that
    sample out (the same expected value, more noise; for tests). An analytic emitter
    part's direct highlight is left out (the solver adds it in closed form).

    And a sample of the delta lights (``sa.lights``: points, spots, directions, which no
    ray can hit), at every glossy hit whatever ``block.lobe_light``: one chosen by power
    (numbers from ``STREAM_GATHER_DELTA``) and its shadow ray, adding f_s cos I / d^2 (E
    for a direction) over the probability of its choice. The gathering vertex's own
    direct highlight of a delta light is the solver's, in closed form.

    A path's id indexes the block's gather samples (vertex ``block.vertices[id //
    n_gather]``, sample ``id % n_gather``), which also key the random numbers. The
    records are unpacked into locals once (see ``photons.trace_photons``), with the
    call's own copy of the small material table. A Phong hit's light samples are
    ``_phong_hit``'s, a microfacet hit's ``_microfacet_hit``'s.
    """
    make_gather_rays(sa, block, light, samples)
    positions, normals, faces, face_normals = sa.positions, sa.normals, sa.faces, sa.face_normals
    face_material, materials, epsilon = sa.face_material, sa.materials.copy(), sa.epsilon
    face_texture = sa.face_texture
    emit_triangles, emit_area_pdf, direct_area_pdf = sa.emit_triangles, sa.emit_area_pdf, sa.direct_area_pdf
    seed, n_light, n_gather, max_depth = block.seed, block.n_light, block.strata * block.strata, block.max_depth
    vertices, lobe_light = block.vertices, block.lobe_light
    env_active, env_pixels, env_rotation = sa.env.active, sa.env.pixels, sa.env.rotation
    sample_wi, incoming = samples.wi, samples.incoming
    rayhit = new_rayhit()
    shadow = _light_visibility(rt, rayhit, light)
    paths, spare, hits = buffers.paths, buffers.spare, buffers.hits
    n = _first_segments(samples, paths)
    rays = shadow
    path_pdf, out_pdf = buffers.pdfs[0], buffers.pdfs[1]
    has_lights = len(emit_triangles) > 0 and lobe_light
    lights = sa.lights
    n_delta = len(lights.kinds)
    # what a Phong hit's light samples read, unpacked once (see ``_phong_hit``)
    emitters = (sa.emit_cdf, emit_triangles, emit_area_pdf, face_material, positions, faces, face_normals)
    triangle, hit_u, hit_v = hits.triangle, hits.u, hits.v
    for depth in range(max_depth):
        if n == 0:
            break
        intersect_rays(rt, paths.origins, paths.directions, hits, 0, n)
        ids, values, origins, directions = paths.ids, paths.values, paths.origins, paths.directions
        n_out = 0
        traced = 0
        for k in range(n):
            t = triangle[k]
            if t < 0:
                if env_active:  # left the scene: the environment's light
                    le = env_lookup(env_pixels, env_rotation, directions[k, 0], directions[k, 1], directions[k, 2])
                    target = ids[k]
                    for c in range(3):
                        incoming[target, c] += values[k, c] * le[c]
                continue
            d = (directions[k, 0], directions[k, 1], directions[k, 2])
            gx, gy, gz = face_normals[t, 0], face_normals[t, 1], face_normals[t, 2]
            m = face_material[t]
            if materials[m, KIND] >= KIND_DIELECTRIC:
                # glass, either face: on through it, reflected or refracted, with no light
                # sample there (so the emission found next counts in full: pdf -1)
                if depth + 1 >= max_depth:
                    continue
                item = (vertices[ids[k] // n_gather] * n_gather + ids[k] % n_gather) * max_depth + depth
                weight3, origin, direction, _ = glass_bounce(
                    (positions, normals, faces, face_normals), epsilon, materials[m],
                    (t, np.float64(hit_u[k]), np.float64(hit_v[k])), d,
                    (rand(seed, STREAM_LOBE, item, 0), rand(seed, STREAM_LOBE, item, 1),
                     rand(seed, STREAM_LOBE, item, 2)), True)
                survives, carried = roulette(
                    (values[k, 0] * weight3[0], values[k, 1] * weight3[1], values[k, 2] * weight3[2]), 1.0,
                    rand(seed, STREAM_LOBE, item, 3))
                if survives:
                    spare.ids[n_out] = ids[k]
                    for c in range(3):
                        spare.values[n_out, c] = carried[c]
                        spare.origins[n_out, c] = origin[c]
                        spare.directions[n_out, c] = direction[c]
                    out_pdf[n_out] = -1.0
                    n_out += 1
                continue
            if d[0] * gx + d[1] * gy + d[2] * gz >= 0.0:
                continue
            uk, vk = np.float64(hit_u[k]), np.float64(hit_v[k])
            w = 1.0 - uk - vk
            i0, i1, i2 = faces[t, 0], faces[t, 1], faces[t, 2]
            px, py, pz = lerp3(positions, i0, i1, i2, w, uk, vk)
            fresnel = materials[m, HAS_FRESNEL] > 0.0
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
                elif lobe_light and path_pdf[k] >= 0.0:  # -1: the segment left glass, which made no light sample
                    p_light = emit_area_pdf[t] * dist * dist / cos_light
                    weight = path_pdf[k] / (path_pdf[k] + p_light)
            nx, ny, nz = facing(lerp3(normals, i0, i1, i2, w, uk, vk), d, (gx, gy, gz))
            # a Fresnel surface's diffuse part leaves less light towards grazing
            kd_scale = diffuse_exitance(materials[m], -(d[0] * nx + d[1] * ny + d[2] * nz)) if fresnel else 1.0
            texture = face_texture[t]
            tex = hit_texel(sa, texture, t, uk, vk) if texture >= 0 else (1.0, 1.0, 1.0)
            for c in range(3):
                e = w * irradiance[i0, c] + uk * irradiance[i1, c] + vk * irradiance[i2, c]
                kd = materials[m, KD + c] * kd_scale if fresnel else materials[m, KD + c]
                radiance = weight * materials[m, EMISSION + c] + kd * tex[c] / math.pi * e
                incoming[target, c] += values[k, c] * radiance
            ks0, ks1, ks2 = materials[m, KS], materials[m, KS + 1], materials[m, KS + 2]
            if max(ks0, ks1, ks2) <= 0.0 or depth + 1 >= max_depth:
                continue
            item = (vertices[target // n_gather] * n_gather + target % n_gather) * max_depth + depth
            if materials[m, KIND] != KIND_PHONG:
                traced += _microfacet_hit(
                    (rt, rayhit, sa), materials[m], ((px, py, pz), (gx, gy, gz), (nx, ny, nz), d),
                    (values[k], target, incoming), (seed, item, has_lights, n_delta),
                )  # fmt: skip
                wix, wiy, wiz, pdf, carried, survives = _microfacet_continuation(
                    materials[m], (nx, ny, nz), d, values[k], seed, item)
                if not survives:
                    continue
                if not wix * gx + wiy * gy + wiz * gz > 0.0:
                    continue
                _push_path(spare, out_pdf, n_out, target, ((px, py, pz), (gx, gy, gz), epsilon),
                           ((wix, wiy, wiz), pdf, carried))
                n_out += 1
                continue
            exponent = materials[m, EXPONENT]
            traced += _phong_hit(
                (rt, rayhit, emitters, lights, epsilon), materials, m, ((px, py, pz), (gx, gy, gz), (nx, ny, nz), d),
                (values, k, target, incoming), (seed, item, has_lights, n_delta),
            )  # fmt: skip
            # the lobe's continuation (a BRDF sample with u1 = 0: the specular lobe; the
            # diffuse lobe's light is in the irradiance)
            tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
            wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
            woy = -(d[0] * bx + d[1] * by + d[2] * bz)
            woz = -(d[0] * nx + d[1] * ny + d[2] * nz)
            wix, wiy, wiz, pdf = brdf_sample(
                materials[m], wox, woy, woz, 0.0, rand(seed, STREAM_LOBE, item, 0), rand(seed, STREAM_LOBE, item, 1)
            )
            sx = wix * tx + wiy * bx + wiz * nx
            sy = wix * ty + wiy * by + wiz * ny
            sz = wix * tz + wiy * bz + wiz * nz
            if not (wiz > 0.0 and pdf > 0.0 and sx * gx + sy * gy + sz * gz > 0.0):
                continue
            # specular lobe sampled exactly: f_s cos / pdf_s = ks (n + 2) / (n + 1) cos
            lobe_weight = (exponent + 2.0) / (exponent + 1.0) * wiz
            if fresnel:
                f0, f1, f2 = schlick(materials[m], half_cosine(wix * wox + wiy * woy + wiz * woz))
                ks0, ks1, ks2 = ks0 * f0, ks1 * f1, ks2 * f2
            q0, q1, q2 = values[k, 0] * ks0 * lobe_weight, values[k, 1] * ks1 * lobe_weight, values[k, 2] * ks2 * lobe_weight
            survives, carried = roulette((q0, q1, q2), 1.0, rand(seed, STREAM_LOBE, item, 2))
            if not survives:
                continue
            cos_alpha = min(max(-wix * wox - wiy * woy + wiz * woz, 0.0), 1.0)
            _push_path(spare, out_pdf, n_out, target, ((px, py, pz), (gx, gy, gz), epsilon),
                       ((sx, sy, sz), (exponent + 1.0) / (2.0 * math.pi) * phong_lobe(cos_alpha, exponent), carried))
            n_out += 1
        rays += n + traced
        shadow += traced
        paths, spare = spare, paths
        path_pdf, out_pdf = out_pdf, path_pdf
        n = n_out
    return rays, shadow


@numba.njit(cache=True, nogil=True, inline="always")
def _push_path(paths, pdfs, n, target, start, step):
    """Slot n of the next depth's ``paths`` (and of its ``pdfs``): a path of ``target``
    leaving start = (point, geometric normal g, epsilon; offset epsilon along g) by step =
    (direction, its sampling density, the value carried)."""
    point, g, epsilon = start
    direction, pdf, value = step
    pdfs[n] = pdf
    paths.ids[n] = target
    for c in range(3):
        paths.origins[n, c] = point[c] + epsilon * g[c]
        paths.directions[n, c] = direction[c]
        paths.values[n, c] = value[c]


@numba.njit(cache=True, nogil=True, inline="always")
def _phong_hit(tracing, materials, m, where, path, numbers):
    """At a gather path's hit on a Phong surface (material m of the call's ``materials``):
    the light sample of an emitter (f_s cos / (p_light + p_lobe), the balance heuristic
    against the lobe's continuation) and of a delta light (f_s cos I / d^2 over its
    choice's probability), f_s = ks (n + 2) / (2 pi) cos^n alpha, alpha from the mirror
    direction (times Schlick's Fresnel where the material has it). tracing = (rt,
    rayhit, emitters, lights, epsilon), emitters = the scene's (emit_cdf, emit_triangles,
    emit_area_pdf, face_material, positions, faces, face_normals); where = (point, geometric normal, shading normal, d the path's
    direction); path = (the paths' throughputs, this one's row k, its target,
    ``incoming``); numbers = (seed, item, has_lights, n_delta). Adds to
    ``incoming[target]``; returns the shadow rays traced. The scene's arrays come
    unpacked and rows are indexed, not taken as views: a record's field or a view read
    per hit costs a reference-count update."""
    rt, rayhit, emitters, lights, epsilon = tracing
    emit_cdf, emit_triangles, emit_area_pdf, face_material, positions, faces, face_normals = emitters
    point, g, n, d = where
    values, k, target, incoming = path
    seed, item, has_lights, n_delta = numbers
    exponent, fresnel = materials[m, EXPONENT], materials[m, HAS_FRESNEL] > 0.0
    ks = (materials[m, KS], materials[m, KS + 1], materials[m, KS + 2])
    nx, ny, nz = n
    dn = d[0] * nx + d[1] * ny + d[2] * nz
    traced = 0
    if has_lights:
        tri = pick_emitter(emit_cdf, emit_triangles, rand(seed, STREAM_GATHER_LIGHT, item, 0))
        area_pdf = emit_area_pdf[tri]
        origin = off_surface(point, g, epsilon)
        (dx, dy, dz), dist, cos_light = (0.0, 0.0, 0.0), 0.0, 0.0
        if area_pdf > 0.0:
            (dx, dy, dz), dist, cos_light = toward_light_point(
                positions, faces, face_normals, epsilon, tri, origin,
                (rand(seed, STREAM_GATHER_LIGHT, item, 1), rand(seed, STREAM_GATHER_LIGHT, item, 2)),
            )  # fmt: skip
        if dist > 0.0:
            cos_i = dx * nx + dy * ny + dz * nz
            if cos_light > 0.0 and cos_i > 0.0 and dx * g[0] + dy * g[1] + dz * g[2] > 0.0:
                cos_alpha = dx * (d[0] - 2.0 * dn * nx) + dy * (d[1] - 2.0 * dn * ny) + dz * (d[2] - 2.0 * dn * nz)
                lobe = phong_lobe(min(cos_alpha, 1.0), exponent) if cos_alpha > 0.0 else 0.0
                if lobe > 0.0:
                    traced += 1
                    if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist):
                        p_light = area_pdf * dist * dist / cos_light
                        p_lobe = (exponent + 1.0) / (2.0 * math.pi) * lobe
                        scale = (exponent + 2.0) / (2.0 * math.pi) * lobe * cos_i / (p_light + p_lobe)
                        lm = face_material[tri]
                        f = (1.0, 1.0, 1.0)
                        if fresnel:
                            f = schlick(materials[m], half_cosine(-(dx * d[0] + dy * d[1] + dz * d[2])))
                        for c in range(3):
                            incoming[target, c] += values[k, c] * (ks[c] * f[c] * materials[lm, EMISSION + c] * scale)
    if n_delta > 0:
        # a delta light: chosen by power, no ray finds it otherwise
        j = pick_light(lights.cdf, rand(seed, STREAM_GATHER_DELTA, item, 0))
        origin = off_surface(point, g, epsilon)
        (dx, dy, dz), dist, le = arriving(lights, j, origin)
        cos_i = dx * nx + dy * ny + dz * nz
        if dist > epsilon and max(le[0], le[1], le[2]) > 0.0 and cos_i > 0.0 and dx * g[0] + dy * g[1] + dz * g[2] > 0.0:
            cos_alpha = dx * (d[0] - 2.0 * dn * nx) + dy * (d[1] - 2.0 * dn * ny) + dz * (d[2] - 2.0 * dn * nz)
            lobe = phong_lobe(min(cos_alpha, 1.0), exponent) if cos_alpha > 0.0 else 0.0
            if lobe > 0.0:
                traced += 1
                if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist - epsilon):
                    scale = (exponent + 2.0) / (2.0 * math.pi) * lobe * cos_i / lights.pick[j]
                    f = (1.0, 1.0, 1.0)
                    if fresnel:
                        f = schlick(materials[m], half_cosine(-(dx * d[0] + dy * d[1] + dz * d[2])))
                    for c in range(3):
                        incoming[target, c] += values[k, c] * (ks[c] * f[c] * le[c] * scale)
    return traced


@numba.njit(cache=True, nogil=True, inline="always")
def _microfacet_hit(tracing, mat, where, path, numbers):
    """At a gather path's hit on a microfacet surface (``mat``): the light sample of an
    emitter and of a delta light, as ``trace_gather``'s Phong hits, with the kind's
    specular part (``specular_eval``) and its sampler's density (``specular_pdf``) in the
    balance heuristic. tracing = (rt, rayhit, sa); where = (point, geometric normal,
    shading normal, d the path's direction); path = (its throughput, its target,
    ``incoming``); numbers = (seed, item, has_lights, n_delta). Adds to
    ``incoming[target]``; returns the shadow rays traced."""
    rt, rayhit, sa = tracing
    point, g, n, d = where
    value, target, incoming = path
    seed, item, has_lights, n_delta = numbers
    tx, ty, tz, bx, by, bz = onb(n[0], n[1], n[2])
    wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
    woy = -(d[0] * bx + d[1] * by + d[2] * bz)
    woz = -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2])
    origin = off_surface(point, g, sa.epsilon)
    traced = 0
    if has_lights:
        tri = pick_emitter(sa.emit_cdf, sa.emit_triangles, rand(seed, STREAM_GATHER_LIGHT, item, 0))
        area_pdf = sa.emit_area_pdf[tri]
        (dx, dy, dz), dist, cos_light = (0.0, 0.0, 0.0), 0.0, 0.0
        if area_pdf > 0.0:
            (dx, dy, dz), dist, cos_light = toward_light_point(
                sa.positions, sa.faces, sa.face_normals, sa.epsilon, tri, origin,
                (rand(seed, STREAM_GATHER_LIGHT, item, 1), rand(seed, STREAM_GATHER_LIGHT, item, 2)),
            )  # fmt: skip
        cos_i = dx * n[0] + dy * n[1] + dz * n[2]
        if dist > 0.0 and cos_light > 0.0 and cos_i > 0.0 and dx * g[0] + dy * g[1] + dz * g[2] > 0.0:
            wix, wiy = dx * tx + dy * ty + dz * tz, dx * bx + dy * by + dz * bz
            f = specular_eval(mat, wix, wiy, cos_i, wox, woy, woz)
            if max(f[0], f[1], f[2]) > 0.0:
                traced += 1
                if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist):
                    p_light = area_pdf * dist * dist / cos_light
                    p_lobe = specular_pdf(mat, wox, woy, woz, wix, wiy, cos_i)
                    scale = cos_i / (p_light + p_lobe)
                    le = sa.materials[sa.face_material[tri]]
                    for c in range(3):
                        incoming[target, c] += value[c] * f[c] * le[EMISSION + c] * scale
    if n_delta > 0:
        lights = sa.lights
        j = pick_light(lights.cdf, rand(seed, STREAM_GATHER_DELTA, item, 0))
        (dx, dy, dz), dist, le = arriving(lights, j, origin)
        cos_i = dx * n[0] + dy * n[1] + dz * n[2]
        if dist > sa.epsilon and max(le[0], le[1], le[2]) > 0.0 and cos_i > 0.0 and dx * g[0] + dy * g[1] + dz * g[2] > 0.0:
            wix, wiy = dx * tx + dy * ty + dz * tz, dx * bx + dy * by + dz * bz
            f = specular_eval(mat, wix, wiy, cos_i, wox, woy, woz)
            if max(f[0], f[1], f[2]) > 0.0:
                traced += 1
                if not occluded1(rt, rayhit, origin, (dx, dy, dz), dist - sa.epsilon):
                    scale = cos_i / lights.pick[j]
                    for c in range(3):
                        incoming[target, c] += value[c] * f[c] * le[c] * scale
    return traced


@numba.njit(cache=True, nogil=True, inline="always")
def _microfacet_continuation(mat, n, d, value, seed, item):
    """The gather path's next direction at a microfacet hit: the specular part sampled
    alone (``specular_sample``), the throughput times f_s cos / pdf, Russian roulette.
    Returns (world direction, pdf, carried (3-tuple), survives)."""
    tx, ty, tz, bx, by, bz = onb(n[0], n[1], n[2])
    wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
    woy = -(d[0] * bx + d[1] * by + d[2] * bz)
    woz = -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2])
    nothing = (0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), False)
    wix, wiy, wiz, pdf = specular_sample(
        mat, wox, woy, woz, rand(seed, STREAM_LOBE, item, 0), rand(seed, STREAM_LOBE, item, 1))
    if not (wiz > 0.0 and pdf > 0.0):
        return nothing
    f = specular_eval(mat, wix, wiy, wiz, wox, woy, woz)
    scale = wiz / pdf
    q = (value[0] * f[0] * scale, value[1] * f[1] * scale, value[2] * f[2] * scale)
    survives, carried = roulette(q, 1.0, rand(seed, STREAM_LOBE, item, 2))
    if not survives:
        return nothing
    sx = wix * tx + wiy * bx + wiz * n[0]
    sy = wix * ty + wiy * by + wiz * n[1]
    sz = wix * tz + wiy * bz + wiz * n[2]
    return sx, sy, sz, pdf, carried, True


@numba.njit(cache=True, nogil=True)
def lobe_window(rx, ry, rz, cone, grid_n):
    """(i_lo, i_hi, j_lo, j_hi): the cells of the n x n direction grid whose centres
    can lie within angle ``cone`` of the unit direction (rx, ry, rz), rz >= 0.

    The cone's directions have polar angles within ``cone`` of the direction's and,
    when the cone leaves the pole out, azimuths within asin(sin cone / sin theta) of
    its azimuth. ``hemisphere_to_square`` sends polar angle to the radius
    r = sqrt(1 - cos theta) (the square point's max-norm) and azimuth to r times a
    point of the unit square's boundary, linear between its corners; so the image of
    that polar rectangle, which holds the cone, lies in the box of the images of its
    ends and of the square's corners it passes, each at the smallest and the largest r."""
    theta = math.atan2(math.hypot(rx, ry), rz)
    r_lo = math.sqrt(max(1.0 - math.cos(max(theta - cone, 0.0)), 0.0))
    r_hi = math.sqrt(max(1.0 - math.cos(min(theta + cone, 0.5 * math.pi)), 0.0))
    if theta <= cone:  # the pole is inside: every azimuth
        a_lo, a_hi, b_lo, b_hi = -r_hi, r_hi, -r_hi, r_hi
    else:
        spread = math.asin(min(math.sin(cone) / math.sin(theta), 1.0)) / _PI_OVER_4
        middle = math.atan2(ry, rx) / _PI_OVER_4
        t, t_end = middle - spread, middle + spread
        corner = 2.0 * math.floor((t - 1.0) / 2.0) + 3.0  # the first corner (an odd t) past t
        a_lo, a_hi, b_lo, b_hi = 2.0, -2.0, 2.0, -2.0
        for _ in range(8):  # the ends and the corners between them (t spans at most 4): bounded even for a NaN
            sa, sb = square_boundary_nb(t - 8.0 * math.floor((t + 4.0) / 8.0))  # t taken into [-4, 4)
            a_lo, a_hi = min(a_lo, r_lo * sa, r_hi * sa), max(a_hi, r_lo * sa, r_hi * sa)
            b_lo, b_hi = min(b_lo, r_lo * sb, r_hi * sb), max(b_hi, r_lo * sb, r_hi * sb)
            if t >= t_end:
                break
            t = min(corner, t_end)
            corner += 2.0
    i_lo = max(0, int(math.floor((a_lo - WINDOW_MARGIN + 1.0) * 0.5 * grid_n - 0.5)))
    i_hi = min(grid_n - 1, int(math.ceil((a_hi + WINDOW_MARGIN + 1.0) * 0.5 * grid_n - 0.5)))
    j_lo = max(0, int(math.floor((b_lo - WINDOW_MARGIN + 1.0) * 0.5 * grid_n - 0.5)))
    j_hi = min(grid_n - 1, int(math.ceil((b_hi + WINDOW_MARGIN + 1.0) * 0.5 * grid_n - 0.5)))
    return i_lo, i_hi, j_lo, j_hi


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


@numba.njit(cache=True, nogil=True, inline="always")
def _vertex_samples(b, light, samples, n_light, n_gather, sign, where, weight):
    """Vertex b's samples that brought light, light samples first: their directions into
    ``where`` (wi, with x and y times ``sign``: -1 gives the mirror direction) and their
    weights into ``weight``: a light sample's balance-heuristic weight against the gather
    rays times its radiance over its density, a gather ray's pi / n_gather times what it
    brought. Returns (how many, how many of them are light samples)."""
    used = 0
    for m in range(n_light):
        i = b * n_light + m
        p = light.pdf[i]
        if p <= 0.0 or not light.visible[i]:
            continue
        wz = light.wi[i, 2]
        p_gather = wz / math.pi
        scale = wz / (p * n_light) * (n_light * p / (n_light * p + n_gather * p_gather))
        where[used, 0], where[used, 1], where[used, 2] = sign * light.wi[i, 0], sign * light.wi[i, 1], wz
        for c in range(3):
            weight[used, c] = scale * light.radiance[i, c]
        used += 1
    used_light = used
    incoming, wi = samples.incoming, samples.wi
    for k in range(n_gather):
        i = b * n_gather + k
        if incoming[i, 0] == 0.0 and incoming[i, 1] == 0.0 and incoming[i, 2] == 0.0:
            continue
        where[used, 0], where[used, 1], where[used, 2] = sign * wi[i, 0], sign * wi[i, 1], wi[i, 2]
        for c in range(3):
            weight[used, c] = math.pi / n_gather * incoming[i, c]
        used += 1
    return used, used_light


@numba.njit(cache=True, nogil=True)
def gather_outputs(mat, emission, diffuse_radiance, light, samples, directions, out, variance):
    """Outgoing radiance of a block of B vertices in every direction of an n x n grid.

    out[b, d] = emission + diffuse_radiance[b] + the specular lobe's integral of the
    incoming light for wo = directions[d], estimated from the vertex's light samples
    (balance-heuristic weighted against the gather rays) and its gather rays, all
    shared by every direction d.

    Each sample adds ks (n + 2) / (2 pi) cos^n(alpha) times its weight (and, with
    Fresnel, times F(wi.h) per channel) to the grid directions within its lobe, alpha measured from its mirror direction; directions
    where the lobe is below LOBE_CUTOFF of its peak are skipped (that loses at most
    LOBE_CUTOFF of the lobe's energy). The cells to visit are those of the lobe's
    window in the grid's square (``lobe_window``, exact for the map), or all of them
    for a lobe of WHOLE_GRID_CONE or wider. cos^n comes from a table over the lobe's range of cos alpha, linearly
    interpolated (relative error ~1e-6 whatever n).

    mat : (NCOL,) the object's material row; emission : (3,); diffuse_radiance :
    (B, 3) kd E / pi (with Fresnel kd E' / pi, times b(wo.z) here per direction); light : ``LightSamples`` (B * n_light, its ``wi``, ``radiance``,
    ``pdf`` and ``visible`` read); samples : ``GatherSamples`` (B * n_gather, its ``wi``
    and ``incoming`` read); directions : (n^2, 3) local, ``directions.grid_directions``;
    out : (B, n^2, 3) float64; variance : (B,) float64 (or empty: not measured), receives each vertex's
    sum over directions of the variance of the luminance (``LUMINANCE``) of out[b, d],
    estimated from the spread of its samples: a group of m samples (light, gather)
    whose terms x_s sum to S1 and their squares to S2 adds S2 - S1^2 / m (samples that
    brought nothing count as zeros). Stratification makes the true variance lower.
    """
    if mat[KIND] != KIND_PHONG:
        _microfacet_outputs(mat, emission, diffuse_radiance, light, samples, directions, out, variance)
        return
    n_blocks = out.shape[0]
    n_light = light.pdf.shape[0] // n_blocks if n_blocks > 0 else 0
    n_gather = samples.wi.shape[0] // n_blocks if n_blocks > 0 else 0
    grid_n = int(round(math.sqrt(directions.shape[0])))
    n = mat[EXPONENT]
    norm = (n + 2.0) / (2.0 * math.pi)
    cos_min = math.exp(math.log(LOBE_CUTOFF) / n) if n > 1e-9 else 0.0
    cone = math.acos(cos_min)
    whole = cone >= WHOLE_GRID_CONE
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
    fresnel = mat[HAS_FRESNEL] > 0.0
    # with Fresnel the noise measure weights each channel's F like the luminance of ks
    total_ks = lum_ks[0] + lum_ks[1] + lum_ks[2]
    lum_f0 = (lum_ks[0] / total_ks, lum_ks[1] / total_ks, lum_ks[2] / total_ks) if total_ks > 0.0 else (1 / 3, 1 / 3, 1 / 3)
    for b in range(n_blocks):
        used, used_light = _vertex_samples(b, light, samples, n_light, n_gather, -1.0, mirror, weight)
        acc = out[b]
        acc[:, :] = 0.0
        moments[:, :] = 0.0
        for s in range(used):
            s1 = moments[0] if s < used_light else moments[2]
            s2 = moments[1] if s < used_light else moments[3]
            y = norm * (lum_ks[0] * weight[s, 0] + lum_ks[1] * weight[s, 1] + lum_ks[2] * weight[s, 2])
            rx, ry, rz = mirror[s, 0], mirror[s, 1], mirror[s, 2]
            if whole:
                i_lo, i_hi, j_lo, j_hi = 0, grid_n - 1, 0, grid_n - 1
            else:
                i_lo, i_hi, j_lo, j_hi = lobe_window(rx, ry, rz, cone, grid_n)
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
                    if fresnel:
                        # F at wi.h: wi = (-rx, -ry, rz), so wi.wo = 2 rz wo.z - cos alpha
                        f0, f1, f2 = schlick(mat, half_cosine(2.0 * rz * directions[d, 2] - cos_alpha))
                        acc[d, 0] += lobe * w0 * f0
                        acc[d, 1] += lobe * w1 * f1
                        acc[d, 2] += lobe * w2 * f2
                        lobe = lobe * (lum_f0[0] * f0 + lum_f0[1] * f1 + lum_f0[2] * f2)
                    else:
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
                if fresnel:
                    diffuse = diffuse_radiance[b, c] * diffuse_exitance(mat, directions[d, 2])
                    acc[d, c] = emission[c] + diffuse + norm * mat[KS + c] * acc[d, c]
                else:
                    acc[d, c] = emission[c] + diffuse_radiance[b, c] + norm * mat[KS + c] * acc[d, c]


FRESNEL_TABLE = 1024  # a microfacet grid's Fresnel values per channel over wi.h in [0, 1]


@numba.njit(cache=True, nogil=True)
def microfacet_cone(mat):
    """The angle from a sample's mirror direction beyond which the microfacet lobe holds
    less than ``LOBE_CUTOFF`` of its energy: 2 atan(t), t the tangent of the half-vector
    angle that leaves that share of the projected distribution D cos beyond it (GGX:
    alpha^2 / (alpha^2 + t^2) = cutoff; Beckmann: exp(-t^2 / alpha^2) = cutoff), a reflected
    direction turning by at most twice its normal's turn. GGX's long tail makes it wide:
    every direction of the grid for alpha above about 0.02."""
    alpha = mat[MF_ALPHA]
    if mat[MF_DISTRIBUTION] == MF_GGX:
        t = alpha * math.sqrt((1.0 - LOBE_CUTOFF) / LOBE_CUTOFF)
    else:
        t = alpha * math.sqrt(-math.log(LOBE_CUTOFF))
    return min(math.pi, 2.0 * math.atan(t))


@numba.njit(cache=True, nogil=True)
def _microfacet_outputs(mat, emission, diffuse_radiance, light, samples, directions, out, variance):
    """``gather_outputs`` for a microfacet material: each sample (light samples weighted
    by the balance heuristic against the gather rays, gather rays by pi / n_gather, as the
    Phong kind's) adds f_s(wi, wo_d) times its weight to every grid direction d within
    ``microfacet_cone`` of its mirror direction (all of them for a cone of
    WHOLE_GRID_CONE or wider; the light beyond it is at most LOBE_CUTOFF of the lobe's),
    f_s = F D G1(wi) G1(wo) / (4 cos_i cos_o). Per pair it
    needs only wi.wo: with x = (1 + wi.wo) / 2 = (wi.h)^2, cos^2 theta_h = (wi.z + wo.z)^2
    / (4 x) gives D, and F is read from a table over x (linear, 1024 entries); G1 / cos
    of every direction and every sample is computed once. The diffuse radiance is scaled
    by ``diffuse_exitance`` per direction (a plastic's t(cos_o)); the noise measure as
    ``gather_outputs``'."""
    n_blocks = out.shape[0]
    n_light = light.pdf.shape[0] // n_blocks if n_blocks > 0 else 0
    n_gather = samples.wi.shape[0] // n_blocks if n_blocks > 0 else 0
    grid_n = int(round(math.sqrt(directions.shape[0])))
    n_dirs = directions.shape[0]
    dist, alpha = mat[MF_DISTRIBUTION], mat[MF_ALPHA]
    a2 = alpha * alpha
    ggx = dist == MF_GGX
    cone = microfacet_cone(mat)
    whole = cone >= WHOLE_GRID_CONE
    fresnel = np.empty((FRESNEL_TABLE, 3))
    for k in range(FRESNEL_TABLE):
        fresnel[k, 0], fresnel[k, 1], fresnel[k, 2] = interface_fresnel(mat, math.sqrt(k / (FRESNEL_TABLE - 1.0)))
    g_out = np.empty(n_dirs)  # G1(wo) / (4 pi cos_o): D's 1 / pi folded in
    exitance = np.empty(n_dirs)
    for d in range(n_dirs):
        cz = directions[d, 2]
        g_out[d] = smith_g1(dist, alpha, cz, 1.0) / (4.0 * math.pi * cz) if cz > 0.0 else 0.0
        exitance[d] = diffuse_exitance(mat, cz)
    n_samples = n_light + n_gather
    wi = np.empty((n_samples, 3))
    weight = np.empty((n_samples, 3))
    g_in = np.empty(n_samples)
    moments = np.empty((4, n_dirs))
    measure = variance.shape[0] > 0
    for b in range(n_blocks):
        used, used_light = _vertex_samples(b, light, samples, n_light, n_gather, 1.0, wi, weight)
        for s in range(used):
            g_in[s] = smith_g1(dist, alpha, wi[s, 2], 1.0) / wi[s, 2] if wi[s, 2] > 0.0 else 0.0
        acc = out[b]
        acc[:, :] = 0.0
        moments[:, :] = 0.0
        for s in range(used):
            if g_in[s] <= 0.0:
                continue
            s1 = moments[0] if s < used_light else moments[2]
            s2 = moments[1] if s < used_light else moments[3]
            ix, iy, iz = wi[s, 0], wi[s, 1], wi[s, 2]
            if whole:
                i_lo, i_hi, j_lo, j_hi = 0, grid_n - 1, 0, grid_n - 1
            else:
                i_lo, i_hi, j_lo, j_hi = lobe_window(-ix, -iy, iz, cone, grid_n)
            w0, w1, w2 = weight[s, 0] * g_in[s], weight[s, 1] * g_in[s], weight[s, 2] * g_in[s]
            for j in range(j_lo, j_hi + 1):
                for i in range(i_lo, i_hi + 1):
                    d = j * grid_n + i
                    x = 0.5 * (1.0 + ix * directions[d, 0] + iy * directions[d, 1] + iz * directions[d, 2])
                    if g_out[d] <= 0.0 or x <= 0.0:
                        continue
                    sz = iz + directions[d, 2]
                    c2 = min(sz * sz / (4.0 * x), 1.0)  # cos^2 of the half vector's angle
                    if ggx:
                        t = a2 * c2 + 1.0 - c2
                        lobe = a2 / (t * t) * g_out[d]
                    else:
                        lobe = math.exp((c2 - 1.0) / (c2 * a2)) / (a2 * c2 * c2) * g_out[d] if c2 > 0.0 else 0.0
                    u = min(x, 1.0) * (FRESNEL_TABLE - 1)
                    kf = min(int(u), FRESNEL_TABLE - 2)
                    f = u - kf
                    f0 = fresnel[kf, 0] + f * (fresnel[kf + 1, 0] - fresnel[kf, 0])
                    f1 = fresnel[kf, 1] + f * (fresnel[kf + 1, 1] - fresnel[kf, 1])
                    f2 = fresnel[kf, 2] + f * (fresnel[kf + 1, 2] - fresnel[kf, 2])
                    acc[d, 0] += lobe * f0 * w0
                    acc[d, 1] += lobe * f1 * w1
                    acc[d, 2] += lobe * f2 * w2
                    if measure:
                        y = lobe * (LUMINANCE[0] * f0 * w0 + LUMINANCE[1] * f1 * w1 + LUMINANCE[2] * f2 * w2)
                        s1[d] += y
                        s2[d] += y * y
        if measure:
            variance[b] = _variance_sum(moments, n_light, n_gather)
        for d in range(n_dirs):
            for c in range(3):
                acc[d, c] = emission[c] + diffuse_radiance[b, c] * exitance[d] + acc[d, c]
