"""The trade that justifies the method, measured: a walkthrough of N frames, three ways,
at equal quality.

Usage:
    python benchmarks/bench_walkthrough.py [--scenes cornell-teapot,interior] [--triangles 100000]
                                           [--size 256x256] [--frames 3] [--truth-spp 4096]
                                           [--tracer-spp N] [--quality draft] [--draws 20] [--cache DIR] [--keep DIR]
                                           [--mitsuba-python PY] [--mitsuba-variant scalar_rgb] [--quick]

Two scenes: the demo (built-in ``cornell-teapot``) and the closed interior of
``bench_scale.py`` (``bench_scale.write_scene``, about ``--triangles`` input triangles).
A camera path through each: the demo's is the path ``vlights video`` flies
(``display.video.walkthrough_path``: a 60-degree swing about the look-at point, in to
55 % of the distance and back); the interior's a walk at eye height (1.6 m) from a
corner of the first room, past its table and through the doorway into the next room,
looking 2 m ahead along the path. ``--frames`` K sample frames are taken along the path
(at (k + 1/2) / K of its length), and on each:

  - the truth: the project's path tracer at ``--truth-spp`` (``display.truth.ground_truth``,
    its noise floor the FLIP between its two halves), cached in ``--cache``;
  - the fitted and the reference display (``display.renderer.Renderer``, one each, as
    ``vlights walk`` would hold it; per pixel, the renderer's 4 samples per pixel): each's
    FLIP (HDR, whole image) against the truth, and its frame time, the median of
    ``--draws`` draws up to glFinish (``bench_display.median_times``: interleaved, the
    renderer reused, drawing only as a walkthrough shows its frames);
  - the path tracer's progress on that frame (``bench_pathtrace.convergence``, another
    seed, up to a quarter of the truth's samples), giving the samples per pixel at which
    it reaches each display's FLIP (``bench_pathtrace.time_to``); that frame is then
    path-traced again at those samples alone and timed: the seconds one path-traced frame
    of the same quality costs. Where the FLIP is not reached, its last pass's samples are
    used and the row says so (the path tracer's cost is then a lower bound);
  - Mitsuba 3, where installed (its own Python, as ``validate_mitsuba.py`` finds it): the
    scene written as Mitsuba XML (the meshes as PLY with their normals, diffuse materials
    as ``diffuse``, a modified-Phong one as a ``blendbsdf`` of ``diffuse`` and a GGX
    ``roughconductor`` whose roughness has the Phong exponent by
    ``radiosity.scene.microfacet``'s rule, emitters as ``area``), each frame rendered
    with the samples our path tracer needed and timed (Mitsuba's noise per sample is no
    lower than ours, ``validate_mitsuba.py``, so its time is a lower bound on its time to
    the same FLIP); its FLIP against our truth is recorded too (it holds the material
    mapping's difference as well as the noise).

The ways, each a fixed cost and a cost per frame (the mean over the sample frames):
  fitted       ``vlights solve`` + ``vlights fit`` (each the command, timed in a process of
               its own, as a user runs them) + the renderer's upload; then a fitted frame;
  reference    ``vlights solve`` + the upload; then a reference frame;
  path tracer  building its scene (Embree); then a frame at the samples matching the fitted
               display's FLIP (and, beside it, the reference display's);
  Mitsuba      loading the XML; then a frame at the same samples.
Totals for N frames: fixed + N x per frame. Reported per scene: the break-even N where
path tracing every frame costs as much as solve + fit + drawing (beyond it the fitted
walkthrough is cheaper), and the ratio of the totals (path tracer / fitted) at N = 1, 100
and 10,000; the same for the reference display against the path tracer at its FLIP.
Numba's compile or cache load is done before any timing (a warm-up solve and fit of the
demo at tiny settings, a tiny path-traced image) and recorded apart.

Results: JSON lines in benchmarks/results/walkthrough.jsonl, the plot
results/walkthrough.png (total seconds against N, log-log, the break-even marked).
``--quick``: 64 x 64, 2 frames, a 256-spp truth, the smallest interior (3 rooms), 3 draws:
a check that everything runs, its rows and plot written beside the truths in ``--cache``
(walkthrough_quick.jsonl, .png), not in results/.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, Recorder

SCENES = ("cornell-teapot", "interior")
FRAME_COUNTS = (1, 100, 10_000)  # N at which the ratios of the totals are reported
PATH_FRAMES = 121  # frames of the demo's walkthrough path the sample frames are picked from
EYE_HEIGHT, LOOK_HEIGHT, LOOK_AHEAD = 1.6, 1.3, 2.0  # the interior's walk (metres)
TRUTH_SEED, TRACER_SEED = 1000, 2000
MITSUBA_SEED = 3000

# -- the arithmetic: a way is {"fixed_s", "per_frame_s"} --------------------------------


def total(way, frames):
    """Seconds of a walkthrough of ``frames`` frames: the fixed cost, then every frame."""
    return way["fixed_s"] + frames * way["per_frame_s"]


def break_even(method, rival):
    """The number of frames N at which ``rival`` (path tracing every frame) costs as much as
    ``method`` (a fixed cost, then cheap frames): beyond it the method is cheaper. 0 if the
    method is never dearer; None if it never becomes cheaper (its frames cost no less)."""
    saved = rival["per_frame_s"] - method["per_frame_s"]
    if saved <= 0:
        return 0.0 if method["fixed_s"] <= rival["fixed_s"] else None
    return max(0.0, (method["fixed_s"] - rival["fixed_s"]) / saved)


def ratios(method, rival, frames=FRAME_COUNTS):
    """{str(N): rival's total / method's total} for each N of ``frames``."""
    return {str(n): total(rival, n) / total(method, n) for n in frames}


def way(fixed_s, per_frame):
    """A way from its fixed seconds and its seconds for each sample frame (their mean)."""
    return {"fixed_s": float(fixed_s), "per_frame_s": float(np.mean(per_frame))}


# -- camera paths -----------------------------------------------------------------------


def demo_views(camera, fractions):
    """The views at ``fractions`` (of 0..1) along the path ``vlights video`` flies."""
    from display.video import walkthrough_path

    path = walkthrough_path(camera, PATH_FRAMES)
    return [path[round(t * (PATH_FRAMES - 1))] for t in fractions]


def walk_keyframes():
    """(x, z) of the interior walk's keyframes: from a corner of room (0, 0), past the
    table's side, through the doorway in the wall at z = ROOM (its middle x = ROOM / 2)
    into room (0, 1), beside that room's table."""
    from bench_scale import ROOM

    door = ROOM / 2
    return np.array([[0.6, 0.6], [door, 0.3 * ROOM], [door, ROOM], [door, 1.55 * ROOM]])


