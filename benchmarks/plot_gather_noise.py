"""The satin block at draft: the gather's blotches, and what removed them.

Usage:
    python benchmarks/plot_gather_noise.py --truth-file truth.npy [--seeds 1,2,3]
        [-o docs/gather_noise.png]

Solves cornell-teapot at draft (refined mesh) three ways with the same seed: the gather
as it was (the light reached over glossy hits found by the lobe alone, one pass), with
a light sample at glossy hits (``SolveOptions(lobe_light=True)``, one pass:
``--extra-gather 0``), and the draft default (light sample and extra passes where the
neighbours' gather is noisy). Renders each solution's reference display at the
scene's camera, crops the block, and puts the path-traced truth beside them. Prints,
per way and seed, FLIP against the truth over the image and over the glossy objects,
and the solve's seconds. The truth: ``vlights truth cornell-teapot --size 256x256
--spp 16384 --hdr truth.npy`` (the crop needs a converged one; 64 spp is speckled).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

WAYS = (
    ("lobe alone, 1 pass (before)", dict(lobe_light=False, extra_gather=0.0)),
    ("light sample at glossy hits, 1 pass", dict(lobe_light=True, extra_gather=0.0)),
    ("and extra passes (draft default)", dict(lobe_light=True)),
)
CROP = (slice(100, 230), slice(20, 150))  # the satin block at 256 x 256


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--truth-file", type=Path, required=True, help="the truth's radiance, (N, N, 3) .npy")
    parser.add_argument("--seeds", default="1", help="comma-separated seeds; the figure shows the first")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/gather_noise.png"))
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.gl import headless_context
    from display.metrics import metrics
    from display.renderer import Renderer, tonemap
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.adaptive import AdaptiveOptions, solve_adaptive
    from radiosity.transport.solve import SolveOptions

    truth = np.load(args.truth_file)
    scene = load_scene("cornell-teapot")
    camera = scene.camera.sized(truth.shape[1], truth.shape[0])
    seeds = [int(s) for s in args.seeds.split(",")]
    ctx = headless_context()
    panels = []
    for seed in seeds:
        for title, knobs in WAYS:
            t = time.perf_counter()
            solution = solve_adaptive(scene, SolveOptions(quality="draft", seed=seed, **knobs), AdaptiveOptions())
            seconds = time.perf_counter() - t
            renderer = Renderer(ctx, solution=solution)
            glossy = [o.name for o in solution.objects if not o.is_diffuse]
            image = renderer.render(camera, "reference")
            numbers = metrics(truth, image, mask=renderer.object_mask(camera, glossy))[0]
            renderer.release()
            print(
                f"seed {seed}  {title:38s} FLIP {numbers['flip_mean']:.4f}  glossy {numbers['flip_mean_glossy']:.4f}"
                f"  solve {seconds:.1f} s",
                flush=True,
            )
            if seed == seeds[0]:
                panels.append((f"{title}\nFLIP {numbers['flip_mean']:.4f}, glossy {numbers['flip_mean_glossy']:.4f}",
                               image))
    ctx.release()
    panels.append(("path-traced truth", truth))
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.7))
    for ax, (title, image) in zip(axes, panels):
        ax.imshow(tonemap(image)[CROP], interpolation="nearest")
        ax.set_title(title, fontsize=8)
        ax.set_axis_off()
    fig.suptitle(f"cornell-teapot, draft, seed {seeds[0]}: the satin block (reference display)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(args.output, dpi=110, bbox_inches="tight")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
