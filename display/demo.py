"""``vlights demo``: the whole pipeline on the built-in ``cornell-teapot`` scene.

Writes into ``out``: solution.npz, fit.npz (the default model: each light directional
or positional as the data require, a specular coefficient per light), the comparison
figures (compare/), an error-against-lights plot (one curve per model, per glossy
object), report.md (a one-line verdict of what the lights bought, what each number
means, the pictures and tables of times and errors) and summary.json (the same
numbers: times per phase, errors per object and per model and K, sizes), and web/ (the
fit as glTF with the WebGL walkthrough, as ``vlights export`` writes). The files appear
together at the end: a failure or Ctrl-C on the way leaves none of them.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from radiosity.formats.atomic import atomic_output

from . import compare as _compare
from . import export as _export
from .gl import DEFAULT_SAMPLES
from .outputs import staged_directory

FILES = ("solution.npz", "fit.npz", "summary.json", "report.md", "error_vs_lights.png") + tuple(
    f"compare/{name}" for name in _compare.FILES
) + (f"web/{_export.FILE}", f"web/{_export.SHADING}") + tuple(f"web/{name}" for name in _export.page_files())


def run_demo(out, quality="draft", size=(512, 512), log=print, samples=DEFAULT_SAMPLES, truth_spp=None):
    """Run the pipeline into ``out`` (created if missing, not its parents); returns the summary.
    The figures have ``samples`` per pixel (antialiasing, ``display.renderer``); the first
    view is also path-traced with ``truth_spp`` samples per pixel (None: the quality
    preset's; 0: no truth) and every display measured against it.

    Everything is written into a hidden directory inside ``out`` and moved into place
    when all of it is done (``display.outputs.staged_directory``). The OpenGL context
    is made first, so a machine without one is told so before the solve.
    """
    out = Path(out)
    ctx = _context(size, samples)
    try:
        with staged_directory(out) as stage:
            return _run(stage, ctx, quality, size, log, samples, truth_spp)
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


SWEEP_MODELS = (
    ("directional/shared", "directional lights, one coefficient per vertex (the paper's model, refined)",
     {"light_kind": "directional", "coefficients": "shared"}, "o-"),
    ("auto/shared", "directional or positional lights, one coefficient per vertex",
     {"light_kind": "auto", "coefficients": "shared"}, "s-"),
    ("auto/per-light", "directional or positional lights, a coefficient per light (the default)",
     {"light_kind": "auto", "coefficients": "per-light"}, "^-"),
)
"""The models of the error-against-lights plot: (key, what it is, FitOptions fields, marker)."""

FLIP_MEANS = ("FLIP: NVIDIA's perceptual difference between two pictures, per pixel from 0 (identical) to 1, "
              "averaged over the glossy objects' pixels; lower is better.")
RMS_MEANS = ("relative RMS: the root of the squared error of the radiance, weighted by vertex area and solid "
             "angle over every vertex and direction of the object, divided by the same sum of the squared "
             "radiance; lower is better, 0 is exact, 1 is as large as the radiance itself.")


def sweep_counts(quality):
    """The light counts the error-against-lights sweep refits: the preset's
    ``demo_light_sweep``, at draft only its two smallest (the sweep refits three models
    at every count, and at draft it must not dwarf the rest of the demo). The demo's
    own fit adds its K to the default model's curve at no cost."""
    from radiosity.formats.presets import preset

    counts = sorted(set(preset(quality).demo_light_sweep))
    return tuple(counts[:2] if quality == "draft" else counts)


def model_words(o):
    """The model of a fitted object in words: kinds, coefficients, floats per vertex."""
    kinds = o.info.get("kinds", [])
    n_pos = sum(k == "positional" for k in kinds)
    kind = (f"{n_pos} positional and {len(kinds) - n_pos} directional" if 0 < n_pos < len(kinds)
            else ("positional" if n_pos else "directional"))
    coeffs = "a specular coefficient per light at each vertex" if o.per_light else "one specular coefficient per vertex"
    return f"{o.n_lights} lights ({kind}), {coeffs}: {o.floats_per_vertex} floats per vertex"


def _run(out, ctx, quality, size, log, samples, truth_spp):
    from fitting import FitOptions, fit
    from radiosity.formats.presets import preset
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.adaptive import solve_adaptive
    from radiosity.transport.solve import SolveOptions

    from .renderer import Renderer

    times = {}
    scene = load_scene("cornell-teapot")
    p = preset(quality)

    truth_spp = p.truth_spp if truth_spp is None else truth_spp
    steps = 5 if truth_spp else 4
    log(f"[1/{steps}] solving cornell-teapot ({quality})")
    t = time.perf_counter()
    solution = solve_adaptive(scene, SolveOptions(quality=quality, seed=1), progress=True)  # mesh refined where the light changes
    solution.save(out / "solution.npz")
    times["solve_s"] = time.perf_counter() - t

    options = FitOptions(lights=p.fit_lights, iterations=p.fit_iterations)
    log(f"[2/{steps}] fitting virtual lights ({p.fit_lights} per glossy object; each directional or positional as the "
        f"data require, a coefficient per light)")
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

        log(f"[3/{steps}] path-tracing the truth of view 1 ({truth_spp} samples per pixel)")
        t = time.perf_counter()
        truths = [ground_truth(solution, view, truth_spp, seed=1, progress=True)]
        times["truth_s"] = time.perf_counter() - t

    log(f"[{steps - 1}/{steps}] rendering the paper's figures ({samples} samples per pixel)")
    t = time.perf_counter()
    renderer = Renderer(ctx, fit=model, solution=solution, samples=samples)
    numbers = _compare.compare(renderer, out / "compare", view, truths=truths)
    renderer.release()
    times["compare_s"] = time.perf_counter() - t

    counts = sweep_counts(quality)
    log(f"[{steps}/{steps}] error against the number of lights (K = {', '.join(map(str, counts))}; "
        f"{len(SWEEP_MODELS)} models per glossy object)")
    t = time.perf_counter()
    sweep, baseline = _sweep(solution, model, options, counts)
    _plot_sweep(sweep, baseline, model, out / "error_vs_lights.png")
    times["sweep_s"] = time.perf_counter() - t
    times["total_s"] = sum(times.values())

    sizes = {name: (out / name).stat().st_size for name in ("solution.npz", "fit.npz")}
    objects = {
        o.name: {
            "lights": o.n_lights, "kinds": o.info.get("kinds", []), "coefficients": o.info.get("coefficients"),
            "floats_per_vertex": o.floats_per_vertex, "model": model_words(o), "shininess": o.info["shininess"],
            **o.info["error"], "diffuse_baseline_relative_rms": baseline[o.name],
        }
        for o in model.objects if o.n_lights
    }
    summary = {
        "verdict": "", "scene": "cornell-teapot", "quality": quality, "samples": samples,
        "times_s": {k: round(v, 3) for k, v in times.items()},
        "solver_time_s": solution.stats["time_s"], "mesh": solution.stats.get("adaptive"),
        "fit_settings": model.settings, "objects": objects,
        "sizes_bytes": sizes,
        "error_vs_lights": {
            "counts": list(counts), "preset_counts": list(p.demo_light_sweep), "iterations": options.iterations,
            "models": {key: words for key, words, _, _ in SWEEP_MODELS},
            "relative_rms": sweep,
        },
        "figures": numbers,
        "truth": numbers.get("truth", {}).get("view1"),
        "meaning": {"truth": TRUTH_MEANS,"relative_rms": RMS_MEANS, "flip": FLIP_MEANS,
                    "diffuse_baseline_relative_rms": "the error of the best colour per vertex with no lights (3 floats)",
                    "diffuse_only_relative_rms": "the error of the fit's emitted colour alone (its lights off)"},
    }
    summary["verdict"] = verdict(summary)
    with atomic_output(out / "summary.json") as f:
        f.write(_compare.json_text(summary).encode())
    with atomic_output(out / "report.md") as f:
        f.write(_report(summary).encode())
    return summary


def _sweep(solution, model, options, counts):
    """Relative RMS of every model of ``SWEEP_MODELS`` at every count, per glossy object
    ({object: {model: {K: error}}}), each fit from scratch as ``vlights fit --lights K``
    would; the demo's own fit is the default model's point at its K (not refitted).
    Also the diffuse baseline's error per object (the best colour per vertex, no lights)."""
    from dataclasses import replace

    from fitting.baselines import diffuse_only
    from fitting.data import fit_data, relative_error
    from fitting.fit import fit_lights, problem_for, reconstruct, start_exponent
    from fitting.mixed import SceneGeometry

    scene = SceneGeometry.of_solution(solution)
    sweep, baseline = {}, {}
    for obj in solution.objects:
        if obj.is_diffuse:
            continue
        data = fit_data(obj)
        baseline[obj.name] = relative_error(data, diffuse_only(obj, data).reconstruction)["relative_rms"]
        fitted = model.object(obj.name)
        curves = {}
        for key, _, fields, _ in SWEEP_MODELS:
            sweep_options = replace(options, method="refined", **fields)
            problem = problem_for(data, sweep_options, scene)
            exponent = start_exponent(obj, sweep_options)
            default = all(getattr(options, f) == v for f, v in fields.items())
            curve = {}
            for k in sorted(set(counts) | ({options.lights} if default else set())):
                if default and k == options.lights:  # the demo's own fit
                    curve[str(k)] = fitted.info["error"]["relative_rms"]
                    continue
                result = fit_lights(problem, k, sweep_options, exponent)
                curve[str(k)] = relative_error(data, reconstruct(problem, result))["relative_rms"]
            curves[key] = curve
        sweep[obj.name] = curves
    return sweep, baseline


def _plot_sweep(sweep, baseline, model, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(sweep)
    n = max(len(names), 1)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 5.0), squeeze=False)
    words = {key: (words, marker) for key, words, _, marker in SWEEP_MODELS}
    requested = model.settings.get("lights")
    for ax, name in zip(axes[0], names):
        top = baseline[name]
        for i, (key, curve) in enumerate(sweep[name].items()):
            ks = [int(k) for k in curve]
            ax.plot(ks, list(curve.values()), words[key][1], color=f"C{i}", label=f"{key}: {words[key][0]}")
            top = max([top, *[v for v in curve.values() if v is not None]])
        o = model.object(name)
        k = requested if isinstance(requested, int) else o.n_lights
        kept = "" if k == o.n_lights else f", {o.n_lights} kept"
        ax.plot([k], [o.info["error"]["relative_rms"]], "*", ms=15, color="k", zorder=5,
                label="the demo's fit (the default model)")
        ax.annotate(f"{o.floats_per_vertex} floats / vertex{kept}", (k, o.info["error"]["relative_rms"]), fontsize=7,
                    xytext=(-8, 10), textcoords="offset points", ha="right")
        ax.axhline(baseline[name], ls=":", color="grey", lw=1.5, label="diffuse only: best colour per vertex, no lights")
        ax.set_xscale("log", base=2)
        ks = sorted({int(k) for curve in sweep[name].values() for k in curve} | {k})
        ax.set_xticks(ks, [str(k) for k in ks])
        ax.minorticks_off()
        ax.set_ylim(0, top * 1.08)
        ax.set_xlabel("virtual lights K (log scale)")
        ax.set_ylabel("relative RMS error (lower is better)")
        ax.set_title(name)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=1 if n == 1 else 2, fontsize=8, frameon=False)
    fig.suptitle("fit error against the number of virtual lights, per model", fontsize=11)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    with atomic_output(path) as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)


