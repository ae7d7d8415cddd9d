"""What does each display mode cost per frame, and how much smaller is the fitted model?

Usage:
    python benchmarks/bench_display.py [--frames 20] [--quick]

Headless (EGL; on machines without a GPU, Mesa llvmpipe on the CPU), at 1280 x 720:
  1. frame time (median over frames, drawing only: glFinish, no read-back; one sample
     per pixel) per mode
     (fitted, diffuse, reference) and shading (gouraud, pixel), for the demo scene
     (cornell-teapot, draft solve, K = 8 fit) and for a scene of about 1 M triangles
     (the teapot tessellated at 128 segments per patch side, 8 synthetic lights, a
     synthetic 6 x 6 direction grid for the reference mode); and for each scene the
     fitted model turned into fit.npz version 2's other kind (``variant``: the K = 8
     lights as point lights, one coefficient per light and vertex, (V, 8, 3)), whose
     coefficients the shaders read from a texture by vertex id;
  2. bytes each mode needs on the GPU;
  3. the targets: fitted Gouraud within 1.5x the frame time of diffuse-only; the fitted
     model at least 10x smaller than the solution (files and arrays);
  4. what antialiasing costs: the demo scene's frame time (drawing and averaging the
     samples) at 1 sample per pixel, the default 4 (4x MSAA) and 16 (2 x 2 supersampling
     of 4x MSAA), fitted per-pixel and Gouraud.

Results: JSON lines in benchmarks/results/display.jsonl, a plot in results/display.png.
Equivalence checks: rendering twice gives the same image; against 64 samples per pixel
(nearest to the box filter) the error falls with the samples, and the antialiased
images' means agree with it within 1 % (one sample's edges are off by up to a pixel).
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, Recorder

CONFIGURATIONS = [(m, s) for m in ("fitted", "diffuse", "reference") for s in ("gouraud", "pixel")]
STANDARD = "directional, shared"  # the paper's model: distant lights, one coefficient per vertex
VARIANT = "point, per light"      # version 2's other end: point lights, a coefficient per light
VARIANT_CONFIGURATIONS = [("fitted", "gouraud"), ("fitted", "pixel")]
AA_SAMPLES = (1, 4, 16)  # one sample (the pixel centre), the default (4x MSAA), supersampled
AA_CONFIGURATIONS = [("fitted", "pixel"), ("fitted", "gouraud")]


def median_times(draws, ctx, frames):
    """Median ms per frame of each of ``draws`` ({key: a function drawing one frame}),
    up to glFinish, after one call each (compile, allocate), interleaved frame by frame
    so that drift in the machine's speed hits them all alike."""
    for draw in draws.values():
        draw()
        ctx.finish()
    times = {key: [] for key in draws}
    for _ in range(frames):
        for key, draw in draws.items():
            t = time.perf_counter()
            draw()
            ctx.finish()
            times[key].append(time.perf_counter() - t)
    return {key: float(np.median(t)) * 1000 for key, t in times.items()}


def frame_times(renderers, view, frames):
    """Median ms per frame of every (lights, mode, shading) of ``renderers`` (a dict of
    lights kind -> (renderer, configurations)), one sample per pixel."""
    draws = {(kind, mode, shading): functools.partial(r.draw, view, mode, shading, samples=1)
             for kind, (r, configurations) in renderers.items() for mode, shading in configurations}
    return median_times(draws, next(iter(renderers.values()))[0].ctx, frames)


def antialiasing_times(renderer, view, frames):
    """Median ms per frame of every (samples, mode, shading) of AA_SAMPLES and
    AA_CONFIGURATIONS: drawing, and averaging the samples into the image."""
    draws = {(n, mode, shading): functools.partial(renderer.draw, view, mode, shading, samples=n)
             for n in AA_SAMPLES for mode, shading in AA_CONFIGURATIONS}
    return median_times(draws, renderer.ctx, frames)


def mode_bytes(fit, solution, mode):
    """GPU bytes a mode needs: vertex attributes and indices (+ light tables and
    per-light coefficients, + radiance)."""
    objects = (fit or solution).objects
    total = 0
    for o in objects:
        v, f = len(o.positions), len(o.faces)
        per_light = mode == "fitted" and o.per_light and o.n_lights > 0
        attributes = {"fitted": 3 if per_light else 4, "diffuse": 2, "reference": 3}[mode]  # vec3 each
        total += v * attributes * 12 + f * 12
        if mode == "fitted":
            total += max(o.n_lights, 1) * 32 + (v * o.n_lights * 12 if per_light else 0)
    if mode == "reference":
        total += sum(o.radiance.size * 4 for o in solution.objects)
    return int(total)


