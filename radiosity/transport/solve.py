"""The radiosity stage: ``solve(scene, options) -> Solution``.

Phases
  1. refine the mesh (``max_edge``) and build the Embree scene;
  2. photons: independent batches, each with its own ids (hence random numbers),
     returning additive accumulators (density moments and an energy tally), summed
     in batch order: deterministic for a seed whatever the thread count, memory
     independent of the photon count, and ready to be farmed out;
  3. density estimation: local linear irradiance at every vertex (``density``);
  4. gather: for every vertex of a glossy object and every direction of its grid,
     emission + diffuse part + the specular lobe's integral of the incoming light;
     then further passes where the neighbours' gather was noisy (``regather``).

Threads: batches (photons) and vertex blocks (gather) run concurrently, a thread
each; a batch or a block is one jitted call that releases the GIL and traces its own
rays, calling Embree directly (``photons.trace_photons``, ``gather.trace_gather``). Or Dask
(``SolveOptions(scheduler="dask" | "tcp://HOST:PORT")``, ``solve(..., client=)``): the
same batches and blocks as tasks on a cluster, combined in the same order, so the
same bits (``radiosity.transport.distributed``).

Knobs are checked before the work: a photon count beyond 2^40, or photons, gather and
light samples, grid and threads whose arrays would not fit in the machine's memory
(``memory_estimate``, ``check_memory``: once with the scene as given, again after
refinement) are refused with an InputError naming the estimate and the memory.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.physics.emitters import MAX_NODES
from radiosity.physics.materials import FLOAT32_MAX
from radiosity.physics.textures import TexturedDiffuse
from radiosity.policies import presets
from radiosity.policies.limits import available_memory, check_seed
from radiosity.scene.emitter_parts import emitter_parts
from radiosity.scene.material_kernels import diffuse_exitances, diffuse_reflectance
from radiosity.transport import density, highlights, regather
from radiosity.transport import lights as delta_lights
from radiosity.transport.batches import (  # noqa: F401 (the units of work, importable from the solver too)
    ALBEDO_TABLE_SIZE,
    MAX_GATHER_DEPTH,
    MAX_PHOTON_DEPTH,
    PHOTON_BATCH,
    gather_block,
    scene_arrays,
    trace_photon_batch,
)
from radiosity.transport.embree import RayTracer, default_threads, origin_offset
from radiosity.transport.records import (
    T_ABSORBED,
    T_BACKFACE,
    T_ESCAPED,
    T_HITS,
    T_INCIDENT,
    T_TERMINATED,
    GatherBlock,
    empty_gather_samples,
    empty_light_samples,
    empty_path_buffers,
    empty_rays,
    empty_tally,
)
from radiosity.transport.threads import ThreadRunner
from radiosity.transport.threads import progress_bar as _progress_factory

MAX_PHOTONS = 1 << 40  # ~1e12: days of tracing on any machine this runs on
GATHER_BLOCK_SAMPLES = 1 << 16  # rays (light + gather) of a gather block, about
MAX_VISIBILITY_SAMPLES = 4096

# bytes per element of the arrays that grow with the knobs (see ``memory_estimate``)
def record_bytes(record):
    """Bytes of a record of arrays (a NamedTuple of arrays and of such records)."""
    return sum(record_bytes(f) if isinstance(f, tuple) else np.asarray(f).nbytes for f in record)


_SAMPLE_WEIGHT_BYTES = 48  # a sample's two RGB float64 weights in the block's outputs
_SHADOW_RAY_BYTES = record_bytes(empty_light_samples(1)._replace(wi=(), radiance=(), pdf=()))  # the copy Embree reads
_PHOTON_VERTEX_BYTES = record_bytes(empty_tally(1)) - record_bytes(empty_tally(0))  # a batch's density moments, per vertex
_LIGHT_SAMPLE_BYTES = record_bytes(empty_light_samples(1)) + _SHADOW_RAY_BYTES + _SAMPLE_WEIGHT_BYTES
_GATHER_SAMPLE_BYTES = (record_bytes(empty_gather_samples(1)) + record_bytes(empty_path_buffers(1))  # the paths, the next
                        + record_bytes(empty_rays(1)) + _SAMPLE_WEIGHT_BYTES)  # the rays' copy, the weights
_OUTPUT_BYTES = 3 * 4  # per vertex and direction: float32 radiance, summed and written in place
# the rest, measured (benchmarks/bench_scale.py, draft, 87k and 553k vertices: 1.2 and 1.8 kB a
# vertex besides the parts above and the process): the scene, its refined and merged meshes,
# Embree's BVH, the density estimate's arrays, the solution's arrays as written
_SCENE_VERTEX_BYTES = 2_500
_PROCESS_BYTES = 250 * 2**20  # Python, numpy, scipy, numba, Embree before any scene


@dataclass(frozen=True)
class SolveSettings:
    """Every knob of a solve with its value for one scene (``SolveOptions.resolved``),
    checked; ``meta()`` is the solution file's ``settings`` (JSON, in this order)."""

    quality: str
    photons: int
    gather_samples: int
    light_samples: int
    kernel_rings: int
    min_photons: int
    extra_gather: float
    gather_tolerance: float
    grid: int | None
    lobe_light: bool
    emitter_highlights: bool
    visibility_samples: int
    emitter_nodes: int
    seed: int
    threads: int
    max_edge: float
    max_edge_chosen_by: str

    def meta(self):
        return dataclasses.asdict(self)


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
    min_photons    : a kernel whose support holds fewer photons widens further, ring by
                     ring (``density.irradiance``; 0: never; more: less noise, more blur)
    extra_gather   : further gather passes where the gather is noisy, at most this
                     times the glossy vertices (0: none), see ``regather``
    gather_tolerance : the relative standard error those passes aim at
    emitter_highlights : the emitters' direct glossy highlights in closed form (True:
                     ``transport.highlights``, the solution's ``emitters`` and each glossy
                     object's ``visibility``, which the displays draw per pixel); False
                     gathers them like any light (for comparisons)
    visibility_samples : shadow rays per glossy vertex and emitter part
    emitter_nodes  : N of the highlights' quadrature (``physics.emitters``)
    lobe_light     : sample the light where gather paths meet glossy surfaces (True);
                     False finds it through the lobe alone: the
                     same expected value, more noise (for comparisons)
    seed, threads  : the random seed; worker threads (default: one per core)
    scheduler      : "threads" (this process), "dask" (a new LocalCluster sized to the
                     machine) or a Dask scheduler's address "tcp://HOST:PORT"; the same
                     seed gives the same bits on any of them
    """

    quality: str = presets.DEFAULT_QUALITY
    photons: int | None = None
    gather_samples: int | None = None
    light_samples: int | None = None
    grid: int | None = None
    max_edge: float | None = None
    kernel_rings: int | None = None
    min_photons: int | None = None
    extra_gather: float | None = None
    gather_tolerance: float | None = None
    emitter_highlights: bool = True
    visibility_samples: int | None = None
    emitter_nodes: int | None = None
    lobe_light: bool = True
    seed: int = 1
    threads: int | None = None
    scheduler: str = "threads"

    def resolved(self, scene):
        """Every knob with its value for this scene (a ``SolveSettings``), checked: one
        line naming the flag for a value out of range or a solve that cannot fit."""
        preset = presets.preset(self.quality)
        out = {
            "quality": self.quality,
            "photons": self.photons if self.photons is not None else preset.photons,
            "gather_samples": self.gather_samples if self.gather_samples is not None else preset.gather_samples,
            "light_samples": self.light_samples if self.light_samples is not None else preset.light_samples,
            "kernel_rings": self.kernel_rings if self.kernel_rings is not None else preset.kernel_rings,
            "min_photons": self.min_photons if self.min_photons is not None else presets.MIN_PHOTONS,
            "extra_gather": float(self.extra_gather if self.extra_gather is not None else preset.extra_gather),
            "gather_tolerance": float(
                self.gather_tolerance if self.gather_tolerance is not None else preset.gather_tolerance
            ),
            "grid": self.grid,
            "lobe_light": bool(self.lobe_light),
            "emitter_highlights": bool(self.emitter_highlights),
            "visibility_samples": (
                self.visibility_samples if self.visibility_samples is not None else preset.visibility_samples
            ),
            "emitter_nodes": self.emitter_nodes if self.emitter_nodes is not None else preset.emitter_nodes,
            "seed": int(self.seed),
            "threads": default_threads() if self.threads is None else self.threads,
        }
        out["max_edge"], out["max_edge_chosen_by"] = presets.max_edge(scene, self.quality, self.max_edge)
        if not math.isfinite(out["max_edge"]):
            raise InputError(f"--max-edge must be a finite length, got {out['max_edge']}")
        for key, low in (
            ("photons", 1), ("gather_samples", 1), ("light_samples", 0), ("kernel_rings", 0), ("min_photons", 0),
            ("threads", 1),
            ("visibility_samples", 1), ("emitter_nodes", 1),
        ):  # fmt: skip
            if int(out[key]) != out[key] or out[key] < low:
                raise InputError(f"--{key.replace('_', '-')} must be a whole number >= {low}, got {out[key]}")
        for key in ("extra_gather", "gather_tolerance"):
            if not (math.isfinite(out[key]) and out[key] >= 0):
                raise InputError(f"--{key.replace('_', '-')} must be a number >= 0, got {out[key]:g}")
        if out["kernel_rings"] > presets.MAX_KERNEL_RINGS:
            raise InputError(
                f"--kernel-rings must be a whole number from 0 to {presets.MAX_KERNEL_RINGS}, got {out['kernel_rings']}"
            )
        if out["emitter_nodes"] > MAX_NODES:
            raise InputError(f"--emitter-nodes must be a whole number from 1 to {MAX_NODES}, got {out['emitter_nodes']}")
        if out["visibility_samples"] > MAX_VISIBILITY_SAMPLES:
            raise InputError(
                f"--visibility-samples must be a whole number from 1 to {MAX_VISIBILITY_SAMPLES}, "
                f"got {out['visibility_samples']}"
            )
        if self.grid is not None and not (isinstance(self.grid, int) and 1 <= self.grid <= 256):
            raise InputError(f"--grid must be a whole number from 1 to 256, got {self.grid}")
        if self.scheduler != "threads":
            from radiosity.policies.cluster import check_scheduler

            check_scheduler(self.scheduler)
        check_seed(self.seed)
        if out["photons"] > MAX_PHOTONS:
            raise InputError(
                f"--photons {out['photons']:,} is more than the {MAX_PHOTONS:,} (2^40) one run can trace; "
                "use fewer photons"
            )
        strata = math.isqrt(out["gather_samples"] - 1) + 1
        out["gather_samples"] = strata * strata
        settings = SolveSettings(**out)
        # the sizes before refinement (a lower bound): refuse hopeless knobs before any work;
        # ``solve`` checks again with the refined mesh
        check_memory(settings, scene.n_vertices, _glossy_sizes(scene.objects, settings))
        return settings


def _glossy_sizes(objects, settings):
    """[(name, vertices, grid n)] of the glossy objects (``Material.has_grid``: a perfect mirror has none)."""
    return [
        (o.name, o.n_vertices, settings.grid or directions.grid_size(o.material.exponent, settings.quality))
        for o in objects
        if o.material.has_grid
    ]


def _gather_block_size(n_light, n_gather):
    """Vertices per gather block: small blocks balance the threads."""
    return max(8, min(256, GATHER_BLOCK_SAMPLES // (n_light + n_gather)))


def memory_estimate(settings, n_vertices, glossy):
    """Peak bytes of the arrays that grow with the knobs, by part.

    settings : a ``SolveSettings``; n_vertices : vertices of the scene;
    glossy : [(name, vertices, grid n)] of its glossy objects. Returns {part: bytes}:
    ``photons`` (the batches in flight: their density moments), ``gather
    buffers`` (the blocks in flight: light samples, gather rays and paths, outputs)
    and ``gather output`` (every glossy object's radiance, V x D x 3).
    """
    in_flight = 2 * settings.threads + 1  # ``threads.run_ordered`` keeps at most this many jobs
    photons = settings.photons
    batches = min(in_flight, -(-photons // PHOTON_BATCH)) + 1  # + the running sums
    per_batch = n_vertices * _PHOTON_VERTEX_BYTES  # the waves' ray buffers are small (PHOTON_WAVE rows)
    n_light, n_gather = settings.light_samples, settings.gather_samples
    block = _gather_block_size(n_light, n_gather)
    buffers = output = 0
    for _, vertices, grid_n in glossy:
        directions_count = grid_n * grid_n
        per_block = block * (n_light * _LIGHT_SAMPLE_BYTES + n_gather * _GATHER_SAMPLE_BYTES + directions_count * 24)
        blocks = min(in_flight, -(-vertices // block))
        buffers = max(buffers, blocks * per_block)
        output += vertices * directions_count * _OUTPUT_BYTES
    scene = _PROCESS_BYTES + n_vertices * _SCENE_VERTEX_BYTES
    return {"scene": scene, "photons": batches * per_batch, "gather buffers": buffers, "gather output": output}


_MEMORY_ADVICE = {
    "scene": "choose a larger --max-edge (fewer vertices) or free memory",
    "photons": "use fewer --threads or a larger --max-edge",
    "gather buffers": "lower --gather-samples, --light-samples or --threads",
    "gather output": "lower --grid or choose a larger --max-edge",
}


def check_memory(settings, n_vertices, glossy, available=None, say=None):
    """Refuse (InputError) a solve whose arrays cannot fit in the machine's memory;
    ``say`` (a function of one line), if given, is told the estimate first.

    ``available`` : bytes; default ``available_memory()`` (unknown: no check).
    """
    available = available_memory() if available is None else available
    parts = memory_estimate(settings, n_vertices, glossy)
    need = sum(parts.values())
    if say is not None:
        largest = max(parts, key=parts.get)
        have = "" if available is None else f" of {_bytes(available)} available"
        say(f"solve: about {_bytes(need)} at most{have} ({n_vertices:,} vertices; the largest part: {largest} "
            f"{_bytes(parts[largest])})")
    if available is None or need <= available:
        return
    worst = max(parts, key=parts.get)
    detail = f"{worst} {_bytes(parts[worst])}"
    if worst == "gather output":
        name, vertices, grid_n = max(glossy, key=lambda g: g[1] * g[2] ** 2)
        detail += f"; {name!r}: {vertices:,} vertices x {grid_n * grid_n:,} directions"
    raise InputError(
        f"the solve would need about {_bytes(need)} of memory ({detail}), more than the "
        f"{_bytes(available)} available; {_MEMORY_ADVICE[worst]}"
    )


def _bytes(n):
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def _runner(opts, settings, client):
    """Where the batches run: the given Dask client, a Dask cluster (``opts.scheduler``,
    connected now: a bad address fails before any work) or this process's threads."""
    if client is None and opts.scheduler == "threads":
        return ThreadRunner(settings.threads)
    from radiosity.policies.cluster import connect
    from radiosity.transport.distributed import DaskRunner

    if client is not None:
        return DaskRunner(client)
    return DaskRunner(*connect(opts.scheduler), own_client=True)


def solve(scene, opts=SolveOptions(), progress=False, client=None):
    """The view-independent solution of ``scene`` (solution.npz, docs/formats.md), as a ``Solution``.

    ``client`` : a ``distributed.Client`` to run the batches on (else ``opts.scheduler``
    says where). Raises InputError for knobs the machine cannot run (``check_memory``),
    a Dask scheduler that cannot be reached, or a radiance beyond single precision;
    warns (SceneWarning) if nothing emits light.
    """
    settings = opts.resolved(scene)
    if not scene.is_lit:
        warnings.warn(
            f"scene {scene.name!r} has no emitters (no material with emission > 0, no light, no environment): "
            "every radiance is 0",
            SceneWarning,
            stacklevel=2,
        )
    runner = _runner(opts, settings, client)
    try:
        return _solve(scene, settings, runner, progress)
    finally:
        runner.close()


class _Photons(NamedTuple):
    """What the photon pass leaves: the density moments, the energy tally, the power
    emitted (RGB), whether anything emits, the photons traced and their rays, the power
    of delta lights no photon carried (RGB)."""

    moment0: np.ndarray
    moment1: np.ndarray
    tally: np.ndarray
    emitted: np.ndarray
    lit: bool
    total: int
    rays: int
    unreached: np.ndarray


def _solve(scene, settings, runner, progress):
    """The solution of ``scene``: photons, then each vertex's irradiance, the glossy
    vertices' gather, the emitters' highlights in closed form, each object's radiance."""
    make_bar = _progress_factory(progress)
    times = {}
    t0 = time.perf_counter()
    refined = scene.refined(settings.max_edge)
    check_memory(settings, refined.n_vertices, _glossy_sizes(refined.objects, settings),
                 say=(lambda line: print(line, file=sys.stderr)) if progress else None)
    merged = refined.merged()
    # parts from the scene as given: refinement would add vertices off a sphere lamp
    parts, analytic = emitter_parts(scene) if settings.emitter_highlights else ((), ())
    # every delta light's direct highlight is in closed form (exact, and nothing else can find
    # it), drawn per pixel where it is a part, else kept in the grid
    closed = parts + tuple(light for light in scene.lights if not any(light is p for p in parts))
    sa = scene_arrays(refined, merged, origin_offset(merged.positions), analytic)
    runner.start(merged, sa, settings.seed)
    times["setup"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    photons = _photon_pass(refined, sa, runner, settings, make_bar)
    times["photons"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    irradiance = _irradiance(refined, merged, photons, settings)
    times["density"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    rays_before = runner.rays_cast
    grid_sizes = {name: grid_n for name, _, grid_n in _glossy_sizes(refined.objects, settings)}
    work = sum(o.n_vertices for o in refined.objects if o.name in grid_sizes)
    bar = make_bar(total=work, desc="gather", unit="vertex") if work else None
    offsets = merged.vertex_offset
    glossy = [
        (o, offsets[i], directions.grid_directions(grid_sizes[o.name]))
        for i, o in enumerate(refined.objects)
        if o.material.has_grid
    ]
    try:
        gathered, regathered = _gather_glossy(runner, sa, settings.seed, irradiance, glossy, settings, bar)
    finally:
        if bar is not None:
            bar.close()
    gather_rays = runner.rays_cast - rays_before
    times["gather"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    visible, own_parts, shadow_rays = _closed_form_highlights(merged, sa, (parts, closed), glossy, gathered, settings)
    times["highlights"] = time.perf_counter() - t0
    results, textured = _radiance_of_objects(refined, offsets, irradiance, gathered, {o.name: d for o, _, d in glossy})

    stats = {
        "photons": int(photons.total) if photons.lit else 0,
        "rays": int(runner.rays_cast),
        "photon_rays": int(photons.rays),
        "gather_rays": int(gather_rays),
        "visibility_rays": int(shadow_rays),
        "emitter_parts": {name: sum(p.source == name for p in parts) for name in (*analytic, *(
            p.source for p in parts if p.is_delta))},
        "time_s": {k: round(v, 4) for k, v in times.items()},
        "photon_rays_per_s": photons.rays / times["photons"] if times["photons"] > 0 else 0.0,
        "gather_rays_per_s": gather_rays / times["gather"] if times["gather"] > 0 else 0.0,
        "seed": settings.seed,
        "threads": runner.threads,
        "scheduler": runner.description,
        "quality": settings.quality,
        "triangles": int(refined.n_triangles),
        "vertices": int(refined.n_vertices),
        "grid": grid_sizes,
        "regather": regathered,
        "energy": _energy(photons, bool(refined.lights)),
    }
    objects = _object_solutions(results, textured, visible, own_parts, len(parts))
    return Solution(
        objects=objects, settings=settings.meta(), stats=stats, scene=scene.source or scene.name, camera=scene.camera,
        emitters=parts, emitter_nodes=int(settings.emitter_nodes), environment=scene.environment,
        lights=scene.lights, microfacet_highlights=True,
    )


def _photon_pass(refined, sa, runner, settings, make_bar):
    """The photons of every emitter, the environment and the delta lights, traced
    (``runner.photon_batches``) into each vertex's density moments (a ``_Photons``)."""
    total = settings.photons
    photon_sums = empty_tally(len(sa.positions))
    emitted = np.zeros(3)
    for o in refined.emitters:
        emitted += o.emitted_power
    lit = bool(refined.emitters) or sa.env.photon_share > 0 or sa.lights.photon_share > 0
    if sa.env.photon_share > 0:
        emitted += refined.environment.power(sa.env.radius)
    if refined.lights:
        emitted += delta_lights.power(refined.lights, sa.lights.radius)
    rays_before = runner.rays_cast

    def combine_photons(result):
        for acc, part in zip(photon_sums, result):
            acc += part

    if lit:
        bar = make_bar(total=total, desc="photons", unit="photon")
        try:
            runner.photon_batches(total, combine_photons, bar)
        finally:
            bar.close()
    moment0, moment1, tally = photon_sums
    unreached = np.zeros(3)
    if refined.lights and lit:  # a point light's power its photons do not carry leaves the scene at once
        unreached = delta_lights.unreached(refined.lights, sa.lights.center, sa.lights.radius)
        tally[T_ESCAPED:T_ESCAPED + 3] += unreached
    return _Photons(moment0, moment1, tally, emitted, lit, total, runner.rays_cast - rays_before, unreached)


def _irradiance(refined, merged, photons, settings):
    """Each vertex's irradiance (N, 3) from the photons' density moments (``density.irradiance``)."""
    irradiance = np.zeros_like(photons.moment0)
    offsets = merged.vertex_offset
    total = photons.total
    photon_power = float(photons.emitted.sum()) / total if photons.lit and total else 0.0  # the RGB sum one photon carries
    for i, o in enumerate(refined.objects):
        sl = slice(offsets[i], offsets[i + 1])
        irradiance[sl] = density.irradiance(
            o.positions, o.normals, o.tangents, o.faces, photons.moment0[sl], photons.moment1[sl], settings.kernel_rings,
            photon_power=photon_power, max_radius=settings.max_edge, min_photons=settings.min_photons,
        )
    return irradiance


def _closed_form_highlights(merged, sa, emitters, glossy, gathered, settings):
    """The emitters' direct highlights on the glossy objects, in closed form: added to
    ``gathered`` where a part is kept in the grid; returns (each object's visibility of the
    parts it draws, its own parts where it draws them, the shadow rays cast).
    emitters = (the parts drawn per pixel, every part in closed form)."""
    parts, closed = emitters
    visible, own_parts, shadow_rays = {}, {}, 0  # own_parts: where the scene has more than one object draws
    if closed and glossy:
        tracer = RayTracer(merged.positions, merged.faces, cutout=merged.cutout)
        for o, _, dirs in glossy:
            if len(parts) > highlights.MAX_RECEIVER_PARTS:
                grid, own_parts[o.name], visible[o.name] = highlights.object_parts(
                    tracer, closed, o, dirs, settings.visibility_samples, sa.epsilon, settings.emitter_nodes,
                    drawn=len(parts))
                gathered[o.name] += grid
                continue
            seen = highlights.visibility(
                tracer, closed, o.positions, o.normals, settings.visibility_samples, sa.epsilon, source=o.name
            )
            gathered[o.name] += highlights.grid_highlights(closed, o, dirs, seen, settings.emitter_nodes)
            visible[o.name] = np.ascontiguousarray(seen[:, :len(parts)])
        shadow_rays = tracer.rays_cast
        tracer.close()
    return visible, own_parts, shadow_rays


def _radiance_of_objects(refined, offsets, irradiance, gathered, glossy_dirs):
    """([(object, its directions, its radiance (V, D, 3))], {name: ``TexturedDiffuse``}):
    a diffuse object's kd / pi E plus its emission in one direction, a glossy one's
    gathered grid; a textured object's diffuse term kept apart (the displays draw it per
    pixel)."""
    results, textured = [], {}
    for i, o in enumerate(refined.objects):
        sl = slice(offsets[i], offsets[i + 1])
        kd = diffuse_reflectance(o.material)  # the kd the photons' estimate is for (a rough plastic's own)
        diffuse = kd / np.pi * irradiance[sl]
        if o.texture is not None:
            # the display multiplies kd * texture(uv) / pi * E per pixel: the radiance
            # keeps the rest (the gather added kd / pi * E to every direction)
            textured[o.name] = TexturedDiffuse(uvs=o.uvs, irradiance=irradiance[sl], texture=o.texture, kd=tuple(kd),
                                               opacity=o.opacity)
            diffuse = np.zeros_like(diffuse)
        if o.material.has_grid:
            dirs = glossy_dirs[o.name]
            radiance = gathered.pop(o.name)  # not held twice where the texture is taken out below
            if o.texture is not None:
                # what the gather added: kd / pi * E in every direction, times the diffuse
                # part's exitance (b(cos_o) with Fresnel, a rough plastic's t(cos_o))
                exitance = diffuse_exitances(o.material, np.asarray(dirs, np.float64)[:, 2])
                added = (kd / np.pi * irradiance[sl])[:, None, :] * exitance[None, :, None]
                radiance = np.maximum(radiance - added, 0.0)
        else:
            dirs = directions.DIFFUSE_DIRECTIONS
            radiance = (diffuse + np.asarray(o.material.emission))[:, None, :]
        results.append((o, dirs, radiance))
    for o, _, radiance in results:
        peak = float(np.max(radiance))
        if peak > FLOAT32_MAX:
            raise InputError(
                f"object {o.name!r}: radiance reaches {peak:.3g}, beyond the largest single-precision number "
                f"({FLOAT32_MAX:.3g}) the solution file can hold; lower the emission"
            )
    return results, textured


def _energy(photons, delta_lights_present):
    """Where the photons' power went (the stats' ``energy``): emitted, escaped, absorbed..."""
    tally = photons.tally
    return {
        "emitted": photons.emitted.tolist(),
        "escaped": tally[T_ESCAPED:T_ESCAPED + 3].tolist(),
        "absorbed": tally[T_ABSORBED:T_ABSORBED + 3].tolist(),
        "backface": tally[T_BACKFACE:T_BACKFACE + 3].tolist(),
        "terminated": tally[T_TERMINATED:T_TERMINATED + 3].tolist(),
        "incident": tally[T_INCIDENT:T_INCIDENT + 3].tolist(),
        "photon_hits": int(tally[T_HITS]),
        **({"unreached": photons.unreached.tolist()} if delta_lights_present else {}),  # of escaped: no photon carried it
    }


def _object_solutions(results, textured, visible, own_parts, n_parts):
    """The ``ObjectSolution`` of every object, as the file keeps them (float32, int32)."""
    return tuple(
        ObjectSolution(
            name=o.name,
            positions=o.positions.astype(np.float32),
            normals=o.normals.astype(np.float32),
            tangents=o.tangents.astype(np.float32),
            faces=o.faces.astype(np.int32),
            directions=np.asarray(dirs, dtype=np.float32),
            radiance=np.asarray(radiance, dtype=np.float32),
            material=o.material.to_dict(),
            visibility=visible.get(o.name, np.ones((o.n_vertices, n_parts), np.float32))
            if o.material.has_grid and n_parts else None,
            emitter_parts=own_parts.get(o.name) if o.material.has_grid else None,
            textured=textured.get(o.name),
        )
        for o, dirs, radiance in results
    )


def _gather_glossy(runner, sa, seed, irradiance, glossy, settings, bar):
    """Radiance {name: (V, D, 3) float32} of the glossy objects ``glossy`` [(object,
    offset of its vertices in the merged scene, its grid directions)], and what the
    extra passes did: {name: {"regathered", "extra_passes", "max_passes", "tolerance"}}.

    Pass 0 gathers every vertex. Then ``regather.plan_passes`` gives each vertex its
    number of passes from its neighbours' noise, within each object's budget
    (``extra_gather`` x its vertices: shared across objects, the sharp lobes of a metal,
    noisy everywhere but masked by their own detail, took it from the satin's flat
    faces, where noise shows), and pass
    k (seed ``regather.pass_seed(seed, k)``) gathers the vertices with more than k. The
    result is the mean of each vertex's passes.

    The sums are kept in float32, the file's precision: a few passes' sum loses 1e-7 of
    its value, far below their noise, and a float64 sum of every glossy object (then
    its float32 copy) was most of a large scene's peak (a staircase of 572,000 vertices:
    6.4 GB of sums and 3.2 GB of copies, 12.5 GB in all)."""
    strata = math.isqrt(settings.gather_samples)

    # light samples per vertex: none where no emitter is left to sample (every one in closed form)
    n_light = settings.light_samples if sa.direct_area_pdf.any() else 0
    radiance = {o.name: np.zeros((o.n_vertices, len(dirs), 3), np.float32) for o, _, dirs in glossy}
    variance = {o.name: np.zeros(o.n_vertices) for o, _, _ in glossy}

    dirs64 = {o.name: np.asarray(dirs, dtype=np.float64) for o, _, dirs in glossy}

    def jobs_of_pass(k, obj, offset, local):
        """Pass k's gather blocks of ``obj``'s vertices ``local``, each with where its
        result goes (its object, its pass)."""
        vertices = local.astype(np.int64) + offset
        pass_seed = regather.pass_seed(seed, k)
        block = _gather_block_size(n_light, settings.gather_samples)
        return [
            (
                GatherBlock(
                    pass_seed, vertices[s:s + block], n_light, strata, MAX_GATHER_DEPTH, settings.lobe_light, k == 0,
                ),
                obj,
                offset,
                k,
            )
            for s in range(0, len(vertices), block)
        ]

    def run(jobs):
        """Gather ``jobs`` (from ``jobs_of_pass``) in one stream, all objects and
        passes, so the threads run out of work once at its end, not once per object
        and pass; results come back in job order, so each vertex's passes are summed
        in pass order."""
        where = deque(jobs)

        def combine(result):
            _, obj, offset, k = where.popleft()
            verts, (values, var) = result
            radiance[obj.name][verts - offset] += values
            if k == 0:
                variance[obj.name][verts - offset] = var

        runner.gather_blocks(
            irradiance, [(b, obj.material, dirs64[obj.name]) for b, obj, _, _ in jobs], combine, bar
        )

    run([job for obj, offset, _ in glossy for job in jobs_of_pass(0, obj, offset, np.arange(obj.n_vertices))])
    own = {o.name: np.ones(o.n_vertices, dtype=np.int64) for o, _, _ in glossy}
    tolerance = {o.name: settings.gather_tolerance for o, _, _ in glossy}
    if settings.extra_gather > 0:
        for obj, _, _ in glossy:
            noise = regather.relative_noise(radiance[obj.name], variance[obj.name])
            predicted = regather.neighbour_noise(obj.faces, obj.n_vertices, noise)
            own[obj.name], tolerance[obj.name] = regather.plan_passes(
                predicted, settings.gather_tolerance, settings.extra_gather
            )
        passes = np.concatenate(list(own.values())) if own else np.ones(0, dtype=np.int64)
        if bar is not None and getattr(bar, "total", None) is not None:  # the bar grows by the extra work
            bar.total += int((passes - 1).sum())
            getattr(bar, "refresh", lambda: None)()
        run(
            [
                job
                for k in range(1, int(passes.max(initial=1)))
                for obj, offset, _ in glossy
                for job in jobs_of_pass(k, obj, offset, np.flatnonzero(own[obj.name] > k))
            ]
        )
        for obj, _, _ in glossy:
            radiance[obj.name] /= own[obj.name][:, None, None]
    info = {
        obj.name: {
            "regathered": int((own[obj.name] > 1).sum()),
            "extra_passes": int((own[obj.name] - 1).sum()),
            "max_passes": int(own[obj.name].max(initial=1)),
            "tolerance": round(float(tolerance[obj.name]), 5),
        }
        for obj, _, _ in glossy
    }
    return radiance, info
