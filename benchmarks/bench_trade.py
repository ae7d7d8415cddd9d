"""What does more time buy? Every solver knob against error, time and size.

Usage:
    python benchmarks/bench_trade.py [--quick]

On cornell-teapot, fixed seeds, 2 cores:
  1. photons against error and time: radiance of every vertex (all objects, all
     directions) against a 16x-photon reference on the same mesh; the log-log slope
     of error against photons (Monte Carlo: -0.5);
  2. gather samples against the glossy objects' error (against 4096 gather rays),
     time and file size;
  3. the direction grid of the glossy objects: error of the stored radiance read
     bilinearly at a 32 x 32 reference grid's directions, against that reference;
     time and file size;
  4. scaling: triangles from about 1e3 to 1e6 (mesh refinement): solve time, peak
     memory (a fresh process each), fit time (paper's method, K = 8);
  5. the three presets: solve time and error against a high-quality reference
     (32 M photons, 4096 gather rays);
  6. the trade end to end, against the truth: a path-traced image of the scene's view
     (``--truth-spp``, its noise floor measured as FLIP between its two halves); per
     preset, solve + fit time against FLIP (HDR) and relative MSE of the walkthrough's
     reference, fitted and diffuse-only displays against it (whole image and glossy
     objects), on the mesh refined where the light changes (``solve_adaptive``) and,
     for the reference display, on the uniform mesh too (vertices of both recorded);
     and the path tracer's own progress (another seed) against the same
     truth, giving the samples and seconds it needs to reach each display's FLIP: how
     many path-traced seconds one walkthrough frame is worth.
Results: JSON lines in benchmarks/results/trade.jsonl, plots in results/trade.png and
results/trade_truth.png. ``--only truth`` runs question 6 alone (trade_truth.jsonl).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from _common import RESULTS, Recorder


def radiance_error(a, b, names=None):
    """Relative RMS difference of two solutions' radiance over the chosen objects."""
    num = den = 0.0
    for x, y in zip(a.objects, b.objects):
        if names is not None and x.name not in names:
            continue
        num += float(np.sum((x.radiance.astype(np.float64) - y.radiance) ** 2))
        den += float(np.sum(y.radiance.astype(np.float64) ** 2))
    return float(np.sqrt(num / den))


def grid_error(test, reference, names):
    """Stored radiance read bilinearly at the reference grid's directions, against it."""
    from radiosity.physics import directions

    num = den = 0.0
    for x, y in zip(test.objects, reference.objects):
        if x.name not in names:
            continue
        idx, weight = directions.grid_lookup_weights(y.directions.astype(np.float64), x.grid_n)
        values = np.einsum("dk,vdkc->vdc", weight, x.radiance[:, idx].astype(np.float64))
        num += float(np.sum((values - y.radiance) ** 2))
        den += float(np.sum(y.radiance.astype(np.float64) ** 2))
    return float(np.sqrt(num / den))


def timed_solve(scene, adaptive=False, **kw):
    """A solve and its seconds; ``adaptive``: through ``solve_adaptive`` with the preset's
    refinement driven by the light (else the uniform mesh alone)."""
    from radiosity.transport.adaptive import AdaptiveOptions, solve_adaptive
    from radiosity.transport.solve import SolveOptions, solve

    opts = SolveOptions(seed=kw.pop("seed", 1), **kw)
    t = time.perf_counter()
    if adaptive:
        solution = solve_adaptive(scene, opts, AdaptiveOptions(enabled=True))
    else:
        solution = solve(scene, opts)
    return solution, time.perf_counter() - t


def file_size(solution):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.npz"
        solution.save(path)
        return path.stat().st_size


