"""``vlights demo``: the whole pipeline on the built-in ``cornell-teapot`` scene.

Writes into ``out``: solution.npz, fit.npz, the comparison figures (compare/), an
error-against-lights plot, report.md (the pictures and a table of times and errors)
and summary.json (times per phase, errors per object, sizes). The files appear
together at the end: a failure or Ctrl-C on the way leaves none of them.
"""

from __future__ import annotations

import time
from pathlib import Path

from radiosity.formats.atomic import atomic_output

from . import compare as _compare
from .outputs import staged_directory

FILES = ("solution.npz", "fit.npz", "summary.json", "report.md", "error_vs_lights.png") + tuple(
    f"compare/{name}" for name in _compare.FILES
)


def run_demo(out, quality="draft", size=(512, 512), log=print):
    """Run the pipeline into ``out`` (created if missing, not its parents); returns the summary.

    Everything is written into a hidden directory inside ``out`` and moved into place
    when all of it is done (``display.outputs.staged_directory``). The OpenGL context
    is made first, so a machine without one is told so before the solve.
    """
    out = Path(out)
    ctx = _context(size)
    try:
        with staged_directory(out) as stage:
            return _run(stage, ctx, quality, size, log)
    finally:
        ctx.release()


def _context(size):
    """The headless context, after checking the figures' size against its limits and memory."""
    from .gl import COMPARE_BYTES_PER_PIXEL, check_image_memory, check_image_size, headless_context

    ctx = headless_context()
    try:
        check_image_size(ctx, *size)
        check_image_memory(*size, COMPARE_BYTES_PER_PIXEL)
    except BaseException:
        ctx.release()
        raise
    return ctx


def _run(out, ctx, quality, size, log):
    from fitting import FitOptions, fit
    from fitting.data import fit_data, relative_error
    from fitting.fit import fit_lights, reconstruct
    from radiosity.formats.presets import preset
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    from .renderer import Renderer

    times = {}
    scene = load_scene("cornell-teapot")

    log(f"[1/4] solving cornell-teapot ({quality})")
    t = time.perf_counter()
    solution = solve(scene, SolveOptions(quality=quality, seed=1), progress=True)
    solution.save(out / "solution.npz")
    times["solve_s"] = time.perf_counter() - t

    log("[2/4] fitting virtual lights (8 per glossy object, refined)")
    t = time.perf_counter()
    model = fit(solution, FitOptions(lights=preset(quality).fit_lights, method="refined", iterations=preset(quality).fit_iterations), progress=True)
    model.save(out / "fit.npz")
    times["fit_s"] = time.perf_counter() - t

    log("[3/4] rendering the paper's figures")
    t = time.perf_counter()
    renderer = Renderer(ctx, fit=model, solution=solution)
    numbers = _compare.compare(renderer, out / "compare", scene.camera.sized(*size))
    renderer.release()
    times["compare_s"] = time.perf_counter() - t

    log("[4/4] error against the number of lights")
    t = time.perf_counter()
    sweep = {}
    for obj in solution.objects:
        if obj.is_diffuse:
            continue
        data = fit_data(obj)
        paper_options = FitOptions(lights=1, method="paper")
        sweep[obj.name] = {
            str(k): relative_error(data, reconstruct(data, fit_lights(data, k, paper_options)))["relative_rms"]
            for k in preset(quality).demo_light_sweep
        }
    _plot_sweep(sweep, model, out / "error_vs_lights.png")
    times["sweep_s"] = time.perf_counter() - t
    times["total_s"] = sum(times.values())

    sizes = {name: (out / name).stat().st_size for name in ("solution.npz", "fit.npz")}
    objects = {
        o.name: {"lights": o.n_lights, "shininess": o.info["shininess"], **o.info["error"]}
        for o in model.objects if o.n_lights
    }
    summary = {
        "scene": "cornell-teapot", "quality": quality, "times_s": {k: round(v, 3) for k, v in times.items()},
        "solver_time_s": solution.stats["time_s"], "objects": objects, "sizes_bytes": sizes,
        "paper_error_vs_lights": sweep, "figures": numbers,
    }
    with atomic_output(out / "summary.json") as f:
        f.write(_compare.json_text(summary).encode())
    with atomic_output(out / "report.md") as f:
        f.write(_report(summary).encode())
    return summary


