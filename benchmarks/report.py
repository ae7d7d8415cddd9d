"""Write benchmarks/RESULTS.md from the JSON lines the benchmarks recorded.

Usage:
    python benchmarks/report.py            # rewrite benchmarks/RESULTS.md from benchmarks/results/*.jsonl
    python benchmarks/report.py --check    # exit 1 if RESULTS.md is not what the results files give

Every number in RESULTS.md comes from a row of a results file; nothing is typed by hand,
so the tables cannot drift from what the benchmarks measured. A benchmark run rewrites
its own results file (``_common.Recorder.save``); run this script afterwards and commit
both. Only the standard library is used, so it runs without the project installed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
OUTPUT = HERE / "RESULTS.md"


def read_rows(path):
    """The rows of one JSON-lines file, in order."""
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def num(x, digits=3):
    """A number with ``digits`` decimals; '' for None."""
    if x is None:
        return ""
    return f"{x:.{digits}f}"


def mega(x):
    return "" if x is None else f"{x / 1e6:.2f}"


def table(head, rows):
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def machine(rows):
    """One line naming the machines the rows were measured on."""
    seen = sorted({(r.get("cores"), r.get("machine"), r.get("python")) for r in rows}, key=str)
    parts = [f"{c} cores, {m}, Python {p}" for c, m, p in seen]
    return "Measured on " + "; ".join(parts) + "."


def where(script, files):
    names = ", ".join(f"`results/{f}`" for f in files)
    return f"Produced by `python benchmarks/{script}` ({names})."


def pick(rows, **match):
    return [r for r in rows if all(r.get(k) == v for k, v in match.items())]


# -- one function per results file ---------------------------------------------------------


def solver(rows):
    out = ["## Solver", "", where("bench_solver.py", ["solver.jsonl"]), machine(rows), ""]
    rays = pick(rows, question="rays per second")
    if rays:
        out += ["Each preset's photon pass and gather against the limit: bare Embree on all cores "
                "tracing the same rays (ratios of rays per second; medians of the repeats).", ""]
        out += table(
            ["preset", "triangles", "limit, photon / gather rays (M rays/s)", "photon pass", "gather",
             "gather, its tracing alone", "solve (s)", "tracing floor (s)", "repeats"],
            [[r["quality"], r["triangles"],
              f"{mega(r['limit_rays_per_s']['photon'])} / {mega(r['limit_rays_per_s']['gather'])}",
              f"{num(r['photon_ratio'], 2)}x", f"{num(r['gather_ratio'], 2)}x",
              f"{num(r['gather_trace_ratio'], 2)}x", num(r["solve_s"], 2), num(r["tracing_floor_s"], 2),
              r["repeats"]] for r in rays])
        out += ["", "The gather's thread-seconds, tracing against the splat into the direction grid: "
                + "; ".join(f"{r['quality']} {num(r['gather_split_thread_s']['trace'], 1)} / "
                            f"{num(r['gather_split_thread_s']['splat'], 1)}" for r in rays) + ".", ""]
    presets = pick(rows, question="solve time per preset") + pick(rows, question="solve time, refined mesh")
    if presets:
        out += ["Solve time per preset (warm numba cache, median):", ""]
        out += table(["preset", "mesh", "solve (s)", "photons (s)", "gather (s)"],
                     [[r["quality"], "refined" if "refined" in r["question"] else "uniform",
                       num(r["solve_s_warm_median"], 2), num(r["phases_s"]["photons"], 2),
                       num(r["phases_s"]["gather"], 2)] for r in presets])
        out.append("")
    for r in pick(rows, question="same answer at 1 and N threads"):
        out.append(f"- Same radiance at 1 and {r['threads']} threads: {'yes' if r['identical'] else 'NO'}.")
    for r in pick(rows, question="peak memory"):
        counts = " and ".join(f"{p / 1e6:g} M" for p in r["photons"])
        peaks = " and ".join(f"{m:.1f} MB" for m in r["peak_rss_mb"])
        out.append(f"- Peak memory at {counts} photons: {peaks} (growth {r['growth'] * 100:.1f} %).")
    for r in pick(rows, question="numba compile time"):
        out.append(f"- numba compile: first solve from an empty cache {num(r['cold_first_solve_s'], 1)} s, "
                   f"warm {num(r['warm_solve_s'], 1)} s (compile {num(r['compile_s'], 1)} s).")
    return out + [""]


def pathtrace(rows):
    out = ["## Path tracer", "", where("bench_pathtrace.py", ["pathtrace.jsonl"]), machine(rows), ""]
    for r in pick(rows, what="speed"):
        out.append(f"- {r['scene']}, {r['size']} x {r['size']}, {r['spp']} spp, {r['threads']} threads: "
                   f"{mega(r['rays_per_s'])} M rays/s against the limit's {mega(r['bare_rays_per_s'])} M: "
                   f"**{num(r['ratio_to_bare'], 2)}x** (target {r['target_ratio']}x); "
                   f"{mega(r['paths_per_s'])} M paths/s.")
    for r in pick(rows, what="repeat")[:1]:
        out.append(f"- {num(r['rays_per_path'], 2)} rays a path, {num(r['shadow_rays_per_path'], 2)} of them "
                   "shadow rays.")
    ref = pick(rows, what="reference")
    for r in pick(rows, what="time to FLIP"):
        if r["spp"] is None:
            out.append(f"- FLIP {r['flip']}: not reached.")
        else:
            out.append(f"- FLIP {r['flip']} reached at {r['spp']} spp, {num(r['seconds'], 1)} s.")
    conv = pick(rows, what="convergence")
    if conv:
        against = f" (against a {ref[0]['spp']}-spp image, another seed)" if ref else ""
        out += ["", f"Convergence{against}:", ""]
        out += table(["spp", "seconds", "FLIP", "relative MSE"],
                     [[r["spp"], num(r["seconds"], 2), num(r["flip"]), num(r["relative_mse"], 4)] for r in conv])
    return out + [""]


FIT_MODELS = {
    "paper": "directional, shared, the paper's method",
    "directional": "directional, shared, refined (the paper's model)",
    "auto/shared": "directional or positional, shared",
    "auto/per-light": "directional or positional, per-light coefficients",
}


def fit(rows):
    out = ["## Virtual lights against baselines", "", where("bench_fit.py", ["fit.jsonl"]), machine(rows), ""]
    storage = pick(rows, question="error vs floats per vertex")
    objects = list(dict.fromkeys(r["object"] for r in storage))
    if storage:
        out += ["Relative RMS error of each glossy object (lower is better) against the floats stored per "
                "vertex; the teapot's fit time.", ""]
        body = []
        for model, words in FIT_MODELS.items():
            for k in sorted({r["K"] for r in pick(storage, model=model)}):
                per = {o: next(iter(pick(storage, model=model, object=o, K=k)), None) for o in objects}
                floats = "/".join(str(f) for f in sorted({r["floats_per_vertex"] for r in per.values() if r}))
                teapot = per.get("teapot")
                body.append([words, k, floats] + [num(per[o]["relative_rms"]) if per[o] else "" for o in objects]
                            + [num(teapot["seconds"], 1) if teapot else ""])
        for model in dict.fromkeys(r["model"] for r in storage if r["baseline"]):
            per = {o: next(iter(pick(storage, model=model, object=o)), None) for o in objects}
            some = next(r for r in per.values() if r)
            body.append([f"baseline: {model.replace('_', ' ')}", "", some["floats_per_vertex"]]
                        + [num(per[o]["relative_rms"]) if per[o] else "" for o in objects] + [""])
        out += table(["model", "K", "floats / vertex"] + [f"{o} relative RMS" for o in objects]
                     + ["teapot fit (s)"], body)
        out.append("")
    verdicts = [v for v in pick(rows, question="virtual lights ahead at equal or fewer floats") if v["ahead"] is not None]
    if verdicts:
        ahead = sum(v["ahead"] for v in verdicts)
        out.append(f"- Virtual lights ahead of a baseline at equal or fewer floats per vertex: {ahead} of "
                   f"{len(verdicts)} comparisons.")
    for r in pick(rows, question="paper method time"):
        out.append(f"- The paper's method, teapot, K = {r['K']}: {num(r['seconds'], 1)} s, median of {r['repeats']} "
                   f"(target {r['target_s']} s: {'met' if r['met'] else 'not met'}).")
    for r in pick(rows, question="refined time vs V x D x K slope"):
        out.append(f"- Refined fit time against V x D x K: log-log slope {num(r['log_log_slope'], 2)}, "
                   f"{num(r['seconds_per_million_VDK'], 2)} s per million.")
    sizes = pick(rows, question="file size")
    if sizes:
        out.append("- Files: " + "; ".join(
            f"{r['file']}{' ' + r['model'] + ' K = ' + str(r['K']) if 'model' in r else ''} "
            f"{r['bytes'] / 1e6:.3f} MB" for r in sizes) + ".")
    return out + [""]


def fit_speed(rows):
    out = ["## Fit speed", "", where("bench_fit_speed.py", ["fit_speed.jsonl"]), machine(rows), ""]
    first = rows[0]
    out += [f"The demo teapot at {first['quality']} (V {first['vertices']}, D {first['directions']}), "
            f"{first['lights']} lights:", ""]
    out += table(["model", "median (s)", "runs (s)", "relative RMS"],
                 [[r["model"], num(r["median_s"], 2), ", ".join(num(s, 2) for s in r["runs_s"]),
                   num(r["relative_rms"])] for r in rows])
    return out + [""]


def fit_time(rows):
    out = ["## The fit against the solve", "", where("bench_fit_time.py", ["fit_time.jsonl"]), machine(rows), "",
           "Each case solved and then fitted as a user types it (`vlights solve SCENE --seed 5 --quality Q`, "
           "`vlights fit`), alternating, each in a process of its own; medians of the runs, the ratio of the "
           "medians and of each run (target: fit <= solve). Peak: the fit's largest process (GNU time's maximum "
           "resident set) and its process tree (summed Pss, sampled).", ""]
    out += table(["case", "commit", "runs", "solve (s)", "fit (s)", "fit / solve", "per run", "fit peak (MB)",
                  "fit tree (MB)"],
                 [[r["case"], r.get("commit", ""), len(r["runs"]), num(r["solve_s"], 1), num(r["fit_s"], 1),
                   num(r["ratio_medians"], 2), ", ".join(num(x, 2) for x in r["ratio_per_run"]), r["fit_peak_mb"],
                   r["fit_tree_mb"]] for r in rows if "case" in r])
    return out + [""]


def fit_memory(rows):
    out = ["## The fit's memory", "", where("bench_fit_memory.py", ["fit_memory.jsonl"]), machine(rows), ""]
    out += table(["case", "commit", "seconds", "peak (MB)", "tree (MB)", "target (GB)", "within"],
                 [[r["case"], r.get("commit", ""), num(r["seconds"], 1), r["peak_mb"], r["tree_mb"],
                   num(r["target_gb"], 1), "yes" if r["within"] else "no"] for r in rows if "case" in r])
    return out + [""]


def glossy(rows_by_quality):
    files = [f"glossy{'' if q == 'draft' else '_' + q}.jsonl" for q in rows_by_quality]
    every = [r for rows in rows_by_quality.values() for r in rows]
    out = ["## Glossy objects against the truth", "", where("bench_glossy.py", files), machine(every), ""]
    for quality, rows in rows_by_quality.items():
        look = pick(rows, question="look")
        if look:
            out += [f"FLIP on the glossy objects' pixels against a path-traced truth ({quality}; "
                    f"truth {look[0]['truth_spp']} spp):", ""]
            out += table(["scene", "view", "reference", "fitted", "diffuse", "fitted / diffuse", "fitted / reference"],
                         [[r["scene"], r["view"], num(r["reference"]["flip_glossy"]), num(r["fitted"]["flip_glossy"]),
                           num(r["diffuse"]["flip_glossy"]), num(r["ratio_fitted_diffuse"], 2),
                           num(r["ratio_fitted_reference"], 2)] for r in look])
            out.append("")
        errors = pick(rows, question="fit error")
        if errors:
            out += [f"Each glossy object's model ({quality}):", ""]
            out += table(["scene", "object", "model", "probe", "lights", "floats / vertex", "relative RMS",
                          "diffuse alone"],
                         [[r["scene"], r["object"], r["model"], r["probe"] or "", r["lights"], r["floats_per_vertex"],
                           num(r["relative_rms"]), num(r["diffuse_only_relative_rms"])] for r in errors])
            out.append("")
        for r in pick(rows, question="highlights present"):
            out.append(f"- {r['scene']}: of {r['highlights']} lamp highlights, the reference display shows "
                       f"{r['reference']}, the fitted {r['fitted']}, the diffuse {r['diffuse']}.")
        for r in pick(rows, question="fit time"):
            out.append(f"- Fit of the whole {r['scene']} scene at {quality}: {num(r['fit_s'], 1)} s "
                       f"(target {num(r['target'], 0)} s).")
        for r in pick(rows, question="frame time"):
            out.append(f"- Frame at {r['width']} x {r['height']}, {r['scene']}, {quality}: fitted per pixel "
                       f"{num(r['fitted_pixel_ms'], 1)} ms, fitted Gouraud {num(r['fitted_gouraud_ms'], 1)} ms, "
                       f"diffuse per pixel {num(r['diffuse_pixel_ms'], 1)} ms, reference per pixel "
                       f"{num(r['reference_pixel_ms'], 1)} ms (fitted / diffuse "
                       f"{num(r['ratio_fitted_diffuse'], 2)}, target {r['target']}).")
        for r in pick(rows, question="files"):
            out.append(f"- {r['scene']}: fit.npz {num(r['fit_mb'], 2)} MB against solution.npz "
                       f"{num(r['solution_mb'], 2)} MB ({num(r['ratio'], 2)}; target {r['target']}).")
        spots = pick(rows, question="highlight")
        if spots:
            out += ["", f"Peak radiance at each lamp's highlight on each plate ({quality}):", ""]
            out += table(["plate", "lamp", "truth", "reference", "fitted", "diffuse"],
                         [[r["plate"], r["lamp"], num(r["truth"], 3), num(r["reference"], 3), num(r["fitted"], 3),
                           num(r["diffuse"], 3)] for r in spots])
        out.append("")
    return out


def display(rows):
    out = ["## Display", "", where("bench_display.py", ["display.jsonl"]), machine(rows)]
    renderers = sorted({r["gl_renderer"] for r in rows})
    out += [f"OpenGL: {', '.join(renderers)}.", ""]
    frames = pick(rows, question="frame time")
    if frames:
        out += ["Frame time (ms, one sample per pixel, drawing only) and bytes on the GPU:", ""]
        out += table(["scene", "triangles", "lights", "mode", "shading", "size", "frame (ms)", "MB"],
                     [[r["scene"], r["triangles"], r["lights"], r["mode"], r["shading"],
                       f"{r['width']} x {r['height']}", num(r["frame_ms"], 1), num(r["bytes"] / 1e6, 2)]
                      for r in frames])
        out.append("")
    for r in pick(rows, question="targets"):
        out.append(f"- {r['scene']}: fitted Gouraud / diffuse Gouraud {num(r['fitted_gouraud_over_diffuse'], 2)} "
                   f"(target <= {r['target']}); the same image twice: {'yes' if r['same_image_twice'] else 'NO'}.")
    for r in pick(rows, question="model size"):
        out.append(f"- Fitted model against the solution: files {num(r['file_ratio'], 1)}x smaller "
                   f"({num(r['fit_file'] / 1e6, 2)} MB against {num(r['solution_file'] / 1e6, 2)} MB), arrays "
                   f"{num(r['array_ratio'], 1)}x (target >= {r['target_ratio']}x).")
    aa = pick(rows, question="antialiasing")
    if aa:
        out += ["", "Antialiasing (fitted, demo scene):", ""]
        out += table(["samples", "MSAA", "supersampling", "shading", "frame (ms)", "over one sample"],
                     [[r["samples"], r["msaa"], f"{r['supersampling']} x {r['supersampling']}", r["shading"],
                       num(r["frame_ms"], 1), num(r["over_one_sample"], 2)] for r in aa])
    checks = pick(rows, question="antialiasing check")
    if checks:
        out += ["", f"Mean absolute difference to a {checks[0]['against_samples']}-sample image at "
                + " / ".join(str(r["samples"]) for r in checks) + " samples per pixel: "
                + " / ".join(num(r["mean_abs_difference"], 4) for r in checks) + "."]
    return out + [""]


def web(rows):
    out = ["## WebGL walkthrough", "", where("bench_web.py", ["web.jsonl"]), machine(rows), ""]
    for r in pick(rows, what="size"):
        out.append(f"- scene.glb {num(r['scene_glb_bytes'] / 1e6, 2)} MB against fit.npz "
                   f"{num(r['fit_npz_bytes'] / 1e6, 2)} MB ({num(r['glb_over_npz'], 2)}x); the page with "
                   f"three.js {num(r['page_bytes'] / 1e6, 2)} MB.")
    for r in pick(rows, what="load"):
        out.append(f"- Load to the first complete frame: {num(r['seconds_median'], 2)} s, median of "
                   f"{len(r['seconds'])}; against `vlights render --shading pixel`: mean absolute difference "
                   f"{num(r['mean_abs_diff_to_render'], 3)} / 255, {num(r['pixels_off_by_more_than_16'] * 100, 3)} % "
                   "of pixels off by more than 16.")
    frames = pick(rows, what="frame")
    if frames:
        size = frames[0]["size"]
        out += ["", f"Frame time in headless chromium (software WebGL2), {size[0]} x {size[1]}:", ""]
        out += table(["mode", "samples", "median (ms)", "min (ms)", "frames"],
                     [[r["mode"], r["samples"], num(r["ms_median"], 1), num(r["ms_min"], 1), r["frames"]]
                      for r in frames])
    return out + [""]


def trade(rows):
    out = ["## What more time buys", "", where("bench_trade.py", ["trade.jsonl"]), machine(rows), ""]
    photons = pick(rows, question="photons")
    if photons:
        out += ["Photons against the diffuse surfaces' error (against 16x the photons):", ""]
        out += table(["photons", "relative RMS", "solve (s)"],
                     [[f"{r['photons'] / 1e6:g} M", f"{r['relative_rms'] * 100:.2f} %", num(r["seconds"], 2)]
                      for r in photons])
        for r in pick(rows, question="photons slope"):
            out += ["", f"Log-log slope {num(r['log_log_slope'])} (Monte Carlo: {r['monte_carlo_is']})."]
        out.append("")
    gather = pick(rows, question="gather samples")
    if gather:
        out += ["Gather rays per glossy vertex against the glossy objects' error (against 4096 rays):", ""]
        out += table(["gather rays", "relative RMS", "solve (s)", "file (MB)"],
                     [[r["gather_samples"], f"{r['relative_rms'] * 100:.1f} %", num(r["seconds"], 2),
                       num(r["file_mb"], 1)] for r in gather])
        out.append("")
    grid = pick(rows, question="grid")
    if grid:
        out += ["Direction grid of the glossy objects against their error (against a 32 x 32 grid):", ""]
        out += table(["grid", "relative RMS", "solve (s)", "file (MB)"],
                     [[f"{r['grid']} x {r['grid']}", f"{r['relative_rms'] * 100:.1f} %", num(r["seconds"], 2),
                       num(r["file_mb"], 1)] for r in grid])
        out.append("")
    scaling = pick(rows, question="scaling")
    if scaling:
        out += ["Scaling with the mesh (peak memory of a fresh process; fit: the paper's method, K = 8):", ""]
        out += table(["max edge", "triangles", "vertices", "solve (s)", "fit (s)", "peak memory (MB)"],
                     [[num(r["max_edge"], 0), f"{r['triangles']:,}", f"{r['vertices']:,}", num(r["solve_s"], 1),
                       num(r["fit_s"], 1), num(r["peak_rss_mb"], 0)] for r in scaling])
        out.append("")
    presets = pick(rows, question="presets")
    if presets:
        out += ["Presets on the uniform mesh, error of the per-object mean radiance against a 32 M-photon, "
                "4096-ray solve:", ""]
        out += table(["preset", "vertices", "solve (s)", "error", "file (MB)"],
                     [[r["quality"], r["vertices"], num(r["seconds"], 1),
                       f"{r['relative_error_of_object_means'] * 100:.2f} %", num(r["file_mb"], 1)] for r in presets])
    return out + [""]


def trade_truth(rows):
    out = ["## The trade against the truth", "", where("bench_trade.py --only truth", ["trade_truth.jsonl"]),
           machine(rows), ""]
    for r in pick(rows, what="truth"):
        out.append(f"The truth: {r['size']} x {r['size']}, {r['spp']} spp, noise floor (FLIP between its halves) "
                   f"{r['noise_flip']}. Displays at 4 samples per pixel; FLIP (HDR) against it.")
    walk = pick(rows, what="walkthrough")
    if walk:
        out += ["", "Each preset: solve and fit time, each display's FLIP over the image and over the glossy objects, "
                "the frame time, and the path tracer's samples and seconds to reach the same FLIP:", ""]
        out += table(["preset", "mesh", "vertices", "solve (s)", "fit (s)", "display", "FLIP", "FLIP glossy",
                      "frame (s)", "path tracer spp", "path tracer (s)"],
                     [[r["quality"], "refined" if r["adaptive"] else "uniform", r["vertices"], num(r["solve_s"], 1),
                       num(r["fit_s"], 1) if r["adaptive"] else "", r["mode"], num(r["flip"], 4),
                       num(r["flip_glossy"]), num(r["frame_s"], 3), r["path_tracer_spp_to_match"],
                       num(r["path_tracer_seconds_to_match"], 1)] for r in walk])
    progress = [r for r in pick(rows, what="path tracer") if r["spp"] & (r["spp"] - 1) == 0]
    if progress:
        out += ["", "The path tracer's own progress against the same truth (another seed; powers of two shown):", ""]
        out += table(["spp", "seconds", "FLIP", "relative MSE"],
                     [[r["spp"], num(r["seconds"], 2), num(r["flip"], 4), num(r["relative_mse"], 4)]
                      for r in progress])
    return out + [""]



def frames_text(n):
    """A break-even number of frames in words."""
    if n is None:
        return "never (its frames cost no less)"
    return f"{n:,.0f}" if n >= 10 else f"{n:.1f}"


WALK_PAIRS = (("fitted", "fitted", "path tracer at the fitted FLIP"),
              ("reference", "reference", "path tracer at the reference FLIP"),
              ("fitted, Mitsuba", "fitted", "Mitsuba at the fitted FLIP's samples"),
              ("reference, Mitsuba", "reference", "Mitsuba at the reference FLIP's samples"))


def walkthrough(rows):
    out = [f"## {walkthrough.title}", "", where("bench_walkthrough.py", ["walkthrough.jsonl", "walkthrough.png"]),
           machine(rows), ""]
    if rows:
        r0 = rows[0]
        out += [f"{r0['size'][0]} x {r0['size'][1]}, {r0['quality']}, {r0['sample_frames']} sample frames along each "
                f"camera path, each display's FLIP (HDR, whole image) against a {r0['truth_spp']}-spp path-traced truth "
                "of that frame; the path tracer at the samples per pixel that reach each display's FLIP on that frame. "
                "A way's total for N frames is its fixed cost + N x its cost per frame (the mean over the sample "
                "frames); solve and fit are the commands, each in a process of its own.", ""]
    for s in pick(rows, what="summary"):
        setup = next(iter(pick(rows, what="setup", scene=s["scene"])), None)
        heading = f"**{s['scene']}**"
        if setup:
            heading += (f" ({setup['triangles']:,} input triangles, {setup['vertices']:,} vertices solved; solve "
                        f"{num(setup['solve_s'], 1)} s, fit {num(setup['fit_s'], 1)} s):")
        out += [heading, ""]
        out += table(["way", "FLIP", "fixed (s)", "per frame (s)", "samples per pixel"],
                     [[name, num(w.get("flip"), 4), num(w["fixed_s"], 2), num(w["per_frame_s"], 4),
                       (", ".join(str(n) for n in w["spp"]) + ("" if w["reached"] else " (not reached: a lower bound)"))
                       if "spp" in w else ""] for name, w in s["ways"].items()])
        out.append("")
        for key, method, rival in WALK_PAIRS:
            if key not in s["break_even_frames"]:
                continue
            ratio = s["ratio_of_totals"][key]
            out.append(f"- {rival[0].upper() + rival[1:]} against the {method} display: break-even at "
                       f"**{frames_text(s['break_even_frames'][key])}** frames; total {rival.split(' at ')[0]} / "
                       f"{method} at N = " + ", ".join(f"{int(n):,}" for n in ratio) + ": "
                       + ", ".join(f"**{num(v, 2)}**" if n == "100" else num(v, 2) for n, v in ratio.items()) + ".")
        out.append("")
    frames = pick(rows, what="frame")
    if frames:
        out += ["Each sample frame (frame times: median of the draws, drawing only):", ""]
        mitsuba = {(r["scene"], r["frame"]): r for r in pick(rows, what="mitsuba frame")}
        body = []
        for r in frames:
            m = mitsuba.get((r["scene"], r["frame"]))
            pt = r["path_tracer"]
            body.append([r["scene"], r["frame"], num(r["truth_noise_flip"], 4), num(r["fitted"]["flip"], 4),
                         num(r["fitted"]["frame_s"] * 1000, 1), num(r["reference"]["flip"], 4),
                         num(r["reference"]["frame_s"] * 1000, 1),
                         f"{pt['fitted']['spp']}{'' if pt['fitted']['reached'] else '+'} / "
                         f"{pt['reference']['spp']}{'' if pt['reference']['reached'] else '+'}",
                         f"{num(pt['fitted']['seconds'], 2)} / {num(pt['reference']['seconds'], 2)}",
                         f"{num(m['fitted']['seconds'], 2)} / {num(m['reference']['seconds'], 2)}" if m else "",
                         num(m["fitted"]["flip"], 4) if m else ""])
        out += table(["scene", "frame", "truth's noise FLIP", "fitted FLIP", "fitted (ms)", "reference FLIP",
                      "reference (ms)", "path tracer spp (fitted / reference)", "path tracer (s)", "Mitsuba (s)",
                      "Mitsuba FLIP (fitted's spp)"], body)
        out += ["", "A + after the samples: the path tracer did not reach the display's FLIP within its progress; its "
                "cost is then a lower bound. Mitsuba renders the path tracer's samples (its noise per sample is no "
                "lower than ours), so its time is a lower bound on its time to the same FLIP; its FLIP holds the "
                "material mapping's difference too."]
    for r in pick(rows, what="mitsuba"):
        out.append(f"- Mitsuba: {r['skipped']}.")
    return out + [""]


walkthrough.title = "A walkthrough of N frames"  # the heading, also when the benchmark has not been run


def mitsuba(rows):
    out = ["## Against Mitsuba 3 on the same XML", "", where("validate_mitsuba.py", ["mitsuba_validation.jsonl"]),
           machine(rows), ""]
    if rows:
        r0 = rows[0]
        out += [f"Mitsuba {r0['mitsuba']} ({r0['variant']}) at {4 * r0['spp']} spp is the reference; ours and "
                f"Mitsuba's own image at {r0['spp']} spp against it (targets: mean within 2 %, our FLIP at or below "
                "Mitsuba's own).", ""]
    out += table(["scene", "size", "mean ratio", "FLIP", "relative MSE", "Mitsuba's mean ratio", "Mitsuba's FLIP",
                  "our FLIP against our 4N", "our 4N: mean ratio, FLIP"],
                 [[r["scene"], "x".join(map(str, r["size"][::-1])), num(r["ours"]["mean_ratio"], 4),
                   num(r["ours"]["flip"], 4), num(r["ours"]["relative_mse"], 4),
                   num(r["mitsuba_noise"]["mean_ratio"], 4), num(r["mitsuba_noise"]["flip"], 4),
                   num(r.get("ours_noise", {}).get("flip"), 4),
                   f"{num(r.get('converged', {}).get('mean_ratio'), 4)}, {num(r.get('converged', {}).get('flip'), 4)}"]
                  for r in rows])
    return out + [""]


def displays(rows):
    out = ["## The displays against Mitsuba 3", "", where("validate_displays.py", ["displays.jsonl", "displays.png"]),
           machine(rows), ""]
    if rows:
        r0 = rows[0]
        out += [f"Mitsuba {r0['mitsuba']} ({r0['variant']}) at {r0['reference_spp']} spp is the reference image; each "
                f"display of a solve and fit at the quality, and our path tracer at {r0['truth_spp']} spp, against it "
                "(`vlights compare --reference`): FLIP over the image and over the glossy objects' pixels, the mean "
                "ratio, and each display's FLIP over the path tracer's (target for the solution display: at most "
                "1.3 x).", ""]
    out += table(["scene", "quality", "display", "FLIP", "/ path tracer", "FLIP glossy", "/ path tracer",
                  "mean ratio", "rel. MSE glossy"],
                 [[r["scene"], r["quality"], name.replace("reference", "solution").replace("_", " "),
                   num(r[name]["flip"], 4), num(r[name]["over_path_tracer"], 2), num(r[name]["flip_glossy"], 4),
                   num(r[name]["glossy_over_path_tracer"], 2), num(r[name]["mean_ratio"], 4),
                   num(r[name]["relative_mse_glossy"], 4)]
                  for r in rows for name in ("reference", "fitted", "diffuse", "path_tracer") if name in r])
    return out + [""]


def materials(rows):
    out = ["## The materials' own models against their Phong stand-ins", "",
           where("bench_materials.py", ["materials.jsonl"]), machine(rows), "",
           "The path tracer on the scene's own camera, with every material's own model (rough plastics and "
           "conductors as microfacet lobes, glass as glass), with the Phong stand-ins, and with the glass left "
           "out (as before glass was modelled), at the same samples and seed, each against the published render "
           "box-averaged to the same size (target: lower FLIP with the models).", ""]
    out += table(["scene", "model", "spp", "size", "FLIP", "mean ratio", "seconds"],
                 [[r["scene"], r["model"], r["spp"], "x".join(map(str, r["size"])), num(r["flip"], 4),
                   num(r["mean_ratio"], 4), num(r["seconds"], 1)] for r in rows if "model" in r])
    return out + [""]


def glass(rows):
    out = ["## Glass: a sphere's caustic, and glass at display", "",
           where("validate_glass.py", ["glass_caustic.jsonl", "glass_caustic.png"]), machine(rows), ""]
    if rows:
        out += [f"Mitsuba {rows[0]['mitsuba']} ({rows[0]['variant']}) at {4 * rows[0]['spp']} spp is the reference; "
                "the caustic's power is the sum of (with the sphere - without it) over the caustic's region, each "
                "renderer's own pair (target: within 5 % of Mitsuba's). The displays: FLIP on the glass balls' "
                "pixels for each way of drawing glass, and a frame's time.", ""]
    out += table(["renderer", "caustic power / Mitsuba's", "not grown", "mean ratio", "FLIP"],
                 [[r["renderer"], num(r["caustic_ratio"], 4), num(r["strict_ratio"], 4), num(r["mean_ratio"], 4),
                   num(r["flip"], 4)] for r in rows if "caustic_ratio" in r])
    out += [""] + table(["display", "FLIP on the glass (Mitsuba)", "(path tracer)", "mean ratio there",
                         "whole image FLIP", "frame (ms)", "first frame (ms)"],
                        [[r["renderer"], num(r["flip_glass"], 4), num(r["flip_glass_vs_truth"], 4),
                          num(r["mean_ratio_glass"], 3), num(r["flip"], 4), num(1e3 * r["frame_s"], 1),
                          num(1e3 * r["first_frame_s"], 0)] for r in rows if "flip_glass" in r])
    return out + [""]


def mirrors(rows):
    out = ["## Perfect mirrors at display", "", where("validate_mirror.py", ["mirrors.jsonl", "mirrors.png"]),
           machine(rows), "",
           "On the mirrors' pixels: the path tracer, and the solution display with the mirrors drawn by what they "
           "reflect and from what the solution stores (\"grid\": their grid, as before solution version 7; "
           "\"stored\": nothing since), against the reference (Mitsuba 3 on the project's "
           "scene, the published render on the living room) and the display against the path tracer.", ""]
    out += table(["scene", "renderer", "reference", "mirror pixels", "FLIP there", "against the path tracer",
                  "mean ratio there", "whole image FLIP"],
                 [[r["scene"], r["renderer"], r["reference"], r["mirror_pixels"], num(r["flip_mirrors"], 4),
                   num(r.get("flip_mirrors_vs_truth"), 4), num(r["mean_ratio_mirrors"], 3), num(r["flip"], 4)]
                  for r in rows if "mirror_pixels" in r])
    return out + [""]


def checkouts(rows):
    out = ["## Two checkouts, interleaved", "", where("bench_checkouts.py", ["checkouts.jsonl"]), machine(rows), ""]
    if rows:
        out += [f"Old: `{rows[0]['old']}`; new: `{rows[0]['new']}`. Medians of the runs, alternating old and new "
                "(target: within 5 %).", ""]
    out += table(["case", "runs", "old wall (s)", "new wall (s)", "wall new / old", "old reported (s)",
                  "new reported (s)", "reported new / old"],
                 [[r["case"], r["repeats"], num(r["wall"]["old_s"], 2), num(r["wall"]["new_s"], 2),
                   num(r["wall"]["ratio"], 3),
                   num(r.get("reported", {}).get("old_s"), 2), num(r.get("reported", {}).get("new_s"), 2),
                   num(r.get("reported", {}).get("ratio"), 3)] for r in rows if "case" in r])
    return out + [""]


def startup(rows):
    out = ["## Start-up", "", where("bench_startup.py", ["startup.jsonl"]), machine(rows), ""]
    if rows:
        out += [f"Old: `{rows[0]['old']}`; new: this checkout. Medians of {rows[0]['repeats']} runs each in a fresh "
                "process, alternating old and new; the heavy modules each imported.", ""]
    cases = list(dict.fromkeys(r["case"] for r in rows))
    by = {(r["case"], r["checkout"]): r for r in rows}
    out += table(["case", "old (s)", "new (s)", "new / old", "old imported", "new imported"],
                 [[c, num(by[c, "old"]["seconds"], 3), num(by[c, "new"]["seconds"], 3),
                   num(by[c, "new"]["seconds"] / by[c, "old"]["seconds"], 2),
                   ", ".join(by[c, "old"]["loaded"]) or "none", ", ".join(by[c, "new"]["loaded"]) or "none"]
                  for c in cases])
    return out + [""]


def test_durations(rows):
    out = ["## The slowest tests", "", "From `VLIGHTS_DURATIONS=benchmarks/results/test_durations.jsonl python -m pytest` "
           "(`tests/conftest.py` keeps the slowest phases of the run): `test_durations.jsonl`.", ""]
    if rows:
        r = rows[0]
        out += [f"Commit {r['commit']}, {r['cores']} cores, {r['workers']} workers, {r['passed']} tests passed.", ""]
    out += table(["test", "phase", "seconds"], [[f"`{r['test']}`", r["phase"], num(r["seconds"], 2)] for r in rows])
    return out + [""]


def interiors(rows):
    out = ["## The field's interiors", "", where("bench_interiors.py", ["interiors.jsonl", "interiors.png",
                                                                       "interiors_<scene>.png"]), machine(rows)]
    runs = {}
    for r in rows:
        runs.setdefault((r.get("date") or "", r.get("commit")), []).append(r["scene"])
    if len(runs) > 1:  # a --merge of runs: say which scenes each measured
        out += ["Rows of more than one run: " + "; ".join(
            f"{', '.join(dict.fromkeys(scenes))} "
            + (f"at commit {commit} ({date})" if commit else "by an earlier run (its commit not recorded)")
            for (date, commit), scenes in sorted(runs.items(), key=str))]
    out += [""]
    summaries = [r for r in rows if r.get("summary")]
    steps = [r for r in rows if "step" in r and r["step"] != "mitsuba reference"]
    if summaries:
        r0 = next((r for r in summaries if "displays" in r), summaries[0])
        out += [f"Each scene from its own XML at {r0.get('quality', 'draft')}; every display and the path tracer "
                f"({r0.get('truth_spp')} spp) against the scene's published render (or Mitsuba 3's, where the copy "
                "has none), FLIP and mean ratio (display / image). Targets: the path tracer's mean within 5 %, the "
                "fitted display's FLIP at most 1.2 x the path tracer's, every step within 8 GB.", ""]
        cell = lambda d: f"{num(d['flip'])} ({num(d['mean_ratio'], 3)})"  # noqa: E731
        out += table(["scene", "against", "path tracer", "solution", "fitted", "diffuse", "fitted / path tracer",
                      "largest step (GB)"],
                     [[r["scene"], r["reference"], *(cell(r["displays"][k]) for k in ("path_tracer", "solution",
                                                                                        "fitted", "diffuse")),
                       num(r["fitted_over_path_tracer"], 2), num(max(r["peak_mb"].values()) / 1024, 2)]
                      if "displays" in r else [r["scene"], r["reference"], f"stopped at {r['stopped_at']}", "", "", "",
                                               "", ""]
                      for r in summaries])
        out += [""]
    if steps:
        names = list(dict.fromkeys(r["scene"] for r in steps))
        order = [s for s in ("scene-info", "solve", "fit", "render", "export", "compare")]
        by = {(r["scene"], r["step"]): r for r in steps}
        out += ["Each step's seconds and peak memory (GB; the process tree's, a fit's workers included), exit "
                "status where it failed:", ""]
        out += table(["scene", *order],
                     [[n, *(("" if (n, s) not in by else
                             f"{num(by[n, s]['seconds'], 1)} s, {num(max(by[n, s]['peak_mb'], by[n, s]['tree_mb']) / 1024, 2)}"
                             + (f", exit {by[n, s]['exit']}" if by[n, s]["exit"] else "")) for s in order)]
                      for n in names])
        out += [""]
    incomplete = [r for r in rows if r.get("incomplete")]
    if incomplete:
        out += ["The copies that lack files: the refusal's one line names the missing file; with the elements that "
                "name missing files left out of a copy of the XML, scene-info on the rest.", ""]
        out += table(["scene", "missing files", "refusal names one", "left out", "the rest: exit, s, GB"],
                     [[r["scene"], len(r["missing"]), "yes" if r["refusal_names_file"] else "no", r["left_out"],
                       f"{r['rest_exit']}, {num(r['rest_seconds'], 1)}, {num(r['rest_peak_mb'] / 1024, 2)}"]
                      for r in incomplete])
        out += [""]
    return out


def load(rows):
    out = ["## Loading scenes", "", where("bench_load.py", ["load.jsonl"]), machine(rows), "",
           "A generated Mitsuba XML scene (OBJ, PLY and serialized meshes, tessellated spheres, transforms, bsdfs) "
           "through `load_scene`, median of fresh processes; target: 100,000 triangles in under 10 s.", ""]
    out += table(["triangles", "objects", "load (s)", "imports (s)"],
                 [[f"{r['triangles']:,}", r["objects"], num(r["load_s_median"], 2), num(r["import_s_median"], 2)]
                  for r in rows])
    return out + [""]


def textures(rows):
    out = ["## Textures", "", where("bench_textures.py", ["textures.jsonl", "textures.png"]), machine(rows), ""]
    scenes = [r for r in rows if r.get("scene") in ("textured", "untextured")]
    if scenes:
        r0 = scenes[0]
        out += [f"A textured room (tiled floor, wallpaper, wooden box) and its untextured twin (each texture folded "
                f"into kd by its mean), {r0['quality']}, {r0['size']}, each display's FLIP against its own scene's "
                f"path-traced truth at {4 * r0['spp']} spp; the truth's row is its own noise ({r0['spp']} spp against "
                f"{4 * r0['spp']}). Target: the reference display's FLIP within 10 % of the untextured scene's.", ""]
    out += table(["scene", "reference FLIP", "fitted FLIP", "diffuse FLIP", "truth noise FLIP", "reference rel. MSE"],
                 [[r["scene"], num(r["reference"]["flip"], 4), num(r["fitted"]["flip"], 4), num(r["diffuse"]["flip"], 4),
                   num(r["truth"]["flip"], 4), num(r["reference"]["relative_mse"], 5)] for r in scenes])
    for r in rows:
        if "flip_ratio" in r:
            ratio = r["flip_ratio"]
            out += ["", f"FLIP ratio textured / untextured: reference {num(ratio['reference'], 3)}, fitted "
                    f"{num(ratio['fitted'], 3)}, diffuse {num(ratio['diffuse'], 3)}, the truth's own noise "
                    f"{num(ratio['truth'], 3)} (target met: {'yes' if r['met'] else 'no'})."]
    return out + [""]


def scale(rows, name="scale.jsonl", title="Scale", plotted=True):
    files = [name, name.replace(".jsonl", ".png")] if plotted else [name]  # the plot: time and memory against triangles
    out = [f"## {title}", "", where("bench_scale.py", files), machine(rows), ""]
    stages = [r for r in rows if "seconds" in r]
    if stages:
        out += [f"A generated closed interior (rooms of full-height walls with doorways, each with a table, a chair (closed by its seat), "
                f"a diffuse statue, a glossy ball of exponent 20, 100 or 1000 and a lamp), {stages[0]['quality']}, "
                "each stage the command a user types in a process of its own. Peak memory: the kernel's figure for "
                "the process, and the process tree's summed proportional set size sampled every 0.1 s (the fit's "
                "worker processes). The targets: 10^6 triangles with solve + fit <= 5 minutes and <= 8 GB; "
                "each stage's log-log slope <= 1.15 between 10^5 and 10^6; the fit's peak <= 2 x the solution's "
                "arrays.", ""]
    notes = sorted({r["note"] for r in stages if r.get("note")})
    out += [f"Note: {n}.\n" for n in notes]
    out += table(["triangles", "rooms", "stage", "seconds", "peak MB (process)", "peak MB (tree)", "solution MB"],
                 [[f"{r['triangles']:,}", r["rooms"], r["stage"], num(r["seconds"], 2), num(r["peak_mb"], 1),
                   num(r.get("tree_peak_mb"), 1), num(r.get("solution_mb"), 1)]
                  for r in stages])
    dask = [r for r in stages if "same_bits_as_threads" in r]
    if dask:
        alone = {(r["triangles"], r["stage"]): r["seconds"] for r in stages}
        out += ["", "On Dask (a LocalCluster on this machine: the -dask stages) against the same command without it "
                "(threads, and the fit's worker processes), in the same run: "
                + "; ".join(f"{r['stage']} at {r['triangles']:,}: {num(r['seconds'] / alone[(r['triangles'], r['stage'][:-5])], 2)}"
                            f" x the time, {'the same bits' if r['same_bits_as_threads'] else 'DIFFERENT BITS'}"
                            for r in dask if (r["triangles"], r["stage"][:-5]) in alone) + "."]
    slopes = [r for r in rows if "time_slope" in r]
    if slopes:
        out += ["", "Log-log slopes between consecutive sizes:", ""]
        out += table(["stage", "from", "to", "time slope", "memory slope"],
                     [[r["stage"], f"{r['from']:,}", f"{r['to']:,}", num(r["time_slope"], 3), num(r["memory_slope"], 3)]
                      for r in slopes])
    return out + [""]


def scale_medium(rows):
    return scale(rows, "scale_medium.jsonl", scale_medium.title)


scale_medium.title = "Scale at medium"


def scale_dask(rows):
    return scale(rows, "scale_dask.jsonl", scale_dask.title, plotted=False)


scale_dask.title = "Scale: threads against Dask"


SECTIONS = (
    ("solver.jsonl", solver),
    ("pathtrace.jsonl", pathtrace),
    ("fit.jsonl", fit),
    ("fit_speed.jsonl", fit_speed),
    ("fit_time.jsonl", fit_time),
    ("fit_memory.jsonl", fit_memory),
    ("display.jsonl", display),
    ("web.jsonl", web),
    ("trade.jsonl", trade),
    ("trade_truth.jsonl", trade_truth),
    ("mitsuba_validation.jsonl", mitsuba),
    ("displays.jsonl", displays),
    ("materials.jsonl", materials),
    ("glass_caustic.jsonl", glass),
    ("mirrors.jsonl", mirrors),
    ("checkouts.jsonl", checkouts),
    ("startup.jsonl", startup),
    ("test_durations.jsonl", test_durations),
    ("load.jsonl", load),
    ("textures.jsonl", textures),
    ("scale.jsonl", scale),
    ("scale_medium.jsonl", scale_medium),
    ("scale_dask.jsonl", scale_dask),
    ("walkthrough.jsonl", walkthrough),
    ("interiors.jsonl", interiors),
)


def render(results=RESULTS):
    """RESULTS.md's text from the results files in ``results``."""
    results = Path(results)
    out = ["# Benchmark results", "",
           "Generated by `python benchmarks/report.py` from `benchmarks/results/*.jsonl`; do not edit by hand. "
           "How to run each benchmark: [README.md](README.md); what each measures: "
           "[docs/benchmarks.md](../docs/benchmarks.md). Timings are wall-clock on shared machines: "
           "compare rows of the same run, not runs of different days.", ""]
    used = set()
    glossy_files = sorted(results.glob("glossy*.jsonl"), key=lambda p: (p.name != "glossy.jsonl", p.name))
    by_quality = {}
    for path in glossy_files:
        rows = read_rows(path)
        if rows:
            by_quality[rows[0]["quality"]] = rows
        used.add(path.name)
    for name, section in SECTIONS:
        path = results / name
        used.add(name)
        if not path.exists():
            title = getattr(section, "title", section.__name__)
            out += [f"## {title}", "", f"No `results/{name}`: the benchmark has not been run.", ""]
            continue
        out += section(read_rows(path))
        if name == "fit_speed.jsonl" and by_quality:
            out += glossy(by_quality)
    others = sorted(p.name for p in results.glob("*.jsonl") if p.name not in used)
    if others:
        out += ["## Other results files", "", "Not summarised here: " + ", ".join(f"`{n}`" for n in others) + ".", ""]
    return "\n".join(out).rstrip("\n") + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if RESULTS.md differs from what the results give")
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = OUTPUT.read_text(encoding="utf-8") if OUTPUT.exists() else ""
        if current != text:
            print(f"{OUTPUT} is out of date: run python benchmarks/report.py", file=sys.stderr)
            return 1
        return 0
    OUTPUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUTPUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