def along(points, s):
    """The point at arc length ``s`` of the polyline ``points`` (n, 2), continued straight
    past either end."""
    steps = np.diff(points, axis=0)
    lengths = np.linalg.norm(steps, axis=1)
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    i = int(np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(steps) - 1))
    return points[i] + steps[i] / lengths[i] * (s - ends[i])


def walk_views(camera, fractions, keyframes):
    """Views at ``fractions`` of the walk through ``keyframes`` ((x, z) of each), at eye
    height, each looking ``LOOK_AHEAD`` further along the path; ``camera`` gives the
    field of view and size."""
    from radiosity.files.camera import Camera

    length = float(np.linalg.norm(np.diff(keyframes, axis=0), axis=1).sum())
    views = []
    for t in fractions:
        eye, ahead = along(keyframes, t * length), along(keyframes, t * length + LOOK_AHEAD)
        views.append(Camera((eye[0], EYE_HEIGHT, eye[1]), (ahead[0], LOOK_HEIGHT, ahead[1]), (0.0, 1.0, 0.0),
                            camera.fov_y_deg, camera.width, camera.height))
    return views


# -- the three ways ---------------------------------------------------------------------


def vlights(args, cwd):
    """``vlights ARGS`` in a process of its own (``bench_scale.run``): its seconds."""
    from bench_scale import run

    return run(args, cwd)[0]


