"""How fast is the solver, against Embree itself, and does its memory stay flat?

Usage:
    python benchmarks/bench_solver.py [--scene cornell-teapot] [--repeats 3] [--quick]
                                      [--parts rays,equivalence,memory,presets]
                                      [--ray-presets draft,high]

Measures, on one scene in one run, with the same thread count throughout:
  1. the limit: how fast this machine traces the solver's own rays through Embree
     on all cores, with nothing else done (jitted prange loops of single-ray
     queries, ``_common.SameRays``): every ray of a photon pass, recorded photon by
     photon in the order the photon loop traces them, and the gather's first rays
     (the light samples' shadow rays and the paths' first segments), on the mesh of
     each preset of ``--ray-presets``; and, for comparison with earlier runs, the
     synthetic limit (random rays off random triangles of the draft mesh:
     ``_common.Limit``), which traces faster or slower than the solver's rays;
  2. each preset's photon pass and gather: their rays per second (rays / phase time,
     all kernel work included), as ratios to (1), repeats interleaved with (1); and
     the tracing floor: the solve's rays at the limit's speed, the time no loop
     calling this Embree on these cores can beat; and the gather's split between
     tracing (its rays and their shading) and the splat into the direction grid
     (no rays), in thread-seconds, with the ratio of its tracing alone;
  3. peak memory (max RSS of a fresh process) at N and 10 N photons;
  4. solve time of the scene at each quality preset, numba compile time apart
     (a first solve in a fresh process with an empty cache, against a warm one).

Medians of ``--repeats`` runs. Results: JSON lines in benchmarks/results/solver.jsonl,
a plot in benchmarks/results/solver.png. Machine and thread count are recorded.
Equivalence check: the same seed gives the same radiance at 1 and N threads.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import RESULTS, Limit, Recorder, SameRays

PHOTON_TARGET, GATHER_TARGET = 0.8, 0.8  # rays/s as a fraction of the limit


def peak_memory_mb(scene_name, photons, threads):
    # a child inherits its parent's high-water RSS across fork and exec: reset it first
    code = (
        "open('/proc/self/clear_refs', 'w').write('5')\n"
        "from radiosity.scene.loaders import load_scene\n"
        "from radiosity.transport.solve import solve, SolveOptions\n"
        f"solve(load_scene({scene_name!r}), SolveOptions(photons={photons}, gather_samples=4, light_samples=1, threads={threads}))\n"
        "status = open('/proc/self/status').read().split('VmHWM:')[1]\n"
        "print(int(status.split()[0]) / 1024)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def timed_solve_in_fresh_process(scene_name, quality, threads, cache_dir, adaptive=False):
    """A solve's seconds in a fresh Python (numba's cache in ``cache_dir``): ``solve`` on
    the preset's uniform mesh, or with ``adaptive`` what ``vlights solve`` runs
    (``solve_adaptive``: estimate, refine, solve)."""
    call = (
        f"solve_adaptive(scene, SolveOptions(quality={quality!r}, threads={threads}))"
        if adaptive
        else f"solve(scene, SolveOptions(quality={quality!r}, threads={threads}))"
    )
    code = (
        "import time, json\n"
        "t0 = time.perf_counter()\n"
        "from radiosity.scene.loaders import load_scene\n"
        "from radiosity.transport.solve import solve, SolveOptions\n"
        "from radiosity.transport.adaptive import solve_adaptive\n"
        f"scene = load_scene({scene_name!r})\n"
        "t1 = time.perf_counter()\n"
        f"sol = {call}\n"
        "t2 = time.perf_counter()\n"
        "print(json.dumps({'import_load_s': t1 - t0, 'solve_s': t2 - t1, 'phases': sol.stats['time_s']}))\n"
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="cornell-teapot")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    parser.add_argument("--quick", action="store_true", help="fewer photons and presets, for a smoke run")
    parser.add_argument("--parts", default="rays,equivalence,memory,presets", help="which measurements, comma-separated")
    parser.add_argument("--ray-presets", default="draft,high", help="presets whose solve is measured against the limit")
    args = parser.parse_args(argv)
    parts = set(args.parts.split(","))
    from radiosity.policies.presets import QUALITIES

    unknown = [q for q in args.ray_presets.split(",") if q not in QUALITIES]
    if unknown:
        parser.error(f"--ray-presets: unknown preset {unknown[0]!r}; choose from {', '.join(QUALITIES)}")

    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    record = Recorder(threads=args.threads, scene=args.scene)
    rows = record.rows

    scene = load_scene(args.scene)
    photons = 500_000 if args.quick else 2_000_000
    opts = SolveOptions(quality="draft", photons=photons, threads=args.threads)
    solve(scene, SolveOptions(photons=1000, gather_samples=4, light_samples=1))  # compile, warm caches
    refined = scene.refined(opts.resolved(scene).max_edge)

    # 1 + 2: rays per second, solver against the limit, interleaved runs, medians
    if "rays" in parts:
        rays_per_second(record, scene, refined, photons, args)
    if "equivalence" in parts:
        equivalence(record, scene, args.threads)
    if "memory" in parts:
        memory(record, args)
    if "presets" in parts:
        solve_times(record, rows, args)
    record.save("solver.jsonl")
    if {"rays", "memory", "presets"} <= parts:
        plot(rows, RESULTS / "solver.png")
    return 0


def rays_per_second(record, scene, refined, photons, args):
    """Each preset's solve against the limit on its own rays (``_common.SameRays``,
    the preset's mesh), and the synthetic limit of earlier runs (``_common.Limit``:
    random rays off random triangles of the draft mesh), repeats interleaved."""
    from radiosity.transport.solve import SolveOptions, solve

    synthetic = Limit(refined, 2_000_000, args.threads)
    try:
        for quality in args.ray_presets.split(","):
            same = SameRays(scene, quality, 300_000 if args.quick else 1_000_000, args.threads)
            options = SolveOptions(quality=quality, threads=args.threads, **({"photons": photons} if args.quick else {}))
            rows = []
            try:
                for _ in range(args.repeats):
                    old = synthetic.rates()["limit"]
                    limit = same.rates()
                    with GatherSplit() as split:
                        stats = solve(scene, options).stats
                    stats["gather_split_thread_s"] = split.seconds
                    rows.append((old, limit, stats))
                    record({"question": "repeat", "quality": quality, "limit_rays_per_s": limit, "synthetic_limit_rays_per_s": old,
                            "photon_rays_per_s": stats["photon_rays_per_s"], "gather_rays_per_s": stats["gather_rays_per_s"],
                            "phases_s": stats["time_s"]})
            finally:
                same.close()
            record(_ray_summary(quality, rows, same, args))
    finally:
        synthetic.close()


class GatherSplit:
    """Thread-seconds of the gather's two kernels while in use: tracing
    (``gather.trace_gather``: the rays and the shading at their hits) and the splat
    (``gather.gather_outputs``: every sample into the direction grid, no rays), as
    ``batches.gather_block`` calls them."""

    def __enter__(self):
        import threading
        import time

        from radiosity.transport import batches as kernels

        self.seconds = {"trace": 0.0, "splat": 0.0}
        self._saved = {"trace": kernels.trace_gather, "splat": kernels.gather_outputs}
        lock = threading.Lock()

        def timed(name, fn):
            def call(*a):
                t = time.perf_counter()
                try:
                    return fn(*a)
                finally:
                    with lock:
                        self.seconds[name] += time.perf_counter() - t

            return call

        kernels.trace_gather = timed("trace", kernels.trace_gather)
        kernels.gather_outputs = timed("splat", kernels.gather_outputs)
        return self

    def __exit__(self, *exc):
        from radiosity.transport import batches as kernels

        kernels.trace_gather, kernels.gather_outputs = self._saved["trace"], self._saved["splat"]


def _ray_summary(quality, rows, same, args):
    def median(f):
        return float(np.median([f(old, limit, stats) for old, limit, stats in rows]))

    photon_limit = median(lambda o, limit, s: limit["photon"])
    gather_limit = median(lambda o, limit, s: limit["gather"])
    photon_rays = median(lambda o, limit, s: s["photon_rays"])
    gather_rays = median(lambda o, limit, s: s["gather_rays"])
    # tracing alone: the solve's rays at the limit's speed, nothing else done
    floor_s = photon_rays / photon_limit + gather_rays / gather_limit
    return {
        "question": "rays per second",
        "quality": quality,
        "triangles": same.triangles,
        "recorded_rays": same.counts,
        "limit_rays_per_s": {"photon": photon_limit, "gather": gather_limit},
        "synthetic_limit_rays_per_s": median(lambda o, limit, s: o),
        "photon_rays_per_s": median(lambda o, limit, s: s["photon_rays_per_s"]),
        "gather_rays_per_s": median(lambda o, limit, s: s["gather_rays_per_s"]),
        "photon_ratio": median(lambda o, limit, s: s["photon_rays_per_s"] / limit["photon"]),
        "gather_ratio": median(lambda o, limit, s: s["gather_rays_per_s"] / limit["gather"]),
        # the gather's tracing alone: its rays over its trace kernel's thread-seconds per thread
        "gather_trace_ratio": median(
            lambda o, limit, s: s["gather_rays"] / (s["gather_split_thread_s"]["trace"] / args.threads) / limit["gather"]
        ),
        "gather_split_thread_s": {
            k: median(lambda o, limit, s, k=k: s["gather_split_thread_s"][k]) for k in ("trace", "splat")
        },
        "photon_ratio_synthetic": median(lambda o, limit, s: s["photon_rays_per_s"] / o),
        "gather_ratio_synthetic": median(lambda o, limit, s: s["gather_rays_per_s"] / o),
        "photon_rays": photon_rays,
        "gather_rays": gather_rays,
        "solve_s": median(lambda o, limit, s: sum(s["time_s"].values())),
        "tracing_floor_s": floor_s,
        "floor_at_target_ratio_s": floor_s / PHOTON_TARGET,
        "target_ratio": {"photons": PHOTON_TARGET, "gather": GATHER_TARGET},
        "target_s": {"draft": 1.5, "high": 15.0}.get(quality),
        "repeats": args.repeats,
    }


def equivalence(record, scene, threads):
    """Thread count does not change the answer."""
    from radiosity.transport.solve import SolveOptions, solve

    small = SolveOptions(photons=100_000, gather_samples=16, light_samples=4, seed=5)
    a = solve(scene, SolveOptions(**{**small.__dict__, "threads": 1}))
    b = solve(scene, SolveOptions(**{**small.__dict__, "threads": threads}))
    same = all(np.array_equal(x.radiance, y.radiance) for x, y in zip(a.objects, b.objects))
    record({"question": "same answer at 1 and N threads", "identical": bool(same)})


def memory(record, args):
    """Peak memory at N and 10 N photons."""
    n_small = 200_000 if args.quick else 1_000_000
    mem = [peak_memory_mb(args.scene, n, args.threads) for n in (n_small, 10 * n_small)]
    record(
        {
            "question": "peak memory",
            "photons": [n_small, 10 * n_small],
            "peak_rss_mb": mem,
            "growth": mem[1] / mem[0] - 1,
            "target_growth": 0.10,
        }
    )


def solve_times(record, rows, args):
    """Solve time per preset, compile apart."""
    presets = ["draft"] if args.quick else ["draft", "medium", "high"]
    cache = Path(tempfile.mkdtemp(prefix="vlights-numba-"))
    try:
        cold = timed_solve_in_fresh_process(args.scene, "draft", args.threads, cache)
        for quality in presets:
            warm = [timed_solve_in_fresh_process(args.scene, quality, args.threads, cache) for _ in range(args.repeats)]
            solve_s = float(np.median([w["solve_s"] for w in warm]))
            record(
                {
                    "question": "solve time per preset",
                    "quality": quality,
                    "solve_s_warm_median": solve_s,
                    "phases_s": warm[0]["phases"],
                    "target_s": {"draft": 1.5, "high": 15.0}.get(quality),
                }
            )
        # what ``vlights solve`` runs at draft: refinement included (the target: 10 s)
        refined = [timed_solve_in_fresh_process(args.scene, "draft", args.threads, cache, adaptive=True)
                   for _ in range(args.repeats)]
        record(
            {
                "question": "solve time, refined mesh",
                "quality": "draft",
                "solve_s_warm_median": float(np.median([w["solve_s"] for w in refined])),
                "solve_s_all": [w["solve_s"] for w in refined],
                "phases_s": refined[0]["phases"],
                "target_s": 10.0,
            }
        )
        warm_draft = next(
            r for r in rows if r.get("quality") == "draft" and r["question"] == "solve time per preset"
        )["solve_s_warm_median"]
        record(
            {
                "question": "numba compile time",
                "cold_first_solve_s": cold["solve_s"],
                "warm_solve_s": warm_draft,
                "compile_s": cold["solve_s"] - warm_draft,
            }
        )
    finally:
        shutil.rmtree(cache, ignore_errors=True)


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(17, 4))
    rays = [r for r in rows if r["question"] == "rays per second"]
    x = np.arange(len(rays))
    axes[0].bar(x - 0.27, [r["photon_ratio"] for r in rays], 0.27, color="tab:orange", label="photon pass")
    axes[0].bar(x, [r["gather_ratio"] for r in rays], 0.27, color="tab:blue", label="gather")
    axes[0].bar(x + 0.27, [r["gather_trace_ratio"] for r in rays], 0.27, color="tab:blue", alpha=0.45, hatch="//",
                label="gather: its tracing alone (no splat)")
    axes[0].axhline(PHOTON_TARGET, ls="--", c="k", lw=1, label=f"target: {PHOTON_TARGET} x limit")
    axes[0].set_xticks(x, [r["quality"] for r in rays])
    axes[0].set_ylim(0, 1)
    axes[0].set_ylabel("rays/s / limit on the same rays")
    axes[0].set_title(f"rays against Embree alone, {rays[0]['threads']} threads")
    axes[0].legend(fontsize=8)
    axes[1].bar(x - 0.27, [r["solve_s"] for r in rays], 0.27, color="tab:purple", label="solve (uniform mesh)")
    axes[1].bar(x, [r["tracing_floor_s"] for r in rays], 0.27, color="grey", label="its rays at the limit")
    axes[1].bar(x + 0.27, [r["target_s"] or 0 for r in rays], 0.27, color="white", edgecolor="k", label="target")
    axes[1].set_xticks(x, [r["quality"] for r in rays])
    axes[1].set_yscale("log")
    axes[1].set_ylabel("seconds")
    axes[1].set_title("solve time against the tracing floor")
    axes[1].legend(fontsize=8)
    m = next(r for r in rows if r["question"] == "peak memory")
    axes[2].bar([f"{n:,}" for n in m["photons"]], m["peak_rss_mb"], color="tab:green")
    axes[2].set_xlabel("photons")
    axes[2].set_ylabel("peak RSS (MB)")
    axes[2].set_title(f"memory: {100 * m['growth']:+.1f} % for 10x photons")
    presets = [r for r in rows if r["question"] == "solve time per preset"]
    axes[3].bar([p["quality"] for p in presets], [p["solve_s_warm_median"] for p in presets], color="tab:purple")
    axes[3].set_ylabel("solve time (s), warm cache")
    axes[3].set_title(f"{rays[0]['scene']} per preset")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
