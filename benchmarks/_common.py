"""What every benchmark script records: the machine, and its rows as JSON lines."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from radiosity.transport.embree import intersect1, new_rayhit, occluded1

RESULTS = Path(__file__).resolve().parent / "results"


def machine():
    return {"cores": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version()}


def git_commit():
    """The checkout's short commit, with "+" where its tracked files differ from it
    (None outside a git checkout): which code a row of results measured."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=here, capture_output=True, text=True)
        dirty = subprocess.run(["git", "diff", "--quiet", "HEAD"], cwd=here).returncode != 0
    except OSError:
        return None
    return head.stdout.strip() + ("+" if dirty else "") if head.returncode == 0 else None


def _children(pid):
    out = []
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out += [int(c) for c in f.read().split()]
    except OSError:
        pass
    return out


def _pss(pid):
    """Proportional set size of ``pid`` in bytes (shared pages divided among their users)."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def tree_memory(pid):
    """The summed Pss of ``pid`` and all its descendants (a fit's worker processes)."""
    tree, todo = [], [pid]
    while todo:
        p = todo.pop()
        tree.append(p)
        todo += _children(p)
    return sum(_pss(p) for p in tree)


@dataclass(frozen=True)
class Run:
    """One ``vlights`` command run by ``run_vlights``: seconds; peak_mb, the process's
    peak resident memory as the kernel counts it; tree_mb, its process tree's summed
    Pss sampled every 0.1 s (with worker processes the kernel's figure is the largest
    one's); exit_code; stderr, all it printed there."""

    seconds: float
    peak_mb: float
    tree_mb: float
    exit_code: int
    stderr: str

    @property
    def last_line(self):
        lines = self.stderr.strip().splitlines()
        return lines[-1] if lines else ""


def run_vlights(args, cwd, timeout=None):
    """Run ``vlights ARGS`` (this checkout's) in ``cwd``, in a process of its own, and
    measure it (``Run``); ``timeout`` seconds, then it is killed (exit code -9)."""
    env = os.environ | {"PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-m", "display", *map(str, args)], cwd=cwd, env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak = [0]
    done = threading.Event()

    def sample():
        while not done.wait(0.1):
            peak[0] = max(peak[0], tree_memory(process.pid))
            if timeout is not None and time.perf_counter() - start > timeout:
                process.kill()

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    stderr = process.stderr.read().decode(errors="replace")  # read while it runs: a full pipe would block it
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    done.set()
    sampler.join()
    process.stderr.close()
    return Run(seconds, usage.ru_maxrss / 1024.0, peak[0] / 2**20, os.waitstatus_to_exitcode(status), stderr)


def vlights_or_exit(args, cwd):
    """``run_vlights``, ending the benchmark (SystemExit naming the command and its last
    line) where the command fails; returns its seconds."""
    run = run_vlights(args, cwd)
    if run.exit_code != 0:
        raise SystemExit(f"vlights {' '.join(map(str, args))} failed: {run.last_line}")
    return run.seconds


class Recorder:
    """Rows of one benchmark run: each printed as it comes, all saved at the end."""

    def __init__(self, **context):
        self.context = machine() | context
        self.rows = []

    def __call__(self, row):
        row = self.context | row
        self.rows.append(row)
        print(json.dumps(row), flush=True)
        return row

    def save(self, name):
        RESULTS.mkdir(exist_ok=True)
        with open(RESULTS / name, "w") as f:
            for row in self.rows:
                f.write(json.dumps(row) + "\n")


def incoherent_rays(merged, n_rays, epsilon, seed=0):
    """(origins, directions) float32 (n, 3) of rays like photons and bounces: origins
    uniform on random triangles of ``merged`` (a ``MergedMesh``), offset ``epsilon``
    off their front, directions uniform over the front hemisphere."""
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, len(merged.faces), n_rays)
    bary = rng.random((n_rays, 2))
    flip = bary.sum(axis=1) > 1
    bary[flip] = 1 - bary[flip]
    p = merged.positions.astype(np.float64)[merged.faces[tri]]
    points = p[:, 0] + bary[:, :1] * (p[:, 1] - p[:, 0]) + bary[:, 1:] * (p[:, 2] - p[:, 0])
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where((np.einsum("ij,ij->i", d, normal) < 0)[:, None], -d, d)
    return (points + epsilon * normal).astype(np.float32), d.astype(np.float32)


