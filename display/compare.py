"""The paper's comparison figures, as files, with error images and numbers.

    figure 5   reference against fitted, from three viewpoints
    figure 6   2 against 8 virtual lights (each against the reference)
    figure 7   with and without virtual lights (fitted against diffuse only)

Every panel pair gets an error image (NVIDIA FLIP, HDR mode, on linear radiance) and
three numbers in ``compare.json``: FLIP mean, PSNR (dB) of the tone-mapped 8-bit
pictures, and relative MSE of the linear radiance, mean over pixels and channels of
(test - ref)^2 / (ref^2 + 0.01), which weighs an error against the light it sits in.
Each is given over the whole image and over the glossy objects' pixels alone
("_glossy"): the diffuse walls are identical in every mode and would otherwise
dilute every difference the virtual lights make.
"""

from __future__ import annotations

import json

import numpy as np
from PIL import Image, ImageDraw

from radiosity.formats import Camera
from radiosity.formats.atomic import atomic_output

from .renderer import tonemap


def metrics(reference, test, exposure=1.0, mask=None):
    """FLIP mean, PSNR and relative MSE of ``test`` against ``reference`` ((H, W, 3) linear),
    over the whole image and, with ``mask`` ((H, W) bool), over the masked pixels alone
    (keys suffixed "_glossy"); and the FLIP error image ((H, W, 3) uint8, magma)."""
    import flip_evaluator

    ref = np.ascontiguousarray(np.maximum(reference, 0), np.float32)
    tst = np.ascontiguousarray(np.maximum(test, 0), np.float32)
    error_map, _, _ = flip_evaluator.evaluate(ref, tst, "HDR", applyMagma=False)
    flip_values = np.asarray(error_map, np.float64).reshape(ref.shape[:2] + (-1,))[..., 0]
    a = tonemap(ref, exposure).astype(np.float64) / 255
    b = tonemap(tst, exposure).astype(np.float64) / 255
    squared = np.mean((a - b) ** 2, axis=2)
    relative = np.mean((tst.astype(np.float64) - ref) ** 2 / (ref.astype(np.float64) ** 2 + 0.01), axis=2)

    def numbers(select):
        mse = float(np.mean(squared[select]))
        return {
            "flip_mean": float(np.mean(flip_values[select])),
            "psnr_db": float("inf") if mse == 0 else float(10 * np.log10(1.0 / mse)),
            "relative_mse": float(np.mean(relative[select])),
        }

    out = numbers(np.ones(squared.shape, bool))
    if mask is not None and mask.any():
        out |= {f"{k}_glossy": v for k, v in numbers(mask).items()}
        out["glossy_pixels"] = int(mask.sum())
    error_image = _magma(flip_values)
    return out, error_image


def _magma(values):
    """(H, W) values in [0, 1] -> (H, W, 3) uint8 through matplotlib's magma colour map."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(values, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


def orbit(view, degrees):
    """``view`` turned about the vertical through its look-at point by ``degrees``."""
    eye, centre, up = (np.asarray(v, np.float64) for v in (view.eye, view.look_at, view.up))
    axis = up / np.linalg.norm(up)
    offset = eye - centre
    angle = np.radians(degrees)
    rotated = (offset * np.cos(angle) + np.cross(axis, offset) * np.sin(angle)
               + axis * (axis @ offset) * (1 - np.cos(angle)))
    return Camera(tuple(centre + rotated), view.look_at, view.up, view.fov_y_deg, view.width, view.height)


def _panel_row(images, labels, path):
    """Images side by side with a caption strip above each; written atomically."""
    h, w = images[0].shape[:2]
    strip = 22
    canvas = Image.new("RGB", (w * len(images), h + strip), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    for i, (image, label) in enumerate(zip(images, labels)):
        canvas.paste(Image.fromarray(image), (i * w, strip))
        draw.text((i * w + 6, 5), label, fill=(0, 0, 0))
    with atomic_output(path) as f:
        canvas.save(f, format="PNG")


def compare(renderer, out_dir, base_view, exposure=1.0, shading="pixel", views=None):
    """Write figures 5 to 7 and compare.json into ``out_dir``; returns the numbers.

    ``renderer`` must hold both a fitted model and a solution. ``views``: the three
    viewpoints of figure 5 (default: ``base_view`` and it turned 35 degrees each way).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    views = views or [base_view, orbit(base_view, -35.0), orbit(base_view, 35.0)]
    k_max = max((o.n_lights for o in renderer.objects), default=0)
    results = {"figure5": {}, "figure6": {}, "figure7": {}, "exposure": exposure, "shading": shading}

    glossy = [o.name for o in renderer.objects if o.n_lights > 0]
    results["glossy_objects"] = glossy

    def shot(view, mode, lights=None):
        return renderer.render(view, mode, shading, lights)

    for i, view in enumerate(views):
        reference, fitted = shot(view, "reference"), shot(view, "fitted")
        numbers, error = metrics(reference, fitted, exposure, renderer.object_mask(view, glossy))
        results["figure5"][f"view{i + 1}"] = numbers | {"eye": list(view.eye)}
        _panel_row([tonemap(reference, exposure), tonemap(fitted, exposure), error],
                   ["reference (solution)", f"fitted, {k_max} virtual lights", f"FLIP error, mean {numbers['flip_mean']:.3f}"],
                   out_dir / f"figure5_view{i + 1}.png")

    view = views[0]
    mask = renderer.object_mask(view, glossy)
    reference = shot(view, "reference")
    few = min(2, k_max)
    panels, labels = [tonemap(reference, exposure)], ["reference"]
    for k in (few, k_max):
        image = shot(view, "fitted", lights=k)
        numbers, error = metrics(reference, image, exposure, mask)
        results["figure6"][f"{k}_lights"] = numbers
        panels += [tonemap(image, exposure), error]
        labels += [f"{k} virtual lights", f"FLIP error, mean {numbers['flip_mean']:.3f}"]
    _panel_row(panels, labels, out_dir / "figure6.png")

    fitted, diffuse = shot(view, "fitted"), shot(view, "diffuse")
    with_lights, error_with = metrics(reference, fitted, exposure, mask)
    without, error_without = metrics(reference, diffuse, exposure, mask)
    results["figure7"] = {"with_virtual_lights": with_lights, "diffuse_only": without}
    _panel_row([tonemap(fitted, exposure), tonemap(diffuse, exposure), error_with, error_without],
               ["with virtual lights", "diffuse only (lights off)", f"FLIP with, mean {with_lights['flip_mean']:.3f}",
                f"FLIP without, mean {without['flip_mean']:.3f}"],
               out_dir / "figure7.png")

    with atomic_output(out_dir / "compare.json") as f:
        f.write(json.dumps(results, indent=2).encode())
    return results
