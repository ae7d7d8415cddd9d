"""The only module that touches Embree: the ``libembree4`` shipped inside the embreex
wheel, called through ctypes and, from numba kernels, directly.

``RayTracer`` builds one Embree scene from a triangle mesh (its own device, scene and
triangle geometry, buffers allocated and padded by Embree, kept alive with the
scene). Kernels get ``RayTracer.embree`` (an ``Embree`` named tuple: the scene handle
and the ``rtcIntersect1`` / ``rtcOccluded1`` function pointers) as an argument, make
one ray-hit record per call (``new_rayhit``) and trace single rays with
``intersect1`` / ``occluded1``: no Python and no batches between rays, and numba's
``cache=True`` keeps working because the function pointers are arguments, not
globals. ``RayTracer.intersect`` / ``occluded`` keep the batched interface (arrays
in, arrays out; a chunk per thread) for tests and benchmarks.

The scene is built as embreex built it (one triangle geometry with three vertices of
its own per triangle, ``RTC_SCENE_FLAG_ROBUST``), and rays are set up as embreex set
them up (tnear 0), so hits are bit-identical to embreex's (tests check it on random
rays). A scene with opacity masks (``Cutout``: a leaf's cut-out) puts its masked
triangles in a second geometry of the same size whose filter function (``_cut``, a
numba cfunc Embree calls on every candidate hit) rejects a hit where the mask's
opacity at its texture coordinates is below the cut-off: rays pass through the holes,
in every kernel and query alike, with no kernel aware of it. Each geometry holds every
triangle's slot, the other's triangles as NaN (which Embree leaves out of its tree), so
a hit's primitive id is the triangle's row in either. Ray origins stay offset off the surfaces they leave (``origin_offset``) rather
than starting at tnear > 0: a tnear would be measured along the ray, so a grazing ray
would leave the surface by tnear times the sine of its angle, much less than the
offset along the normal; and the kernels keep their rays, so a seed keeps its bits.
"""

from __future__ import annotations

import ctypes
import glob
import importlib.util
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba
import numpy as np
from numba import carray, types
from numba.core import cgutils
from numba.extending import intrinsic

from radiosity import jit_cache  # noqa: F401 (numba's cache keyed on every source a kernel inlines)
from radiosity.physics.textures import OPACITY_CUTOFF, texel
from radiosity.transport.signals import HeldSignals

MISS = -1
RELATIVE_EPSILON = 1e-5  # ray-origin offset, as a fraction of the scene's bounding-box diagonal
OFFSET_ULPS = 8  # ... and at least this many float32 spacings of the largest coordinate
SPLIT_RAYS = 4096  # a batch smaller than this runs on one thread

# -- the Embree 4 ABI (embree4/rtcore_*.h) ------------------------------------------------
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003
RTC_SCENE_FLAG_ROBUST = 1 << 2
INVALID_ID = -1  # RTC_INVALID_GEOMETRY_ID (0xFFFFFFFF) as the int32 it is stored as

# RTCRayHit in 4-byte words: RTCRay (org, tnear, dir, time, tfar, mask, id, flags), then
# RTCHit (Ng, u, v, primID, geomID, instID[1], and instPrimID[1] in builds with instance
# arrays), 16-byte aligned. RAYHIT_WORDS leaves room for the largest of these layouts.
ORG, TNEAR, DIR, TIME, TFAR, MASK, RAY_ID, FLAGS = 0, 3, 4, 7, 8, 9, 10, 11
HIT_U, HIT_V, PRIM_ID, GEOM_ID, INST_ID = 15, 16, 17, 18, 19
RAYHIT_WORDS = 24  # 96 bytes
RAYHIT_ALIGN = 16  # bytes
FAR = np.float32(np.inf)  # tfar of a closest-hit query

# rtcIntersect1(RTCScene, RTCRayHit*, RTCIntersectArguments*) and rtcOccluded1(RTCScene,
# RTCRay*, RTCOccludedArguments*): pointers passed as size_t (the same on every ABI
# Embree supports), arguments NULL (the defaults: incoherent rays, every feature)
QUERY = ctypes.CFUNCTYPE(None, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_size_t)


