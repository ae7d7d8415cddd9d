"""Do glossy objects in the fitted walkthrough look like the truth?

Usage:
    python benchmarks/bench_glossy.py [--parts look,highlights,time,variants] [--truth-spp 1024]
                                      [--quality draft] [--cache DIR] [--quick]

Parts (each a question; results as JSON lines in benchmarks/results/glossy.jsonl, a plot
in results/glossy.png, the pictures in results/glossy_*.png):
  look        per scene (cornell-teapot, plates) and view (the scene's camera and two
              orbits of it), FLIP and relative MSE on the glossy objects' pixels of the
              reference, fitted and diffuse displays against a path-traced truth
              (``--truth-spp``, cached in ``--cache``); with each glossy object's relative
              RMS, model and floats, the files' sizes. Targets: fitted FLIP <= 0.5 x the
              diffuse walkthrough's and <= 1.4 x the reference display's (teapot scene),
              fitted and reference <= 0.5 x diffuse (plates); relative RMS teapot <= 0.12,
              satin block <= 0.03; the fit file <= a tenth of the solution.
  highlights  plates: where each lamp's highlight falls on each plate (the mirror image of
              the camera through the plate's plane, joined to the lamp), the peak luminance
              there in the truth, the reference and the fitted display, the diffuse
              walkthrough; a highlight is present where the display's peak reaches half the
              truth's.
  time        the fit of each whole scene (median of 3, one core count), the fitted
              display's frame at 1280 x 720 against the diffuse walkthrough's (median of
              20 frames, interleaved, drawing only; Mesa llvmpipe here). Target: <= 20 s
              at draft; fitted frame <= 1.5 x diffuse.
  variants    the alternatives measured on the teapot scene, each fitted and drawn per pixel
              (the probe's model evaluated on the solution's grid and drawn by the
              reference display where no display draws it): the probe without the lobe's
              albedo S, probe sizes, the relative loss, the occluders the box does not know
              (a probe whose look-up is corrected by the real geometry's distance per
              texel; four probes, one per cluster of vertices).

Equivalence check: the fitted display is also compared with the reference display
(the model against its own data): the same picture up to what the model leaves.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from _common import RESULTS, Recorder

SCENES = {"cornell-teapot": (256, 256), "plates": (320, 180)}
ORBIT_DEG = {"cornell-teapot": 35.0, "plates": 20.0}
TARGETS = {"fitted_vs_diffuse": 0.5, "fitted_vs_reference": 1.4, "teapot_rms": 0.12, "block_rms": 0.03,
           "fit_draft_s": 20.0, "fit_high_s": 120.0, "frame_ratio": 1.5, "size_ratio": 0.1}


def views_of(name, camera, size):
    from display.compare import orbit

    base = replace(camera, width=size[0], height=size[1])
    return [base, orbit(base, ORBIT_DEG[name]), orbit(base, -ORBIT_DEG[name])]


def truth_of(solution, view, spp, cache, key):
    from display.truth import ground_truth

    path = Path(cache) / f"{key}_{spp}spp.npy"
    if path.exists():
        return np.load(path)
    image = ground_truth(solution, view, spp, seed=5).radiance
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, image)
    return image


def solve_and_fit(name, quality, cache):
    """(solution, fit, fit seconds), cached by scene and quality."""
    from fitting import FitOptions, fit, load_fit
    from radiosity.files.solution import load_solution
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.adaptive import solve_adaptive
    from radiosity.transport.solve import SolveOptions

    sol_path = Path(cache) / f"{name}_{quality}_solution.npz"
    fit_path = Path(cache) / f"{name}_{quality}_fit.npz"
    if sol_path.exists():
        solution = load_solution(sol_path)
    else:
        solution = solve_adaptive(load_scene(name), SolveOptions(quality=quality, seed=5))
        sol_path.parent.mkdir(parents=True, exist_ok=True)
        solution.save(sol_path)
    t = time.perf_counter()
    model = fit(solution, FitOptions.for_quality(quality))
    seconds = time.perf_counter() - t
    model.save(fit_path)
    return solution, load_fit(fit_path), seconds, sol_path, fit_path


def look(record, args, pictures):
    from display.gl import headless_context
    from display.metrics import metrics
    from display.renderer import Renderer

    ctx = headless_context()
    for name, size in SCENES.items():
        solution, model, fit_s, sol_path, fit_path = solve_and_fit(name, args.quality, args.cache)
        sizes = {"solution_mb": sol_path.stat().st_size / 1e6, "fit_mb": fit_path.stat().st_size / 1e6}
        record({"question": "files", "scene": name, **sizes, "ratio": sizes["fit_mb"] / sizes["solution_mb"],
                "target": TARGETS["size_ratio"]})
        for o in model.objects:
            if o.info.get("model") in (None, "diffuse") and not o.n_lights:
                continue
            record({"question": "fit error", "scene": name, "object": o.name, "model": o.info.get("model"),
                    "floats_per_vertex": o.floats_per_vertex, "lights": o.n_lights,
                    "probe": o.probe.size if o.probe is not None else 0, **o.info["error"]})
        r = Renderer(ctx, fit=model, solution=solution, samples=4)
        glossy = [o.name for o in r.objects if o.glossy]
        for i, view in enumerate(views_of(name, solution.camera, size)):
            truth = truth_of(solution, view, args.truth_spp, args.cache, f"{name}_{args.quality}_view{i + 1}")
            mask = r.object_mask(view, glossy)
            row = {"question": "look", "scene": name, "view": i + 1, "truth_spp": args.truth_spp,
                   "glossy_pixels": int(mask.sum())}
            images = {mode: r.render(view, mode) for mode in ("reference", "fitted", "diffuse")}
            for mode, image in images.items():
                m, _ = metrics(truth, image, mask=mask)
                row[mode] = {"flip_glossy": m["flip_mean_glossy"], "flip": m["flip_mean"],
                             "relative_mse_glossy": m["relative_mse_glossy"]}
            same, _ = metrics(images["reference"], images["fitted"], mask=mask)
            row["fitted_vs_reference_display"] = same["flip_mean_glossy"]
            row["ratio_fitted_diffuse"] = row["fitted"]["flip_glossy"] / row["diffuse"]["flip_glossy"]
            row["ratio_fitted_reference"] = row["fitted"]["flip_glossy"] / row["reference"]["flip_glossy"]
            row["ratio_reference_diffuse"] = row["reference"]["flip_glossy"] / row["diffuse"]["flip_glossy"]
            record(row)
            pictures[(name, i + 1)] = (truth, images)
        r.release()
    ctx.release()


def project(view, point):
    """(row, col) of a world point in ``view``'s image, or None behind the camera or outside."""
    near, far = 1e-3, 1e3
    clip = view.projection_matrix(near, far) @ view.view_matrix() @ np.append(point, 1.0)
    if clip[3] <= 0:
        return None
    ndc = clip[:3] / clip[3]
    col, row = (ndc[0] + 1) / 2 * view.width, (1 - ndc[1]) / 2 * view.height
    if not (0 <= row < view.height and 0 <= col < view.width):
        return None
    return int(row), int(col)