TRUTH_MEANS = ("the first view path-traced (NEE + BRDF sampling by MIS, a box filter over each pixel) from the "
               "solution's meshes and materials; each display's FLIP and relative MSE against it. noise_flip: FLIP "
               "between the truth's two independent halves, the level below which an error is its noise")


def truth_line(truth):
    """One sentence: each display's FLIP against the path-traced truth, glossy objects in brackets."""
    def flip(mode):
        m = truth[mode]
        glossy = f" ({m['flip_mean_glossy']:.3f})" if "flip_mean_glossy" in m else ""
        return f"{m['flip_mean']:.3f}{glossy}"

    noise = "" if truth["noise_flip"] is None else f"; the truth's own noise floor {truth['noise_flip']:.3f}"
    return (f"Against a path tracer ({truth['spp']} spp), FLIP over the image (glossy objects): reference display "
            f"{flip('reference')}, fitted {flip('fitted')}, diffuse only {flip('diffuse')}{noise}.")


def _fmt(value, digits=2):
    return "n/a" if value is None else f"{value:.{digits}f}"


def verdict(s):
    """The report's first line: what the virtual lights bought, in relative RMS per
    glossy object against the diffuse baseline and in FLIP on the glossy objects with
    the lights on and off (figure 7)."""
    objects = s["objects"]
    if not objects:
        return "No glossy object: the scene has nothing for virtual lights to do."
    parts = [f"of the {name} from {_fmt(o['diffuse_baseline_relative_rms'])}" + (" (diffuse only)" if i == 0 else "")
             + f" to {_fmt(o['relative_rms'])}" for i, (name, o) in enumerate(objects.items())]
    fell = all(o["relative_rms"] is not None and o["diffuse_baseline_relative_rms"] is not None
               and o["relative_rms"] < o["diffuse_baseline_relative_rms"] for o in objects.values())
    cut = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
    line = f"Virtual lights {'cut' if fell else 'took'} the relative RMS error {cut}"
    line = _verdict_lights(s, line)
    return line + (" " + truth_line(s["truth"]) if s.get("truth") else "")