class Limit:
    """The fastest this machine traces incoherent rays through Embree: jitted loops of
    single-ray queries (``embree.intersect1``) over the same rays, either a thread per
    core each running one nogil loop over its chunk (``RayTracer.intersect``) or a numba
    ``prange`` loop; ``rates()`` times both, the limit is the faster.

    scene : a ``Scene`` (its merged mesh is traced); n_rays incoherent rays (origins on
    the surfaces, directions over the front hemisphere: ``incoherent_rays``).
    """

    def __init__(self, scene, n_rays, threads):
        from radiosity.transport.embree import RayTracer

        merged = scene.merged()
        self.threads = threads
        self.tracer = RayTracer(merged.positions, merged.faces, threads=threads, cutout=merged.cutout)
        self.origins, self.directions = incoherent_rays(merged, n_rays, self.tracer.epsilon)
        self.n = n_rays
        self.triangle = np.empty(n_rays, np.int32)
        self.rates()  # compile, warm caches

    def rates(self):
        """{"threads": rays/s, "prange": rays/s, "limit": the larger} of one pass each."""
        t = time.perf_counter()
        hits = self.tracer.intersect(self.origins, self.directions)
        threads = self.n / (time.perf_counter() - t)
        previous = numba.get_num_threads()
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        try:
            t = time.perf_counter()
            _trace_prange(self.tracer.embree, self.origins, self.directions, self.threads * 16, self.triangle)
            prange = self.n / (time.perf_counter() - t)
        finally:
            numba.set_num_threads(previous)
        assert np.array_equal(hits.triangle, self.triangle)  # the same rays, the same answers
        return {"threads": threads, "prange": prange, "limit": max(threads, prange)}

    def close(self):
        self.tracer.close()