def highlight_points(solution, scene, view):
    """[(plate, lamp, (row, col))] where each lamp's highlight is seen on each plate (mirror geometry)."""
    out = []
    eye = np.asarray(view.eye, float)
    for plate in (o for o in solution.objects if o.name.startswith("plate")):
        p = plate.positions.astype(float)
        c = p.mean(axis=0)
        n = plate.normals.astype(float).mean(axis=0)
        n /= np.linalg.norm(n)
        image_eye = eye - 2 * ((eye - c) @ n) * n
        for lamp in (o for o in scene.objects if o.name.startswith("lamp")):
            centre = lamp.positions.mean(axis=0)
            d = centre - image_eye
            t = ((c - image_eye) @ n) / (d @ n)
            s = image_eye + t * d
            local = s - c
            # inside the plate's rectangle (its extent along its own axes)
            span = p - c
            if (np.abs(local @ span.T) > (span**2).sum(axis=1)).all():
                continue
            rc = project(view, s)
            if rc is not None:
                out.append((plate.name, lamp.name, rc))
    return out


def highlights(record, args, pictures):
    from radiosity.scene.loaders import load_scene

    name = "plates"
    solution, _, _, _, _ = solve_and_fit(name, args.quality, args.cache)
    scene = load_scene(name)
    lum = np.array([0.2126, 0.7152, 0.0722])
    if (name, 1) not in pictures:
        raise SystemExit("the highlights part needs the look part's pictures (run them together)")
    truth, images = pictures[(name, 1)]
    view = views_of(name, solution.camera, SCENES[name])[0]
    present = {mode: 0 for mode in images}
    points = highlight_points(solution, scene, view)
    for plate, lamp, (row, col) in points:
        def peak(image):
            y0, y1 = max(0, row - 3), min(image.shape[0], row + 4)
            x0, x1 = max(0, col - 3), min(image.shape[1], col + 4)
            return float((image[y0:y1, x0:x1] @ lum).max())

        t = peak(truth)
        entry = {"question": "highlight", "plate": plate, "lamp": lamp, "pixel": [int(row), int(col)], "truth": t}
        for mode, image in images.items():
            entry[mode] = peak(image)
            present[mode] += entry[mode] >= 0.5 * t
        record(entry)
    record({"question": "highlights present", "scene": name, "highlights": len(points), **present})


