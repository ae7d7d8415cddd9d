"""What does each virtual-light model buy, per float stored, against simpler per-vertex models?

Usage:
    python benchmarks/bench_fit.py [--quality draft] [--seed 5] [--lights 1 2 4 8] [--repeats 3] [--quick]
    python benchmarks/bench_fit.py --plot-only        # redraw the plots from results/fit.jsonl

On the demo scene's solution (cornell-teapot, draft, seed 5), for both glossy objects
(the teapot and the satin tall block):
  1. error against floats stored per vertex, for every model:
       virtual lights, at K = 1, 2, 4, 8 (each fit from scratch, as ``vlights fit
       --lights K``; the preset's refinement iterations):
         paper           directional, shared coefficients, the paper's method (section 3.2)
         directional     directional, shared, refined (the paper's model, variable projection)
         auto/shared     each light directional or positional as the error requires, shared
         auto/per-light  the same with a specular coefficient per light (the default model)
       floats per vertex: shared 6 (emitted + specular RGB), per-light 3 + 3K (K the lights
       kept); the lights themselves are per object (7 or 8 numbers each), not counted;
       baselines (``fitting.baselines``): diffuse (3), dominant direction (8),
       SH L1 (12), SH L2 (27);
     and whether virtual lights are ahead of every baseline at equal or fewer floats;
  2. the refined fit's time against V x D x K (the teapot's data, a subset of its
     vertices and of its directions, K lights): should grow linearly, the log-log slope
     is reported; and each model's time at K = 8;
  3. the paper method's time (teapot, K = 8, median of --repeats; target <= 5 s);
  4. file sizes: the solution, and fit.npz of each model at K = 8.

Results: JSON lines in benchmarks/results/fit.jsonl; plots in benchmarks/results/fit_models.png
(error against floats per vertex, log x, one marker per model, one panel per object) and
benchmarks/results/fit.png (error and time against K, time against V x D x K).
Equivalence check: every model's error at K lights is at most the diffuse baseline's.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _common import RESULTS, Recorder

MODELS = (  # (name, FitOptions fields, marker)
    ("paper", {"method": "paper"}, "o"),
    ("directional", {"method": "refined", "light_kind": "directional", "coefficients": "shared"}, "s"),
    ("auto/shared", {"method": "refined", "light_kind": "auto", "coefficients": "shared"}, "D"),
    ("auto/per-light", {"method": "refined", "light_kind": "auto", "coefficients": "per-light"}, "^"),
)
WORDS = {
    "paper": "directional, shared, the paper's method",
    "directional": "directional, shared, refined (the paper's model)",
    "auto/shared": "directional or positional, shared",
    "auto/per-light": "directional or positional, per-light coefficients (default)",
}
BASELINE_MARKERS = {"diffuse": "x", "dominant_direction": "P", "sh_l1": "v", "sh_l2": "<"}
SCALING = [(0.25, 2, 2), (0.5, 2, 4), (0.5, 1, 4), (1.0, 1, 4), (1.0, 1, 8)]  # vertex fraction, direction step, K


def median_time(fn, repeats):
    times, result = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), result


def floats_per_vertex(result):
    """Numbers stored per vertex: emitted (3) + specular (3 shared, 3 per light kept)."""
    return 3 + int(np.prod(np.shape(result.specular)[1:]))


def subset(data, vertex_fraction, direction_step):
    """The teapot's data on a subset of its vertices and directions (weights renormalised):
    a smaller problem of the same kind, for the time-against-size question."""
    from fitting.data import FitData

    v = np.arange(0, data.n_vertices, max(1, round(1 / vertex_fraction)))
    d = np.arange(0, data.n_directions, direction_step)
    weights = data.weights[np.ix_(v, d)]
    return FitData(radiance=data.radiance[np.ix_(v, d)], views=data.views[np.ix_(v, d)], normals=data.normals[v],
                   weights=weights / weights.sum(), positions=data.positions[v])


def fitted_model(solution, results):
    """A FittedModel of the whole solution: the glossy objects' fits from ``results``
    ({name: LightsFit}), the diffuse objects' radiance as their emitted colour."""
    from fitting import FittedModel, FittedObject

    objects = []
    for obj in solution.objects:
        r = results.get(obj.name)
        if r is None:
            emitted = np.asarray(obj.radiance[:, 0, :], np.float32)
            specular, pos, rgb, shin = np.zeros_like(emitted), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0)
        else:
            emitted, specular, pos, rgb, shin = r.emitted, r.specular, r.pos, r.rgb, r.shininess
        objects.append(FittedObject(
            name=obj.name, positions=np.asarray(obj.positions, np.float32), normals=np.asarray(obj.normals, np.float32),
            faces=np.asarray(obj.faces, np.int32), emitted=np.asarray(emitted, np.float32),
            specular=np.asarray(specular, np.float32), light_pos=np.asarray(pos, np.float32).reshape(-1, 4),
            light_rgb=np.asarray(rgb, np.float32).reshape(-1, 3), shininess=np.asarray(shin, np.float32).reshape(-1)))
    return FittedModel(objects=tuple(objects), source=str(solution.scene))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quality", default="draft")
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--lights", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="K = 1, 2; one repeat; two sizes")
    parser.add_argument("--plot-only", action="store_true", help="redraw the plots from results/fit.jsonl")
    args = parser.parse_args(argv)
    if args.plot_only:
        rows = [json.loads(line) for line in open(RESULTS / "fit.jsonl")]
        plot(rows)
        print(table(rows))
        return 0
    if args.quick:
        args.lights, args.repeats = [1, 2], 1

    from fitting import FitOptions
    from fitting.baselines import all_baselines
    from fitting.data import fit_data, relative_error
    from fitting.lights import fit_lights, problem_for, reconstruct, start_exponent
    from fitting.mixed import SceneGeometry
    from radiosity.policies.presets import preset
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    iterations = preset(args.quality).fit_iterations
    record = Recorder(quality=args.quality, seed=args.seed, iterations=iterations)
    rows = record.rows
    work = Path(tempfile.mkdtemp(prefix="bench_fit_"))

    solution = solve(load_scene("cornell-teapot"), SolveOptions(quality=args.quality, seed=args.seed))
    solution.save(work / "solution.npz")
    scene = SceneGeometry.of_solution(solution)
    glossy = [o for o in solution.objects if not o.is_diffuse]
    base = FitOptions(iterations=iterations)
    warm = fit_data(glossy[0])  # compile every kernel before anything is timed
    for _, fields, _ in MODELS:
        options = replace(base, **fields)
        fit_lights(problem_for(warm, options, scene), 1, options, start_exponent(glossy[0], options))

    # 1: error against floats per vertex (and each fit's time)
    k_top = max(args.lights)
    at_top = {name: {} for name, _, _ in MODELS}
    for obj in glossy:
        data = fit_data(obj)
        for approximation in all_baselines(obj, data):
            record({
                "question": "error vs floats per vertex", "object": obj.name, "model": approximation.name,
                "baseline": True, "floats_per_vertex": approximation.floats_per_vertex,
                "relative_rms": relative_error(data, approximation.reconstruction)["relative_rms"],
            })
        for name, fields, _ in MODELS:
            options = replace(base, **fields)
            problem = problem_for(data, options, scene)
            exponent = start_exponent(obj, options)
            for k in args.lights:
                repeats = args.repeats if name == "paper" and obj.name == "teapot" and k == k_top else 1
                seconds, result = median_time(lambda: fit_lights(problem, k, options, exponent), repeats)
                if k == k_top:
                    at_top[name][obj.name] = result
                error = relative_error(data, reconstruct(problem, result))
                record({
                    "question": "error vs floats per vertex", "object": obj.name, "model": name, "baseline": False,
                    "K": k, "lights_kept": int(result.n_lights),
                    "kinds": ["positional" if w == 1 else "directional" for w in result.pos[:, 3]],
                    "floats_per_vertex": floats_per_vertex(result), "relative_rms": error["relative_rms"],
                    "worst_vertex": error["worst_vertex"], "seconds": seconds, "repeats": repeats,
                    "V": data.n_vertices, "D": data.n_directions,
                    "shininess": [round(float(p), 2) for p in result.shininess],
                })

    # 3: the paper method's time
    paper = next(r for r in rows if r.get("model") == "paper" and r.get("object") == "teapot" and r.get("K") == k_top)
    record({"question": "paper method time", "object": "teapot", "K": k_top, "seconds": paper["seconds"],
            "repeats": paper["repeats"], "target_s": 5.0, "met": paper["seconds"] <= 5.0})

    # 2: the refined fit's time against V x D x K
    teapot = next(o for o in glossy if o.name == "teapot")
    full = fit_data(teapot)
    options = replace(base, method="refined")
    sizes = []
    for fraction, step, k in SCALING[:2] if args.quick else SCALING:
        data = subset(full, fraction, step)
        problem = problem_for(data, options, scene)
        seconds, result = median_time(lambda: fit_lights(problem, k, options, start_exponent(teapot, options)), 1)
        work_units = data.n_vertices * data.n_directions * k
        sizes.append((work_units, seconds))
        record({"question": "refined time vs V x D x K", "model": "auto/per-light", "V": data.n_vertices,
                "D": data.n_directions, "K": k, "VDK": work_units, "seconds": seconds,
                "iterations_last_refinement": int(result.iterations), "evaluations_last_refinement": int(result.evaluations)})
    w, s = np.array(sizes).T
    slope = float(np.polyfit(np.log(w), np.log(s), 1)[0]) if len(sizes) > 1 else float("nan")
    record({"question": "refined time vs V x D x K slope", "log_log_slope": slope, "linear_is": 1.0,
            "seconds_per_million_VDK": float(np.median(s / w) * 1e6)})

    # 4: file sizes
    record({"question": "file size", "file": "solution.npz", "bytes": (work / "solution.npz").stat().st_size})
    for name, _, _ in MODELS:
        path = work / f"fit_{name.replace('/', '_')}.npz"
        fitted_model(solution, at_top[name]).save(path)
        record({"question": "file size", "file": "fit.npz", "model": name, "K": k_top, "bytes": path.stat().st_size})

    # 5: the verdict and the equivalence check
    for verdict in ahead(rows):
        record(verdict)
    for r in rows:
        if r["question"] == "error vs floats per vertex" and not r["baseline"]:
            diffuse = next(b for b in rows if b.get("baseline") and b["object"] == r["object"] and b["model"] == "diffuse")
            if r["relative_rms"] > diffuse["relative_rms"] * (1 + 1e-6):
                print(f"check: {r['object']} {r['model']} K={r['K']} is worse than the diffuse baseline", file=sys.stderr)

    record.save("fit.jsonl")
    plot(rows)
    print(table(rows))
    return 0