def _verdict_lights(s, line):
    g = s["figures"].get("glossy_flip")
    if not g:
        return line + "."
    ratio = g.get("ratio")
    finite = isinstance(ratio, float) and math.isfinite(ratio)
    off, on = _fmt(g["diffuse_only"], 3), _fmt(g["with_virtual_lights"], 3)
    if finite and ratio <= 0.95:
        return line + f", and FLIP on the glossy objects from {off} (lights off) to {on} ({ratio:.2f}x)."
    return line + (f"; but FLIP on the glossy objects did not fall: {off} with the lights off, {on} with them"
                   + (f" ({ratio:.2f}x)." if finite else "."))


def _mesh_words(mesh):
    """The report's sentence on the solver's mesh (``stats["adaptive"]``)."""
    if not mesh:
        return ""
    if not mesh["enabled"]:
        return f" The solver's mesh: uniform, {mesh['vertices_before']:,} vertices."
    return (f" The solver's mesh: refined where the light changes, {mesh['vertices_before']:,} -> "
            f"{mesh['vertices_after']:,} vertices (budget {mesh['vertex_budget']:,}).")


def _report(s):
    t = s["times_s"]
    sw = s["error_vs_lights"]
    lines = [
        "# virtual-lights demo: cornell-teapot", "",
        f"**{s['verdict']}**", "",
        "## What the numbers mean", "",
        f"- **Relative RMS** ({RMS_MEANS[len('relative RMS: '):]}) *Diffuse only* is the best colour per vertex "
        "with no lights at all (3 floats per vertex); *lights off* is the fit's own emitted colour alone.",
        f"- **FLIP** ({FLIP_MEANS[len('FLIP: '):]}) The error images show it per pixel through the magma colour "
        "map, black 0 to pale yellow 1, with the scale beside each.",
        "- **PSNR** of the tone-mapped pictures: higher is better.", "",
        "The model: per glossy object, " + "; ".join(f"{name}: {o['model']}" for name, o in s["objects"].items())
        + ". Floats per vertex are what the display stores per vertex besides the mesh (emitted colour and "
        "specular coefficients); the lights themselves are a few numbers per object.", "",
        f"Quality `{s['quality']}`; figures with {s['samples']} samples per pixel (antialiasing: their mean, a box "
        f"filter over each pixel). Total {t['total_s']:.1f} s: solve {t['solve_s']:.1f} s, fit {t['fit_s']:.1f} s, "
        + (f"truth {t['truth_s']:.1f} s, " if "truth_s" in t else "")
        + f"figures {t['compare_s']:.1f} s, lights sweep {t['sweep_s']:.1f} s. "
        f"solution.npz {s['sizes_bytes']['solution.npz'] / 1e6:.2f} MB, fit.npz {s['sizes_bytes']['fit.npz'] / 1e6:.2f} MB."
        + _mesh_words(s.get("mesh")), "",
        "## Fit per glossy object", "",
        "| object | lights | kinds | floats / vertex | exponent(s) | relative RMS | worst vertex | diffuse only | lights off |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, o in s["objects"].items():
        exps = ", ".join(f"{p:.4g}" for p in sorted(set(o["shininess"])))
        kinds = ", ".join(f"{o['kinds'].count(k)} {k}" for k in ("positional", "directional") if o["kinds"].count(k))
        lines.append(f"| {name} | {o['lights']} | {kinds} | {o['floats_per_vertex']} | {exps} | {_fmt(o['relative_rms'], 4)} | "
                     f"{_fmt(o['worst_vertex'], 4)} | {_fmt(o['diffuse_baseline_relative_rms'], 4)} | "
                     f"{_fmt(o['diffuse_only_relative_rms'], 4)} |")
    counts = ", ".join(map(str, sw["counts"]))
    preset_counts = sorted(set(sw.get("preset_counts", sw["counts"])))
    thinned = list(sw["counts"]) != preset_counts
    all_counts = sorted({int(k) for curves in sw["relative_rms"].values() for c in curves.values() for k in c})
    lines += ["", "## Error against the number of lights", "",
              f"Swept: K = {counts} for every model"
              + (f" (the `{s['quality']}` preset's light counts are {', '.join(map(str, preset_counts))}; draft refits "
                 "only the two smallest to keep the demo quick: `--quality medium` sweeps them all)" if thinned else "")
              + ", and the demo's own fit for the default model; each fit from scratch, as `vlights fit --lights K` "
              f"would, with {sw['iterations']} refinement iterations. The models:", ""]
    lines += [f"- `{key}`: {words}" for key, words in sw["models"].items()]
    lines += ["", "| object | model | " + " | ".join(f"K = {k}" for k in all_counts) + " |",
              "|---|---|" + "---|" * len(all_counts)]
    for name, curves in sw["relative_rms"].items():
        for key, curve in curves.items():
            lines.append(f"| {name} | {key} | "
                         + " | ".join(_fmt(curve[str(k)], 4) if str(k) in curve else "" for k in all_counts) + " |")
    lines += ["", "![error against lights](error_vs_lights.png)", "",
              "## Figures (reference from the solution; FLIP over the image / the glossy objects)", ""]
    f = s["figures"]
    for i in range(1, 4):
        m = f["figure5"][f"view{i}"]
        lines += [f"**Figure 5, view {i}**: reference, fitted, FLIP error. FLIP {m['flip_mean']:.4f} / {m.get('flip_mean_glossy', float('nan')):.4f}, "
                  f"PSNR {m['psnr_db']:.2f} / {m.get('psnr_db_glossy', float('nan')):.2f} dB", "", f"![figure 5 view {i}](compare/figure5_view{i}.png)", ""]
    lines += ["**Figure 6**: 2 against all lights", "", "![figure 6](compare/figure6.png)", "",
              "**Figure 7**: with and without virtual lights", "", "![figure 7](compare/figure7.png)", ""]
    w, wo = f["figure7"]["with_virtual_lights"], f["figure7"]["diffuse_only"]
    g = f.get("glossy_flip", {})
    ratio = g.get("ratio")
    lines += [f"On the glossy objects: FLIP {w.get('flip_mean_glossy', float('nan')):.4f} with the lights, "
              f"{wo.get('flip_mean_glossy', float('nan')):.4f} without"
              + (f" (ratio {ratio:.2f}; target <= {g['target_ratio']}: {'met' if g['meets_target'] else 'not met'})"
                 if isinstance(ratio, float) and math.isfinite(ratio) else "")
              + f"; PSNR {w.get('psnr_db_glossy', float('nan')):.2f} against {wo.get('psnr_db_glossy', float('nan')):.2f} dB.", ""]
    truth = s.get("truth")
    if truth:
        noise = "n/a" if truth["noise_flip"] is None else f"{truth['noise_flip']:.4f}"
        lines += ["## Against the truth (view 1, path-traced)", "",
                  f"{TRUTH_MEANS[0].upper() + TRUTH_MEANS[1:]}. {truth['spp']} samples per pixel in "
                  f"{t.get('truth_s', float('nan')):.1f} s; noise floor {noise}. Figure 5, view 1 starts with it.", "",
                  "| display | FLIP | relative MSE | FLIP, glossy | relative MSE, glossy |", "|---|---|---|---|---|"]
        for mode in ("reference", "fitted", "diffuse"):
            m = truth[mode]
            lines.append(f"| {mode} | {m['flip_mean']:.4f} | {m['relative_mse']:.4g} | "
                         f"{_fmt(m.get('flip_mean_glossy'), 4)} | {_fmt(m.get('relative_mse_glossy'), 4)} |")
        lines.append("")
    return "\n".join(lines)


def key_numbers(summary, out):
    t = summary["times_s"]
    lines = [summary["verdict"],
             f"done in {t['total_s']:.1f} s; everything is in {out}/:",
             "  solution.npz, fit.npz           the solution and its fitted model",
             "  compare/figure5_view*.png       reference against fitted (the paper's figure 5)",
             "  compare/figure6.png             2 against all lights (figure 6)",
             "  compare/figure7.png             with and without virtual lights (figure 7)",
             "  error_vs_lights.png             fit error against the number of lights, per model",
             "  report.md, summary.json         the verdict, pictures, times and errors",
             f"  web/                            the walkthrough in a browser: vlights serve {out}/web"]
    for name, o in summary["objects"].items():
        lines.append(f"  {name}: {o['model']}; relative RMS {_fmt(o['relative_rms'], 3)} "
                     f"(diffuse only {_fmt(o['diffuse_baseline_relative_rms'], 3)}, lights off {_fmt(o['diffuse_only_relative_rms'], 3)})")
    m = summary["figures"]["figure5"]["view1"]
    lines.append(f"  figure 5, view 1: FLIP {m['flip_mean']:.4f} (glossy objects {m.get('flip_mean_glossy', float('nan')):.4f}), PSNR {m['psnr_db']:.2f} dB")
    if summary.get("truth"):
        lines.append("  " + truth_line(summary["truth"]))
    lines.append("  (relative RMS and FLIP: lower is better, 0 = exact; see report.md)")
    return "\n".join(lines)
