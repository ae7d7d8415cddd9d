"""Small inlined helpers of the transport kernels (the solver's photons and gather,
and the path tracer): barycentric points, texture coordinates and shading normals at hits, the cosine
direction, Russian roulette, choosing a point on an emitter, a path's way through glass
(``glass_bounce``), and a cache hint.

They take arrays and numbers, not records: a named tuple handed to an inlined helper
costs a reference-count update (an atomic operation) of each of its arrays at every
call, which the kernels' inner loops cannot afford.
"""

from __future__ import annotations

import math

import numba
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.cdf import search_cdf
from radiosity.physics.textures import texel
from radiosity.scene.glass_kernels import glass_sample
from radiosity.scene.material_kernels import onb


@intrinsic
def prefetch_row(typingctx, array, row):
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


@numba.njit(cache=True, nogil=True, inline="always")
def lerp3(a, i0, i1, i2, w, u, v):
    """w a[i0] + u a[i1] + v a[i2] of the rows of a (N, 3), as a 3-tuple: a point or a
    normal inside a triangle from its corners' values and barycentrics."""
    return (
        w * a[i0, 0] + u * a[i1, 0] + v * a[i2, 0],
        w * a[i0, 1] + u * a[i1, 1] + v * a[i2, 1],
        w * a[i0, 2] + u * a[i1, 2] + v * a[i2, 2],
    )


@numba.njit(cache=True, nogil=True, inline="always")
def facing(n, d, g):
    """The interpolated normal n normalised, where it faces the ray arriving along d;
    else the geometric normal g (which then faces it): the shading normal at a hit."""
    length = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    if length > 0.0 and (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) < 0.0:
        return n[0] / length, n[1] / length, n[2] / length
    return g[0], g[1], g[2]


@numba.njit(cache=True, nogil=True, inline="always")
def barycentric_point(sa, tri, u, v):
    return lerp3(sa.positions, sa.faces[tri, 0], sa.faces[tri, 1], sa.faces[tri, 2], 1.0 - u - v, u, v)


@numba.njit(cache=True, nogil=True, inline="always")
def hit_uv(uvs, faces, tri, u, v):
    """Texture coordinates at barycentrics (u, v) of triangle ``tri``: its corners'
    ``uvs`` (N, 2) interpolated, as (u, v)."""
    i0, i1, i2 = faces[tri, 0], faces[tri, 1], faces[tri, 2]
    w = 1.0 - u - v
    return (
        w * uvs[i0, 0] + u * uvs[i1, 0] + v * uvs[i2, 0],
        w * uvs[i0, 1] + u * uvs[i1, 1] + v * uvs[i2, 1],
    )


@numba.njit(cache=True, nogil=True, inline="always")
def hit_texel(sa, texture, tri, u, v):
    """Texture ``texture`` of the scene's atlas at barycentrics (u, v) of triangle
    ``tri`` (its corners' uvs interpolated: ``hit_uv``), as an RGB 3-tuple."""
    tu, tv = hit_uv(sa.uvs, sa.faces, tri, u, v)
    return texel(sa.texture_pixels, sa.texture_offsets, sa.texture_sizes, texture, tu, tv)


@numba.njit(cache=True, nogil=True, inline="always")
def shading_normal(sa, tri, u, v, d):
    """Interpolated shading normal at a hit reached along direction d = (dx, dy, dz),
    or the geometric one where the interpolated normal would put the incoming ray's
    side behind the surface (``facing``)."""
    n = lerp3(sa.normals, sa.faces[tri, 0], sa.faces[tri, 1], sa.faces[tri, 2], 1.0 - u - v, u, v)
    g = sa.face_normals[tri]
    return facing(n, d, (g[0], g[1], g[2]))


@numba.njit(cache=True, nogil=True, inline="always")
def cosine_direction(u1, u2):
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
def roulette(value, reference, u):
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
def pick_emitter(cdf, triangles, u):
    """The emitter triangle whose slot of the power CDF ``cdf`` holds u."""
    return triangles[min(search_cdf(cdf, u), len(triangles) - 1)]