def scaling_run(max_edge):
    code = (
        "open('/proc/self/clear_refs', 'w').write('5')\n"
        "import json, time\n"
        "from radiosity.scene.loaders import load_scene\n"
        "from radiosity.transport.solve import solve, SolveOptions\n"
        "from fitting import fit, FitOptions\n"
        "scene = load_scene('cornell-teapot')\n"
        "t = time.perf_counter()\n"
        f"sol = solve(scene, SolveOptions(max_edge={max_edge}, photons=2_000_000, gather_samples=64, light_samples=16))\n"
        "t_solve = time.perf_counter() - t\n"
        "t = time.perf_counter()\n"
        "fit(sol, FitOptions(lights=8, method='paper'))\n"
        "t_fit = time.perf_counter() - t\n"
        "hwm = int(open('/proc/self/status').read().split('VmHWM:')[1].split()[0]) / 1024\n"
        "print(json.dumps({'triangles': sol.stats['triangles'], 'vertices': sol.stats['vertices'], 'solve_s': t_solve, 'fit_s': t_fit, 'peak_rss_mb': hwm}))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", choices=("truth",), help="run question 6 alone")
    parser.add_argument("--size", type=int, default=256, help="question 6: image side (default: %(default)s)")
    parser.add_argument("--truth-spp", type=int, default=4096, help="question 6: samples of the truth (default: %(default)s)")
    parser.add_argument("--truth-file", type=Path, metavar="NPY",
                        help="question 6: a truth already path-traced at the scene's camera and --size (vlights truth "
                        "cornell-teapot --size NxN --spp S --hdr NPY); --truth-spp then says its samples")
    parser.add_argument("--truth-noise", type=float, metavar="FLIP",
                        help="with --truth-file: its noise floor as 'vlights truth' printed it")
    args = parser.parse_args(argv)
    from radiosity.scene.loaders import load_scene

    if args.only == "truth":
        record = Recorder(question="truth")
        truth_trade(record, args)
        record.save("trade_truth.jsonl")
        plot_truth(record.rows, RESULTS / "trade_truth.png")
        return 0

    record = Recorder()
    rows = record.rows

    scene = load_scene("cornell-teapot")
    glossy = ["teapot", "tall_block"]
    edge = 40.0
    timed_solve(scene, photons=1000, gather_samples=4, light_samples=1, max_edge=200.0)  # compile

    # 1 photons
    counts = [125_000, 500_000, 2_000_000] if args.quick else [125_000, 250_000, 500_000, 1_000_000, 2_000_000, 4_000_000]
    base = dict(max_edge=edge, gather_samples=16, light_samples=4, grid=8)
    reference, _ = timed_solve(scene, photons=16 * counts[-1], seed=99, **base)
    errors = []
    for n in counts:
        sol, seconds = timed_solve(scene, photons=n, **base)
        errors.append(radiance_error(sol, reference, names=[o.name for o in sol.objects if o.name not in glossy + ["light"]]))
        record({"question": "photons", "photons": n, "relative_rms": errors[-1], "seconds": seconds, "photon_phase_s": sol.stats["time_s"]["photons"]})
    slope = float(np.polyfit(np.log(counts), np.log(errors), 1)[0])
    record({"question": "photons slope", "log_log_slope": slope, "monte_carlo_is": -0.5})

    # 2 gather samples
    samples = [16, 64, 256] if args.quick else [16, 64, 256, 1024]
    gbase = dict(max_edge=edge, photons=2_000_000, grid=12, light_samples=32)
    reference, _ = timed_solve(scene, gather_samples=4096, seed=98, **gbase)
    for g in samples:
        sol, seconds = timed_solve(scene, gather_samples=g, **gbase)
        record({"question": "gather samples", "gather_samples": g, "relative_rms": radiance_error(sol, reference, glossy),
                "seconds": seconds, "gather_phase_s": sol.stats["time_s"]["gather"], "file_mb": file_size(sol) / 1e6})

    # 3 grid size
    grids = [8, 17, 24] if args.quick else [6, 8, 12, 17, 24]
    rbase = dict(max_edge=edge, photons=2_000_000, gather_samples=256, light_samples=32)
    reference, _ = timed_solve(scene, grid=32, **rbase)
    for n in grids:
        sol, seconds = timed_solve(scene, grid=n, **rbase)
        record({"question": "grid", "grid": n, "relative_rms": grid_error(sol, reference, glossy), "seconds": seconds,
                "gather_phase_s": sol.stats["time_s"]["gather"], "file_mb": file_size(sol) / 1e6})

    # 4 scaling with triangles
    edges = [300.0, 60.0, 15.0] if args.quick else [600.0, 150.0, 40.0, 12.0, 4.0, 2.0]
    for e in edges:
        record({"question": "scaling", "max_edge": e} | scaling_run(e))

    # 5 presets
    reference, _ = timed_solve(scene, quality="high", photons=32_000_000, gather_samples=4096, seed=97)
    for quality in ("draft", "medium", "high"):
        sol, seconds = timed_solve(scene, quality=quality)
        # presets refine differently: compare on the reference's mesh by re-solving is not
        # possible, so error is measured per object on the diffuse part's mean and the glossy
        # objects' direction-averaged radiance, area-weighted over vertices
        record({"question": "presets", "quality": quality, "seconds": seconds, "vertices": sol.stats["vertices"],
                "file_mb": file_size(sol) / 1e6, "relative_error_of_object_means": preset_error(sol, reference)})

    # 6 the trade against the truth
    truth_trade(record, args)

    record.save("trade.jsonl")
    plot(rows, RESULTS / "trade.png")
    plot_truth(rows, RESULTS / "trade_truth.png")
    return 0