def frame_times(renderer, view, frames, keys):
    """Median ms per frame of each (mode, shading) of ``keys``, one sample per pixel
    (``bench_display.median_times``: interleaved, drawing only, up to glFinish)."""
    from bench_display import median_times

    draws = {k: (lambda k=k: renderer.draw(view, k[0], k[1], samples=1)) for k in keys}
    return median_times(draws, renderer.ctx, frames)


def timing(record, args):
    from display.gl import headless_context
    from display.renderer import Renderer

    ctx = headless_context()
    for name in SCENES:
        fits = []
        for _ in range(1 if args.quick else 3):
            solution, model, seconds, _, _ = solve_and_fit(name, args.quality, args.cache)
            fits.append(seconds)
        record({"question": "fit time", "scene": name, "quality": args.quality, "fit_s": float(np.median(fits)),
                "runs": fits, "cores": os.cpu_count(), "target": TARGETS["fit_draft_s"] if args.quality == "draft"
                else TARGETS["fit_high_s"]})
        r = Renderer(ctx, fit=model, solution=solution, samples=1)
        view = replace(solution.camera, width=1280, height=720)
        keys = [("fitted", "pixel"), ("diffuse", "pixel"), ("fitted", "gouraud"), ("reference", "pixel")]
        ms = frame_times(r, view, 5 if args.quick else 20, keys)
        record({"question": "frame time", "scene": name, "width": 1280, "height": 720,
                **{f"{m}_{s}_ms": v for (m, s), v in ms.items()},
                "ratio_fitted_diffuse": ms[("fitted", "pixel")] / ms[("diffuse", "pixel")],
                "target": TARGETS["frame_ratio"]})
        r.release()
    ctx.release()


def variants(record, args):
    """The alternatives, on the teapot scene's first view, each against the truth."""
    sys.path.insert(0, str(Path(__file__).parent))
    from _probe_variants import run_variants

    name = "cornell-teapot"
    solution, _, _, _, _ = solve_and_fit(name, args.quality, args.cache)
    view = views_of(name, solution.camera, SCENES[name])[0]
    truth = truth_of(solution, view, args.truth_spp, args.cache, f"{name}_{args.quality}_view1")
    for row in run_variants(solution, view, truth):
        record({"question": "variant", "scene": name, **row})


def save_pictures(pictures):
    import imageio.v3 as iio

    from display.metrics import metrics
    from display.renderer import tonemap

    for (name, view), (truth, images) in pictures.items():
        row = [tonemap(truth)] + [tonemap(images[m]) for m in ("reference", "fitted", "diffuse")]
        errors = [metrics(truth, images[m])[1] for m in ("reference", "fitted", "diffuse")]
        top = np.concatenate([np.pad(p, ((2, 2), (2, 2), (0, 0))) for p in row], axis=1)
        bottom = np.concatenate([np.pad(np.zeros_like(row[0]), ((2, 2), (2, 2), (0, 0)))]
                                + [np.pad(e, ((2, 2), (2, 2), (0, 0))) for e in errors], axis=1)
        iio.imwrite(RESULTS / f"glossy_{name}_view{view}.png", np.concatenate([top, bottom], axis=0))


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    looks = [r for r in rows if r["question"] == "look"]
    if not looks:
        return
    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [f"{r['scene']}\nview {r['view']}" for r in looks]
    x = np.arange(len(looks))
    for j, mode in enumerate(("reference", "fitted", "diffuse")):
        ax.bar(x + (j - 1) * 0.27, [r[mode]["flip_glossy"] for r in looks], 0.27, label=mode)
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_ylabel("FLIP on the glossy objects against the truth (lower is better)")
    ax.legend()
    ax.set_title("the displays against a path-traced truth")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="look,highlights,time,variants")
    parser.add_argument("--truth-spp", type=int, default=1024)
    parser.add_argument("--quality", default="draft")
    parser.add_argument("--cache", default="/tmp/vlights-bench-glossy")
    parser.add_argument("--quick", action="store_true", help="64 spp truths, fewer repeats")
    args = parser.parse_args(argv)
    if args.quick:
        args.truth_spp = min(args.truth_spp, 64)
    parts = args.parts.split(",")
    record = Recorder(benchmark="glossy", quality=args.quality)
    pictures = {}
    if "look" in parts or "highlights" in parts:
        look(record, args, pictures)
        save_pictures(pictures)
    if "highlights" in parts:
        highlights(record, args, pictures)
    if "time" in parts:
        timing(record, args)
    if "variants" in parts:
        variants(record, args)
    name = "glossy.jsonl" if args.quality == "draft" else f"glossy_{args.quality}.jsonl"
    record.save(name)
    plot(record.rows, RESULTS / "glossy.png")
    print(json.dumps({"saved": str(RESULTS / name)}))


if __name__ == "__main__":
    main()