def warm_up(record, work, commands=True):
    """Numba's compile or cache load, before anything is timed: a tiny solve and fit of the
    demo through the commands (unless not ``commands``), a tiny path-traced image."""
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.pathtrace import PathTracer

    t = time.perf_counter()
    if commands:
        vlights(["solve", "cornell-teapot", "--photons", "20000", "--gather-samples", "4", "--max-edge", "300",
                 "--no-adaptive", "-o", "warm.npz"], work)
        vlights(["fit", "warm.npz", "-o", "warm_fit.npz"], work)
    scene = load_scene("cornell-teapot")
    with PathTracer(scene) as tracer:
        tracer.render(scene.camera.sized(8, 8), 1)
    record({"what": "warm-up (numba compile or cache load)", "seconds": time.perf_counter() - t,
            "commands": commands})


def truth_of(scene, view, spp, cache, key):
    """(radiance (H, W, 3), {"noise_flip", "seconds", "cached"}) of ``view``: cached in
    ``cache`` under ``key``, the view's pose and size and ``spp``."""
    from display.truth import ground_truth

    pose = hashlib.sha1(json.dumps([view.to_dict(), view.width, view.height]).encode()).hexdigest()[:10]
    name = Path(cache) / f"{key}_{view.width}x{view.height}_{pose}_{spp}spp"
    npy, meta = name.with_suffix(".npy"), name.with_suffix(".json")
    if npy.exists() and meta.exists():
        return np.load(npy), json.loads(meta.read_text()) | {"cached": True}
    truth = ground_truth(scene, view, spp, seed=TRUTH_SEED, progress=spp >= 1024)
    npy.parent.mkdir(parents=True, exist_ok=True)
    np.save(npy, truth.radiance)
    info = {"noise_flip": truth.noise_flip, "seconds": truth.stats["seconds"]}
    meta.write_text(json.dumps(info))
    return truth.radiance, info | {"cached": False}


def matched_frames(tracer, view, truth, targets, max_spp):
    """The path tracer on ``view`` at each display's FLIP (``targets``: {name: FLIP}):
    {name: {"spp", "seconds", "flip", "reached"}}, each frame rendered again at the
    samples its FLIP needed and timed; and the progress rows (spp, seconds, FLIP, rel. MSE)."""
    from bench_pathtrace import convergence, time_to

    from display.metrics import metrics

    progress = convergence(tracer, view, truth, max_spp, seed=TRACER_SEED)
    rendered, out = {}, {}
    for name, flip in targets.items():
        spp, _ = time_to(progress, flip)
        reached = spp is not None
        spp = spp if reached else progress[-1][0]
        if spp not in rendered:
            t = time.perf_counter()
            image = tracer.render(view, spp, seed=TRACER_SEED)  # the same image as the progress's at spp
            seconds = time.perf_counter() - t
            rendered[spp] = (seconds, metrics(truth, image.radiance)[0]["flip_mean"], image.radiance)
        seconds, achieved, _ = rendered[spp]
        out[name] = {"spp": spp, "seconds": seconds, "flip": achieved, "reached": reached}
    return out, progress, {spp: r[2] for spp, r in rendered.items()}


def display_frames(renderers, view, truth, draws):
    """{mode: {"flip", "frame_s"}} of each (mode, renderer) of ``renderers`` on ``view``,
    and the images: FLIP of ``render`` against ``truth``, the median draw time."""
    from bench_display import median_times

    from display.metrics import metrics

    images = {mode: r.render(view, mode) for mode, r in renderers.items()}
    ctx = next(iter(renderers.values())).ctx
    ms = median_times({mode: (lambda r=r, mode=mode: r.draw(view, mode, "pixel")) for mode, r in renderers.items()},
                      ctx, draws)
    return {mode: {"flip": metrics(truth, images[mode])[0]["flip_mean"], "frame_s": ms[mode] / 1000}
            for mode in renderers}, images