def ahead(rows):
    """Per object and baseline: the best virtual-light fit with at most the baseline's
    floats per vertex, and whether it is ahead (lower error)."""
    storage = [r for r in rows if r["question"] == "error vs floats per vertex"]
    out = []
    for name in dict.fromkeys(r["object"] for r in storage):
        lights = [r for r in storage if r["object"] == name and not r["baseline"]]
        for b in (r for r in storage if r["object"] == name and r["baseline"]):
            fits = [r for r in lights if r["floats_per_vertex"] <= b["floats_per_vertex"]]
            best = min(fits, key=lambda r: r["relative_rms"], default=None)
            out.append({
                "question": "virtual lights ahead at equal or fewer floats", "object": name, "baseline": b["model"],
                "baseline_floats": b["floats_per_vertex"], "baseline_error": b["relative_rms"],
                "best_lights": None if best is None else f"{best['model']} K={best['K']}",
                "best_lights_floats": None if best is None else best["floats_per_vertex"],
                "best_lights_error": None if best is None else best["relative_rms"],
                "ahead": None if best is None else bool(best["relative_rms"] < b["relative_rms"]),
            })
    return out


def table(rows):
    """The markdown table of the fitting section (benchmarks/RESULTS.md is made by report.py)."""
    storage = [r for r in rows if r["question"] == "error vs floats per vertex"]
    names = list(dict.fromkeys(r["object"] for r in storage))
    head = "| model | K | floats / vertex | " + " | ".join(f"{n} relative RMS" for n in names) + " | teapot fit time (s) |"
    lines = [head, "|---|---|---|" + "---|" * len(names) + "---|"]

    def cell(r):
        return "" if r is None else f"{r['relative_rms']:.3f}"

    for name, _, _ in MODELS:
        ks = sorted({r["K"] for r in storage if r["model"] == name})
        for k in ks:
            per = {n: next((r for r in storage if r["model"] == name and r["object"] == n and r["K"] == k), None)
                   for n in names}
            floats = sorted({r["floats_per_vertex"] for r in per.values() if r})
            t = per.get("teapot")
            seconds = "" if t is None else f"{t['seconds']:.1f}"
            lines.append(f"| {WORDS[name]} | {k} | {'/'.join(map(str, floats))} | "
                         + " | ".join(cell(per[n]) for n in names) + f" | {seconds} |")
    for model in BASELINE_MARKERS:
        per = {n: next((r for r in storage if r["model"] == model and r["object"] == n), None) for n in names}
        any_row = next((r for r in per.values() if r), None)
        if any_row:
            lines.append(f"| baseline: {model.replace('_', ' ')} | | {any_row['floats_per_vertex']} | "
                         + " | ".join(cell(per[n]) for n in names) + " | |")
    verdicts = [r for r in rows if r["question"] == "virtual lights ahead at equal or fewer floats"]
    if verdicts:
        lines += ["", "Virtual lights against each baseline at equal or fewer floats per vertex:", ""]
        for v in verdicts:
            if v["ahead"] is None:
                lines.append(f"- {v['object']}, {v['baseline']} ({v['baseline_floats']} floats, {v['baseline_error']:.3f}): "
                             "no virtual-light model stores that few")
            else:
                lines.append(f"- {v['object']}, {v['baseline']} ({v['baseline_floats']} floats, {v['baseline_error']:.3f}): "
                             f"{'ahead' if v['ahead'] else 'NOT ahead'}, best {v['best_lights']} "
                             f"({v['best_lights_floats']} floats, {v['best_lights_error']:.3f})")
        comparable = [v for v in verdicts if v["ahead"] is not None]
        every = all(v["ahead"] for v in comparable)
        lines += ["", f"**Ahead of every baseline at equal or fewer floats per vertex: {'yes' if every else 'no'}** "
                  f"({sum(v['ahead'] for v in comparable)} of {len(comparable)} comparisons)."]
    return "\n".join(lines)


