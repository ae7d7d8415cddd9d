"""Does a texture cost accuracy? A textured room against the same room untextured.

The target: a textured scene's reference display keeps the texture's detail,
its FLIP against the path tracer within 10 % of the same scene's without textures.

The scene (written by this script with its images): a room with a tiled floor, a
wallpapered back wall and a wooden box (8-bit sRGB PNG textures, fine detail: tiles
with grout, stripes and diamonds, wood rings), a red wall, a white ceiling with an area
lamp and a glossy ball that reflects them. Its untextured twin has each textured
material's kd multiplied by its texture's mean (linear) colour: the same light, no
detail. Both go through the command line a user runs (``vlights solve``, ``fit``,
``render --hdr``, ``truth --hdr``) at the same settings, and each display is measured
against its own scene's path-traced truth (FLIP, relative MSE). The truth's own noise
is measured too (the path tracer at N against 4N samples per pixel), since FLIP counts
it as error in both scenes alike.

    python benchmarks/bench_textures.py [--quality draft] [--size 240x180] [--spp 256] [--samples 64]

Writes benchmarks/results/textures.jsonl and textures.png (the pictures side by side
with their FLIP images), and keeps the run's files in --keep DIR if given.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, Recorder

SCENE = """\
[camera]
position = [0, 1.6, 5.5]
look_at = [0, 1.0, 0]
up = [0, 1, 0]
fov_y_deg = 50

[materials.tiles]
diffuse = {tiles}
[materials.wallpaper]
diffuse = {wallpaper}
[materials.wood]
diffuse = {wood}
[materials.white]
diffuse = 0.7
[materials.red]
diffuse = [0.6, 0.1, 0.1]
[materials.glossy]
diffuse = [0.1, 0.1, 0.15]
specular = [0.5, 0.5, 0.5]
exponent = 200
[materials.lamp]
emission = 20.0