@numba.njit(cache=True, nogil=True, inline="always")
def off_surface(point, g, epsilon):
    """``point`` moved ``epsilon`` along the front normal g (3-tuples): where a ray leaves it."""
    return point[0] + epsilon * g[0], point[1] + epsilon * g[1], point[2] + epsilon * g[2]


@numba.njit(cache=True, nogil=True, inline="always")
def toward_light_point(positions, faces, face_normals, epsilon, tri, origin, rnd):
    """The way from ``origin`` (already off its surface) to a point area-uniform on
    emitter triangle ``tri``, chosen by rnd = (u1, u2) and offset by epsilon off the
    triangle's front: (unit direction (3-tuple), distance (0: unusable), cosine at the
    light)."""
    r = math.sqrt(rnd[0])
    u = r * (1.0 - rnd[1])
    v = r - u
    qx, qy, qz = lerp3(positions, faces[tri, 0], faces[tri, 1], faces[tri, 2], 1.0 - u - v, u, v)
    gl0, gl1, gl2 = face_normals[tri, 0], face_normals[tri, 1], face_normals[tri, 2]
    ox, oy, oz = origin
    dx, dy, dz = qx + epsilon * gl0 - ox, qy + epsilon * gl1 - oy, qz + epsilon * gl2 - oz
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if dist <= 0.0:
        return (0.0, 0.0, 0.0), 0.0, 0.0
    dx, dy, dz = dx / dist, dy / dist, dz / dist
    return (dx, dy, dz), dist, -(dx * gl0 + dy * gl1 + dz * gl2)


@numba.njit(cache=True, nogil=True, inline="always")
def glass_bounce(mesh, epsilon, mat, hit, d, rnd, radiance):
    """A path meeting a glass triangle (material row ``mat`` of a glass kind) at ``hit`` =
    (triangle, u, v) of ``mesh`` = (positions, normals, faces, face_normals), arriving along
    d, goes on by ``glass_kernels.glass_sample`` with
    the uniform numbers rnd = (u1, u2, u3) (``radiance``: a camera path's 1 / eta^2 on
    refraction). The frame's normal is the interpolated one turned to the triangle's
    outward side (the geometric normal where it is degenerate), so either face may be hit.
    Returns (weight RGB, the new ray's origin, its direction, the sample's density: 0 for
    a smooth kind); a weight of 0 where the sample is absorbed or would leave on the
    true surface's wrong side (reflected through it or refracted back)."""
    positions, normals, faces, face_normals = mesh
    tri, u, v = hit
    g = face_normals[tri]
    i0, i1, i2 = faces[tri, 0], faces[tri, 1], faces[tri, 2]
    w = 1.0 - u - v
    nx, ny, nz = lerp3(normals, i0, i1, i2, w, u, v)
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length > 0.0 and nx * g[0] + ny * g[1] + nz * g[2] > 0.0:
        nx, ny, nz = nx / length, ny / length, nz / length
    else:
        nx, ny, nz = g[0], g[1], g[2]
    tx, ty, tz, bx, by, bz = onb(nx, ny, nz)
    wox = -(d[0] * tx + d[1] * ty + d[2] * tz)
    woy = -(d[0] * bx + d[1] * by + d[2] * bz)
    woz = -(d[0] * nx + d[1] * ny + d[2] * nz)
    wix, wiy, wiz, w0, w1, w2, pdf = glass_sample(mat, wox, woy, woz, rnd[0], rnd[1], rnd[2], radiance)
    sx = wix * tx + wiy * bx + wiz * nx
    sy = wix * ty + wiy * by + wiz * ny
    sz = wix * tz + wiy * bz + wiz * nz
    out = sx * g[0] + sy * g[1] + sz * g[2]  # the side it leaves on
    came = -(d[0] * g[0] + d[1] * g[1] + d[2] * g[2])  # the side it came from
    if (wiz * woz > 0.0) != (out * came > 0.0) or out == 0.0:
        w0, w1, w2 = 0.0, 0.0, 0.0
    px, py, pz = lerp3(positions, i0, i1, i2, w, u, v)
    e = epsilon if out > 0.0 else -epsilon
    return (w0, w1, w2), (px + e * g[0], py + e * g[1], pz + e * g[2]), (sx, sy, sz), pdf
