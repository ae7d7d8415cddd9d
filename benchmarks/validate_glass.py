"""A glass sphere's caustic on a diffuse floor: its power in Mitsuba 3, in the project's
path tracer and in the solver's solution (photons, density estimation), on the same XML.

The scene (tests/data/mitsuba/validate_glass.xml) is rendered with the glass sphere and
without it (the same file with the sphere's shape taken out) by each renderer at the
film's size. The caustic is the largest connected region where Mitsuba's converged image
with the sphere (smoothed over a pixel) is brighter than without it by more than
``--threshold`` (25 %), the sphere's own pixels left out (a ray-sphere test from the
scene's camera, one pixel of margin), grown by ``--grow`` pixels (3) so that a
renderer that blurs it (the solver's density estimation) keeps its power inside; the
caustic's power is the sum over those pixels of (with - without), each renderer's own
pair (so the light the sphere takes from the floor there counts against it in every
renderer alike). Reported: each renderer's caustic power over Mitsuba's (target: within
5 %), the same over the region not grown, the whole image's mean ratio and HDR-FLIP
against Mitsuba's, the seconds; and a figure of the pictures and the region.

Mitsuba is not a dependency (see validate_mitsuba.py for its venv); without it the
script says so and exits 0.

    python benchmarks/validate_glass.py                       # 4096 spp Mitsuba, 1024 ours
    python benchmarks/validate_glass.py --variant llvm_ad_rgb --qualities draft medium
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder, mitsuba_python, mitsuba_render  # noqa: E402
from _common import vlights_or_exit as vlights

SCENE = Path(__file__).resolve().parent.parent / "tests" / "data" / "mitsuba" / "validate_glass.xml"
BALL = "glass_ball"


def without_ball(xml: Path, out: Path) -> Path:
    text, count = re.subn(rf'<shape type="sphere" id="{BALL}">.*?</shape>', "", xml.read_text(), flags=re.S)
    if count != 1:
        raise SystemExit(f"{xml}: no shape {BALL!r} to take out")
    out.write_text(text)
    return out


def ball_pixels(xml: Path, name=BALL, grow=1) -> np.ndarray:
    """(H, W) bool: the pixels whose centre's camera ray meets the sphere ``name``, grown by
    ``grow`` pixels (shrunk where negative)."""
    from scipy.ndimage import binary_dilation

    from radiosity.scene.loaders import load_scene
    from radiosity.transport.pathtrace import camera_rays

    scene = load_scene(xml)
    ball = scene.object(name).positions
    centre = ball.mean(axis=0)
    radius = np.linalg.norm(ball - centre, axis=1).max()
    camera = scene.camera
    rays = camera_rays(camera)
    sx = (np.arange(camera.width) + 0.5) / camera.width * 2 - 1
    sy = 1 - (np.arange(camera.height) + 0.5) / camera.height * 2
    d = rays.forward + sx[None, :, None] * rays.right + sy[:, None, None] * rays.up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    to_centre = centre - rays.eye
    hit = (d @ to_centre) ** 2 - (to_centre @ to_centre - radius**2) > 0
    if grow < 0:
        from scipy.ndimage import binary_erosion

        return binary_erosion(hit, iterations=-grow)
    return binary_dilation(hit, iterations=grow) if grow else hit



def caustic_region(reference, empty, ball, threshold, grow):
    """(the region grown, the region): the largest connected set of pixels where the
    smoothed reference with the ball is brighter than without it by ``threshold``."""
    from scipy.ndimage import binary_dilation, gaussian_filter, label

    brighter = gaussian_filter(reference.mean(axis=2), 1.0) > (1 + threshold) * gaussian_filter(empty.mean(axis=2), 1.0)
    labels, count = label(brighter & ~ball)
    if count == 0:
        raise SystemExit("no caustic found in Mitsuba's image")
    largest = labels == 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))
    return binary_dilation(largest, iterations=grow) & ~ball if grow else largest, largest


def caustic(with_ball, without, mask):
    return float(np.sum((with_ball - without)[mask]))


def display_approaches(solution_path, size, samples=4, frames=5):
    """{approach: (image, seconds of the first frame (its probes drawn), median seconds of
    ``frames`` more)} of the solution display of ``solution_path`` at its camera."""
    from display.commands.common import headless
    from display.glass import APPROACHES
    from display.renderer import Renderer
    from radiosity.files.solution import load_solution

    solution = load_solution(solution_path)
    out = {}
    with headless(size, samples) as ctx:
        view = solution.camera.sized(*size)
        for approach in APPROACHES:
            renderer = Renderer(ctx, solution=solution, samples=samples)
            renderer.glass_approach = approach
            start = time.perf_counter()
            image = renderer.render(view, "reference")
            first = time.perf_counter() - start
            times = []
            for _ in range(frames):
                start = time.perf_counter()
                renderer.render(view, "reference")
                times.append(time.perf_counter() - start)
            out[approach] = (image, first, float(np.median(times)))
            renderer.release()
    return out


def figure(panels, mask, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap

    columns = 4
    rows = -(-(len(panels) + 1) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 2.0 * rows), squeeze=False)
    axes = axes.ravel()
    for ax, (title, image) in zip(axes, panels, strict=False):
        ax.imshow(tonemap(image))
        ax.set_title(title, fontsize=8)
    axes[len(panels)].imshow(mask, cmap="gray")
    axes[len(panels)].set_title("the caustic's pixels", fontsize=8)
    for ax in axes:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", type=Path, default=SCENE)
    parser.add_argument("--spp", type=int, default=1024, help="the path tracer's samples (Mitsuba's: 4x)")
    parser.add_argument("--qualities", nargs="*", default=["draft", "medium"], help="the solver's presets")
    parser.add_argument("--threshold", type=float, default=0.25, help="how much brighter a caustic pixel is")
    parser.add_argument("--grow", type=int, default=3, help="pixels the caustic's region is grown by")
    parser.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (default scalar_rgb)")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba installed")
    args = parser.parse_args(argv)
    python, version = mitsuba_python(args.mitsuba_python)
    if python is None:
        print("mitsuba is not installed (see validate_mitsuba.py's docstring): nothing to compare")
        return 0
    from display.metrics import metrics

    record = Recorder(benchmark="glass_caustic", mitsuba=version, variant=args.variant, spp=args.spp)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scenes = {"with": args.scene.resolve(), "without": without_ball(args.scene, tmp / "without.xml")}
        images, seconds = {}, {}
        for key, xml in scenes.items():
            seconds[f"mitsuba_{key}"], images[("mitsuba", key)] = mitsuba_render(
                python, args.variant, xml, 4 * args.spp, 1, tmp / f"mitsuba_{key}.npy")
            out = tmp / f"truth_{key}.npy"
            seconds[f"truth_{key}"] = vlights(["truth", xml, "--spp", args.spp, "--seed", 3, "--hdr", out,
                                              "-o", out.with_suffix(".png")], tmp)
            images[("truth", key)] = np.load(out)
            height, width = images[("mitsuba", key)].shape[:2]
            for quality in args.qualities:
                solution, out = tmp / f"{quality}_{key}.npz", tmp / f"{quality}_{key}.npy"
                start = time.perf_counter()
                vlights(["solve", xml, "--quality", quality, "-o", solution], tmp)
                seconds[f"solve_{quality}_{key}"] = time.perf_counter() - start
                vlights(["render", solution, "--size", f"{width}x{height}", "--hdr", out,
                         "-o", out.with_suffix(".png")], tmp)
                images[(f"solution {quality}", key)] = np.load(out)
        reference, empty = images[("mitsuba", "with")], images[("mitsuba", "without")]
        mask, strict = caustic_region(reference, empty, ball_pixels(args.scene), args.threshold, args.grow)
        power, strict_power = caustic(reference, empty, mask), caustic(reference, empty, strict)
        panels = [("Mitsuba 3", reference)]
        for name in ["truth"] + [f"solution {q}" for q in args.qualities]:
            mine = images[(name, "with")]
            ratio = caustic(mine, images[(name, "without")], mask) / power
            numbers, _ = metrics(reference, mine)
            row = record({"renderer": name, "caustic_pixels": int(mask.sum()), "caustic_ratio": ratio,
                          "strict_pixels": int(strict.sum()),
                          "strict_ratio": caustic(mine, images[(name, "without")], strict) / strict_power,
                          "within_5pct": abs(ratio - 1) <= 0.05, "mean_ratio": float(mine.mean() / reference.mean()),
                          "flip": numbers["flip_mean"], "seconds": seconds})
            print(f"{name}: caustic {row['caustic_ratio']:.4f} of Mitsuba's over {row['caustic_pixels']} pixels "
                  f"({row['strict_ratio']:.4f} over the {row['strict_pixels']} not grown), "
                  f"mean ratio {row['mean_ratio']:.4f}, FLIP {row['flip']:.4f}", flush=True)
            panels.append((f"{name}: caustic x{ratio:.3f}", mine))
        # the walkthrough's glass, each approach, against Mitsuba and the path tracer on the glass balls
        truth = images[("truth", "with")]
        balls = ball_pixels(args.scene, grow=-1) | ball_pixels(args.scene, "rough_ball", grow=-1)
        quality = args.qualities[-1]
        height, width = reference.shape[:2]
        for approach, (mine, first, frame) in display_approaches(tmp / f"{quality}_with.npz", (width, height)).items():
            against_mitsuba, _ = metrics(reference, mine, mask=balls)
            against_truth, _ = metrics(truth, mine, mask=balls)
            on = balls[..., None]
            row = record({"renderer": f"solution {quality} display, glass {approach}", "glass_pixels": int(balls.sum()),
                          "flip_glass": against_mitsuba["flip_mean_glossy"], "flip": against_mitsuba["flip_mean"],
                          "flip_glass_vs_truth": against_truth["flip_mean_glossy"],
                          "mean_ratio_glass": float((mine * on).sum() / (reference * on).sum()),
                          "first_frame_s": first, "frame_s": frame})
            print(f"glass {approach}: FLIP on the glass balls {row['flip_glass']:.4f} against Mitsuba "
                  f"({row['flip_glass_vs_truth']:.4f} against our path tracer), their mean ratio "
                  f"{row['mean_ratio_glass']:.3f}; whole image {row['flip']:.4f}; frame {1e3 * frame:.1f} ms "
                  f"(first, with its probes, {1e3 * first:.0f} ms)", flush=True)
            panels.append((f"display, glass {approach}", mine))
        truth_balls, _ = metrics(reference, truth, mask=balls)
        print(f"our path tracer on the glass balls: FLIP {truth_balls['flip_mean_glossy']:.4f} against Mitsuba")
    record.save("glass_caustic.jsonl")
    figure(panels, mask, RESULTS / "glass_caustic.png")
    print(json.dumps({"figure": str(RESULTS / "glass_caustic.png")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