def scene_files(name, args, work):
    """(the argument ``vlights solve`` takes, the Scene, the cache key, input triangles,
    rooms) of ``name``."""
    from bench_scale import write_scene

    from radiosity.scene.loaders import load_scene

    if name == "cornell-teapot":
        scene = load_scene(name)
        return name, scene, name, sum(len(o.faces) for o in scene.objects), None
    path = work / "interior.toml"
    nx, nz = write_scene(path, args.triangles)
    if nz < 2:
        raise SystemExit(f"the interior of {args.triangles} triangles has {nx} x {nz} rooms: the walk needs two along z")
    scene = load_scene(str(path))
    key = "interior_" + hashlib.sha1(path.read_bytes()).hexdigest()[:10]
    return str(path), scene, key, sum(len(o.faces) for o in scene.objects), nx * nz


def measure_scene(record, name, args, work, ctx):
    """Every row of one scene: the fixed costs, each sample frame, the summary."""
    from display.renderer import Renderer
    from fitting import load_fit
    from radiosity.files.solution import load_solution
    from radiosity.transport.pathtrace import PathTracer

    source, scene, key, triangles, rooms = scene_files(name, args, work)
    solve_s = vlights(["solve", source, "--quality", args.quality, "-o", "solution.npz"], work)
    fit_s = vlights(["fit", "solution.npz", "--quality", args.quality, "-o", "fit.npz"], work)
    solution, model = load_solution(work / "solution.npz"), load_fit(work / "fit.npz")
    t = time.perf_counter()
    fitted = Renderer(ctx, fit=model)
    upload_fitted_s = time.perf_counter() - t
    t = time.perf_counter()
    reference = Renderer(ctx, solution=solution)
    upload_reference_s = time.perf_counter() - t
    t = time.perf_counter()
    tracer = PathTracer(scene)
    tracer_setup_s = time.perf_counter() - t
    setup = record({"what": "setup", "scene": name, "triangles": triangles, "rooms": rooms,
                    "vertices": sum(len(o.positions) for o in solution.objects), "solve_s": solve_s, "fit_s": fit_s,
                    "upload_fitted_s": upload_fitted_s, "upload_reference_s": upload_reference_s,
                    "tracer_setup_s": tracer_setup_s, "threads": tracer.threads})

    camera = scene.camera.sized(*args.size)
    fractions = [(k + 0.5) / args.frames for k in range(args.frames)]
    views = demo_views(camera, fractions) if name == "cornell-teapot" else walk_views(camera, fractions, walk_keyframes())
    frames, truths = [], []
    try:
        for k, (t_path, view) in enumerate(zip(fractions, views)):
            truth, info = truth_of(scene, view, args.truth_spp, args.cache, key)
            truths.append(truth)
            displays, images = display_frames({"fitted": fitted, "reference": reference}, view, truth, args.draws)
            matched, progress, traced = matched_frames(tracer, view, truth, {m: d["flip"] for m, d in displays.items()},
                                                       args.tracer_spp or max(1, args.truth_spp // 4))
            frames.append(record({"what": "frame", "scene": name, "frame": k + 1, "path_fraction": t_path,
                                  "eye": list(view.eye), "look_at": list(view.look_at), "truth_spp": args.truth_spp,
                                  "truth_noise_flip": info["noise_flip"], "truth_seconds": info["seconds"],
                                  "truth_cached": info["cached"], **displays, "path_tracer": matched,
                                  "path_tracer_progress": [list(p) for p in progress]}))
            if args.keep:
                keep_pictures(args.keep / f"{name}_frame{k + 1}.png", truth, images, traced)
    finally:
        tracer.close()
        fitted.release()
        reference.release()

    mitsuba = mitsuba_frames(scene, views, frames, truths, args, work)
    if mitsuba is not None:
        for row, m in zip(frames, mitsuba["frames"]):
            record({"what": "mitsuba frame", "scene": name, "frame": row["frame"], "mitsuba": mitsuba["version"],
                    "variant": args.mitsuba_variant, **m})
    record(summary(name, setup, frames, mitsuba))


def summary(name, setup, frames, mitsuba=None):
    """The ways' fixed and per-frame costs, the break-even N and the ratios of the totals."""
    ways = {
        "fitted": way(setup["solve_s"] + setup["fit_s"] + setup["upload_fitted_s"], [f["fitted"]["frame_s"] for f in frames]),
        "reference": way(setup["solve_s"] + setup["upload_reference_s"], [f["reference"]["frame_s"] for f in frames]),
        "path tracer at the fitted FLIP": way(setup["tracer_setup_s"],
                                              [f["path_tracer"]["fitted"]["seconds"] for f in frames]),
        "path tracer at the reference FLIP": way(setup["tracer_setup_s"],
                                                 [f["path_tracer"]["reference"]["seconds"] for f in frames]),
    }
    for w, mode in (("fitted", "fitted"), ("reference", "reference")):
        ways[w]["flip"] = float(np.mean([f[mode]["flip"] for f in frames]))
        tracer = ways[f"path tracer at the {mode} FLIP"]
        tracer["flip"] = float(np.mean([f["path_tracer"][mode]["flip"] for f in frames]))
        tracer["spp"] = [f["path_tracer"][mode]["spp"] for f in frames]
        tracer["reached"] = all(f["path_tracer"][mode]["reached"] for f in frames)
    pairs = {"fitted": ("fitted", "path tracer at the fitted FLIP"),
             "reference": ("reference", "path tracer at the reference FLIP")}
    if mitsuba is not None:
        for mode in ("fitted", "reference"):
            ways[f"Mitsuba at the {mode} FLIP's samples"] = way(mitsuba["load_s"], [m[mode]["seconds"] for m in mitsuba["frames"]])
            ways[f"Mitsuba at the {mode} FLIP's samples"]["flip"] = float(np.mean([m[mode]["flip"] for m in mitsuba["frames"]]))
        pairs |= {"fitted, Mitsuba": ("fitted", "Mitsuba at the fitted FLIP's samples"),
                  "reference, Mitsuba": ("reference", "Mitsuba at the reference FLIP's samples")}
    return {"what": "summary", "scene": name, "frames_sampled": len(frames), "ways": ways,
            "break_even_frames": {k: break_even(ways[a], ways[b]) for k, (a, b) in pairs.items()},
            "ratio_of_totals": {k: ratios(ways[a], ways[b]) for k, (a, b) in pairs.items()}}


# -- Mitsuba 3 --------------------------------------------------------------------------

MITSUBA_RENDER = """
import json, sys, time
import numpy as np
import mitsuba as mi
mi.set_variant(sys.argv[1])
start = time.perf_counter()
scene = mi.load_file(sys.argv[2])
load_s = time.perf_counter() - start
mi.render(scene, sensor=0, spp=1, seed=0)  # first use: allocations, kernels
seconds = []
for sensor, spp, seed, out in json.loads(sys.argv[3]):
    start = time.perf_counter()
    image = np.array(mi.render(scene, sensor=sensor, spp=spp, seed=seed), dtype=np.float32)[..., :3]
    seconds.append(time.perf_counter() - start)
    np.save(out, image)
print(json.dumps({"load_s": load_s, "seconds": seconds}))
"""


def ggx_alpha(exponent):
    """The GGX roughness whose lobe has the modified-Phong ``exponent`` by
    ``radiosity.scene.microfacet``'s rule (its inverse; the broadest it knows for lower)."""
    from scipy.optimize import brentq

    from radiosity.scene.microfacet import phong_exponent

    low, high = 1e-3, 0.7
    if exponent <= phong_exponent("ggx", high):
        return high
    if exponent >= phong_exponent("ggx", low):
        return low
    return float(brentq(lambda a: phong_exponent("ggx", a) - exponent, low, high, xtol=1e-6))


def mitsuba_bsdf(material, ident):
    """Mitsuba XML of ``material`` (kd + modified-Phong ks, n): ``diffuse``, or a
    ``blendbsdf`` of ``diffuse`` (kd / (1 - w)) and a GGX ``roughconductor`` with a
    perfect mirror's Fresnel (ks / w), w the largest ks."""
    kd, ks = np.asarray(material.diffuse), np.asarray(material.specular)

    def rgb(name, value):
        return f'<rgb name="{name}" value="{", ".join(f"{v:.6g}" for v in np.clip(value, 0, 1))}"/>'

    if not ks.any():
        return f'<bsdf type="diffuse" id="{ident}">{rgb("reflectance", kd)}</bsdf>'
    w = float(ks.max())
    return (f'<bsdf type="blendbsdf" id="{ident}"><float name="weight" value="{w:.6g}"/>'
            f'<bsdf type="diffuse">{rgb("reflectance", kd / (1 - w))}</bsdf>'
            f'<bsdf type="roughconductor"><string name="material" value="none"/>'
            f'<string name="distribution" value="ggx"/><float name="alpha" value="{ggx_alpha(material.exponent):.6g}"/>'
            f'{rgb("specular_reflectance", ks / w)}</bsdf></bsdf>')


def mitsuba_scene(scene, views, directory):
    """Write ``scene`` and a sensor per view of ``views`` as ``directory``/scene.xml (the
    meshes as PLY beside it); its path. SystemExit if the scene holds what this does not
    write (textures, an environment, Fresnel)."""
    import trimesh

    from radiosity.transport.pathtrace import MAX_DEPTH, ROULETTE_DEPTH

    if scene.environment is not None or any(o.textured or o.material.fresnel for o in scene.objects):
        raise SystemExit("the Mitsuba export writes untextured, Fresnel-free scenes without an environment")
    lines = ['<scene version="3.0.0">',
             f'<integrator type="path"><integer name="max_depth" value="{MAX_DEPTH}"/>'
             f'<integer name="rr_depth" value="{ROULETTE_DEPTH}"/></integrator>']
    for view in views:
        vec = ", ".join
        lines.append(
            f'<sensor type="perspective"><float name="fov" value="{view.fov_y_deg:.8g}"/>'
            '<string name="fov_axis" value="y"/><transform name="to_world">'
            f'<lookat origin="{vec(f"{v:.8g}" for v in view.eye)}" target="{vec(f"{v:.8g}" for v in view.look_at)}" '
            f'up="{vec(f"{v:.8g}" for v in view.up)}"/></transform>'
            '<sampler type="independent"><integer name="sample_count" value="1"/></sampler>'
            f'<film type="hdrfilm"><integer name="width" value="{view.width}"/>'
            f'<integer name="height" value="{view.height}"/><string name="pixel_format" value="rgb"/>'
            '<rfilter type="box"/></film></sensor>')
    materials = {}
    for o in scene.objects:
        if o.material.name not in materials:
            materials[o.material.name] = f"m{len(materials)}"
            lines.append(mitsuba_bsdf(o.material, materials[o.material.name]))
    for i, o in enumerate(scene.objects):
        ply = directory / f"o{i}.ply"
        mesh = trimesh.Trimesh(o.positions, o.faces, vertex_normals=o.normals, process=False)
        ply.write_bytes(trimesh.exchange.ply.export_ply(mesh, vertex_normal=True))
        emitter = ""
        if any(o.material.emission):
            emitter = ('<emitter type="area"><rgb name="radiance" value="'
                       + ", ".join(f"{v:.6g}" for v in o.material.emission) + '"/></emitter>')
        lines.append(f'<shape type="ply"><string name="filename" value="{ply.name}"/>'
                     f'<ref id="{materials[o.material.name]}"/>{emitter}</shape>')
    path = directory / "scene.xml"
    path.write_text("\n".join(lines + ["</scene>"]) + "\n")
    return path


def mitsuba_frames(scene, views, frames, truths, args, work):
    """Mitsuba's seconds and FLIP (against ``truths``, one per view) per frame at the
    samples our path tracer needed for each display's FLIP: {"version", "load_s",
    "frames": [{mode: {"spp", "seconds", "flip", "mean_ratio"}}]}, or None without Mitsuba."""
    from display.metrics import metrics

    if args.mitsuba_python is None:
        return None
    directory = work / "mitsuba"
    directory.mkdir(exist_ok=True)
    xml = mitsuba_scene(scene, views, directory)
    jobs = [[k, frame["path_tracer"][mode]["spp"], MITSUBA_SEED + k, str(directory / f"frame{k}_{mode}.npy"), mode]
            for k, frame in enumerate(frames) for mode in ("fitted", "reference")]
    run = subprocess.run([args.mitsuba_python, "-c", MITSUBA_RENDER, args.mitsuba_variant, str(xml),
                          json.dumps([job[:4] for job in jobs])], capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"mitsuba failed: {run.stderr.strip().splitlines()[-1:]}")
    out = json.loads(run.stdout.strip().splitlines()[-1])
    per_frame = [{} for _ in frames]
    for (k, spp, _, image_path, mode), seconds in zip(jobs, out["seconds"], strict=True):
        image = np.load(image_path)
        per_frame[k][mode] = {"spp": spp, "seconds": seconds, "flip": metrics(truths[k], image)[0]["flip_mean"],
                              "mean_ratio": float(image.mean() / truths[k].mean())}
    return {"version": args.mitsuba_version, "load_s": out["load_s"], "frames": per_frame}


# -- pictures and the plot --------------------------------------------------------------


def keep_pictures(path, truth, images, traced):
    """truth | fitted | reference | the path tracer at each matched spp, tone-mapped, in a row."""
    import imageio.v3 as iio

    from display.renderer import tonemap

    row = [truth, images["fitted"], images["reference"], *(traced[s] for s in sorted(traced))]
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.concatenate([np.pad(tonemap(p), ((2, 2), (2, 2), (0, 0))) for p in row], axis=1))


STYLES = {"fitted": ("tab:blue", "-"), "reference": ("tab:green", "-"),
          "path tracer at the fitted FLIP": ("tab:blue", "--"), "path tracer at the reference FLIP": ("tab:green", "--"),
          "Mitsuba at the fitted FLIP's samples": ("tab:blue", ":"), "Mitsuba at the reference FLIP's samples": ("tab:green", ":")}


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summaries = [r for r in rows if r.get("what") == "summary"]
    if not summaries:
        return
    n = np.geomspace(1, 1e5, 200)
    fig, axes = plt.subplots(1, len(summaries), figsize=(6.5 * len(summaries), 5), squeeze=False)
    for ax, s in zip(axes[0], summaries):
        for name, w in s["ways"].items():
            colour, style = STYLES[name]
            bound = ", not reached: a lower bound" if w.get("reached") is False else ""
            ax.loglog(n, [total(w, x) for x in n], color=colour, ls=style,
                      label=f"{name} (FLIP {w['flip']:.3f}{bound})")
        for pair, colour in (("fitted", "tab:blue"), ("reference", "tab:green")):
            at = s["break_even_frames"][pair]
            if at is not None and at >= 1:
                w = s["ways"][pair]
                ax.plot([at], [total(w, at)], "o", color=colour, mfc="none", ms=10)
                ax.axvline(at, color=colour, lw=0.6, ls=":")
                above = pair == "fitted"
                ax.annotate(f"{pair}: break-even {at:,.0f} frames", (at, total(w, at)), textcoords="offset points",
                            xytext=(-10, 12) if above else (10, -16), ha="right" if above else "left", fontsize=8,
                            color=colour)
        ax.set_xlabel("frames of the walkthrough N")
        ax.set_ylabel("total seconds")
        ax.set_title(f"{s['scene']}: {s['frames_sampled']} sample frames", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("a walkthrough of N frames: solve + fit once then draw, against path tracing every frame at the "
                 "same FLIP", fontsize=10)
    fig.tight_layout()
    RESULTS.mkdir(exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def size_of(text):
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes WIDTHxHEIGHT, got {text!r}") from None
    return width, height


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", default=",".join(SCENES), help="comma-separated, of %(default)s")
    parser.add_argument("--triangles", type=int, default=100_000, help="the interior's input triangles, about")
    parser.add_argument("--size", type=size_of, default=(256, 256), help="image size WxH (default 256x256)")
    parser.add_argument("--frames", type=int, default=3, help="sample frames along each path (default 3)")
    parser.add_argument("--truth-spp", type=int, default=4096, help="samples per pixel of the truth (default 4096)")
    parser.add_argument("--tracer-spp", type=int, help="the path tracer's progress goes up to these samples per pixel "
                        "(default: a quarter of --truth-spp)")
    parser.add_argument("--quality", default="draft", choices=("draft", "medium", "high"))
    parser.add_argument("--draws", type=int, default=20, help="draws per frame time, their median (default 20)")
    parser.add_argument("--cache", type=Path, default=Path("/tmp/vlights-bench-walkthrough"), help="the truths")
    parser.add_argument("--keep", type=Path, help="keep the solutions, fits and each frame's pictures here")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba (validate_mitsuba.py's default)")
    parser.add_argument("--mitsuba-variant", default="scalar_rgb")
    parser.add_argument("--quick", action="store_true", help="a check that it runs: tiny images, few samples")
    args = parser.parse_args(argv)
    scenes = args.scenes.split(",")
    if set(scenes) - set(SCENES):
        parser.error(f"--scenes: of {', '.join(SCENES)}")
    if args.quick:
        args.size, args.frames, args.truth_spp, args.draws, args.triangles = (64, 64), 2, 256, 3, 10_000
    from _common import mitsuba_python

    from display.gl import headless_context

    args.mitsuba_python, args.mitsuba_version = mitsuba_python(args.mitsuba_python)
    record = Recorder(benchmark="walkthrough", quality=args.quality, size=list(args.size),
                      truth_spp=args.truth_spp, sample_frames=args.frames, quick=args.quick)
    if args.mitsuba_python is None:
        record({"what": "mitsuba", "skipped": "mitsuba is not installed (see validate_mitsuba.py)"})
    with tempfile.TemporaryDirectory() as tmp:
        ctx = headless_context()
        try:
            for name in scenes:
                work = (args.keep or Path(tmp)) / name
                work.mkdir(parents=True, exist_ok=True)
                if name == scenes[0]:
                    warm_up(record, work, commands=not args.quick)
                measure_scene(record, name, args, work, ctx)
        finally:
            ctx.release()
    if args.quick:  # a check, not a result: beside the truths, not in results/
        args.cache.mkdir(parents=True, exist_ok=True)
        saved = args.cache / "walkthrough_quick.jsonl"
        saved.write_text("".join(json.dumps(row) + "\n" for row in record.rows))
        plot(record.rows, args.cache / "walkthrough_quick.png")
    else:
        record.save("walkthrough.jsonl")
        saved = RESULTS / "walkthrough.jsonl"
        plot(record.rows, RESULTS / "walkthrough.png")
    for s in (r for r in record.rows if r["what"] == "summary"):
        print(f"{s['scene']}: break-even {s['break_even_frames']}; path tracer / fitted at N = 1, 100, 10000: "
              + ", ".join(f"{v:.3g}" for v in s["ratio_of_totals"]["fitted"].values()), flush=True)
    print(json.dumps({"saved": str(saved)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