class Embree(NamedTuple):
    """What a numba kernel needs to trace rays in one scene (``RayTracer.embree``).

    scene     : int    the RTCScene handle
    intersect : QUERY  rtcIntersect1
    occluded  : QUERY  rtcOccluded1
    """

    scene: int
    intersect: object
    occluded: object


class Hits(NamedTuple):
    """Closest hits of a batch of N rays (``RayTracer.intersect``).

    triangle : (N,) int32    row of the tracer's ``faces``; MISS (-1) where nothing is hit
    t        : (N,) float32  distance along the (unit) direction to the hit (inf: a miss)
    u, v     : (N,) float32  barycentrics: the hit is (1 - u - v) p0 + u p1 + v p2 (0: a miss)
    """

    triangle: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray


def empty_hits(count):
    """Uninitialised ``Hits`` for ``count`` rays."""
    return Hits(
        np.empty(count, np.int32), np.empty(count, np.float32), np.empty(count, np.float32), np.empty(count, np.float32)
    )


@numba.njit(cache=True, nogil=True)
def head_hits(hits, n):
    """The first n rows of ``hits``, as views."""
    return Hits(hits.triangle[:n], hits.t[:n], hits.u[:n], hits.v[:n])


def default_threads():
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def origin_offset(positions):
    """How far off a surface a ray must start (scene units) not to hit it again.

    RELATIVE_EPSILON of the bounding-box diagonal, and at least OFFSET_ULPS float32
    spacings at the largest coordinate: a scene far from the origin has coarse
    single-precision coordinates, and an offset below their spacing would round away.
    """
    positions = np.asarray(positions, dtype=np.float64)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    relative = RELATIVE_EPSILON * float(np.linalg.norm(hi - lo))
    spacing = float(np.spacing(np.float32(np.abs(positions).max())))
    return max(relative, OFFSET_ULPS * spacing)


# -- opacity masks: Embree's filter function --------------------------------------------------

# RTCFilterFunctionNArguments: int* valid, void* geometryUserPtr, RTCRayQueryContext* context,
# RTCRayN* ray, RTCHitN* hit, unsigned int N; the hits of N rays structure-of-arrays:
# Ng_x[N], Ng_y[N], Ng_z[N], u[N], v[N], primID[N], geomID[N], ...
ARG_VALID, ARG_USER, ARG_HIT, ARG_N = 0, 1, 4, 5
HITN_U, HITN_V, HITN_PRIM = 3, 4, 5
# the user data: a header of int64 addresses and sizes (``_cutout_header``)
CUT_TRIANGLES, CUT_IMAGE, CUT_UVS, CUT_PIXELS, CUT_N_PIXELS, CUT_OFFSETS, CUT_SIZES, CUT_N_IMAGES = range(8)


