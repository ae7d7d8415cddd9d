"""What the materials' own models buy the path tracer, against the published renders.

For each scene (default: staircase2 and living-room of the field's collection, and the
project's validate_kinds.xml, whose reference is Mitsuba 3's render of the same XML when
Mitsuba is installed): ``vlights truth``'s path tracer renders the scene's own camera at
its film's size shrunk by a whole factor to at most --max-side, at --spp samples, twice
in one process, alternating: with every material's own model (rough plastics and
conductors as microfacet lobes, glass as glass: what ``vlights truth`` renders), with the
Phong stand-ins the solver's grids and the displays draw, and with its glass shapes left
out (as the reader had them before glass was modelled: light passing as through clear
glass, no reflection). Each against the
published render box-averaged to that size: FLIP and the mean ratio (ours / published),
and the seconds.

    python benchmarks/bench_materials.py [--scenes staircase2,living-room] [--spp 64] [--max-side 320]
                                         [--root DIR]

The collection's scenes are not part of this repository: give its folder with --root
(default: $VLIGHTS_SCENES, else /work/scenes); scenes missing there are skipped, saying so.
Writes results/materials.jsonl (a row per scene and model) and results/materials_<scene>.png
(published, own models, Phong stand-ins, and their FLIP error images).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder  # noqa: E402

COLLECTION = {
    "staircase2": ("staircase2/scene.xml", "staircase2/TungstenRender.exr"),
    "living-room": ("living-room/scene.xml", "living-room/TungstenRender.exr"),
    "staircase": ("staircase/scene.xml", "staircase/TungstenRender.exr"),
    "veach_mi": ("veach_mi/scene.xml", None),
}
# label: (own microfacet models, glass kept): what vlights truth renders, the Phong stand-ins the solver's
# grids and the displays draw, and its glass left out as the reader left it before glass was modelled
MODELS = {"own models": (True, True), "phong stand-ins": (False, True), "glass left out": (True, False)}


def shrink_factor(width, height, max_side):
    """The smallest whole factor dividing both sides that brings the larger to <= max_side."""
    for factor in range(1, max(width, height) + 1):
        if width % factor == 0 and height % factor == 0 and max(width, height) // factor <= max_side:
            return factor
    return 1


def render(scene, camera, spp, seed, microfacet_models):
    from radiosity.transport.pathtrace import PathTracer

    start = time.perf_counter()
    with PathTracer(scene, microfacet_models=microfacet_models) as tracer:
        image = tracer.render(camera, spp, seed).radiance
    return image, time.perf_counter() - start


def without_glass(scene):
    """``scene`` with its glass objects left out, None where it has none."""
    from dataclasses import replace

    kept = tuple(o for o in scene.objects if not o.material.is_glass)
    return None if len(kept) == len(scene.objects) else replace(scene, objects=kept)


def figure(name, reference, images, numbers, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.metrics import metrics
    from display.renderer import tonemap

    fig, axes = plt.subplots(2, 1 + len(images), figsize=(4.2 * (1 + len(images)), 6.2))
    axes[0, 0].imshow(tonemap(reference))
    axes[0, 0].set_title(f"{name}: published")
    axes[1, 0].axis("off")
    for k, (label, image) in enumerate(images.items(), start=1):
        axes[0, k].imshow(tonemap(image))
        axes[0, k].set_title(f"{label}: FLIP {numbers[label]['flip']:.3f}, mean x{numbers[label]['mean_ratio']:.3f}")
        axes[1, k].imshow(metrics(reference, image)[1], cmap="magma", vmin=0, vmax=1)
        axes[1, k].set_title(f"{label}: FLIP error")
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", default="staircase2,living-room")
    parser.add_argument("--root", type=Path, default=Path(os.environ.get("VLIGHTS_SCENES", "/work/scenes")))
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--max-side", type=int, default=320)
    args = parser.parse_args()

    from display.compare import reference_at
    from display.metrics import metrics
    from radiosity.files.images import read_hdr_image
    from radiosity.scene.loaders import load_scene

    record = Recorder(benchmark="materials")
    for name in args.scenes.split(","):
        xml, published = COLLECTION[name]
        if not (args.root / xml).exists() or published is None or not (args.root / published).exists():
            print(f"{name}: not in {args.root} (or no published render there), skipped")
            continue
        scene = load_scene(str(args.root / xml))
        reference = read_hdr_image(args.root / published, "the published render")
        height, width = reference.shape[:2]
        factor = shrink_factor(width, height, args.max_side)
        camera = scene.camera.sized(width // factor, height // factor)
        reference, _ = reference_at(reference, (camera.width, camera.height), str(published))
        images, numbers = {}, {}
        for label, (own, glass) in MODELS.items():
            shown = scene if glass else without_glass(scene)
            if shown is None:
                continue  # no glass to leave out: the same picture as the own models'
            image, seconds = render(shown, camera, args.spp, args.seed, own)
            values, _ = metrics(reference, image)
            numbers[label] = {"flip": values["flip_mean"], "mean_ratio": float(image.mean() / reference.mean()),
                              "seconds": round(seconds, 2)}
            images[label] = image
            record({"scene": name, "model": label, "spp": args.spp, "size": [camera.width, camera.height],
                    **numbers[label]})
            print(f"{name} {label}: FLIP {numbers[label]['flip']:.4f}, mean ratio {numbers[label]['mean_ratio']:.4f}, "
                  f"{seconds:.1f} s")
        figure(name, reference, images, numbers, RESULTS / f"materials_{name}.png")
    record.save("materials.jsonl")


if __name__ == "__main__":
    main()