def truth_trade(record, args):
    """Question 6: presets end to end against a path-traced truth (see the module text)."""
    from bench_pathtrace import convergence, time_to

    from display.gl import headless_context
    from display.metrics import metrics
    from display.renderer import Renderer
    from display.truth import ground_truth
    from fitting import FitOptions, fit
    from radiosity.policies import presets
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.pathtrace import PathTracer

    size, truth_spp = (96, 256) if args.quick else (args.size, args.truth_spp)
    scene = load_scene("cornell-teapot")
    camera = scene.camera.sized(size, size)
    if args.truth_file is not None:
        radiance = np.load(args.truth_file)
        if radiance.shape != (size, size, 3):
            raise SystemExit(f"--truth-file {args.truth_file}: {radiance.shape}, not ({size}, {size}, 3) (--size)")
        truth = SimpleNamespace(radiance=radiance, noise_flip=args.truth_noise, stats={"seconds": None, "paths_per_s": None})
    else:
        truth = ground_truth(scene, camera, truth_spp, seed=1000, progress=True)
    record({"question": "truth", "what": "truth", "size": size, "spp": truth_spp, "seconds": truth.stats["seconds"],
            "paths_per_s": truth.stats["paths_per_s"], "noise_flip": truth.noise_flip,
            "file": str(args.truth_file) if args.truth_file else None})

    # the path tracer against the same truth, pass by pass (another seed)
    with PathTracer(scene) as tracer:
        progress = convergence(tracer, camera, truth.radiance, max(1, truth_spp // 4), seed=2000)
    for spp, seconds, flip, relative_mse in progress:
        record({"question": "truth", "what": "path tracer", "spp": spp, "seconds": seconds,
                "flip": flip, "relative_mse": relative_mse})

    ctx = headless_context()
    try:
        for quality, adaptive in [(q, a) for q in (("draft",) if args.quick else presets.QUALITIES) for a in (False, True)]:
            # with and without the refinement driven by the light: the uniform
            # mesh's reference display alone, the refined one's every display
            knobs = presets.preset(quality)
            solution, solve_s = timed_solve(scene, adaptive=adaptive, quality=quality)
            t = time.perf_counter()
            model = fit(solution, FitOptions(lights=knobs.fit_lights, iterations=knobs.fit_iterations)) if adaptive else None
            fit_s = time.perf_counter() - t
            renderer = Renderer(ctx, fit=model, solution=solution)
            glossy = [o.name for o in solution.objects if not o.is_diffuse]
            mask = renderer.object_mask(camera, glossy)
            refinement = solution.stats.get("adaptive", {})
            for mode in ("reference", "fitted", "diffuse") if adaptive else ("reference",):
                t = time.perf_counter()
                image = renderer.render(camera, mode)
                frame_s = time.perf_counter() - t
                numbers = metrics(truth.radiance, image, mask=mask)[0]
                flip = numbers["flip_mean"]
                reached = time_to(progress, flip)
                record({"question": "truth", "what": "walkthrough", "quality": quality, "mode": mode,
                        "adaptive": adaptive, "vertices": solution.stats["vertices"],
                        "vertices_uniform": refinement.get("vertices_before", solution.stats["vertices"]),
                        "solve_s": solve_s, "fit_s": fit_s, "frame_s": frame_s, "samples": renderer.plan.samples,
                        "flip": flip, "relative_mse": numbers["relative_mse"],
                        "flip_glossy": numbers.get("flip_mean_glossy"),
                        "relative_mse_glossy": numbers.get("relative_mse_glossy"),
                        "path_tracer_spp_to_match": reached[0], "path_tracer_seconds_to_match": reached[1]})
            renderer.release()
    finally:
        ctx.release()


def plot_truth(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tracer = [r for r in rows if r.get("what") == "path tracer"]
    walk = [r for r in rows if r.get("what") == "walkthrough"]
    truth = next((r for r in rows if r.get("what") == "truth"), None)
    if not tracer or truth is None:
        return
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.loglog([r["seconds"] for r in tracer], [r["flip"] for r in tracer], "k.-", label="path tracer (progressive)")
    markers = {"reference": "o", "fitted": "s", "diffuse": "^"}
    colours = {"draft": "tab:blue", "medium": "tab:orange", "high": "tab:red"}
    for r in walk:
        uniform = not r.get("adaptive", True)
        ax.loglog(r["solve_s"] + r["fit_s"], r["flip"], markers[r["mode"]], color=colours[r["quality"]],
                  mfc="none" if uniform else None,
                  label=f"{r['quality']} {r['mode']} ({'uniform mesh, ' if uniform else ''}solve + fit)")
    if truth["noise_flip"] is not None:
        ax.axhline(truth["noise_flip"], color="grey", ls=":", label="truth's noise floor (FLIP of its halves)")
    ax.set_xlabel("seconds (path tracer: to this image; walkthrough: solve + fit, then frames are free)")
    ax.set_ylabel(f"FLIP against the truth ({truth['spp']} spp)")
    ax.set_title(f"cornell-teapot {truth['size']}x{truth['size']}: what time buys")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def preset_error(test, reference):
    """Meshes differ between presets: compare each object's mean outgoing radiance per
    direction (area-weighted over vertices), RMS over objects, directions and channels."""
    from fitting.data import vertex_areas
    from radiosity.physics import directions

    num = den = 0.0
    for x, y in zip(test.objects, reference.objects):
        ax, ay = vertex_areas(x.positions, x.faces), vertex_areas(y.positions, y.faces)
        if x.is_diffuse:
            mx = (ax[:, None, None] * x.radiance).sum(axis=0) / ax.sum()
            my = (ay[:, None, None] * y.radiance).sum(axis=0) / ay.sum()
        else:
            idx, weight = directions.grid_lookup_weights(y.directions.astype(np.float64), x.grid_n)
            values = np.einsum("dk,vdkc->vdc", weight, x.radiance[:, idx].astype(np.float64))
            mx = (ax[:, None, None] * values).sum(axis=0) / ax.sum()
            my = (ay[:, None, None] * y.radiance).sum(axis=0) / ay.sum()
        num += float(np.sum((mx - my) ** 2))
        den += float(np.sum(my**2))
    return float(np.sqrt(num / den))


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(15, 8))
    p = [r for r in rows if r["question"] == "photons"]
    ax = axes[0, 0]
    ax.loglog([r["photons"] for r in p], [r["relative_rms"] for r in p], "o-")
    slope = next(r["log_log_slope"] for r in rows if r["question"] == "photons slope")
    ax.set_title(f"photons: error (slope {slope:.2f}; MC -0.5)")
    ax.set_xlabel("photons")
    ax.set_ylabel("relative RMS vs 16x reference")
    ax2 = ax.twinx()
    ax2.loglog([r["photons"] for r in p], [r["seconds"] for r in p], "s--", color="tab:red")
    ax2.set_ylabel("solve time (s)", color="tab:red")
    g = [r for r in rows if r["question"] == "gather samples"]
    ax = axes[0, 1]
    ax.loglog([r["gather_samples"] for r in g], [r["relative_rms"] for r in g], "o-")
    ax.set_title("gather rays per vertex: glossy error")
    ax.set_xlabel("gather rays")
    ax.set_ylabel("relative RMS vs 4096")
    ax2 = ax.twinx()
    ax2.loglog([r["gather_samples"] for r in g], [r["seconds"] for r in g], "s--", color="tab:red")
    ax2.set_ylabel("solve time (s)", color="tab:red")
    d = [r for r in rows if r["question"] == "grid"]
    ax = axes[0, 2]
    ax.plot([r["grid"] for r in d], [r["relative_rms"] for r in d], "o-")
    ax.set_title("direction grid n x n: error vs 32 x 32")
    ax.set_xlabel("n")
    ax.set_ylabel("relative RMS")
    ax2 = ax.twinx()
    ax2.plot([r["grid"] for r in d], [r["file_mb"] for r in d], "s--", color="tab:green")
    ax2.set_ylabel("solution.npz (MB)", color="tab:green")
    s = [r for r in rows if r["question"] == "scaling"]
    ax = axes[1, 0]
    ax.loglog([r["triangles"] for r in s], [r["solve_s"] for r in s], "o-", label="solve")
    ax.loglog([r["triangles"] for r in s], [r["fit_s"] for r in s], "s-", label="fit (paper, K=8)")
    ax.set_xlabel("triangles")
    ax.set_ylabel("seconds")
    ax.set_title("scaling: time")
    ax.legend()
    ax = axes[1, 1]
    ax.semilogx([r["triangles"] for r in s], [r["peak_rss_mb"] for r in s], "o-")
    ax.set_xlabel("triangles")
    ax.set_ylabel("peak RSS (MB)")
    ax.set_title("scaling: memory")
    q = [r for r in rows if r["question"] == "presets"]
    ax = axes[1, 2]
    ax.bar([r["quality"] for r in q], [r["seconds"] for r in q])
    for i, r in enumerate(q):
        ax.annotate(f"err {r['relative_error_of_object_means']:.3f}", (i, r["seconds"]), ha="center", va="bottom")
    ax.set_ylabel("solve time (s)")
    ax.set_title("presets: time (error of object means vs high reference)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    sys.exit(main())