def point_light_variant(model, rng):
    """``model`` with every glossy object's lights made point lights (each on its light's
    direction, two bounding radii from the object's centre) and its coefficient split
    into one per light (the shared one times a random factor in [0.5, 1.5])."""
    from fitting import FittedModel, FittedObject

    objects = []
    for o in model.objects:
        if not o.n_lights:
            objects.append(o)
            continue
        p = np.asarray(o.positions, np.float64)
        centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
        radius = 0.5 * np.linalg.norm(p.max(axis=0) - p.min(axis=0))
        light_pos = np.asarray(o.light_pos, np.float64).copy()
        directional = light_pos[:, 3] == 0
        light_pos[directional, :3] = centre + 2 * radius * light_pos[directional, :3]
        light_pos[:, 3] = 1.0
        shared = o.specular if not o.per_light else o.specular.mean(axis=1)
        specular = shared[:, None, :] * rng.uniform(0.5, 1.5, (len(p), o.n_lights, 1))
        objects.append(FittedObject(name=o.name, positions=o.positions, normals=o.normals, faces=o.faces,
                                    emitted=o.emitted, specular=specular.astype(np.float32),
                                    light_pos=light_pos.astype(np.float32), light_rgb=o.light_rgb,
                                    shininess=o.shininess, info=o.info))
    return FittedModel(objects=tuple(objects), source=model.source, model=model.model, settings=model.settings,
                       camera=model.camera)


def big_scene(rng):
    """About 1 M triangles: the teapot at 128 segments per patch side."""
    from fitting import FittedModel, FittedObject
    from fitting.model import directional
    from radiosity.files.solution import ObjectSolution, Solution
    from radiosity.physics import directions
    from radiosity.scene import geometry, teapot

    positions, faces = teapot.tessellate(128)
    positions, faces, normals = geometry.crease_normals(positions, faces, 40.0)
    tangents = geometry.tangents(normals)
    v = len(positions)
    dirs = rng.normal(size=(8, 3))
    dirs[:, 1] = np.abs(dirs[:, 1])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    fit = FittedModel(objects=(FittedObject(
        name="teapot", positions=positions.astype(np.float32), normals=normals.astype(np.float32), faces=faces.astype(np.int32),
        emitted=rng.uniform(0, 0.2, (v, 3)).astype(np.float32), specular=rng.uniform(0, 1, (v, 3)).astype(np.float32),
        light_pos=directional(dirs).astype(np.float32), light_rgb=rng.uniform(0.5, 2, (8, 3)).astype(np.float32),
        shininess=np.full(8, 120.0, np.float32)),), source="")
    grid = 6
    solution = Solution(objects=(ObjectSolution(
        name="teapot", positions=positions.astype(np.float32), normals=normals.astype(np.float32),
        tangents=tangents.astype(np.float32), faces=faces.astype(np.int32),
        directions=directions.grid_directions(grid).astype(np.float32),
        radiance=rng.uniform(0, 1, (v, grid * grid, 3)).astype(np.float32),
        material={"diffuse": [0.1] * 3, "specular": [0.5] * 3, "exponent": 120.0, "emission": [0.0] * 3}),), settings={}, stats={}, scene="")
    return fit, solution


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)

    from display.camera import framing_view
    from display.gl import headless_context
    from display.renderer import Renderer
    from fitting import FitOptions, fit
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    ctx = headless_context()
    record = Recorder(gl_renderer=ctx.info["GL_RENDERER"], gl_max_samples=ctx.max_samples)
    print(f"{os.cpu_count()} cores; {ctx.info['GL_RENDERER']}, MSAA up to {ctx.max_samples}", flush=True)
    rows = record.rows
    width, height = (640, 360) if args.quick else (1280, 720)
    frames = 3 if args.quick else args.frames

    scene = load_scene("cornell-teapot")
    solution = solve(scene, SolveOptions(quality="draft", seed=1))
    model = fit(solution, FitOptions(lights=8, method="paper"))
    with tempfile.TemporaryDirectory() as tmp:
        solution.save(Path(tmp) / "s.npz")
        model.save(Path(tmp) / "f.npz")
        sizes = {"solution_file": (Path(tmp) / "s.npz").stat().st_size, "fit_file": (Path(tmp) / "f.npz").stat().st_size}
    sizes["solution_arrays"] = sum(sum(a.nbytes for a in (o.positions, o.normals, o.tangents, o.faces, o.directions, o.radiance)) for o in solution.objects)
    sizes["fit_arrays"] = sum(sum(a.nbytes for a in o.arrays().values()) for o in model.objects)
    record({"question": "model size", **sizes, "file_ratio": sizes["solution_file"] / sizes["fit_file"],
            "array_ratio": sizes["solution_arrays"] / sizes["fit_arrays"], "target_ratio": 10})

    scenes = [("cornell-teapot", model, solution, scene.camera.sized(width, height))]
    if not args.quick:
        big_fit, big_solution = big_scene(np.random.default_rng(0))
        lo = big_fit.objects[0].positions.min(axis=0)
        hi = big_fit.objects[0].positions.max(axis=0)
        scenes.append(("teapot 1M triangles", big_fit, big_solution, framing_view(lo, hi, width, height)))
    for name, f, s, view in scenes:
        variant = point_light_variant(f, np.random.default_rng(1))
        renderer = Renderer(ctx, fit=f, solution=s)
        variant_renderer = Renderer(ctx, fit=variant)
        triangles = sum(len(o.faces) for o in f.objects)
        results = frame_times({STANDARD: (renderer, CONFIGURATIONS), VARIANT: (variant_renderer, VARIANT_CONFIGURATIONS)},
                              view, frames)
        for (kind, mode, shading), ms in results.items():
            fit_of = f if kind == STANDARD else variant
            record({"question": "frame time", "scene": name, "triangles": triangles, "lights": kind, "mode": mode,
                    "shading": shading, "width": width, "height": height, "frame_ms": ms,
                    "bytes": mode_bytes(fit_of, s, mode)})
        a = renderer.render(view, "fitted", "pixel")
        b = renderer.render(view, "fitted", "pixel")
        c = variant_renderer.render(view, "fitted", "pixel")
        d = variant_renderer.render(view, "fitted", "pixel")
        diffuse = results[(STANDARD, "diffuse", "gouraud")]
        record({"question": "targets", "scene": name,
                "fitted_gouraud_over_diffuse": results[(STANDARD, "fitted", "gouraud")] / diffuse,
                "variant_gouraud_over_diffuse": results[(VARIANT, "fitted", "gouraud")] / diffuse,
                "target": 1.5, "same_image_twice": bool(np.array_equal(a, b) and np.array_equal(c, d))})
        if name == "cornell-teapot":
            antialiasing(record, renderer, view, frames)
        renderer.release()
        variant_renderer.release()

    record.save("display.jsonl")
    plot(rows, RESULTS / "display.png")
    return 0


