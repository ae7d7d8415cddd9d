"""Perfect mirrors at display against the path tracer and a reference render: the
project's own scene (tests/data/mitsuba/validate_mirror.xml: a flat silver mirror and a
chrome ball, against Mitsuba 3) and the living room of the rendering community's
collection (its mirror over the fireplace, against the published Tungsten render).

For each scene: the reference (Mitsuba at 4 x ``--spp``, or the published render shrunk
by a whole factor to at most ``--max-side`` pixels), ``vlights truth`` at ``--spp`` at
that size, ``vlights solve`` at ``--quality``, and the solution display at the scene's
camera twice: the mirrors drawn by what they reflect (``display.mirror``: the scene
reflected in a flat mirror's plane, a curved one's probe) and from what the solution stores
for them (``Renderer.mirrors`` False: their grid before solution version 7, which was black
and blotched; nothing since, black). On the mirrors' pixels (the camera's rays
whose first hit is a mirror, Embree on the solution's meshes): HDR-FLIP and mean ratio
against the reference and against the path tracer; the whole image's FLIP; a figure.

    python benchmarks/validate_mirror.py                      # both scenes (the living room if present)
    python benchmarks/validate_mirror.py --scenes validate_mirror --quality medium
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, Recorder, mitsuba_python, mitsuba_render  # noqa: E402
from _common import vlights_or_exit as vlights

ROOT = Path(__file__).resolve().parent.parent
SCENES = {
    "validate_mirror": (ROOT / "tests" / "data" / "mitsuba" / "validate_mirror.xml", None),
    "living-room": (Path("living-room/scene.xml"), Path("living-room/TungstenRender.exr")),
}



def shrunk(image, max_side):
    """``image`` box-filtered by the least whole factor dividing both sides that brings its
    longer side to ``max_side`` or below."""
    h, w = image.shape[:2]
    factor = next((f for f in range(1, max(h, w) + 1) if h % f == 0 and w % f == 0 and max(h, w) // f <= max_side),
                  1)
    return image.reshape(h // factor, factor, w // factor, factor, 3).mean(axis=(1, 3)).astype(np.float32)


def mirror_pixels(solution, camera):
    """(H, W) bool: the pixels whose centre's ray first meets a perfect mirror."""
    from display.mirror import mirror_of
    from radiosity.transport.embree import RayTracer

    positions, faces, owner, offset = [], [], [], 0
    for index, o in enumerate(solution.objects):
        positions.append(np.asarray(o.positions, np.float64))
        faces.append(np.asarray(o.faces) + offset)
        owner.append(np.full(len(o.faces), index))
        offset += len(o.positions)
    mirrors = np.array([mirror_of(o) is not None for o in solution.objects])
    rays = camera.pixel_rays().reshape(-1, 3)
    with RayTracer(np.concatenate(positions), np.concatenate(faces)) as tracer:
        hits = tracer.intersect(np.broadcast_to(np.asarray(camera.eye, np.float32), rays.shape), rays)
    triangle = np.asarray(hits.triangle)
    owners = np.concatenate(owner)
    hit = triangle >= 0
    out = np.zeros(len(rays), bool)
    out[hit] = mirrors[owners[triangle[hit]]]
    return out.reshape(camera.height, camera.width)


def displays(solution_path, size, samples=4):
    """{"reflected": image, "grid": image} of the solution display at its camera, and the mask."""
    from display.commands.common import headless
    from display.renderer import Renderer
    from radiosity.files.solution import load_solution

    solution = load_solution(solution_path)
    camera = solution.camera.sized(*size)
    out = {}
    with headless(size, samples) as ctx:
        for name, on in (("reflected", True), ("stored", False)):
            renderer = Renderer(ctx, solution=solution, samples=samples)
            renderer.mirrors = on
            start = time.perf_counter()
            out[name] = (renderer.render(camera, "reference"), time.perf_counter() - start)
            renderer.release()
    return out, mirror_pixels(solution, camera)