def _plot_sweep(sweep, model, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for name, errors in sweep.items():
        ks = [int(k) for k in errors]
        line, = ax.plot(ks, list(errors.values()), "o-", label=f"{name}, paper's method")
        o = model.object(name)
        ax.plot([o.n_lights], [o.info["error"]["relative_rms"]], "*", ms=14, color=line.get_color(),
                label=f"{name}, refined (K={o.n_lights})")
        ax.axhline(o.info["error"]["diffuse_only_relative_rms"], ls=":", color=line.get_color(), lw=1)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("virtual lights K")
    ax.set_ylabel("relative RMS error (dotted: emitted colour alone)")
    ax.set_title("fit error against the number of virtual lights")
    ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_output(path) as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)


def _report(s):
    t = s["times_s"]
    lines = [
        "# virtual-lights demo: cornell-teapot", "",
        f"Quality `{s['quality']}`. Total {t['total_s']:.1f} s: solve {t['solve_s']:.1f} s, fit {t['fit_s']:.1f} s, "
        f"figures {t['compare_s']:.1f} s, lights sweep {t['sweep_s']:.1f} s. "
        f"solution.npz {s['sizes_bytes']['solution.npz'] / 1e6:.2f} MB, fit.npz {s['sizes_bytes']['fit.npz'] / 1e6:.2f} MB.", "",
        "## Fit per glossy object", "",
        "| object | lights | exponent(s) | relative RMS | worst vertex | emitted colour alone |", "|---|---|---|---|---|---|",
    ]
    for name, o in s["objects"].items():
        exps = ", ".join(f"{p:.4g}" for p in sorted(set(o["shininess"])))
        lines.append(f"| {name} | {o['lights']} | {exps} | {o['relative_rms']:.4f} | {o['worst_vertex']:.4f} | {o['diffuse_only_relative_rms']:.4f} |")
    lines += ["", "![error against lights](error_vs_lights.png)", "", "## Figures (reference from the solution; FLIP over the image / the glossy objects)", ""]
    f = s["figures"]
    for i in range(1, 4):
        m = f["figure5"][f"view{i}"]
        lines += [f"**Figure 5, view {i}**: reference, fitted, FLIP error. FLIP {m['flip_mean']:.4f} / {m.get('flip_mean_glossy', float('nan')):.4f}, "
                  f"PSNR {m['psnr_db']:.2f} / {m.get('psnr_db_glossy', float('nan')):.2f} dB", "", f"![figure 5 view {i}](compare/figure5_view{i}.png)", ""]
    lines += ["**Figure 6**: 2 against all lights", "", "![figure 6](compare/figure6.png)", "",
              "**Figure 7**: with and without virtual lights", "", "![figure 7](compare/figure7.png)", ""]
    w, wo = f["figure7"]["with_virtual_lights"], f["figure7"]["diffuse_only"]
    lines += [f"On the glossy objects: FLIP {w.get('flip_mean_glossy', float('nan')):.4f} with the lights, "
              f"{wo.get('flip_mean_glossy', float('nan')):.4f} without; PSNR {w.get('psnr_db_glossy', float('nan')):.2f} against "
              f"{wo.get('psnr_db_glossy', float('nan')):.2f} dB.", ""]
    return "\n".join(lines)


def key_numbers(summary, out):
    t = summary["times_s"]
    lines = [f"done in {t['total_s']:.1f} s; everything is in {out}/:",
             "  solution.npz, fit.npz           the solution and its fitted model",
             "  compare/figure5_view*.png       reference against fitted (the paper's figure 5)",
             "  compare/figure6.png             2 against 8 lights (figure 6)",
             "  compare/figure7.png             with and without virtual lights (figure 7)",
             "  error_vs_lights.png             fit error against the number of lights",
             "  report.md, summary.json         the pictures, times and errors"]
    for name, o in summary["objects"].items():
        lines.append(f"  {name}: {o['lights']} lights, relative RMS {o['relative_rms']:.3f} (emitted alone {o['diffuse_only_relative_rms']:.3f})")
    m = summary["figures"]["figure5"]["view1"]
    lines.append(f"  figure 5, view 1: FLIP {m['flip_mean']:.4f} (glossy objects {m.get('flip_mean_glossy', float('nan')):.4f}), PSNR {m['psnr_db']:.2f} dB")
    return "\n".join(lines)
