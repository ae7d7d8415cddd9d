"""The field's interiors, each from its own XML, unchanged: every step a user types,
timed, and every display against the scene's published render.

The scenes are Bitterli's rendering resources and Mitsuba's Cornell boxes, as the public
repository jgarciapueyo/mitsuba2-transient-scenes holds them: Mitsuba XML with the
converged renders published beside them (Tungsten's for the interiors). They are not
part of this repository: check that one out and give its folder with --root (default:
$VLIGHTS_SCENES, else /work/scenes).

For each complete scene (``COMPLETE``): ``vlights scene-info``, ``solve``, ``fit``,
``render``, ``export`` and ``compare --reference <published render> --truth-spp N`` at
--quality (at the render's size shrunk by a whole factor to --max-side, default 640),
each the command a user types in a process of its own, timed, its peak memory
read (the kernel's maxrss and the process tree's summed Pss, sampled every 0.1 s). A step
that fails is recorded with its exit status and last line, and the scene's later steps
are skipped. From compare.json: the FLIP and mean ratio (display / image) against the
published render of the solution display, the fitted display, the diffuse walkthrough
and the path tracer at N samples per pixel. The pictures side by side, tone-mapped alike:
results/interiors_<scene>.png (published render, path tracer, solution, fitted, diffuse;
the FLIP error images below). A scene whose copy has no converged render (cbox-spheres,
whose EXR the copy lacks; cbox-point-light, published without one; cbox, whose
aov_scene.exr was rendered at 4 samples per pixel) is measured against
Mitsuba 3's render of the same XML (``--mitsuba-spp``; Mitsuba in a venv of its own, as
``validate_mitsuba.py`` finds it), which its row says; without Mitsuba it is skipped.

For the scenes whose copy lacks files (``INCOMPLETE``): ``scene-info``'s refusal (its one
line must name the missing file), and ``scene-info`` of a copy of the XML with every
element naming a missing file left out (a shape, an emitter or a texture), written beside
the original (its paths are relative to it) and removed after.

    python benchmarks/bench_interiors.py [--scenes cbox,veach_mi,...] [--merge] [--quality draft] [--truth-spp 128]
                                         [--root DIR] [--keep DIR] [--mitsuba-python PY]
    python benchmarks/bench_interiors.py --plot-only

Writes results/interiors.jsonl (interiors_<quality>.jsonl at another quality): a row per
scene and step (seconds, MB, exit status), a row per complete scene with every display's
numbers, a row per incomplete scene; the side-by-side pictures; and interiors.png, each
display's FLIP per scene beside the path tracer's, with the target (fitted <= 1.2 x the
path tracer's) drawn.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder, git_commit, mitsuba_python, mitsuba_render, run_vlights  # noqa: E402

# name -> (the scene's XML, its published render or None: Mitsuba 3 renders one)
COMPLETE = {
    "cbox": ("cbox/scene.xml", None),  # its aov_scene.exr is a 4-spp render (max depth 5): noise, not a reference
    "cbox-spheres": ("cbox-spheres/scene.xml", None),  # the copy lacks its _scene.exr
    "cbox-point-light": ("cbox-point-light/scene.xml", None),
    "veach_mi": ("veach_mi/scene.xml", "veach_mi/mi.exr"),
    "staircase2": ("staircase2/scene.xml", "staircase2/TungstenRender.exr"),
    "living-room": ("living-room/scene.xml", "living-room/TungstenRender.exr"),
    "staircase": ("staircase/scene.xml", "staircase/TungstenRender.exr"),
}
INCOMPLETE = ("bathroom", "bathroom2", "kitchen", "dining-room")
STEPS = ("scene-info", "solve", "fit", "render", "export", "compare")
DISPLAYS = ("solution", "fitted", "diffuse", "path_tracer")
MEMORY_LIMIT_MB = 8 * 1024  # every step within 8 GB
TARGET = 1.2  # the fitted display's FLIP at most this times the path tracer's
TIMEOUT_S = 4 * 3600  # a step running longer is stopped and recorded as such
MITSUBA2_ONLY = {"high_quality_edges"}  # the film's Mitsuba 2 option: Mitsuba 3 refuses a property it does not read
LIBLLVM = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"  # Debian's libllvm19, for Mitsuba's llvm_* variants


def scenes_root(given):
    root = Path(given or os.environ.get("VLIGHTS_SCENES") or "/work/scenes")
    if not (root / "veach_mi" / "scene.xml").is_file():
        raise SystemExit(f"{root}: not a checkout of jgarciapueyo/mitsuba2-transient-scenes (no veach_mi/scene.xml);"
                         " give its folder with --root or $VLIGHTS_SCENES")
    return root


def displays_of(compare_json):
    """{display: {"flip", "mean_ratio", ...}} against the reference image, from compare.json
    (the solution display was called "reference" there before it had its own name)."""
    found = compare_json["reference_image"]["displays"]
    named = {"reference": "solution"}
    return {named.get(k, k): {"flip": v["flip_mean"], "mean_ratio": v["mean_ratio"],
                              **({"flip_glossy": v["flip_mean_glossy"]} if "flip_mean_glossy" in v else {}),
                              **({"spp": v["spp"], "noise_flip": v.get("noise_flip")} if "spp" in v else {})}
            for k, v in found.items()}


def published(root, name, work, args, record):
    """The path of the image scene ``name`` is measured against, and where it comes from."""
    xml, image = COMPLETE[name]
    if image is not None:
        return root / image, "published"
    out = work / "mitsuba_reference.npy"  # compare --reference reads .npy: linear radiance (H, W, 3) float32
    label = f"Mitsuba {args.mitsuba_version} {args.mitsuba_variant} ({args.mitsuba_spp} spp)"
    if out.exists():
        return out, label
    if args.mitsuba_python is None:
        return None, "no published render, and Mitsuba 3 is not installed"
    copy = (root / xml).with_name("scene.mitsuba3.xml")  # beside the original: its paths are relative to it
    try:
        tree = ET.parse(root / xml)
        parents = {child: parent for parent in tree.iter() for child in parent}
        for element in [e for e in tree.iter() if e.get("name") in MITSUBA2_ONLY]:
            parents[element].remove(element)
        tree.write(copy)
        seconds, _ = mitsuba_render(args.mitsuba_python, args.mitsuba_variant, copy, args.mitsuba_spp, 1, out)
    finally:
        copy.unlink(missing_ok=True)
    record({"scene": name, "step": "mitsuba reference", "seconds": round(seconds, 2), "spp": args.mitsuba_spp})
    return out, label


def commands(xml, reference, args):
    quality = ["--quality", args.quality]
    return {
        "scene-info": ["scene-info", xml, *quality],
        "solve": ["solve", xml, *quality, "-o", "solution.npz"],
        "fit": ["fit", "solution.npz", *quality, "-o", "fit.npz"],
        "render": ["render", "fit.npz", "-o", "render.png"],
        "export": ["export", "fit.npz", "-o", "web"],
        "compare": ["compare", "fit.npz", "solution.npz", "--reference", reference, "--truth-spp", args.truth_spp,
                    "--out", "compare", *compared_size(reference, args.max_side)],
    }


def compared_size(reference, max_side):
    """compare's --size for ``reference``: its own size shrunk by the least whole factor
    that brings its longer side to ``max_side`` or below (none where it is already)."""
    from radiosity.files.images import read_hdr_image

    height, width = read_hdr_image(reference).shape[:2]
    factor = next(f for f in range(1, max(height, width) + 1)
                  if height % f == 0 and width % f == 0 and max(height, width) // f <= max_side
                  or f == math.gcd(height, width))
    return [] if factor == 1 else ["--size", f"{width // factor}x{height // factor}"]


def complete_scene(root, name, args, record):
    """Every step of scene ``name`` in ``work``; its summary row (None when it stopped)."""
    work = args.keep / name
    work.mkdir(parents=True, exist_ok=True)
    reference, source = published(root, name, work, args, record)
    if reference is None:
        print(f"{name}: skipped: {source}")
        return None
    xml = root / COMPLETE[name][0]
    steps = {}
    for step, argv in commands(xml, reference, args).items():
        done = run_vlights(argv, work, timeout=TIMEOUT_S)
        warnings = sum(": warning: " in line for line in done.stderr.splitlines())
        steps[step] = record({"scene": name, "step": step, "seconds": round(done.seconds, 2),
                              "peak_mb": round(done.peak_mb, 1), "tree_mb": round(done.tree_mb, 1),
                              "exit": done.exit_code, "warnings": warnings,
                              **({"error": done.last_line} if done.exit_code else {})})
        if done.exit_code:
            return record({"scene": name, "summary": True, "stopped_at": step, "reference": source,
                           "steps": {k: v["exit"] for k, v in steps.items()}})
    with open(work / "compare" / "compare.json") as f:
        numbers = displays_of(json.load(f))
    tracer = numbers["path_tracer"]["flip"]
    row = record({
        "scene": name, "summary": True, "reference": source, "quality": args.quality, "truth_spp": args.truth_spp,
        "displays": numbers,
        "fitted_over_path_tracer": numbers["fitted"]["flip"] / tracer,
        "meets_target": numbers["fitted"]["flip"] <= TARGET * tracer,
        "path_tracer_mean_within_5pct": abs(numbers["path_tracer"]["mean_ratio"] - 1) <= 0.05,
        "within_memory": all(max(s["peak_mb"], s["tree_mb"]) <= MEMORY_LIMIT_MB for s in steps.values()),
        "seconds": {k: v["seconds"] for k, v in steps.items()},
        "peak_mb": {k: max(v["peak_mb"], v["tree_mb"]) for k, v in steps.items()},
    })
    side_by_side(work, reference, name, numbers, source, RESULTS / f"interiors_{name}.png")
    return row


def side_by_side(work, reference, name, numbers, source, path):
    """The published render, the path tracer and the three displays, tone-mapped alike,
    their FLIP error images below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap
    from radiosity.files.images import read_hdr_image

    truth = read_hdr_image(reference)
    folder = work / "compare" / "reference"
    files = {"solution": "reference_display", "fitted": "fitted_display", "diffuse": "diffuse_display",
             "path_tracer": "path_tracer"}
    shown = [("published" if source == "published" else source, truth, None)]
    for key in ("path_tracer", "solution", "fitted", "diffuse"):
        image = np.load(folder / f"{files[key]}.npy")
        shown.append((key.replace("_", " "), image, numbers[key]))
    from display.metrics import metrics

    height, width = truth.shape[:2]
    panel = 2.6  # inches across a picture
    fig, axes = plt.subplots(2, len(shown), figsize=(panel * len(shown), 2 * panel * height / width + 0.8),
                             squeeze=False)
    for column, (title, image, measured) in enumerate(shown):
        top, bottom = axes[0, column], axes[1, column]
        if image.shape[:2] != truth.shape[:2]:  # a display drawn smaller by a whole factor: shown as it is
            factor = truth.shape[0] // image.shape[0]
            reference_image = truth.reshape(image.shape[0], factor, image.shape[1], factor, 3).mean(axis=(1, 3))
        else:
            reference_image = truth
        top.imshow(tonemap(image))
        label = title if measured is None else f"{title}\nFLIP {measured['flip']:.3f}, ratio {measured['mean_ratio']:.3f}"
        top.set_title(label, fontsize=8)
        if measured is not None:
            _, error = metrics(reference_image, image)
            bottom.imshow(error)  # FLIP per pixel through magma
        for ax in (top, bottom):
            ax.axis("off")
    fig.suptitle(name, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def missing_files(xml):
    """The file names ``xml`` gives (any ``filename`` property) that do not exist beside it."""
    tree = ET.parse(xml)
    names = {e.get("value") for e in tree.iter("string") if e.get("name") == "filename"}
    return sorted(n for n in names if n and not (xml.parent / n).is_file())


def without_missing(xml, missing, out):
    """A copy of ``xml`` at ``out`` with every shape, emitter or texture that names a file
    of ``missing`` left out (the innermost such element); how many were left out."""
    tree = ET.parse(xml)
    parents = {child: parent for parent in tree.iter() for child in parent}
    dropped = 0
    for element in list(tree.iter("string")):
        if element.get("name") == "filename" and element.get("value") in missing:
            node = element
            while node in parents and node.tag not in ("shape", "emitter", "texture"):
                node = parents[node]
            if node in parents:
                parents[node].remove(node)
                dropped += 1
    tree.write(out)
    return dropped


def incomplete_scene(root, name, args, record):
    xml = root / name / "scene.xml"
    missing = missing_files(xml)
    refused = run_vlights(["scene-info", xml], root / name)
    named = any(m in refused.last_line for m in missing)
    pruned = xml.with_name("scene.complete-parts.xml")
    try:
        dropped = without_missing(xml, set(missing), pruned)
        rest = run_vlights(["scene-info", pruned, "--quality", args.quality], root / name)
    finally:
        pruned.unlink(missing_ok=True)
    return record({"scene": name, "incomplete": True, "missing": missing, "refusal": refused.last_line,
                   "refusal_exit": refused.exit_code, "refusal_names_file": named, "left_out": dropped,
                   "rest_exit": rest.exit_code, "rest_seconds": round(rest.seconds, 2),
                   "rest_peak_mb": round(rest.peak_mb, 1),
                   **({"rest_error": rest.last_line} if rest.exit_code else {})})


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summaries = [r for r in rows if r.get("summary") and "displays" in r]
    if not summaries:
        return
    fig, ax = plt.subplots(figsize=(max(6, 1.3 * len(summaries)), 3.6))
    width = 0.8 / len(DISPLAYS)
    for k, display in enumerate(DISPLAYS):
        values = [r["displays"].get(display, {}).get("flip", np.nan) for r in summaries]
        ax.bar(np.arange(len(summaries)) + (k - 1.5) * width, values, width, label=display.replace("_", " "))
    for i, r in enumerate(summaries):
        ax.plot([i - 0.4, i + 0.4], [TARGET * r["displays"]["path_tracer"]["flip"]] * 2, "k--", lw=1,
                label="target: 1.2 x path tracer" if i == 0 else None)
    ax.set_xticks(range(len(summaries)), [r["scene"] for r in summaries], fontsize=8)
    ax.set_ylabel("FLIP against the published render")
    ax.set_title(f"each display and the path tracer ({summaries[0]['truth_spp']} spp), {summaries[0]['quality']}",
                 fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", default=",".join([*COMPLETE, *INCOMPLETE]),
                        help="comma-separated names (default: every scene of the collection)")
    parser.add_argument("--root", help="the collection's folder (default: $VLIGHTS_SCENES, else /work/scenes)")
    parser.add_argument("--quality", default="draft", choices=("draft", "medium", "high"))
    parser.add_argument("--truth-spp", type=int, default=128, help="the path tracer's samples per pixel (default 128)")
    parser.add_argument("--max-side", type=int, default=640,
                        help="compare at the published render's size shrunk by a whole factor to this longest side or "
                             "less (default 640)")
    parser.add_argument("--keep", type=Path, help="keep every step's files in this folder (default: a temporary one)")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba (validate_mitsuba.py's default)")
    parser.add_argument("--mitsuba-variant", help="Mitsuba's variant (default: llvm_ad_rgb where $DRJIT_LIBLLVM_PATH or "
                        f"{LIBLLVM} is, else scalar_rgb)")
    parser.add_argument("--mitsuba-spp", type=int, default=256, help="a Mitsuba reference's samples (default 256)")
    parser.add_argument("--plot-only", action="store_true", help="draw interiors.png again from the results file")
    parser.add_argument("--merge", action="store_true",
                        help="keep the results file's rows of the scenes not run now (each row says its commit and "
                             "date); default: the file holds this run alone")
    args = parser.parse_args(argv)
    name = "interiors.jsonl" if args.quality == "draft" else f"interiors_{args.quality}.jsonl"
    if args.plot_only:
        with open(RESULTS / name) as f:
            plot([json.loads(line) for line in f if line.strip()], RESULTS / name.replace(".jsonl", ".png"))
        return 0
    root = scenes_root(args.root)
    wanted = [s.strip() for s in args.scenes.split(",") if s.strip()]
    unknown = sorted(set(wanted) - set(COMPLETE) - set(INCOMPLETE))
    if unknown:
        raise SystemExit(f"unknown scene {unknown[0]!r}; the collection's: {', '.join([*COMPLETE, *INCOMPLETE])}")
    args.mitsuba_python, args.mitsuba_version = mitsuba_python(args.mitsuba_python)
    if args.mitsuba_variant is None:
        if "DRJIT_LIBLLVM_PATH" not in os.environ and Path(LIBLLVM).exists():
            os.environ["DRJIT_LIBLLVM_PATH"] = LIBLLVM  # Mitsuba's process inherits it
        args.mitsuba_variant = "llvm_ad_rgb" if "DRJIT_LIBLLVM_PATH" in os.environ else "scalar_rgb"
    record = Recorder(benchmark="interiors", quality=args.quality, commit=git_commit(),
                      date=time.strftime("%Y-%m-%d %H:%M", time.gmtime()))
    with tempfile.TemporaryDirectory() as tmp:
        args.keep = (args.keep or Path(tmp)).resolve()
        for scene in wanted:
            if scene in COMPLETE:
                complete_scene(root, scene, args, record)
            else:
                incomplete_scene(root, scene, args, record)
    if args.merge and (RESULTS / name).exists():
        with open(RESULTS / name) as f:
            earlier = [json.loads(line) for line in f if line.strip()]
        order = {scene: k for k, scene in enumerate([*COMPLETE, *INCOMPLETE])}
        rows = [r for r in earlier if r.get("scene") not in wanted] + record.rows
        record.rows = sorted(rows, key=lambda r: order.get(r.get("scene"), len(order)))  # stable: a scene's steps in order
    record.save(name)
    plot(record.rows, RESULTS / name.replace(".jsonl", ".png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