def figure(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap

    fig, axes = plt.subplots(len(rows), 4, figsize=(13, 2.4 * len(rows)), squeeze=False)
    for row, (scene, panels, mask) in zip(axes, rows, strict=True):
        for ax, (title, image) in zip(row, panels, strict=True):
            ax.imshow(tonemap(image))
            ax.contour(mask, levels=[0.5], colors="cyan", linewidths=0.5)
            ax.set_title(f"{scene}: {title}", fontsize=8)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--root", type=Path, default=Path(os.environ.get("VLIGHTS_SCENES", "/work/scenes")),
                        help="where the collection's scenes are (default $VLIGHTS_SCENES or /work/scenes)")
    parser.add_argument("--spp", type=int, default=256, help="the path tracer's samples (Mitsuba's: 4x)")
    parser.add_argument("--max-side", type=int, default=320, help="a published render shrunk to at most this")
    parser.add_argument("--quality", default="draft", help="the solver's preset (default draft)")
    parser.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (default scalar_rgb)")
    parser.add_argument("--mitsuba-python", help="the Python of a venv with mitsuba installed")
    args = parser.parse_args(argv)
    from display.metrics import metrics
    from radiosity.files.images import read_hdr_image

    python, version = mitsuba_python(args.mitsuba_python)
    record = Recorder(benchmark="mirrors", spp=args.spp, quality=args.quality, mitsuba=version)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in args.scenes:
            xml, published = SCENES[name]
            xml = xml if xml.is_absolute() else args.root / xml
            if not xml.exists():
                print(f"{name}: skipped: {xml} is not here (fetch the collection, see benchmarks/README.md)")
                continue
            work = tmp / name
            work.mkdir()
            if published is None:
                if python is None:
                    print(f"{name}: skipped: Mitsuba 3 is not installed (see validate_mitsuba.py)")
                    continue
                _, reference = mitsuba_render(python, args.variant, xml, 4 * args.spp, 1, work / "mitsuba.npy")
                source = f"Mitsuba {version} ({4 * args.spp} spp)"
            else:
                reference = shrunk(read_hdr_image(args.root / published), args.max_side)
                source = "the published render"
            height, width = reference.shape[:2]
            truth_path = work / "truth.npy"
            truth_s = vlights(["truth", xml, "--spp", args.spp, "--size", f"{width}x{height}", "--hdr", truth_path,
                               "-o", work / "truth.png"], work)
            truth = np.load(truth_path)
            solve_s = vlights(["solve", xml, "--quality", args.quality, "-o", work / "solution.npz"], work)
            images, mask = displays(work / "solution.npz", (width, height))
            for label, image in (("truth", truth), *((f"display, mirrors {k}", v[0]) for k, v in images.items())):
                against, _ = metrics(reference, image, mask=mask)
                row = {"scene": name, "renderer": label, "reference": source, "mirror_pixels": int(mask.sum()),
                       "flip_mirrors": against.get("flip_mean_glossy"), "flip": against["flip_mean"],
                       "mean_ratio_mirrors": float(image[mask].sum() / reference[mask].sum()) if mask.any() else None,
                       "seconds": {"truth": truth_s, "solve": solve_s}}
                if label != "truth":
                    versus, _ = metrics(truth, image, mask=mask)
                    row["flip_mirrors_vs_truth"] = versus.get("flip_mean_glossy")
                    row["frame_s"] = images[label.split()[-1]][1]
                record(row)
                print(f"{name} {label}: on the mirrors ({row['mirror_pixels']} pixels) FLIP {row['flip_mirrors']:.4f} "
                      f"against {source}"
                      + (f", {row['flip_mirrors_vs_truth']:.4f} against the path tracer" if label != "truth" else "")
                      + f", mean ratio {row['mean_ratio_mirrors']:.3f}; whole image FLIP {row['flip']:.4f}", flush=True)
            rows.append((name, [(source, reference), ("path tracer", truth)]
                         + [(f"display, mirrors {k}", v[0]) for k, v in images.items()], mask))
    record.save("mirrors.jsonl")
    if rows:
        figure(rows, RESULTS / "mirrors.png")
        print(json.dumps({"figure": str(RESULTS / "mirrors.png")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
