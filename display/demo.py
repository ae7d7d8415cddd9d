"""``vlights demo``: the whole pipeline on the built-in scenes ``cornell-teapot`` (the
paper's kind of room: a glazed teapot, a satin block, the box's walls reflected) and
``plates`` (glossy plates from near-mirror to broad under sphere lamps, after Veach).

For each scene, into ``out/<scene>/``: solution.npz, fit.npz (``vlights fit``'s default
model: per glossy object the emitters' highlights in closed form, a reflection probe and
virtual lights, the cheapest that reaches the error target), the comparison figures
(compare/), and web/ (the fit as glTF with the WebGL walkthrough, as ``vlights export``
writes). Then ``models.png`` (each glossy object's error against the numbers it stores,
for every model the fitter tried), ``report.md`` (a verdict per scene, what each number
means, the pictures and tables of times and errors) and ``summary.json`` (the same
numbers). The files appear together at the end: a failure or Ctrl-C on the way leaves
none of them.

The demo runs the earlier stages itself (scene loading, the solve, the path tracer) and
reaches them through ``display.pipeline`` alone, as the truth command does; the fit
through ``fitting``'s public ``fit``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from radiosity.files.atomic import atomic_output

from . import compare as _compare
from . import export as _export
from .choices import ASPECT, DEMO_SCENES  # noqa: F401 (a demo scene's figures)
from .gl import DEFAULT_SAMPLES
from .images import write_figure
from .outputs import staged_directory

SCENES = DEMO_SCENES
FILES = ("summary.json", "report.md", "models.png") + tuple(
    f"{scene}/{name}" for scene in SCENES
    for name in ("solution.npz", "fit.npz", *(f"compare/{f}" for f in _compare.FILES), f"web/{_export.FILE}",
                 f"web/{_export.SHADING}", *(f"web/{f}" for f in _export.page_files()))
)


def run_demo(out, quality="draft", size=(512, 512), log=print, samples=DEFAULT_SAMPLES, truth_spp=None, scenes=SCENES):
    """Run the pipeline for each of ``scenes`` into ``out`` (created if missing, not its
    parents); returns the summary. The figures have ``samples`` per pixel (antialiasing,
    ``display.renderer``); the first view of each scene is also path-traced with
    ``truth_spp`` samples per pixel (None: the quality preset's; 0: no truth) and every
    display measured against it.

    Everything is written into a hidden directory inside ``out`` and moved into place
    when all of it is done (``display.outputs.staged_directory``). The OpenGL context
    is made first, so a machine without one is told so before the solve.
    """
    from .gl import framebuffer_refusals

    out = Path(out)
    ctx = _context(size, samples)
    try:
        with framebuffer_refusals(size, samples), staged_directory(out) as stage:
            return _run(stage, ctx, quality, size, log, samples, truth_spp, scenes)
    finally:
        ctx.release()


def _context(size, samples):
    """The headless context, after checking the figures' size and samples against its
    limits and memory."""
    from .gl import COMPARE_BYTES_PER_PIXEL, check_image_memory, check_image_size, check_samples, headless_context

    ctx = headless_context()
    try:
        check_image_size(ctx, *size)
        check_samples(ctx, samples, *size)
        check_image_memory(*size, COMPARE_BYTES_PER_PIXEL, samples=samples)
    except BaseException:
        ctx.release()
        raise
    return ctx


FLIP_MEANS = ("FLIP: NVIDIA's perceptual difference between two pictures, per pixel from 0 (identical) to 1, "
              "averaged over the glossy objects' pixels; lower is better.")
RMS_MEANS = ("relative RMS: the root of the squared error of the radiance, weighted by vertex area and solid "
             "angle over every vertex and direction of the object, divided by the same sum of the squared "
             "radiance; lower is better, 0 is exact, 1 is as large as the radiance itself.")
PERCEPTUAL_MEANS = ("perceptual: the same relative RMS with the radiance scaled by the object's mean and raised "
                    "to the display's gamma 1 / 2.2, nearer what a viewer sees; what --model auto chooses by.")


def model_words(o):
    """The model of a fitted object in words: its parts and the floats it stores."""
    parts = []
    if o.highlight is not None:
        parts.append("the emitters' highlights")
    if o.probe is not None:
        parts.append(f"a {o.probe.size}x{o.probe.size} reflection probe")
    if o.n_lights:
        n_pos = int(o.positional.sum())
        kind = (f"{n_pos} positional and {o.n_lights - n_pos} directional" if 0 < n_pos < o.n_lights
                else ("positional" if n_pos else "directional"))
        parts.append(f"{o.n_lights} virtual lights ({kind})")
    what = " + ".join(parts) if parts else "its emitted colour alone"
    return f"{o.info.get('model', 'lights')}: {what}; {o.floats_per_vertex} floats per vertex"


def _run(out, ctx, quality, size, log, samples, truth_spp, scenes):
    from radiosity.policies.presets import preset

    p = preset(quality)
    truth_spp = p.truth_spp if truth_spp is None else truth_spp
    summary = {"verdict": "", "quality": quality, "samples": samples, "scenes": {}, "times_s": {}}
    steps = len(scenes) * (4 if truth_spp else 3) + 1
    step = [0]

    def say(text):
        step[0] += 1
        log(f"[{step[0]}/{steps}] {text}")

    for name in scenes:
        (out / name).mkdir()
        summary["scenes"][name] = _scene(out / name, name, ctx, quality, _scene_size(name, size), samples, truth_spp, say)
    say("plotting each glossy object's error against what it stores")
    t = time.perf_counter()
    _plot_models(summary["scenes"], out / "models.png")
    summary["times_s"]["plot_s"] = time.perf_counter() - t
    summary["times_s"]["total_s"] = sum(s["times_s"]["total_s"] for s in summary["scenes"].values()) + summary["times_s"]["plot_s"]
    summary["meaning"] = {"truth": TRUTH_MEANS, "relative_rms": RMS_MEANS, "perceptual": PERCEPTUAL_MEANS, "flip": FLIP_MEANS,
                          "diffuse": "a diffuse walkthrough of the solution: each vertex's radiance averaged over "
                                     "directions (3 floats per vertex)"}
    summary["verdict"] = " ".join(f"{name}: {verdict(s)}." for name, s in summary["scenes"].items())
    with atomic_output(out / "summary.json") as f:
        f.write(_compare.json_text(summary).encode())
    with atomic_output(out / "report.md") as f:
        f.write(_report(summary).encode())
    return summary


def _scene_size(name, size):
    w, h = size
    return (w, max(16, round(w * ASPECT[name]))) if name in ASPECT else (w, h)


def _scene(out, name, ctx, quality, size, samples, truth_spp, say):
    """One scene's solve, fit, export, truth and figures into ``out``; its summary."""
    from fitting import fit

    from . import pipeline
    from .renderer import Renderer

    times = {}
    scene = pipeline.load_scene(name)
    say(f"{name}: solving ({quality})")
    t = time.perf_counter()
    solution = pipeline.solve(scene, quality, seed=1, progress=True)
    solution.save(out / "solution.npz")
    times["solve_s"] = time.perf_counter() - t

    options = pipeline.fit_options(quality)
    say(f"{name}: fitting each glossy object's model (--model {options.model})")
    t = time.perf_counter()
    model = fit(solution, options, progress=True)
    model.save(out / "fit.npz")
    times["fit_s"] = time.perf_counter() - t
    (out / "web").mkdir()
    _export.write_files(model, out / "web")  # the WebGL walkthrough: vlights serve DIR/web

    view = scene.camera.sized(*size)
    truths = []
    if truth_spp:
        from .truth import ground_truth

        say(f"{name}: path-tracing the truth of view 1 ({truth_spp} samples per pixel)")
        t = time.perf_counter()
        truths = [ground_truth(solution, view, truth_spp, seed=1, progress=True)]
        times["truth_s"] = time.perf_counter() - t

    say(f"{name}: rendering the paper's figures ({samples} samples per pixel)")
    t = time.perf_counter()
    renderer = Renderer(ctx, fit=model, solution=solution, samples=samples)
    numbers = _compare.compare(renderer, out / "compare", view, truths=truths)
    renderer.release()
    times["compare_s"] = time.perf_counter() - t
    times["total_s"] = sum(times.values())

    sizes = {f: (out / f).stat().st_size for f in ("solution.npz", "fit.npz")}
    objects = {
        o.name: {
            "model": o.info.get("model"), "words": model_words(o), "lights": o.n_lights,
            "probe_size": o.probe.size if o.probe is not None else 0, "emitters": o.highlight is not None,
            "floats_per_vertex": o.floats_per_vertex, "floats": o.floats, "shininess": o.info["shininess"],
            "loss": o.info.get("loss"), "tried": o.info.get("tried", []), "time_s": o.info.get("time_s"), **o.info["error"],
        }
        for o in model.objects if o.info.get("model") not in (None, "diffuse") or o.n_lights
    }
    return {
        "scene": name, "times_s": {k: round(v, 3) for k, v in times.items()}, "solver_time_s": solution.stats["time_s"],
        "mesh": solution.stats.get("adaptive"), "emitter_parts": len(solution.emitters), "fit_settings": model.settings,
        "objects": objects, "sizes_bytes": sizes, "figures": numbers, "truth": numbers.get("truth", {}).get("view1"),
    }


def _plot_models(scenes, path):
    """One panel per glossy object: the perceptual error of each model tried against the
    floats it stores (log scale), the model kept ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(scene, name, o) for scene, s in scenes.items() for name, o in s["objects"].items() if o["tried"]]
    n = max(len(panels), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.8 * rows), squeeze=False)
    for ax in axes.ravel()[len(panels):]:
        ax.axis("off")
    for ax, (scene, name, o) in zip(axes.ravel(), panels):
        for t in o["tried"]:
            label = (t["model"] + (f" {t['probe_size']}" if t["probe_size"] else "") + (f" {t['lights']}L" if t["lights"] else "")
                     + (f" ({t['loss']})" if t.get("loss") else ""))
            kept = (t["model"] == o["model"] and t["probe_size"] == o["probe_size"] and t["lights"] == o["lights"]
                    and t.get("loss", o.get("loss")) == o.get("loss") and t.get("kept", True))
            ax.plot(t["floats"], t["perceptual"], "o", color="C1" if kept else "C0", ms=9 if kept else 6)
            ax.annotate(label, (t["floats"], t["perceptual"]), fontsize=7, xytext=(4, 4), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("floats stored (log)")
        ax.set_ylabel("perceptual error (log, lower is better)")
        ax.set_title(f"{scene}: {name}", fontsize=9)
    fig.suptitle("each glossy object's models: error against what they store (orange: kept)", fontsize=10)
    fig.tight_layout()
    write_figure(path, fig, dpi=110)
    plt.close(fig)


TRUTH_MEANS = ("the first view path-traced (NEE + BRDF sampling by MIS, a box filter over each pixel) from the "
               "solution's meshes and materials; each display's FLIP and relative MSE against it. noise_flip: FLIP "
               "between the truth's two independent halves, the level below which an error is its noise")


DISPLAYS = (("reference", "solution display"), ("fitted", "fitted display"), ("diffuse", "diffuse display"))


def _fmt(value, digits=2):
    return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.{digits}f}"


def _objects_words(s):
    return ", ".join(f"{n} {o['model']}" for n, o in s["objects"].items()) or "no glossy object"


def verdict_rows(s):
    """A scene's verdict as a table: (column headings, rows, the one-line verdict). Per
    display, its FLIP against the solution (on the glossy objects: figure 7's numbers)
    and against the path-traced truth (on the glossy objects and over the whole image),
    then the truth's noise floor; the truth's columns only where there is one."""
    g = s["figures"].get("glossy_flip") or {}
    over = "glossy objects" if g.get("over", "glossy objects") == "glossy objects" else "whole image"
    truth = s.get("truth")
    against_solution = {"reference": "itself", "fitted": _fmt(g.get("with_virtual_lights"), 3),
                        "diffuse": _fmt(g.get("diffuse_only"), 3)}
    headings = [("FLIP against", ""), ("the solution", over)]
    if truth:
        headings += [("the truth", over), ("the truth", "whole image")]
    rows = []
    for mode, label in DISPLAYS:
        row = [label, against_solution[mode]]
        if truth:
            m = truth[mode]
            row += [_fmt(m.get("flip_mean_glossy", m["flip_mean"]), 3), _fmt(m["flip_mean"], 3)]
        rows.append(row)
    if truth:
        rows.append([f"noise floor ({truth['spp']} spp)", "", "", _fmt(truth["noise_flip"], 3)])
    return headings, rows, verdict(s)


def verdict(s):
    """One line: what the fitted model keeps of the solution's glossy look (its FLIP
    against the solution over the diffuse display's, figure 7, against the target), and,
    with a truth, how far behind (or ahead of) the solution display it is against the
    truth, and whether the truth's noise hides the difference."""
    g = s["figures"].get("glossy_flip") or {}
    if not s["objects"]:
        return "no glossy object: the fitted display is the diffuse one"
    ratio, target = g.get("ratio"), g.get("target_ratio")
    if not isinstance(ratio, float) or not math.isfinite(ratio):
        line = "the fit cannot be judged: the diffuse display matches the solution exactly"
    else:
        said = f"{ratio:.2f}x the diffuse display against the solution"
        if target is not None and ratio <= target:
            line = f"the fit keeps the glossy look ({said}, target {target:.2f}x)"
        elif ratio < 1:
            line = f"the fit keeps part of the glossy look ({said}, target {_fmt(target)}x)"
        else:
            line = f"the fit changes nothing a viewer sees ({said})"
    truth = s.get("truth")
    if truth:
        def flip(mode):
            return truth[mode].get("flip_mean_glossy", truth[mode]["flip_mean"])

        more = flip("fitted") - flip("reference")
        if more >= 0.0005:
            line += f"; {more:.3f} behind the solution display against the truth"
        elif more <= -0.0005:
            line += f"; {-more:.3f} ahead of the solution display against the truth"
        else:
            line += "; level with the solution display against the truth"
        noise = truth.get("noise_flip")
        if noise is not None and max(truth["fitted"]["flip_mean"], truth["reference"]["flip_mean"]) <= noise:
            line += ", within its noise"
    return line


def verdict_text(name, s):
    """A scene's verdict for a terminal: a heading, the table's aligned rows, the verdict line."""
    headings, rows, line = verdict_rows(s)
    table = [[h[0] for h in headings], [h[1] for h in headings], *rows]
    widths = [max(len(r[i]) for r in table) for i in range(len(headings))]
    out = [f"{name} ({_objects_words(s)})"]
    for r in table:
        cells = [r[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(r[1:], widths[1:])]
        out.append(("  " + "   ".join(cells)).rstrip())
    out.append(f"  verdict: {line}")
    return "\n".join(out)


def verdict_markdown(name, s):
    """The same table for report.md."""
    headings, rows, line = verdict_rows(s)
    names = [f"{a}, {b}" if b else a for a, b in headings]
    out = [f"### {name} ({_objects_words(s)})", "", "| " + " | ".join(names) + " |",
           "|" + "|".join(["---"] + ["---:"] * (len(names) - 1)) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out + ["", f"**Verdict**: {line}.", ""]


def _mesh_words(mesh):
    """The report's sentence on the solver's mesh (``stats["adaptive"]``)."""
    if not mesh:
        return ""
    if not mesh["enabled"]:
        return f" The solver's mesh: uniform, {mesh['vertices_before']:,} vertices."
    return (f" The solver's mesh: refined where the light changes, {mesh['vertices_before']:,} -> "
            f"{mesh['vertices_after']:,} vertices (budget {mesh['vertex_budget']:,}).")


def _report(summary):
    lines = [
        "# virtual-lights demo: " + ", ".join(summary["scenes"]), "",
        "## Verdict", "",
        "Each display's FLIP (0 = identical, lower is better) against the solution (the solution display, what "
        "the model is fitted to)" + (" and against the truth (path-traced from the scene's camera); an error near "
                                     "the truth's noise floor is the truth's own noise." if any(
                                         s.get("truth") for s in summary["scenes"].values()) else "."), "",
        *(line for name, s in summary["scenes"].items() for line in verdict_markdown(name, s)),
        "## What the numbers mean", "",
        f"- **Relative RMS** ({RMS_MEANS[len('relative RMS: '):]})",
        f"- **Perceptual** ({PERCEPTUAL_MEANS[len('perceptual: '):]})",
        f"- **FLIP** ({FLIP_MEANS[len('FLIP: '):]}) The error images show it per pixel through the magma colour "
        "map, black 0 to pale yellow 1, with the scale beside each.",
        "- **Solution display**: the solution drawn directly (each vertex's radiance read in its direction grid, "
        "the emitters' highlights in closed form): what the fitted model is fitted to, so an error against it is "
        "the fit's alone. Older outputs, compare.json and `--mode` call it `reference`.",
        "- **Fitted display**: the fitted model as the walkthrough draws it.",
        "- **Diffuse display**: " + summary["meaning"]["diffuse"] + ".",
        "- **Truth**: " + TRUTH_MEANS + ".",
        "- **PSNR** of the tone-mapped pictures: higher is better.", "",
        f"Quality `{summary['quality']}`; figures with {summary['samples']} samples per pixel (antialiasing: their "
        f"mean, a box filter over each pixel). Total {summary['times_s']['total_s']:.1f} s.", "",
        "![models](models.png)", "",
        "*Each glossy object's models, as `vlights fit --model auto` tried them: the perceptual error against the "
        "numbers stored; the one kept in orange.*", "",
    ]
    for name, s in summary["scenes"].items():
        lines += _scene_report(name, s)
    return "\n".join(lines)


def _scene_report(name, s):
    t = s["times_s"]
    lines = [
        f"## {name}", "",
        f"Solve {t['solve_s']:.1f} s, fit {t['fit_s']:.1f} s, " + (f"truth {t['truth_s']:.1f} s, " if "truth_s" in t else "")
        + f"figures {t['compare_s']:.1f} s. solution.npz {s['sizes_bytes']['solution.npz'] / 1e6:.2f} MB, fit.npz "
        f"{s['sizes_bytes']['fit.npz'] / 1e6:.2f} MB; {s['emitter_parts']} emitter part(s) in closed form."
        + _mesh_words(s.get("mesh")), "",
        "| object | model | floats / vertex | relative RMS | perceptual | best colour per vertex | fit time |",
        "|---|---|---|---|---|---|---|",
    ]
    for obj, o in s["objects"].items():
        lines.append(f"| {obj} | {o['words']} | {o['floats_per_vertex']} | {_fmt(o.get('relative_rms'), 4)} | "
                     f"{_fmt(o.get('perceptual'), 4)} | {_fmt(o.get('diffuse_only_relative_rms'), 4)} | "
                     f"{_fmt(o.get('time_s'), 1)} s |")
    f = s["figures"]
    lines.append("")
    for i in range(1, 4):
        m = f["figure5"][f"view{i}"]
        lines += [f"**Figure 5, view {i}**: the solution display, the fitted display, the FLIP error between them"
                  + (" (and the truth first, the fitted display's FLIP against it last)" if i == 1 and s.get("truth")
                     else "") + f". FLIP {m['flip_mean']:.4f} / "
                  f"{m.get('flip_mean_glossy', float('nan')):.4f} (image / glossy objects), PSNR {m['psnr_db']:.2f} dB",
                  "", f"![figure 5 view {i}]({name}/compare/figure5_view{i}.png)", ""]
    lines += ["**Figure 6**: 2 against all virtual lights", "", f"![figure 6]({name}/compare/figure6.png)", "",
              "**Figure 7**: the fitted display against a diffuse walkthrough, each with its FLIP against the solution "
              "display", "", f"![figure 7]({name}/compare/figure7.png)", ""]
    truth = s.get("truth")
    if truth:
        noise = "n/a" if truth["noise_flip"] is None else f"{truth['noise_flip']:.4f}"
        lines += [f"Against the truth (view 1, path-traced, {truth['spp']} samples per pixel; noise floor {noise}):", "",
                  "| display | FLIP | relative MSE | FLIP, glossy | relative MSE, glossy |", "|---|---|---|---|---|"]
        for mode, label in DISPLAYS:
            m = truth[mode]
            lines.append(f"| {label} | {m['flip_mean']:.4f} | {m['relative_mse']:.4g} | "
                         f"{_fmt(m.get('flip_mean_glossy'), 4)} | {_fmt(m.get('relative_mse_glossy'), 4)} |")
        lines.append("")
    return lines


def key_numbers(summary, out):
    """What the demo prints at the end: where everything is, then each scene's verdict table."""
    t = summary["times_s"]
    width = max(len(f"{name}/solution.npz, fit.npz") for name in summary["scenes"])

    def file(name, what):
        return f"  {name:<{width}}   {what}"

    lines = [f"done in {t['total_s']:.1f} s; everything is in {out}/:"]
    for name, s in summary["scenes"].items():
        lines += [file(f"{name}/solution.npz, fit.npz", "the solution and its fitted model"),
                  file(f"{name}/compare/", "the solution display against the fitted display (figures 5, 6, 7)"),
                  file(f"{name}/web/", f"the walkthrough in a browser: vlights serve {out}/{name}/web")]
        for obj, o in s["objects"].items():
            lines.append(f"    {obj}: {o['words']}; relative RMS {_fmt(o.get('relative_rms'), 3)}, "
                         f"perceptual {_fmt(o.get('perceptual'), 3)}")
    lines += [file("models.png", "each glossy object's models: error against floats stored"),
              file("report.md, summary.json", "these verdicts with the pictures, times and errors"), ""]
    for name, s in summary["scenes"].items():
        lines += [verdict_text(name, s), ""]
    truth = (" The truth: path-traced from the scene's camera; an error near its noise floor is its own noise."
             if any(s.get("truth") for s in summary["scenes"].values()) else "")
    lines.append("FLIP: 0 = identical, 1 = as different as can be. The solution: the solution display, what the "
                 "model is fitted to." + truth)
    return "\n".join(lines)
