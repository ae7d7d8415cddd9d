"""The project's path tracer against Mitsuba 3 on the same Mitsuba XML scenes.

For each scene: Mitsuba renders it at its film's size with N and 4N samples per
pixel (two seeds); ``vlights truth`` renders the same file with N samples. Reported
against Mitsuba's 4N-spp image: the mean ratio (ours / Mitsuba's, over the image),
HDR-FLIP and relative MSE of ours, and, as the noise level to read them by, the same
for Mitsuba's own N-spp image; and, to tell noise from a difference of models, ours at
N against ours at 4N (our noise) and ours at 4N against Mitsuba's 4N (the models). Targets: mean within 2 %, and our FLIP at or
below Mitsuba's own N-spp noise level. ``validate_textured.xml`` holds diffuse bitmap textures (a 4 x 4 image
with distinct corners on a rectangle with to_uv and mirror wrapping, a sphere and an obj): a flipped or rotated
mapping shows in its FLIP.

Mitsuba is not a dependency of the project: install it in a venv of its own
(``python3 -m venv /work/mitsuba-venv && /work/mitsuba-venv/bin/pip install mitsuba``)
and give its Python with --mitsuba-python (default: $VLIGHTS_MITSUBA_PYTHON, else
/work/mitsuba-venv/bin/python). Without it the script says so and exits 0.

    python benchmarks/validate_mitsuba.py                     # the XML scenes in tests/data/mitsuba
    python benchmarks/validate_mitsuba.py scene.xml --spp 256 --variant llvm_ad_rgb
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder, mitsuba_python, mitsuba_render  # noqa: E402

SCENES = sorted((Path(__file__).resolve().parent.parent / "tests" / "data" / "mitsuba").glob("validate_*.xml"))
def ours(scene, spp, seed, out):
    start = time.perf_counter()
    run = subprocess.run(["vlights", "truth", str(scene), "--spp", str(spp), "--seed", str(seed), "-o",
                          str(out.with_suffix(".png")), "--hdr", str(out)], capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"vlights truth failed on {scene}: {run.stderr.strip()}")
    warnings = [line for line in run.stderr.splitlines() if "warning" in line]
    return time.perf_counter() - start, np.load(out), warnings


def against(reference, image):
    from display.metrics import metrics

    numbers, _ = metrics(reference, image)
    return {"mean_ratio": float(image.mean() / reference.mean()), "flip": numbers["flip_mean"],
            "relative_mse": numbers["relative_mse"]}


def figure(rows_images, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap

    fig, axes = plt.subplots(len(rows_images), 3, figsize=(9, 3 * len(rows_images)), squeeze=False)
    for row, (name, reference, mine, error) in zip(axes, rows_images, strict=True):
        for ax, image, title in zip(row, (reference, mine, error), ("Mitsuba 3", "vlights truth", "|difference|"),
                                    strict=True):
            ax.imshow(tonemap(image) if image.ndim == 3 else image, cmap="magma")
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenes", nargs="*", type=Path, default=SCENES)
    parser.add_argument("--spp", type=int, default=256, help="our samples and Mitsuba's noisy image's (default 256)")
    parser.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (default scalar_rgb)")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba installed")
    args = parser.parse_args(argv)
    python, version = mitsuba_python(args.mitsuba_python)
    if python is None:
        print("mitsuba is not installed (see this script's docstring): nothing to compare")
        return 0
    record = Recorder(benchmark="mitsuba_validation", mitsuba=version, variant=args.variant, spp=args.spp)
    pictures = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scene in args.scenes:
            t_ref, reference = mitsuba_render(python, args.variant, scene, 4 * args.spp, 1, tmp / "ref.npy")
            t_noisy, noisy = mitsuba_render(python, args.variant, scene, args.spp, 2, tmp / "noisy.npy")
            t_ours, mine, warnings = ours(scene, args.spp, 3, tmp / "ours.npy")
            _, mine_converged, _ = ours(scene, 4 * args.spp, 4, tmp / "ours_ref.npy")
            if mine.shape != reference.shape:
                raise SystemExit(f"{scene}: our image is {mine.shape}, Mitsuba's {reference.shape}")
            row = record({
                "scene": scene.name, "size": list(reference.shape[:2]), "ours": against(reference, mine),
                "mitsuba_noise": against(reference, noisy),
                "ours_noise": against(mine_converged, mine),  # our own noise level, against our own 4N spp
                "converged": against(reference, mine_converged),  # the models' difference, with little noise
                "seconds": {"mitsuba_ref": t_ref, "mitsuba": t_noisy,
                                                                        "ours": t_ours},
                "warnings": warnings,
            })
            row["mean_within_2pct"] = abs(row["ours"]["mean_ratio"] - 1) <= 0.02
            row["flip_at_noise_level"] = row["ours"]["flip"] <= row["mitsuba_noise"]["flip"]
            print(f"{scene.name}: mean ratio {row['ours']['mean_ratio']:.4f}, FLIP {row['ours']['flip']:.4f} "
                  f"(Mitsuba's own {args.spp} spp: {row['mitsuba_noise']['flip']:.4f}, mean ratio "
                  f"{row['mitsuba_noise']['mean_ratio']:.4f})", flush=True)
            pictures.append((scene.stem, reference, mine, np.abs(mine - reference).mean(axis=2)))
    record.save("mitsuba_validation.jsonl")
    figure(pictures, RESULTS / "mitsuba_validation.png")
    print(json.dumps({"scenes": len(pictures), "figure": str(RESULTS / "mitsuba_validation.png")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