[[objects]]
name = "floor"
builtin = "quad"
material = "tiles"
scale = [4, 1, 4]
[[objects]]
name = "back"
builtin = "quad"
material = "wallpaper"
scale = [4, 1, 3]
rotate_deg = [90, 0, 0]
translate = [0, 1.5, -2]
[[objects]]
name = "left"
builtin = "quad"
material = "red"
scale = [3, 1, 4]
rotate_deg = [0, 0, -90]
translate = [-2, 1.5, 0]
[[objects]]
name = "ceiling"
builtin = "quad"
material = "white"
scale = [4, 1, 4]
flip = true
translate = [0, 3, 0]
[[objects]]
name = "lamp"
builtin = "quad"
material = "lamp"
scale = [0.8, 1, 0.8]
flip = true
translate = [0, 2.99, 0]
[[objects]]
name = "box"
builtin = "cube"
material = "wood"
scale = 0.7
rotate_deg = [0, 25, 0]
translate = [0.8, 0.35, -0.5]
[[objects]]
name = "ball"
builtin = "sphere"
material = "glossy"
scale = 0.45
translate = [-0.7, 0.45, 0.2]
"""

KD = {"tiles": 0.9, "wallpaper": 0.85, "wood": 0.9}


def textures(seed=1):
    """The three images, (H, W, 3) uint8 sRGB: floor tiles with grout, wallpaper, wood."""
    rng = np.random.default_rng(seed)
    n, px = 8, 32
    y, x = np.mgrid[0:n * px, 0:n * px]
    tile = ((x // px) + (y // px)) % 2
    tiles = np.where(tile[..., None] == 1, [200, 180, 150], [120, 60, 40]).astype(float)
    tiles[((x % px) < 2) | ((y % px) < 2)] = [60, 60, 60]
    tiles += rng.normal(0, 6, tiles.shape)
    y, x = np.mgrid[0:256, 0:256]
    stripes = np.sin(x / 256 * 2 * np.pi * 12) > 0
    wallpaper = np.where(stripes[..., None], [210, 200, 170], [170, 190, 200]).astype(float)
    wallpaper[(np.abs((x % 32) - 16) + np.abs((y % 32) - 16)) < 6] = [150, 40, 60]
    y, x = np.mgrid[0:128, 0:128]
    rings = np.sin((x + 6 * np.sin(y / 9)) / 3.0) * 0.5 + 0.5
    wood = np.stack([150 + 60 * rings, 90 + 40 * rings, 40 + 20 * rings], axis=-1)
    return {name: np.clip(a, 0, 255).astype(np.uint8) for name, a in (("tiles", tiles), ("wallpaper", wallpaper),
                                                                          ("wood", wood))}


def write_scenes(directory):
    """scene.toml (textured) and plain.toml (each texture folded into kd by its mean)."""
    from PIL import Image

    from radiosity.physics.materials import srgb_to_linear

    textured, plain = {}, {}
    for name, image in textures().items():
        Image.fromarray(image).save(directory / f"{name}.png")
        textured[name] = f'{KD[name]}\ndiffuse_texture = "{name}.png"'
        mean = KD[name] * srgb_to_linear(image / 255.0).reshape(-1, 3).mean(axis=0)
        plain[name] = "[" + ", ".join(f"{c:.6f}" for c in mean) + "]"
    (directory / "scene.toml").write_text(SCENE.format(**textured))
    (directory / "plain.toml").write_text(SCENE.format(**plain))


def vlights(*args, cwd):
    """Run the command line; its wall time."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "display", *map(str, args)], cwd=cwd, check=True,
                   stdout=subprocess.DEVNULL, env=os.environ | {"PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    return time.perf_counter() - t0


def run_scene(name, directory, args):
    """Solve, fit, the displays and the truths of ``name``.toml; the images by label."""
    d = directory
    times = {
        "solve": vlights("solve", f"{name}.toml", "--quality", args.quality, "-o", f"{name}_sol.npz", cwd=d),
        "fit": vlights("fit", f"{name}_sol.npz", "--quality", args.quality, "-o", f"{name}_fit.npz", cwd=d),
    }
    size = ["--size", args.size]
    for mode in ("reference", "fitted", "diffuse"):
        vlights("render", f"{name}_fit.npz", "--solution", f"{name}_sol.npz", "--mode", mode, *size,
                "--samples", args.samples, "--hdr", f"{name}_{mode}.npy", cwd=d)
    for label, spp, seed in (("truth", args.spp, 1), ("truth_4x", 4 * args.spp, 2)):
        times[label] = vlights("truth", f"{name}_sol.npz", *size, "--spp", spp, "--seed", seed,
                               "--hdr", f"{name}_{label}.npy", cwd=d)
    images = {k: np.load(d / f"{name}_{k}.npy") for k in ("reference", "fitted", "diffuse", "truth", "truth_4x")}
    return images, times


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quality", default="draft", choices=("draft", "medium", "high"))
    parser.add_argument("--size", default="240x180")
    parser.add_argument("--spp", type=int, default=256, help="the truth's samples per pixel (its noise: against 4x)")
    parser.add_argument("--samples", type=int, default=64, help="the displays' samples per pixel (antialiasing)")
    parser.add_argument("--keep", type=Path, help="keep the run's files in this directory")
    args = parser.parse_args(argv)
    from display.metrics import metrics

    record = Recorder(benchmark="textures", quality=args.quality, size=args.size, spp=args.spp, samples=args.samples)
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.keep or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        write_scenes(directory)
        results, shown = {}, {}
        for name in ("scene", "plain"):
            images, times = run_scene(name, directory, args)
            truth = images["truth_4x"]
            row = {"scene": "textured" if name == "scene" else "untextured", "time_s": {k: round(v, 2) for k, v in times.items()}}
            for label in ("reference", "fitted", "diffuse", "truth"):
                m, flip_image = metrics(truth, images[label])
                row[label] = {"flip": round(float(m["flip_mean"]), 5), "relative_mse": round(float(m["relative_mse"]), 5)}
                shown[(name, label)] = (images[label], flip_image)
            results[name] = record(row)
        ratios = {label: results["scene"][label]["flip"] / results["plain"][label]["flip"]
                  for label in ("reference", "fitted", "diffuse", "truth")}
        record({"scene": "ratio textured / untextured", "flip_ratio": {k: round(v, 4) for k, v in ratios.items()},
                "target": "reference within 1.10", "met": bool(ratios["reference"] <= 1.10)})
        record.save("textures.jsonl")
        plot(shown, results, RESULTS / "textures.png")


def plot(shown, results, path):
    """The displays and their FLIP images against the truth, textured above, untextured below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from display.renderer import tonemap

    labels = ("reference", "fitted", "truth")
    fig, axes = plt.subplots(4, 3, figsize=(12, 12))
    for r, name in enumerate(("scene", "plain")):
        for c, label in enumerate(labels):
            image, flip = shown[(name, label)]
            axes[2 * r, c].imshow(tonemap(image))
            axes[2 * r, c].set_title(f"{'textured' if name == 'scene' else 'untextured'}: {label}")
            axes[2 * r + 1, c].imshow(flip)
            axes[2 * r + 1, c].set_title(f"FLIP {results[name][label]['flip']:.4f}")
    for ax in axes.ravel():
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    print(json.dumps({"plot": str(path)}))


if __name__ == "__main__":
    main()