def plot(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    storage = [r for r in rows if r["question"] == "error vs floats per vertex"]
    names = list(dict.fromkeys(r["object"] for r in storage))

    # error against floats per vertex: one panel per object, one marker per model
    fig, axes = plt.subplots(1, len(names), figsize=(6.5 * len(names), 5.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        mine = [r for r in storage if r["object"] == name]
        for model, _, marker in MODELS:
            sel = sorted((r for r in mine if r["model"] == model), key=lambda r: r["K"])
            if sel:
                shared = len({r["floats_per_vertex"] for r in sel}) == 1
                ks = f"K = {sel[0]['K']}..{sel[-1]['K']}" + (f", all {sel[0]['floats_per_vertex']} floats" if shared else "")
                ax.plot([r["floats_per_vertex"] for r in sel], [r["relative_rms"] for r in sel], marker=marker, ls="-",
                        ms=7, alpha=0.85, label=f"virtual lights: {WORDS[model]} ({ks})")
                for r in sel if not shared else ():
                    ax.annotate(f"K={r['K']}", (r["floats_per_vertex"], r["relative_rms"]), fontsize=7,
                                xytext=(4, 3), textcoords="offset points")
        for model, marker in BASELINE_MARKERS.items():
            r = next((r for r in mine if r["model"] == model), None)
            if r:
                ax.plot([r["floats_per_vertex"]], [r["relative_rms"]], marker=marker, ls="none", ms=10, color="k",
                        label=f"baseline: {model.replace('_', ' ')} ({r['floats_per_vertex']} floats)")
        ax.set_xscale("log")
        ticks = sorted({r["floats_per_vertex"] for r in mine})
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_ylim(bottom=0)
        ax.set_xlabel("floats stored per vertex (log scale)")
        ax.set_ylabel("relative RMS error (lower is better)")
        ax.set_title(f"{name}: error against storage")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    fig.savefig(RESULTS / "fit_models.png", dpi=100)
    plt.close(fig)

    # error and time against K per model; time against V x D x K
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.6))
    for name, ls in zip(names, ("-", "--", ":")):
        for i, (model, _, marker) in enumerate(MODELS):
            sel = sorted((r for r in storage if r["object"] == name and r["model"] == model), key=lambda r: r["K"])
            if sel:
                for ax, key in ((axes[0], "relative_rms"), (axes[1], "seconds")):
                    ax.plot([r["K"] for r in sel], [r[key] for r in sel], marker=marker, ls=ls, color=f"C{i}",
                            label=f"{name}, {model}")
    for ax, label in ((axes[0], "relative RMS error"), (axes[1], "fit time (s)")):
        ax.set_xscale("log", base=2)
        ks = sorted({r["K"] for r in storage if "K" in r})
        ax.set_xticks(ks, [str(k) for k in ks])
        ax.set_xlabel("virtual lights K")
        ax.set_ylabel(label)
        ax.set_title(f"{label} against K")
        ax.legend(fontsize=6)
    axes[1].set_yscale("log")
    scaling = [r for r in rows if r["question"] == "refined time vs V x D x K"]
    if scaling:
        axes[2].loglog([r["VDK"] for r in scaling], [r["seconds"] for r in scaling], "o")
        for r in scaling:
            axes[2].annotate(f"V{r['V']} D{r['D']} K{r['K']}", (r["VDK"], r["seconds"]), fontsize=7,
                             xytext=(3, 3), textcoords="offset points")
        slope = next((r["log_log_slope"] for r in rows if r["question"] == "refined time vs V x D x K slope"), None)
        if slope is not None and math.isfinite(slope):
            axes[2].set_title(f"refined fit (teapot data): time against V x D x K, slope {slope:.2f}")
    axes[2].xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    axes[2].set_xlabel("V x D x K")
    axes[2].set_ylabel("fit time (s)")
    fig.tight_layout()
    fig.savefig(RESULTS / "fit.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
