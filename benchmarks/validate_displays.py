"""The displays against Mitsuba 3 on the project's microfacet scenes: how close the
walkthrough's pictures come to the truth, next to our path tracer's.

For each scene (default: validate_kinds.xml, a rough plastic and a rough conductor of
each distribution, and validate_plates.xml) and each quality: Mitsuba renders the XML at
--reference-spp (once, kept in --cache); ``vlights solve`` at the quality, ``vlights
fit``, and ``vlights compare --reference`` (the solution display, the fitted display,
the diffuse display and our path tracer at --truth-spp, all at the film's camera).
Reported: FLIP and the mean ratio of each against Mitsuba's image, over the whole image
and over the glossy objects' pixels, and each display's FLIP over the path tracer's
(target: the solution display at most 1.3 x).

    python benchmarks/validate_displays.py [scene.xml ...] [--qualities draft,medium]
                                           [--reference-spp 4096] [--truth-spp 256]
                                           [--variant llvm_ad_rgb] [--cache DIR]

Mitsuba is not a dependency: see validate_mitsuba.py for its venv. Without it the
script says so and exits 0. Writes results/displays.jsonl and results/displays.png (a row
per scene and quality: Mitsuba's image, the solution display, the fitted display, our path
tracer).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder, mitsuba_python, mitsuba_render, vlights_or_exit  # noqa: E402

MITSUBA_SCENES = Path(__file__).resolve().parent.parent / "tests" / "data" / "mitsuba"
SCENES = [MITSUBA_SCENES / "validate_kinds.xml", MITSUBA_SCENES / "validate_plates.xml"]
DISPLAYS = ("reference", "fitted", "diffuse", "path_tracer")


def reference_image(python, variant, scene, spp, cache):
    """Mitsuba's image of ``scene`` at ``spp`` (seed 1), rendered once into ``cache``."""
    path = cache / f"{scene.stem}_{variant}_{spp}.npy"
    if not path.exists():
        cache.mkdir(parents=True, exist_ok=True)
        mitsuba_render(python, variant, scene, spp, 1, path)
    return path


def measure(scene, quality, reference, truth_spp, work):
    """Solve, fit and compare ``scene`` at ``quality``: (seconds, the compare's numbers of
    each display against the reference image)."""
    solution, fit = work / "solution.npz", work / "fit.npz"
    seconds = {"solve": vlights_or_exit(["solve", scene, "--quality", quality, "-o", solution], work)}
    seconds["fit"] = vlights_or_exit(["fit", solution, "-o", fit], work)
    seconds["compare"] = vlights_or_exit(["compare", fit, solution, "--reference", reference, "--truth-spp",
                                          truth_spp, "--out", work / "compare"], work)
    displays = json.loads((work / "compare" / "compare.json").read_text())["reference_image"]["displays"]
    return seconds, displays


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", type=Path, default=SCENES)
    parser.add_argument("--qualities", default="draft,medium")
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--truth-spp", type=int, default=256)
    parser.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (default scalar_rgb)")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba installed")
    parser.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "vlights" / "mitsuba",
                        help="where Mitsuba's images are kept between runs (default ~/.cache/vlights/mitsuba)")
    args = parser.parse_args(argv)
    python, version = mitsuba_python(args.mitsuba_python)
    if python is None:
        print("mitsuba is not installed (see validate_mitsuba.py's docstring): nothing to compare")
        return 0
    record = Recorder(benchmark="displays", mitsuba=version, variant=args.variant,
                      reference_spp=args.reference_spp, truth_spp=args.truth_spp)
    pictures = []
    for scene in args.scenes:
        reference = reference_image(python, args.variant, scene, args.reference_spp, args.cache)
        for quality in args.qualities.split(","):
            with tempfile.TemporaryDirectory() as tmp:
                work = Path(tmp)
                seconds, displays = measure(scene, quality, reference, args.truth_spp, work)
                folder = work / "compare" / "reference"
                pictures.append((f"{scene.stem}, {quality}", np.load(reference),
                                 *(np.load(folder / f"{stem}.npy") for stem in ("reference_display", "fitted_display",
                                                                                "path_tracer"))))
            truth = displays["path_tracer"]
            row = {"scene": scene.name, "quality": quality, "seconds": seconds}
            for name in DISPLAYS:
                d = displays[name]
                row[name] = {"flip": d["flip_mean"], "flip_glossy": d["flip_mean_glossy"], "mean_ratio": d["mean_ratio"],
                             "relative_mse_glossy": d["relative_mse_glossy"],
                             "over_path_tracer": d["flip_mean"] / truth["flip_mean"],
                             "glossy_over_path_tracer": d["flip_mean_glossy"] / truth["flip_mean_glossy"]}
            row["reference"]["within_1_3"] = row["reference"]["over_path_tracer"] <= 1.3
            record(row)
            print(f"{scene.name} {quality}: solution display FLIP {row['reference']['flip']:.4f} "
                  f"({row['reference']['over_path_tracer']:.2f} x the path tracer's {truth['flip_mean']:.4f}), "
                  f"fitted {row['fitted']['flip']:.4f}", flush=True)
    record.save("displays.jsonl")
    figure(pictures, RESULTS / "displays.png")
    print(json.dumps({"rows": len(record.rows), "figure": str(RESULTS / "displays.png")}))
    return 0


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap

    titles = ("Mitsuba 3", "solution display", "fitted display", "path tracer")
    fig, axes = plt.subplots(len(rows), 4, figsize=(12, 2.2 * len(rows)), squeeze=False)
    for row, (name, *images) in zip(axes, rows, strict=True):
        for ax, image, title in zip(row, images, titles, strict=True):
            ax.imshow(tonemap(image))
            ax.set_title(f"{name}: {title}", fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