def antialiasing(record, renderer, view, frames):
    """Question 4: the frame time at each of AA_SAMPLES; the equivalence check."""
    from display.gl import sample_plan

    results = antialiasing_times(renderer, view, frames)
    for (n, mode, shading), ms in results.items():
        plan = sample_plan(n, renderer.ctx.max_samples)
        record({"question": "antialiasing", "scene": "cornell-teapot", "samples": n, "msaa": plan.msaa,
                "supersampling": plan.factor, "samples_per_pixel": plan.per_pixel, "mode": mode, "shading": shading,
                "width": view.width, "height": view.height, "frame_ms": ms,
                "over_one_sample": ms / results[(1, mode, shading)]})
    # the check: against 64 samples (nearest to the box filter), the error falls with the samples,
    # and the antialiased images' means agree with it (one sample's edges are off by up to a pixel)
    best = renderer.render(view, "fitted", "pixel", samples=64).astype(np.float64)
    for n in AA_SAMPLES:
        image = renderer.render(view, "fitted", "pixel", samples=n)
        record({"question": "antialiasing check", "samples": n, "against_samples": 64,
                "mean_abs_difference": float(np.abs(image - best).mean()), "mean_ratio": float(image.mean() / best.mean()),
                "mean_within_1_percent": bool(abs(image.mean() / best.mean() - 1) < 0.01)})
    line = ", ".join(f"{shading} {n}: {results[(n, mode, shading)]:.1f} ms" for mode, shading in AA_CONFIGURATIONS
                     for n in AA_SAMPLES)
    print(f"antialiasing, cornell-teapot {view.width}x{view.height}, fitted, {os.cpu_count()} cores: {line}", flush=True)


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows if r["question"] == "frame time"))
    aa = [r for r in rows if r["question"] == "antialiasing"]
    fig, axes = plt.subplots(1, len(scenes) + bool(aa), figsize=(7.5 * len(scenes) + 4 * bool(aa), 4), squeeze=False)
    colours = {"fitted": "tab:orange", "diffuse": "tab:green", "reference": "tab:blue"}
    for ax, scene in zip(axes[0], scenes):
        sel = [r for r in rows if r["question"] == "frame time" and r["scene"] == scene]
        variant = [r.get("lights", STANDARD) == VARIANT for r in sel]
        suffix = " (point,\nper light)"
        labels = [f"{r['mode']}{suffix if v else ''}\n{r['shading']}" for r, v in zip(sel, variant)]
        ax.bar(labels, [r["frame_ms"] for r in sel], color=[colours[r["mode"]] for r in sel],
               edgecolor=["black" if v else "none" for v in variant])
        ax.tick_params(axis="x", labelsize=7)
        ax.set_ylabel("frame time (ms)")
        ax.set_title(f"{scene} ({sel[0]['triangles']:,} triangles), {sel[0]['width']}x{sel[0]['height']}")
    if aa:
        ax = axes[0, -1]
        ax.bar([f"{r['shading']}\n{r['samples']} spp" for r in aa], [r["frame_ms"] for r in aa],
               color=["tab:orange" if r["shading"] == "pixel" else "tab:red" for r in aa])
        ax.tick_params(axis="x", labelsize=7)
        ax.set_ylabel("frame time (ms)")
        ax.set_title(f"antialiasing, fitted, {aa[0]['width']}x{aa[0]['height']}")
    fig.suptitle(rows[0].get("gl_renderer", ""), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    sys.exit(main())
