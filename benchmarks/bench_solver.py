"""How fast is the solver, against Embree itself, and does its memory stay flat?

Usage:
    python benchmarks/bench_solver.py [--scene cornell-teapot] [--repeats 3] [--quick]
                                      [--parts rays,equivalence,memory,presets]

Measures, on one scene in one run, with the same thread count throughout:
  1. the limit: the fastest this machine traces incoherent rays (origins on the
     surfaces, directions over the hemisphere, like photons and gather rays) through
     Embree on all cores: jitted loops of single-ray queries, a nogil loop per thread
     or a numba prange loop, whichever is faster (``_common.Limit``);
  2. the solver's photon pass and gather: their rays per second (rays / phase time,
     all kernel work included), as ratios to (1), repeats interleaved with (1);
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
from _common import RESULTS, Limit, Recorder

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
    args = parser.parse_args(argv)
    parts = set(args.parts.split(","))

    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    record = Recorder(threads=args.threads, scene=args.scene)
    rows = record.rows

    scene = load_scene(args.scene)
    photons = 500_000 if args.quick else 2_000_000
    opts = SolveOptions(quality="draft", photons=photons, threads=args.threads)
    solve(scene, SolveOptions(photons=1000, gather_samples=4, light_samples=1))  # compile, warm caches
    refined = scene.refined(opts.resolved(scene)["max_edge"])

    # 1 + 2: rays per second, solver against the limit, interleaved runs, medians
    if "rays" in parts:
        rays_per_second(record, scene, refined, opts, photons, args)
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


def rays_per_second(record, scene, refined, opts, photons, args):
    from radiosity.transport.solve import solve

    limit = Limit(refined, 2_000_000, args.threads)
    by_threads, by_prange, limits, photon_rate, gather_rate = [], [], [], [], []
    try:
        for _ in range(args.repeats):
            rates = limit.rates()
            by_threads.append(rates["threads"])
            by_prange.append(rates["prange"])
            limits.append(rates["limit"])
            stats = solve(scene, opts).stats
            photon_rate.append(stats["photon_rays_per_s"])
            gather_rate.append(stats["gather_rays_per_s"])
            record({"question": "repeat", "limit_rays_per_s": rates["limit"], "photon_rays_per_s": photon_rate[-1],
                    "gather_rays_per_s": gather_rate[-1], "phases_s": stats["time_s"]})
    finally:
        limit.close()
    limit_rate = float(np.median(limits))
    record(
        {
            "question": "rays per second",
            "limit_rays_per_s": limit_rate,
            "limit_threads_rays_per_s": float(np.median(by_threads)),
            "limit_prange_rays_per_s": float(np.median(by_prange)),
            "photon_rays_per_s": float(np.median(photon_rate)),
            "gather_rays_per_s": float(np.median(gather_rate)),
            "photon_ratio": float(np.median(photon_rate)) / limit_rate,
            "gather_ratio": float(np.median(gather_rate)) / limit_rate,
            "photon_ratio_median_of_repeats": float(np.median(np.divide(photon_rate, limits))),
            "gather_ratio_median_of_repeats": float(np.median(np.divide(gather_rate, limits))),
            "target_ratio": {"photons": PHOTON_TARGET, "gather": GATHER_TARGET},
            "photons": photons,
            "repeats": args.repeats,
        }
    )


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
        # what ``vlights solve`` runs at draft: refinement included (issue 13's target: 10 s)
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

    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    r = next(r for r in rows if r["question"] == "rays per second")
    names = ["limit", "photon pass", "gather"]
    values = [r["limit_rays_per_s"], r["photon_rays_per_s"], r["gather_rays_per_s"]]
    axes[0].bar(names, np.array(values) / 1e6, color=["grey", "tab:orange", "tab:blue"])
    axes[0].axhline(PHOTON_TARGET * values[0] / 1e6, ls="--", c="k", lw=1, label=f"target: {PHOTON_TARGET} x limit")
    axes[0].set_ylabel("M rays / s")
    axes[0].set_title(f"rays per second, {r['threads']} threads")
    axes[0].legend()
    m = next(r for r in rows if r["question"] == "peak memory")
    axes[1].bar([f"{n:,}" for n in m["photons"]], m["peak_rss_mb"], color="tab:green")
    axes[1].set_xlabel("photons")
    axes[1].set_ylabel("peak RSS (MB)")
    axes[1].set_title(f"memory: {100 * m['growth']:+.1f} % for 10x photons")
    presets = [r for r in rows if r["question"] == "solve time per preset"]
    axes[2].bar([p["quality"] for p in presets], [p["solve_s_warm_median"] for p in presets], color="tab:purple")
    axes[2].set_ylabel("solve time (s), warm cache")
    axes[2].set_title(f"{r['scene']} per preset")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