@numba.njit(cache=True, parallel=True)
def _trace_prange(rt, origins, directions, chunks, triangle):
    n = origins.shape[0]
    for c in numba.prange(chunks):
        rayhit = new_rayhit()
        for k in range(c * n // chunks, (c + 1) * n // chunks):
            o, d = origins[k], directions[k]
            triangle[k] = intersect1(rt, rayhit, (o[0], o[1], o[2]), (d[0], d[1], d[2]))[0]


@numba.njit(cache=True, parallel=True)
def _occlude_prange(rt, origins, directions, distances, chunks, blocked):
    n = origins.shape[0]
    for c in numba.prange(chunks):
        rayhit = new_rayhit()
        for k in range(c * n // chunks, (c + 1) * n // chunks):
            o, d = origins[k], directions[k]
            blocked[k] = occluded1(rt, rayhit, (o[0], o[1], o[2]), (d[0], d[1], d[2]), distances[k])


def _oracle():
    """The tests' wavefront oracle module (tests/oracles/wavefront.py), imported from the tree."""
    import sys
    from pathlib import Path

    tests = str(Path(__file__).resolve().parent.parent / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    from oracles import wavefront

    return wavefront


def photon_rays(tracer, sa, photons, seed=1):
    """(origins, directions) float32 (R, 3): every ray a photon pass of ``photons``
    photons traces in the scene of ``tracer`` (a ``RayTracer``) and ``sa`` (its
    ``records.SceneArrays``), photon by photon, each from its emission to its end.
    Recorded with the tests' readable wavefront oracle (tests/oracles/wavefront.py:
    ``emit_photons``, ``bounce_photons``), which tests hold to the solver's rays bit
    for bit."""
    from radiosity.transport import records
    from radiosity.transport.solve import MAX_PHOTON_DEPTH

    wavefront = _oracle()
    batch = records.PhotonBatch(seed, 0, photons, photons, MAX_PHOTON_DEPTH)
    flying = records.empty_rays(photons)
    wavefront.emit_photons(sa, seed, 0, photons, flying)
    out, acc = records.empty_rays(photons), records.empty_tally(len(sa.positions))
    ids, origins, directions = [], [], []
    for depth in range(MAX_PHOTON_DEPTH):
        if not len(flying.ids):
            break
        ids.append(flying.ids.copy())
        origins.append(flying.origins.copy())
        directions.append(flying.directions.copy())
        hits = tracer.intersect(flying.origins, flying.directions)
        n = wavefront.bounce_photons(sa, batch, depth, flying, hits, acc, out)
        flying = records.Rays(*(a[:n].copy() for a in out))
    order = np.argsort(np.concatenate(ids), kind="stable")  # depth-major -> photon by photon
    return np.concatenate(origins)[order], np.concatenate(directions)[order]


def gather_rays(scene, merged, sa, quality, vertices_per_object=256, seed=1):
    """The first rays of the gather at ``quality`` from up to ``vertices_per_object``
    random vertices of each glossy object of ``scene`` (already refined; ``merged`` its
    merged mesh, ``sa`` its ``records.SceneArrays``): the light
    samples' shadow rays (origins, directions, distances: those that can contribute)
    and the gather paths' first segments (origins, directions), as
    ``gather.make_gather_rays`` makes them. Later segments and the light samples at
    glossy hits are not recorded: they leave the same surfaces for the same lights."""
    from radiosity.transport import gather, records
    from radiosity.transport.solve import MAX_GATHER_DEPTH, SolveOptions

    settings = SolveOptions(quality=quality).resolved(scene)
    rng = np.random.default_rng(seed)
    offsets = merged.vertex_offset
    vertices = np.concatenate(
        [
            offsets[i] + np.sort(rng.choice(o.n_vertices, min(vertices_per_object, o.n_vertices), replace=False))
            for i, o in enumerate(scene.objects)
            if o.material.is_glossy
        ]
    ).astype(np.int64)
    strata = int(np.sqrt(settings.gather_samples))
    n_light = settings.light_samples
    block = records.GatherBlock(seed, vertices, n_light, strata, MAX_GATHER_DEPTH)
    light = records.empty_light_samples(len(vertices) * n_light)
    samples = records.empty_gather_samples(len(vertices) * strata * strata)
    gather.make_gather_rays(sa, block, light, samples)
    used = light.pdf > 0
    shadow = (light.origins[used].copy(), light.directions[used].copy(), light.distances[used].copy())
    return shadow, (samples.origins.copy(), samples.directions.copy())


class SameRays:
    """The limit on the solver's own rays: bare Embree (jitted ``prange`` loops of
    single-ray queries on all cores) tracing exactly the rays a photon pass traces
    (``photon_rays``) and the gather's first rays (``gather_rays``), in ``scene`` at
    ``quality`` (its uniformly refined mesh, the one ``solve`` traces)."""

    def __init__(self, scene, quality, photons, threads):
        from radiosity.transport.embree import RayTracer
        from radiosity.transport.solve import SolveOptions, scene_arrays

        refined = scene.refined(SolveOptions(quality=quality).resolved(scene).max_edge)
        merged = refined.merged()
        self.threads = threads
        self.triangles = len(merged.faces)
        self.tracer = RayTracer(merged.positions, merged.faces, threads=threads, cutout=merged.cutout)
        sa = scene_arrays(refined, merged, self.tracer.epsilon)
        self.photon = photon_rays(self.tracer, sa, photons)
        self.shadow, self.first = gather_rays(refined, merged, sa, quality)
        self.photon_hits = np.empty(len(self.photon[0]), np.int32)
        self.first_hits = np.empty(len(self.first[0]), np.int32)
        self.blocked = np.empty(len(self.shadow[0]), bool)
        self.rates()  # compile, warm caches

    @property
    def counts(self):
        return {"photon": len(self.photon[0]), "gather_shadow": len(self.shadow[0]), "gather_first": len(self.first[0])}

    def rates(self):
        """{"photon", "gather": rays/s} of one pass each over the recorded rays (the
        gather's: shadow and first rays together, their count over their time)."""
        previous = numba.get_num_threads()
        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        chunks, rt = self.threads * 16, self.tracer.embree
        try:
            t = time.perf_counter()
            _trace_prange(rt, *self.photon, chunks, self.photon_hits)
            photon = len(self.photon_hits) / (time.perf_counter() - t)
            t = time.perf_counter()
            _occlude_prange(rt, *self.shadow, chunks, self.blocked)
            _trace_prange(rt, *self.first, chunks, self.first_hits)
            gather = (len(self.blocked) + len(self.first_hits)) / (time.perf_counter() - t)
        finally:
            numba.set_num_threads(previous)
        return {"photon": photon, "gather": gather}

    def close(self):
        self.tracer.close()


# -- Mitsuba 3, in a venv of its own ------------------------------------------------------

MITSUBA_RENDER = """
import sys, time, numpy as np, mitsuba as mi
mi.set_variant(sys.argv[1])
scene = mi.load_file(sys.argv[2])
start = time.perf_counter()
image = np.array(mi.render(scene, spp=int(sys.argv[3]), seed=int(sys.argv[4])), dtype=np.float32)[..., :3]
np.save(sys.argv[5], image)
print(time.perf_counter() - start)
"""


def mitsuba_python(given):
    candidates = [given, os.environ.get("VLIGHTS_MITSUBA_PYTHON"), "/work/mitsuba-venv/bin/python"]
    for python in filter(None, candidates):
        if Path(python).exists():
            probe = subprocess.run([python, "-c", "import mitsuba; print(mitsuba.__version__)"],
                                   capture_output=True, text=True)
            if probe.returncode == 0:
                return python, probe.stdout.strip()
    return None, None


def mitsuba_render(python, variant, scene, spp, seed, out):
    run = subprocess.run([python, "-c", MITSUBA_RENDER, variant, str(scene), str(spp), str(seed), str(out)],
                         capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"mitsuba failed on {scene}: {run.stderr.strip().splitlines()[-1:]}")
    return float(run.stdout.strip().splitlines()[-1]), np.load(out)
