"""The radiosity stage: ``solve(scene, options) -> Solution``.

Phases
  1. refine the mesh (``max_edge``) and build the Embree scene;
  2. photons: independent batches, each with its own ids (hence random numbers),
     returning additive accumulators (density moments and an energy tally), summed
     in batch order: deterministic for a seed whatever the thread count, memory
     independent of the photon count, and ready to be farmed out;
  3. density estimation: local linear irradiance at every vertex (``density``);
  4. gather: for every vertex of a glossy object and every direction of its grid,
     emission + diffuse part + the specular lobe's integral of the incoming light.

Threads: batches (photons) and vertex blocks (gather) run concurrently, a thread
each; the numba kernels and Embree both release the GIL.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from radiosity.formats import directions, presets
from radiosity.formats.errors import InputError
from radiosity.formats.solution import ObjectSolution, Solution
from radiosity.scene.materials import albedo, pack_materials
from radiosity.transport import density, kernels
from radiosity.transport.embree import RayTracer, default_threads

MAX_PHOTON_DEPTH = 64
MAX_GATHER_DEPTH = 8
PHOTON_BATCH = 1 << 16
ALBEDO_TABLE_SIZE = 129

@dataclass(frozen=True)
class SolveOptions:
    """Knobs of the solver; None means "as the quality preset says".

    photons        : photons emitted in total
    gather_samples : gather rays per glossy vertex (rounded up to a square, for strata)
    light_samples  : light samples (shadow rays) per glossy vertex
    grid           : n of the n x n direction grid of every glossy object
                     (default: from each object's exponent, ``directions.grid_size``)
    max_edge       : refine to edges no longer than this (scene units)
    kernel_rings   : density kernel of each vertex: its hat function widened by this
                     many rings of neighbours (0: the hat alone; more: less noise,
                     more blur), see ``density.widen``
    seed, threads  : the random seed; worker threads (default: one per core)
    """

    quality: str = presets.DEFAULT_QUALITY
    photons: int | None = None
    gather_samples: int | None = None
    light_samples: int | None = None
    grid: int | None = None
    max_edge: float | None = None
    kernel_rings: int | None = None
    seed: int = 1
    threads: int | None = None

    def resolved(self, scene):
        """Every knob with its value for this scene (a plain dict, JSON-ready)."""
        preset = presets.preset(self.quality)
        out = {
            "quality": self.quality,
            "photons": self.photons if self.photons is not None else preset.photons,
            "gather_samples": self.gather_samples if self.gather_samples is not None else preset.gather_samples,
            "light_samples": self.light_samples if self.light_samples is not None else preset.light_samples,
            "kernel_rings": self.kernel_rings if self.kernel_rings is not None else preset.kernel_rings,
            "grid": self.grid,
            "seed": int(self.seed),
            "threads": default_threads() if self.threads is None else self.threads,
        }
        out["max_edge"], out["max_edge_chosen_by"] = presets.max_edge(scene, self.quality, self.max_edge)
        for key, low in (("photons", 1), ("gather_samples", 1), ("light_samples", 0), ("kernel_rings", 0), ("threads", 1)):
            if int(out[key]) != out[key] or out[key] < low:
                raise InputError(f"--{key.replace('_', '-')} must be a whole number >= {low}, got {out[key]}")
        if self.grid is not None and not (isinstance(self.grid, int) and 1 <= self.grid <= 256):
            raise InputError(f"--grid must be a whole number from 1 to 256, got {self.grid}")
        if not 0 <= self.seed < 2**63:
            raise InputError(f"--seed must be between 0 and 2^63, got {self.seed}")
        strata = math.isqrt(out["gather_samples"] - 1) + 1
        out["gather_samples"] = strata * strata
        return out


class _NullProgress:
    def __init__(self, *args, **kwargs):
        pass

    def update(self, n=1):
        pass

    def close(self):
        pass


def _progress_factory(enabled):
    if not enabled:
        return _NullProgress
    from tqdm import tqdm

    return lambda **kw: tqdm(unit_scale=True, dynamic_ncols=True, leave=True, disable=None, **kw)


def scene_arrays(scene, merged, epsilon):
    """The merged scene as the kernels read it (``kernels.SceneArrays``)."""
    material_names = list(scene.materials)
    table = pack_materials([scene.materials[n] for n in material_names])
    cos_grid = np.linspace(0.0, 1.0, ALBEDO_TABLE_SIZE)
    albedo_table = np.stack([albedo(scene.materials[n], cos_grid) for n in material_names])
    object_material = np.array([material_names.index(o.material.name) for o in scene.objects])
    face_material = object_material[merged.triangle_object].astype(np.int64)

    positions = np.concatenate([o.positions for o in scene.objects])
    faces = merged.faces.astype(np.int64)
    tri = positions[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    twice_area = np.linalg.norm(cross, axis=1)
    face_normals = cross / np.maximum(twice_area, 1e-300)[:, None]
    power = np.pi * table[face_material, 7:10].sum(axis=1) * 0.5 * twice_area
    emitting = np.nonzero(power > 0)[0]
    emit_area_pdf = np.zeros(len(faces))
    if len(emitting):
        probability = power[emitting] / power[emitting].sum()
        emit_area_pdf[emitting] = probability / (0.5 * twice_area[emitting])
        cdf = np.cumsum(probability)
        cdf[-1] = 1.0
    else:
        cdf = np.ones(1)
        emitting = np.zeros(1, dtype=np.int64)
    return kernels.SceneArrays(
        positions=positions,
        normals=np.concatenate([o.normals for o in scene.objects]),
        tangents=np.concatenate([o.tangents for o in scene.objects]),
        faces=faces,
        face_normals=face_normals,
        face_material=face_material,
        materials=table,
        albedo_table=albedo_table,
        emit_cdf=cdf,
        emit_triangles=emitting.astype(np.int64),
        emit_area_pdf=emit_area_pdf,
        epsilon=float(epsilon),
    )


def trace_photon_batch(tracer, sa, seed, first_id, count, total):
    """Trace photons first_id .. first_id + count - 1 of ``total``.

    Returns (moment0 (N, 3), moment1 (N, 3, 2), tally (T_LENGTH,)) float64, all additive.
    """
    n_vertices = len(sa.positions)
    moment0 = np.zeros((n_vertices, 3))
    moment1 = np.zeros((n_vertices, 3, 2))
    tally = np.zeros(kernels.T_LENGTH)
    org = np.empty((count, 3), dtype=np.float32)
    dirn = np.empty((count, 3), dtype=np.float32)
    power = np.empty((count, 3))
    ids = np.empty(count, dtype=np.int64)
    kernels.emit_photons(sa, seed, first_id, count, total, org, dirn, power, ids)
    out = (np.empty_like(ids), np.empty_like(org), np.empty_like(dirn), np.empty_like(power))
    depth = 0
    while len(ids):
        tri, _, u, v = tracer.intersect(org, dirn)
        n = kernels.bounce_photons(
            sa, seed, depth, MAX_PHOTON_DEPTH, ids, org, dirn, power, tri, u, v,
            moment0, moment1, tally, *out,
        )
        ids, org, dirn, power = (a[:n].copy() for a in out)
        depth += 1
    return moment0, moment1, tally


def _run_ordered(pool, threads, fn, jobs, combine, progress, weights):
    """Run ``fn(job)`` for every job, a few at a time, and ``combine`` the results in
    job order (deterministic sums); stops early and cleanly on KeyboardInterrupt."""
    pending = []
    try:
        for job, weight in zip(jobs, weights):
            pending.append((pool.submit(fn, job), weight))
            if len(pending) > 2 * threads:
                future, w = pending.pop(0)
                combine(future.result())
                progress.update(w)
        for future, w in pending:
            combine(future.result())
            progress.update(w)
    except BaseException:
        for future, _ in pending:
            future.cancel()
        raise


def solve(scene, opts=SolveOptions(), progress=False):
    """The view-independent solution of ``scene`` (Contract 1), as a ``Solution``."""
    settings = opts.resolved(scene)
    make_bar = _progress_factory(progress)
    times = {}
    t0 = time.perf_counter()
    refined = scene.refined(settings["max_edge"])
    merged = refined.merged()
    tracer = RayTracer(merged.positions, merged.faces, threads=1)
    sa = scene_arrays(refined, merged, tracer.epsilon)
    times["setup"] = time.perf_counter() - t0
    threads = settings["threads"]
    seed = settings["seed"]

    with ThreadPoolExecutor(threads) as pool:
        # -- photons ------------------------------------------------------------------
        t0 = time.perf_counter()
        total = settings["photons"]
        moment0 = np.zeros((len(sa.positions), 3))
        moment1 = np.zeros((len(sa.positions), 3, 2))
        tally = np.zeros(kernels.T_LENGTH)
        emitted = np.zeros(3)
        for o in refined.emitters:
            emitted += o.emitted_power
        rays_before = tracer.rays_cast

        def combine_photons(result):
            moment0.__iadd__(result[0])
            moment1.__iadd__(result[1])
            tally.__iadd__(result[2])

        starts = list(range(0, total, PHOTON_BATCH))
        counts = [min(PHOTON_BATCH, total - s) for s in starts]
        if refined.emitters:
            bar = make_bar(total=total, desc="photons", unit="photon")
            _run_ordered(
                pool,
                threads,
                lambda job: trace_photon_batch(tracer, sa, seed, job[0], job[1], total),
                list(zip(starts, counts)),
                combine_photons,
                bar,
                counts,
            )
            bar.close()
        photon_rays = tracer.rays_cast - rays_before
        times["photons"] = time.perf_counter() - t0

        # -- density ------------------------------------------------------------------
        t0 = time.perf_counter()
        irradiance = np.zeros_like(moment0)
        offsets = merged.vertex_offset
        for i, o in enumerate(refined.objects):
            sl = slice(offsets[i], offsets[i + 1])
            irradiance[sl] = density.irradiance(
                o.positions, o.normals, o.tangents, o.faces, moment0[sl], moment1[sl], settings["kernel_rings"]
            )
        times["density"] = time.perf_counter() - t0

        # -- gather -------------------------------------------------------------------
        t0 = time.perf_counter()
        rays_before = tracer.rays_cast
        results = []
        glossy = [o for o in refined.objects if o.material.is_glossy]
        grid_sizes = {
            o.name: settings["grid"] or directions.grid_size(o.material.exponent, settings["quality"])
            for o in glossy
        }
        work = sum(o.n_vertices for o in glossy)
        bar = make_bar(total=work, desc="gather", unit="vertex") if work else None
        for i, o in enumerate(refined.objects):
            sl = slice(offsets[i], offsets[i + 1])
            mat = o.material
            diffuse = np.asarray(mat.diffuse) / np.pi * irradiance[sl] + np.asarray(mat.emission)
            if not mat.is_glossy:
                dirs = directions.DIFFUSE_DIRECTIONS
                radiance = diffuse[:, None, :]
            else:
                dirs = directions.grid_directions(grid_sizes[o.name])
                radiance = _gather_object(pool, tracer, sa, irradiance, o, offsets[i], dirs, settings, bar)
            results.append((o, dirs, radiance))
        if bar is not None:
            bar.close()
        gather_rays = tracer.rays_cast - rays_before
        times["gather"] = time.perf_counter() - t0
    tracer.close()

    stats = {
        "photons": int(total) if refined.emitters else 0,
        "rays": int(tracer.rays_cast),
        "photon_rays": int(photon_rays),
        "gather_rays": int(gather_rays),
        "time_s": {k: round(v, 4) for k, v in times.items()},
        "photon_rays_per_s": photon_rays / times["photons"] if times["photons"] > 0 else 0.0,
        "gather_rays_per_s": gather_rays / times["gather"] if times["gather"] > 0 else 0.0,
        "seed": seed,
        "threads": threads,
        "quality": settings["quality"],
        "triangles": int(refined.n_triangles),
        "vertices": int(refined.n_vertices),
        "grid": grid_sizes,
        "energy": {
            "emitted": emitted.tolist(),
            "escaped": tally[kernels.T_ESCAPED:kernels.T_ESCAPED + 3].tolist(),
            "absorbed": tally[kernels.T_ABSORBED:kernels.T_ABSORBED + 3].tolist(),
            "backface": tally[kernels.T_BACKFACE:kernels.T_BACKFACE + 3].tolist(),
            "terminated": tally[kernels.T_TERMINATED:kernels.T_TERMINATED + 3].tolist(),
            "incident": tally[kernels.T_INCIDENT:kernels.T_INCIDENT + 3].tolist(),
            "photon_hits": int(tally[kernels.T_HITS]),
        },
    }
    objects = tuple(
        ObjectSolution(
            name=o.name,
            positions=o.positions.astype(np.float32),
            normals=o.normals.astype(np.float32),
            tangents=o.tangents.astype(np.float32),
            faces=o.faces.astype(np.int32),
            directions=np.asarray(dirs, dtype=np.float32),
            radiance=np.asarray(radiance, dtype=np.float32),
            material=o.material.to_dict(),
        )
        for o, dirs, radiance in results
    )
    return Solution(
        objects=objects, settings=dict(settings), stats=stats, scene=scene.source or scene.name, camera=scene.camera
    )


def _gather_object(pool, tracer, sa, irradiance, obj, offset, dirs, settings, bar):
    """Radiance (V, D, 3) float64 of one glossy object's vertices."""
    n_light = settings["light_samples"] if len(sa.emit_triangles) and sa.emit_area_pdf.any() else 0
    n_gather = settings["gather_samples"]
    strata = math.isqrt(n_gather)
    block = max(8, min(256, (1 << 16) // (n_light + n_gather)))  # small blocks balance the threads
    vertices = np.arange(offset, offset + obj.n_vertices, dtype=np.int64)
    blocks = [vertices[s:s + block] for s in range(0, len(vertices), block)]
    mat = pack_materials([obj.material])[0]
    emission = np.asarray(obj.material.emission, dtype=np.float64)
    kd = np.asarray(obj.material.diffuse) / np.pi
    radiance = np.empty((obj.n_vertices, len(dirs), 3))
    dirs64 = np.asarray(dirs, dtype=np.float64)

    def run(verts):
        return verts, gather_block(tracer, sa, irradiance, verts, mat, emission, kd, n_light, n_gather, strata, dirs64, settings["seed"])

    def combine(result):
        verts, values = result
        radiance[verts - offset] = values

    _run_ordered(pool, settings["threads"], run, blocks, combine, bar, [len(b) for b in blocks])
    return radiance


def gather_block(tracer, sa, irradiance, verts, mat, emission, kd, n_light, n_gather, strata, dirs, seed):
    """Outgoing radiance (B, D, 3) of a block of vertices of one glossy object."""
    b = len(verts)
    nl, ng = b * n_light, b * n_gather
    light_org = np.empty((nl, 3), np.float32)
    light_dir = np.empty((nl, 3), np.float32)
    light_dist = np.empty(nl, np.float32)
    light_wi = np.zeros((nl, 3))
    light_le = np.zeros((nl, 3))
    light_pdf = np.zeros(nl)
    g_org = np.empty((ng, 3), np.float32)
    g_dir = np.empty((ng, 3), np.float32)
    g_wi = np.empty((ng, 3))
    kernels.make_gather_rays(
        sa, seed, verts, n_light, strata, light_org, light_dir, light_dist, light_wi, light_le, light_pdf,
        g_org, g_dir, g_wi,
    )
    visible = np.zeros(nl, dtype=bool)
    valid = light_pdf > 0
    if valid.any():
        visible[valid] = ~tracer.occluded(light_org[valid], light_dir[valid], light_dist[valid])

    incoming = np.zeros((ng, 3))
    ids = np.arange(ng, dtype=np.int64)
    throughput = np.ones((ng, 3))
    first_cos = g_wi[:, 2].copy()
    org, dirn = g_org, g_dir
    out = (np.empty_like(ids), np.empty_like(throughput), np.empty_like(org), np.empty_like(dirn))
    for depth in range(MAX_GATHER_DEPTH):
        if not len(ids):
            break
        tri, _, u, v = tracer.intersect(org, dirn)
        n = kernels.shade_paths(
            sa, irradiance, seed, depth, MAX_GATHER_DEPTH, n_light, n_gather, verts,
            ids, throughput, org, dirn, first_cos, tri, u, v, incoming, *out,
        )
        ids, throughput, org, dirn = (a[:n].copy() for a in out)

    values = np.empty((b, len(dirs), 3))
    diffuse = kd[None, :] * irradiance[verts]
    kernels.gather_outputs(
        mat, emission, diffuse, n_light, n_gather, light_wi, light_le, light_pdf, visible,
        g_wi, incoming, math.isqrt(len(dirs)), dirs, values,
    )
    return values