@intrinsic
def _pointer(typingctx, address):
    """An int64 address as a void pointer (for ``carray``)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)

    return types.voidptr(types.int64), codegen


@numba.cfunc(types.void(types.CPointer(types.int64)), cache=True, nopython=True)
def _cut(args):
    """Embree's filter function of the masked geometry (intersect and occluded alike):
    a candidate hit whose mask reads below OPACITY_CUTOFF at its texture coordinates (the
    corners' uvs at the hit's barycentrics, ``texel``: bilinear, repeating) is
    rejected, and Embree goes on to the next."""
    n = args[ARG_N] & 0xFFFFFFFF  # the unsigned int N, then the struct's padding
    valid = carray(_pointer(args[ARG_VALID]), n, np.int32)
    header = carray(_pointer(args[ARG_USER]), 8, np.int64)
    count = header[CUT_TRIANGLES]
    image = carray(_pointer(header[CUT_IMAGE]), count, np.int64)
    uvs = carray(_pointer(header[CUT_UVS]), (count, 6), np.float32)
    pixels = carray(_pointer(header[CUT_PIXELS]), header[CUT_N_PIXELS], np.float32)
    offsets = carray(_pointer(header[CUT_OFFSETS]), header[CUT_N_IMAGES], np.int64)
    sizes = carray(_pointer(header[CUT_SIZES]), (header[CUT_N_IMAGES], 2), np.int64)
    floats = carray(_pointer(args[ARG_HIT]), 8 * n, np.float32)
    ints = carray(_pointer(args[ARG_HIT]), 8 * n, np.int32)
    for k in range(n):
        if valid[k] == 0:
            continue
        tri = np.int64(ints[HITN_PRIM * n + k])
        if tri < 0 or tri >= count or image[tri] < 0:
            continue
        u = np.float64(floats[HITN_U * n + k])
        v = np.float64(floats[HITN_V * n + k])
        w = 1.0 - u - v
        tu = w * uvs[tri, 0] + u * uvs[tri, 2] + v * uvs[tri, 4]
        tv = w * uvs[tri, 1] + u * uvs[tri, 3] + v * uvs[tri, 5]
        if texel(pixels, offsets, sizes, image[tri], tu, tv)[0] < OPACITY_CUTOFF:
            valid[k] = 0


def _cutout_header(cutout):
    """(header, the arrays it points into): what ``_cut`` reads, kept alive together."""
    arrays = (
        np.ascontiguousarray(cutout.image, np.int64),
        np.ascontiguousarray(cutout.corner_uvs, np.float32).reshape(-1, 6),
        np.ascontiguousarray(cutout.pixels, np.float32),
        np.ascontiguousarray(cutout.offsets, np.int64),
        np.ascontiguousarray(cutout.sizes, np.int64).reshape(-1, 2),
    )
    image, uvs, pixels, offsets, sizes = arrays
    header = np.array([len(image), image.ctypes.data, uvs.ctypes.data, pixels.ctypes.data, len(pixels),
                       offsets.ctypes.data, sizes.ctypes.data, len(offsets)], np.int64)
    return header, arrays


# -- the library ----------------------------------------------------------------------------

_LIB = None
_DEVICE = None
_LIB_LOCK = threading.Lock()


def library_path():
    """The ``libembree4`` shipped inside the embreex wheel (found without importing embreex)."""
    spec = importlib.util.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("embreex is not installed: it ships the Embree library the ray tracer uses")
    package = list(spec.submodule_search_locations)[0]
    found = sorted(glob.glob(os.path.join(os.path.dirname(package), "embreex.libs", "libembree4*.so*")))
    found += sorted(glob.glob(os.path.join(package, "libembree4*")))
    if not found:
        raise ImportError(f"no libembree4 next to embreex in {os.path.dirname(package)}")
    return found[0]


def _library():
    """(the ctypes library, the process's one Embree device), loaded on first use."""
    global _LIB, _DEVICE
    with _LIB_LOCK:
        if _LIB is None:
            lib = ctypes.CDLL(library_path())
            p, u, i, s = ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_size_t
            for name, restype, argtypes in (
                ("rtcNewDevice", p, [ctypes.c_char_p]),
                ("rtcGetDeviceError", i, [p]),
                ("rtcNewScene", p, [p]),
                ("rtcSetSceneFlags", None, [p, i]),
                ("rtcCommitScene", None, [p]),
                ("rtcReleaseScene", None, [p]),
                ("rtcNewGeometry", p, [p, i]),
                ("rtcSetNewGeometryBuffer", p, [p, i, u, i, s, s]),
                ("rtcCommitGeometry", None, [p]),
                ("rtcAttachGeometry", u, [p, p]),
                ("rtcReleaseGeometry", None, [p]),
                ("rtcSetGeometryUserData", None, [p, p]),
                ("rtcSetGeometryIntersectFilterFunction", None, [p, p]),
                ("rtcSetGeometryOccludedFilterFunction", None, [p, p]),
            ):
                fn = getattr(lib, name)
                fn.restype, fn.argtypes = restype, argtypes
            device = lib.rtcNewDevice(None)
            if not device:
                raise RuntimeError(f"Embree could not create a device (error {lib.rtcGetDeviceError(None)})")
            _LIB, _DEVICE = lib, device
        return _LIB, _DEVICE


def _check(lib, device, what):
    code = lib.rtcGetDeviceError(device)
    if code:
        raise RuntimeError(f"Embree failed to {what} (RTCError {code})")


def _queries(lib):
    def pointer(name):
        return QUERY(ctypes.cast(getattr(lib, name), ctypes.c_void_p).value)

    return pointer("rtcIntersect1"), pointer("rtcOccluded1")


# -- single rays, from numba kernels ----------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def new_rayhit():
    """A ray-hit record for ``intersect1`` / ``occluded1``: (floats, ints), two views
    (float32, int32) of the same RAYHIT_WORDS words, RAYHIT_ALIGN-byte aligned. One per
    thread: it is written and read by every query."""
    buf = np.empty(RAYHIT_WORDS + RAYHIT_ALIGN // 4, np.float32)
    skip = ((RAYHIT_ALIGN - buf.ctypes.data % RAYHIT_ALIGN) % RAYHIT_ALIGN) // 4
    floats = buf[skip:skip + RAYHIT_WORDS]
    return floats, floats.view(np.int32)


@numba.njit(cache=True, nogil=True, inline="always")
def _set_ray(floats, ints, origin, direction, tfar):
    floats[ORG], floats[ORG + 1], floats[ORG + 2] = origin
    floats[TNEAR] = 0.0
    floats[DIR], floats[DIR + 1], floats[DIR + 2] = direction
    floats[TIME] = 0.0
    floats[TFAR] = tfar
    ints[MASK] = -1
    ints[RAY_ID] = 0
    ints[FLAGS] = 0
    ints[GEOM_ID] = INVALID_ID
    ints[PRIM_ID] = INVALID_ID
    ints[INST_ID] = INVALID_ID


_ONE_ULP_DOWN = np.float32(1.0 - 2.0**-24)  # x * this is the float32 below x (x > 0 normal)


@numba.njit(cache=True, nogil=True, inline="always")
def inside_triangle(u, v):
    """Barycentrics (u, v) float32 moved into the triangle: u, v >= 0 and u + v <= 1
    exactly when summed in float64, as every kernel sums them (w = 1 - u - v). Embree's
    u and v are quotients rounded on their own, so a hit near an edge can have u + v a
    rounding above 1; w is then about -1e-8, and a value interpolated with it (an
    irradiance, a texel) is negative where a corner's is 0 and another's is not.
    Inside the triangle (u, v) is returned as it is."""
    u = max(u, np.float32(0.0))
    v = max(v, np.float32(0.0))
    total = np.float64(u) + np.float64(v)
    if total > 1.0:
        u = np.float32(np.float64(u) / total)
        v = np.float32(1.0 - np.float64(u))
        while np.float64(u) + np.float64(v) > 1.0:
            v = v * _ONE_ULP_DOWN
    return u, v


@numba.njit(cache=True, nogil=True, inline="always")
def intersect1(rt, rayhit, origin, direction):
    """The closest hit of the ray origin + s direction, s > 0 (3-tuples, stored as
    float32; unit direction): (triangle int, MISS where none; t, u, v float32) as
    ``Hits``, (u, v) inside the triangle (``inside_triangle``); a miss has t = inf and
    u = v = 0."""
    floats, ints = rayhit
    _set_ray(floats, ints, origin, direction, FAR)
    rt.intersect(rt.scene, floats.ctypes.data, 0)
    if ints[GEOM_ID] == INVALID_ID:
        return MISS, FAR, np.float32(0.0), np.float32(0.0)
    u, v = inside_triangle(floats[HIT_U], floats[HIT_V])
    return ints[PRIM_ID], floats[TFAR], u, v


@numba.njit(cache=True, nogil=True, inline="always")
def occluded1(rt, rayhit, origin, direction, distance):
    """Whether the segment origin + s direction, 0 < s < distance (3-tuples), hits anything."""
    floats, ints = rayhit
    _set_ray(floats, ints, origin, direction, distance)
    rt.occluded(rt.scene, floats.ctypes.data, 0)
    return floats[TFAR] < 0.0  # Embree sets tfar to -inf on a hit


@numba.njit(cache=True, nogil=True)
def intersect_rays(rt, origins, directions, hits, start, stop):
    """Closest hits of rays start .. stop - 1 (origins, directions (N, 3) float32) into
    ``hits`` (``Hits``, same rows)."""
    rayhit = new_rayhit()
    for k in range(start, stop):
        tri, t, u, v = intersect1(
            rt, rayhit, (origins[k, 0], origins[k, 1], origins[k, 2]), (directions[k, 0], directions[k, 1], directions[k, 2])
        )
        hits.triangle[k] = tri
        hits.t[k] = t
        hits.u[k] = u
        hits.v[k] = v


@numba.njit(cache=True, nogil=True)
def occluded_rays(rt, origins, directions, distances, blocked, start, stop):
    """``occluded1`` of rays start .. stop - 1 into blocked (N,) bool."""
    rayhit = new_rayhit()
    for k in range(start, stop):
        blocked[k] = occluded1(
            rt,
            rayhit,
            (origins[k, 0], origins[k, 1], origins[k, 2]),
            (directions[k, 0], directions[k, 1], directions[k, 2]),
            distances[k],
        )


# -- the scene ----------------------------------------------------------------------------------


class RayTracer:
    """Closest-hit and shadow queries against one triangle mesh.

    positions : (N, 3) float32 and faces : (T, 3) int32 of the merged scene mesh;
    ``cutout`` (``textures.Cutout``, or None): its triangles' opacity masks, through whose holes
    every query passes. The triangle index returned is the row of ``faces``; u and v are Embree's
    barycentrics (the hit is (1 - u - v) p0 + u p1 + v p2 of that row's vertices).
    Triangles are hit from both sides. ``epsilon`` is the ray-origin offset callers
    must apply (``origin_offset``). ``embree`` is what numba kernels trace with; it is
    valid while this tracer is referenced (keep the tracer, not only ``embree``, in
    hand while a kernel runs). ``threads`` splits the batched queries, nothing else.
    """

    def __init__(self, positions, faces, threads=None, cutout=None):
        triangles = np.ascontiguousarray(np.asarray(positions)[np.asarray(faces)], dtype=np.float32).reshape(-1, 3, 3)
        self.n_triangles = len(triangles)
        self.threads = threads or default_threads()
        self.epsilon = origin_offset(positions) if len(positions) else 0.0
        lib, device = _library()
        self._lib = lib
        scene = lib.rtcNewScene(device)
        _check(lib, device, "create a scene")
        lib.rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST)
        self._cutout = None
        masked = None if cutout is None else np.asarray(cutout.image) >= 0
        if masked is not None and len(masked) != self.n_triangles:
            raise ValueError(f"a cutout of {len(masked)} triangles for {self.n_triangles}")
        if self.n_triangles:
            if masked is None or not masked.any():
                self._attach(scene, triangles)
            else:  # the masked triangles in a geometry of their own, filtered; each a NaN in the other's
                self._cutout = _cutout_header(cutout)
                self._attach(scene, np.where(masked[:, None, None], np.float32(np.nan), triangles))
                self._attach(scene, np.where(masked[:, None, None], triangles, np.float32(np.nan)), self._cutout[0])
        lib.rtcCommitScene(scene)  # builds the BVH here, from the calling thread
        _check(lib, device, "build the scene")
        self._scene = scene
        self.embree = Embree(int(scene), *_queries(lib))
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._lock = threading.Lock()
        self.rays_cast = 0  # every query's rays
        self.shadow_rays_cast = 0  # of which occlusion queries

    def _attach(self, scene, triangles, cut=None):
        """One triangle geometry of ``triangles`` (T, 3, 3) in ``scene``; ``cut``: the
        header of its masks (``_cutout_header``), its filter function ``_cut``."""
        lib, device = _library()
        n = len(triangles)
        geometry = lib.rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE)
        # Embree's own buffers (padded as it needs, freed with the scene), laid out
        # as embreex lays them out: three vertices of its own per triangle
        vertex = lib.rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 16, 3 * n)
        index = lib.rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, n)
        _check(lib, device, f"allocate the buffers of {n:,} triangles")
        vertices = np.ctypeslib.as_array((ctypes.c_float * (12 * n)).from_address(vertex)).reshape(3 * n, 4)
        vertices[:, :3] = triangles.reshape(-1, 3)
        vertices[:, 3] = 0.0
        np.ctypeslib.as_array((ctypes.c_uint32 * (3 * n)).from_address(index))[:] = np.arange(3 * n)
        if cut is not None:
            lib.rtcSetGeometryUserData(geometry, cut.ctypes.data)
            lib.rtcSetGeometryIntersectFilterFunction(geometry, _cut.address)
            lib.rtcSetGeometryOccludedFilterFunction(geometry, _cut.address)
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(scene, geometry)
        lib.rtcReleaseGeometry(geometry)  # the scene holds it

    def count(self, rays, shadow_rays=0):
        """Add ``rays`` traced by kernels (of which ``shadow_rays`` occlusion queries)."""
        with self._lock:
            self.rays_cast += int(rays)
            self.shadow_rays_cast += int(shadow_rays)

    def close(self, wait=True):
        """Stop the batched queries' threads (``wait``: once their queries are done).
        The Embree scene itself is released with the last reference to this tracer
        (``__del__``): a kernel still tracing with ``embree`` (a task cancelled on a Dask
        worker, say) holds one through its caller."""
        if self._pool is not None:
            self._pool.shutdown(wait=wait)
            self._pool = None

    def __del__(self):
        try:
            # no waiting: the garbage collector may run this in any thread, one of the
            # pool's own or one holding a lock its threads want
            self.close(wait=False)
            if self._scene is not None:
                self._lib.rtcReleaseScene(self._scene)
                self._scene = None
        except Exception:  # interpreter shutdown: the library may be gone already
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _map(self, fn, n):
        k = self.threads if (self._pool is not None and n >= SPLIT_RAYS) else 1
        bounds = np.linspace(0, n, k + 1).astype(int)
        chunks = list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))
        if k == 1:
            fn(*chunks[0])
        else:  # a Ctrl-C or SIGTERM held until the chunks are done (signals.py says why)
            with HeldSignals():
                list(self._pool.map(lambda c: fn(*c), chunks))

    def intersect(self, origins, directions):
        """Closest hits of rays (origins, directions: (N, 3) float32; directions unit).

        Returns ``Hits`` (triangle (N,) int32, MISS where nothing is hit; t, u, v (N,)
        float32).
        """
        n = len(origins)
        hits = empty_hits(n)
        if n == 0:
            return hits
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)
        rt = self.embree
        self._map(lambda a, b: intersect_rays(rt, origins, directions, hits, a, b), n)
        self.count(n)
        return hits

    def occluded(self, origins, directions, distances):
        """Whether each segment origin + s * direction, 0 < s < distance, hits anything.

        Returns (N,) bool.
        """
        n = len(origins)
        blocked = np.empty(n, dtype=bool)
        if n == 0:
            return blocked
        origins = np.ascontiguousarray(origins, dtype=np.float32)
        directions = np.ascontiguousarray(directions, dtype=np.float32)
        distances = np.ascontiguousarray(distances, dtype=np.float32)
        rt = self.embree
        self._map(lambda a, b: occluded_rays(rt, origins, directions, distances, blocked, a, b), n)
        self.count(n, n)
        return blocked
