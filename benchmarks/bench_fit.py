"""What does each fitting method buy, at what cost, against simpler per-vertex models?

Usage:
    python benchmarks/bench_fit.py [--quality draft] [--lights 1 2 4 8 16] [--repeats 3] [--quick]

On the demo scene's solution (cornell-teapot, fixed seed), for its glossy objects:
  1. fit time and relative RMS error for K lights with the paper's method, refined,
     and refined with per-light exponents;
  2. the paper's method's time against V x D x K on synthetic data of several sizes
     (should grow linearly: the log-log slope is reported);
  3. error against floats stored per vertex: virtual lights (6 per vertex: emitted and
     specular; the lights themselves are per object), diffuse only (3), the dominant
     direction (8), spherical harmonics L1 (12) and L2 (27);
  4. the targets: teapot, K = 8, paper's method under 5 s; refinement lowering the
     paper's error by 30 % on each glossy object.

Results: JSON lines in benchmarks/results/fit.jsonl, plots in benchmarks/results/fit.png.
Equivalence check: the refined error never exceeds the paper's on the same data.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from _common import RESULTS, Recorder


def median_time(fn, repeats):
    times, result = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), result


def synthetic_data(rng, n_vertices, grid):
    from fitting.data import FitData
    from radiosity.formats import directions

    normals = rng.normal(size=(n_vertices, 3))
    normals[:, 2] = np.abs(normals[:, 2]) + 0.3
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    local = directions.grid_directions(grid)
    t = np.cross(normals, [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(normals, t)
    views = local[None, :, :1] * t[:, None] + local[None, :, 1:2] * b[:, None] + local[None, :, 2:] * normals[:, None]
    radiance = rng.uniform(0, 1, (n_vertices, len(local), 3)) + 5 * np.maximum(views[..., 2:3], 0) ** 20
    weights = np.full((n_vertices, len(local)), 1.0 / (n_vertices * len(local)))
    return FitData(radiance=radiance, views=views, normals=normals, weights=weights)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quality", default="draft")
    parser.add_argument("--lights", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--plot-only", action="store_true", help="redraw the plot from results/fit.jsonl")
    args = parser.parse_args(argv)
    if args.plot_only:
        rows = [json.loads(line) for line in open(RESULTS / "fit.jsonl")]
        names = list(dict.fromkeys(r["object"] for r in rows if r["question"] == "fit time and error"))
        plot(rows, names, RESULTS / "fit.png")
        return 0
    if args.quick:
        args.lights, args.repeats = [1, 4], 1

    from fitting.baselines import all_baselines
    from fitting.data import fit_data, relative_error
    from fitting.fit import FitOptions, fit_lights, reconstruct
    from fitting.paper import fit_paper
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    record = Recorder()
    rows = record.rows

    solution = solve(load_scene("cornell-teapot"), SolveOptions(quality=args.quality, seed=1))
    glossy = [o for o in solution.objects if not o.is_diffuse]
    fit_paper(fit_data(glossy[0]), 1)  # compile

    # 1 + 4: time and error per K and method
    for obj in glossy:
        data = fit_data(obj)
        previous = {"refined": None, "per-light": None}
        for k in args.lights:
            for method in ("paper", "refined", "per-light"):
                options = FitOptions(lights=k, method=method)
                repeats = args.repeats if method == "paper" else 1
                seconds, result = median_time(
                    lambda: fit_lights(data, k, options, previous=previous.get(method)), repeats
                )
                if method in previous:
                    previous[method] = result
                error = relative_error(data, reconstruct(data, result))
                record({
                    "question": "fit time and error", "object": obj.name, "V": data.n_vertices,
                    "D": data.n_directions, "K": k, "method": method, "seconds": seconds,
                    "relative_rms": error["relative_rms"], "worst_vertex": error["worst_vertex"],
                    "shininess": [float(p) for p in result.shininess],
                })

    by = {(r["object"], r["K"], r["method"]): r for r in rows if r["question"] == "fit time and error"}
    for obj in glossy:
        k = 8 if 8 in args.lights else max(args.lights)
        paper_err = by[(obj.name, k, "paper")]["relative_rms"]
        refined_err = by[(obj.name, k, "refined")]["relative_rms"]
        record({
            "question": "targets", "object": obj.name, "K": k,
            "paper_seconds": by[(obj.name, k, "paper")]["seconds"], "paper_target_s": 5.0,
            "paper_error": paper_err, "refined_error": refined_err,
            "refined_reduction": 1 - refined_err / paper_err, "reduction_target": 0.30,
            "refined_never_worse": refined_err <= paper_err * (1 + 1e-9),
        })

    # 2: linear in V x D x K
    rng = np.random.default_rng(0)
    sizes = []
    for n_v, grid, k in [(500, 8, 2), (1000, 8, 4), (2000, 16, 2), (1000, 16, 8), (4000, 16, 4), (2000, 32, 4)]:
        data = synthetic_data(rng, n_v, grid)
        seconds, _ = median_time(lambda: fit_paper(data, k), max(1, args.repeats - 1))
        sizes.append((n_v * grid * grid * k, seconds))
        record({"question": "time vs V x D x K", "V": n_v, "D": grid * grid, "K": k, "seconds": seconds})
    work, seconds = np.array(sizes).T
    slope = float(np.polyfit(np.log(work), np.log(seconds), 1)[0])
    record({"question": "time vs V x D x K slope", "log_log_slope": slope, "linear_is": 1.0})

    # 3: error against storage
    for obj in glossy:
        data = fit_data(obj)
        for approximation in all_baselines(obj, data):
            record({
                "question": "error vs floats per vertex", "object": obj.name, "model": approximation.name,
                "floats_per_vertex": approximation.floats_per_vertex,
                "relative_rms": relative_error(data, approximation.reconstruction)["relative_rms"],
            })
        for k in args.lights:
            r = by[(obj.name, k, "refined")]
            record({
                "question": "error vs floats per vertex", "object": obj.name, "model": f"virtual lights K={k}",
                "floats_per_vertex": 6 + 7 * k / data.n_vertices, "relative_rms": r["relative_rms"],
            })

    record.save("fit.jsonl")
    plot(rows, [o.name for o in glossy], RESULTS / "fit.png")
    return 0


def plot(rows, names, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(names), 3, figsize=(15, 4.2 * len(names)), squeeze=False)
    for i, name in enumerate(names):
        fits = [r for r in rows if r["question"] == "fit time and error" and r["object"] == name]
        for method, style in (("paper", "o-"), ("refined", "s-"), ("per-light", "^--")):
            sel = [r for r in fits if r["method"] == method]
            axes[i, 0].plot([r["K"] for r in sel], [r["relative_rms"] for r in sel], style, label=method)
            axes[i, 1].plot([r["K"] for r in sel], [r["seconds"] for r in sel], style, label=method)
        for ax, label in ((axes[i, 0], "relative RMS error"), (axes[i, 1], "fit time (s)")):
            ax.set_xscale("log", base=2)
            ax.set_xlabel("virtual lights K")
            ax.set_ylabel(label)
            ax.set_title(f"{name}: {label} against K")
            ax.legend()
        axes[i, 1].set_yscale("log")
        storage = [r for r in rows if r["question"] == "error vs floats per vertex" and r["object"] == name]
        lights = [r for r in storage if r["model"].startswith("virtual")]
        for r in storage:
            if r in lights:
                continue
            axes[i, 2].scatter(r["floats_per_vertex"], r["relative_rms"], marker="o")
            axes[i, 2].annotate(r["model"], (r["floats_per_vertex"], r["relative_rms"]), fontsize=8,
                                xytext=(4, 2), textcoords="offset points")
        if lights:  # K barely changes the storage per vertex: one marker group, one label
            axes[i, 2].scatter([r["floats_per_vertex"] for r in lights], [r["relative_rms"] for r in lights], marker="s", c="k")
            ks = [r["model"].split("=")[1] for r in lights]
            best = min(r["relative_rms"] for r in lights)
            axes[i, 2].annotate(f"virtual lights K={ks[0]}..{ks[-1]}", (lights[0]["floats_per_vertex"], best),
                                fontsize=8, xytext=(4, -10), textcoords="offset points")
        axes[i, 2].set_xlabel("floats stored per vertex")
        axes[i, 2].set_ylabel("relative RMS error")
        axes[i, 2].set_title(f"{name}: error against storage")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    sys.exit(main())
