"""The paper's comparison figures, as files, with error images and numbers.

    figure 5   reference against fitted, from three viewpoints
    figure 6   2 against 8 virtual lights (each against the reference)
    figure 7   the fitted model against a diffuse walkthrough (the solution's radiance
               averaged over directions at each vertex)

Every panel pair gets an error image (NVIDIA FLIP, HDR mode, on linear radiance) and
three numbers (``display.metrics``) in ``compare.json``: FLIP mean, PSNR (dB) of the tone-mapped 8-bit
pictures, and relative MSE of the linear radiance, mean over pixels and channels of
(test - ref)^2 / (ref^2 + 0.01), which weighs an error against the light it sits in.
Each is given over the whole image and over the glossy objects' pixels alone
("_glossy"): the diffuse walls are identical in every mode and would otherwise
dilute every difference the virtual lights make.

How to read them: FLIP is NVIDIA's perceptual difference of two pictures, per pixel
from 0 (identical) to 1 (as different as can be), lower is better; every error image
shows it through the magma colour map (black 0, pale yellow 1) with a colour bar of
that scale beside it. PSNR: higher is better. Relative MSE: lower is better, 0 exact.

Every picture is antialiased as the renderer draws it (its ``samples`` per pixel,
averaged with equal weights: a box filter over the pixel); ``compare.json`` records the
samples and how they were drawn ("antialiasing"). The glossy objects' pixels are those
whose centre sees one (``Renderer.object_mask``, one sample).

With a path-traced truth for a view (``display.truth``), figure 5's row for that view
starts with the truth and ends with the fitted display's FLIP against it, and
``compare.json``'s "truth" holds FLIP, PSNR and relative MSE of the reference, fitted
and diffuse-only displays against the truth (whole image and glossy objects), with the
truth's samples and noise floor (FLIP between its two halves).

With an external reference image (``ReferenceImage``: another renderer's picture of
the scene from its camera, ``vlights compare --reference``), ``compare.json``'s
"reference_image" holds, for the reference, fitted and diffuse displays and (when it
was traced) the path tracer, each against that image at its size: FLIP, PSNR and
relative MSE (whole image and glossy objects) and the mean ratio (mean of the display
over mean of the image: 1 is as much light, 0.5 half); ``reference/`` holds the
renders (.npy, linear), their FLIP error images and a panel row per display.

Figure 7 is what the model buys over a diffuse walkthrough: ``compare.json``'s
"glossy_flip" holds FLIP on the glossy objects of the fitted display and of the
diffuse one, their ratio, and whether it meets the target (at most ``FIGURE7_TARGET``
times diffuse-only).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace

import numpy as np
from PIL import Image, ImageDraw

from radiosity.files.atomic import atomic_output
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError

from .choices import ORBIT_DEGREES
from .images import write_npy, write_png
from .metrics import BLACK, NOT_FINITE, against_truth, is_black, magma, mean_ratio, metrics
from .outputs import staged_directory
from .renderer import tonemap

FILES = ("figure5_view1.png", "figure5_view2.png", "figure5_view3.png", "figure6.png", "figure7.png", "compare.json")
FIGURE7_TARGET = 0.5  # the target: FLIP on the glossy objects of the fitted display <= 0.5 x diffuse-only
CAPTION = 22  # height of the caption strip above each panel, pixels
BAR_WIDTH = 44  # the colour bar column beside each FLIP error image, pixels


def orbit(view, degrees):
    """``view`` turned about the vertical through its look-at point by ``degrees``."""
    eye, centre, up = (np.asarray(v, np.float64) for v in (view.eye, view.look_at, view.up))
    axis = up / np.linalg.norm(up)
    offset = eye - centre
    angle = np.radians(degrees)
    rotated = (offset * np.cos(angle) + np.cross(axis, offset) * np.sin(angle)
               + axis * (axis @ offset) * (1 - np.cos(angle)))
    return replace(view, eye=tuple(centre + rotated))  # its fov along its axis, its size


def colour_bar(height, width=BAR_WIDTH):
    """(height, width, 3) uint8: FLIP's scale as drawn beside every error image, a
    magma gradient from 1 (top) to 0 (bottom) with short ticks at 1, 0.5 and 0 and
    their values."""
    column = Image.new("RGB", (width, height), (255, 255, 255))
    pad = 6 if height >= 40 else 1
    span = max(height - 2 * pad, 2)
    values = np.linspace(1.0, 0.0, span)[:, None].repeat(10, axis=1)
    column.paste(Image.fromarray(magma(values)), (3, pad))
    draw = ImageDraw.Draw(column)
    for value, text in ((1.0, "1"), (0.5, "0.5"), (0.0, "0")):
        y = pad + round((1.0 - value) * (span - 1))
        draw.line([(13, y), (14, y)], fill=(0, 0, 0))
        draw.text((17, min(max(y - 5, 0), max(height - 11, 0))), text, fill=(0, 0, 0))
    return np.asarray(column)


def _panel_row(images, labels, path, errors=()):
    """Images side by side with a caption strip above each; written atomically.

    ``errors``: indices of the panels that are FLIP error images: each gets a colour
    bar of FLIP's scale (0 to 1, magma) beside it, captioned "FLIP"."""
    h, w = images[0].shape[:2]
    errors = set(errors)
    width = w * len(images) + BAR_WIDTH * len(errors)
    canvas = Image.new("RGB", (width, h + CAPTION), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    x = 0
    for i, (image, label) in enumerate(zip(images, labels)):
        canvas.paste(Image.fromarray(image), (x, CAPTION))
        draw.text((x + 6, 5), label, fill=(0, 0, 0))
        x += w
        if i in errors:
            canvas.paste(Image.fromarray(colour_bar(h)), (x, CAPTION))
            draw.text((x + 3, 5), "FLIP", fill=(0, 0, 0))
            x += BAR_WIDTH
    write_png(path, canvas)


def json_ready(value, notes, where=""):
    """``value`` (dicts, lists, numbers) with every non-finite float replaced by None,
    so that it is strict JSON; each replacement is explained in ``notes``."""
    if isinstance(value, dict):
        return {k: json_ready(v, notes, f"{where}.{k}" if where else str(k)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v, notes, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, float | np.floating) and not math.isfinite(value):
        if where.split(".")[-1].startswith("psnr_db") and value > 0:
            notes.append(f"{where} is null: the two pictures are identical, so the PSNR is infinite")
        else:
            notes.append(f"{where} is null: the value is {float(value)!r}, not a finite number")
        return None
    if isinstance(value, np.generic):
        return value.item()
    return value


def json_text(results):
    """``results`` as strict JSON (no NaN or Infinity): non-finite numbers become null
    and a "notes" list says which and why."""
    notes = []
    ready = json_ready(results, notes)
    if notes:
        ready["notes"] = notes
    return json.dumps(ready, indent=2, allow_nan=False)


def _glossy(numbers):
    """FLIP over the glossy objects' pixels (over the whole image where none shows)."""
    return numbers.get("flip_mean_glossy", numbers["flip_mean"])


def glossy_flip(with_lights, diffuse_only, target=FIGURE7_TARGET):
    """Figure 7's point in numbers: FLIP on the glossy objects with the virtual lights
    and with the emitted colour alone, their ratio (lower is better: 1 means the lights
    change nothing a viewer sees), and whether it meets ``target``."""
    w, wo = _glossy(with_lights), _glossy(diffuse_only)
    ratio = w / wo if wo > 0 else (1.0 if w == 0 else float("inf"))
    return {
        "over": "glossy objects" if "flip_mean_glossy" in with_lights else "whole image (no glossy object in view)",
        "with_virtual_lights": w, "diffuse_only": wo, "ratio": ratio,
        "target_ratio": target, "meets_target": bool(ratio <= target),
    }


def _fitted_words(renderer):
    """The fitted panel's label: what the glossy objects' models hold."""
    objects = [o for o in renderer.objects if o.glossy]
    parts = []
    if any("fitted" in o.highlight for o in objects):
        parts.append("emitters")
    if any(o.probe is not None for o in objects):
        parts.append("probe")
    k = max((o.n_lights for o in objects), default=0)
    if k:
        parts.append(f"{k} lights")
    return "fitted: " + (" + ".join(parts) if parts else "emitted colour")




def figure5_views(base_view):
    """Figure 5's three viewpoints: ``base_view`` and it turned ORBIT_DEGREES each way."""
    return [base_view, orbit(base_view, -ORBIT_DEGREES), orbit(base_view, ORBIT_DEGREES)]


def truth_numbers(truth, images, exposure, mask):
    """Each display image ({mode: (H, W, 3)}) against a ``GroundTruth``: (its metrics per
    mode with the truth's samples and noise floor, {mode: FLIP error image})."""
    numbers, errors = against_truth(truth.radiance, images, exposure, mask)
    return {"spp": truth.spp, "noise_flip": truth.noise_flip,
            "noise_means": "FLIP between the two independent halves of the truth's samples: errors near it are noise",
            **numbers}, errors


REFERENCE_DIR = "reference"  # compare --reference's files, inside --out
REFERENCE_STEMS = {"reference": "reference_display", "fitted": "fitted_display", "diffuse": "diffuse_display",
                   "path_tracer": "path_tracer"}
DISPLAY_LABELS = {"reference": "solution display", "fitted": "fitted display",
                     "diffuse": "diffuse display", "path_tracer": "path tracer"}


@dataclass(frozen=True)
class ReferenceImage:
    """An external picture of the scene to measure every display against.

    radiance : (H, W, 3) float32 linear radiance, row 0 at the top (``display.images.read_hdr_image``)
    camera   : the ``Camera`` it was taken with, at its size (W x H)
    file     : where it was read from, as given
    factor   : the whole factor it was box-averaged down by to that size (1: as read)
    """

    radiance: np.ndarray
    camera: Camera
    file: str
    factor: int = 1


def reference_files(path_traced):
    """The files ``compare`` writes for a ``ReferenceImage``, relative to its output
    directory; with ``path_traced``, the path tracer's too."""
    modes = [m for m in REFERENCE_STEMS if path_traced or m != "path_tracer"]
    return (f"{REFERENCE_DIR}/image.png",) + tuple(
        f"{REFERENCE_DIR}/{REFERENCE_STEMS[m]}{ext}" for m in modes for ext in (".png", "_flip.png", ".npy"))


def reference_at(image, size, where):
    """(``image`` at ``size``, the factor): as read when ``size`` is None or its own,
    box-averaged by a whole factor when ``size`` ((width, height)) divides it so (what a
    display pixel's samples average); InputError naming ``where`` otherwise (another
    aspect ratio, or a size no whole factor reaches)."""
    h, w = image.shape[:2]
    if size is None or tuple(size) == (w, h):
        return image, 1
    width, height = size
    if w * height != h * width:
        raise InputError(f"{where} is {w}x{h} (aspect ratio {w / h:.4g}), but --size {width}x{height} has aspect "
                         f"ratio {width / height:.4g}: the renders must frame what the image frames; leave --size out "
                         "to render at the image's size")
    factor = w // width
    if w % width or h % height or factor < 2:
        raise InputError(f"{where} is {w}x{h}; --size {width}x{height} is not it shrunk by a whole factor (a box "
                         "average of whole pixels); leave --size out to render at the image's size")
    shrunk = image.astype(np.float64).reshape(height, factor, width, factor, 3).mean(axis=(1, 3))
    return shrunk.astype(np.float32), factor


def _against_reference(reference, images, exposure, mask, stage):
    """Each of ``images`` ({mode: (H, W, 3) linear}) against ``reference`` (a
    ``ReferenceImage``): its numbers, and its render, FLIP error image and panel row
    written into ``stage``/reference/."""
    folder = stage / REFERENCE_DIR
    folder.mkdir(exist_ok=True)
    shown = tonemap(reference.radiance, exposure)
    write_png(folder / "image.png", shown)
    numbers = {}
    for mode, image in images.items():
        measured, error = metrics(reference.radiance, image, exposure, mask)
        measured["mean_ratio"] = mean_ratio(reference.radiance, image)
        numbers[mode] = measured
        stem = folder / REFERENCE_STEMS[mode]
        write_npy(stem.with_suffix(".npy"), np.asarray(image, np.float32))
        write_png(folder / f"{REFERENCE_STEMS[mode]}_flip.png", error)
        _panel_row([shown, tonemap(image, exposure), error],
                   ["reference image", DISPLAY_LABELS[mode],
                    f"FLIP {measured['flip_mean']:.3f}, ratio {measured['mean_ratio']:.3f}"],
                   stem.with_suffix(".png"), errors=(2,))
    return numbers


def compare(renderer, out_dir, base_view, exposure=1.0, shading="pixel", views=None, truths=None, *,
            reference_image=None):
    """Write figures 5 to 7 and compare.json into ``out_dir``; returns the numbers.

    ``renderer`` must hold both a fitted model and a solution. ``views``: the three
    viewpoints of figure 5 (default: ``base_view`` and it turned 35 degrees each way).
    ``out_dir`` is created if missing (not its parents). The files appear together at
    the end (``display.outputs.staged_directory``): a failure or Ctrl-C leaves none.
    The returned numbers keep infinities (the PSNR of identical pictures); compare.json
    has null there, explained in its "notes". ``truths``: per view, a
    ``display.truth.GroundTruth`` (or None where there is none). ``reference_image``: a
    ``ReferenceImage`` (at ``base_view``, which is figure 5's first view) to measure
    the displays and the truth of the first view, if there is one, against; its numbers
    are compare.json's "reference_image", its files in reference/.
    """
    views = views or figure5_views(base_view)
    truths = list(truths or []) + [None] * (len(views) - len(truths or []))
    k_max = max((o.n_lights for o in renderer.objects), default=0)
    plan = renderer.plan
    results = {"figure5": {}, "figure6": {}, "figure7": {}, "exposure": exposure, "shading": shading,
               "samples": plan.samples,
               "antialiasing": {"msaa": plan.msaa, "supersampling": plan.factor, "samples_per_pixel": plan.per_pixel,
                                "filter": "box (the mean of the samples inside each pixel)"}}

    glossy = [o.name for o in renderer.objects if o.glossy]
    results["glossy_objects"] = glossy

    def shot(view, mode, lights=None):
        return renderer.render(view, mode, shading, lights)

    references = []  # all three first: a black one is refused before any work or file
    for i, view in enumerate(views):
        references.append(shot(view, "reference"))
        if not np.isfinite(references[-1]).all():
            count = int(np.sum(~np.isfinite(references[-1])))
            raise InputError(f"the reference image (the solution seen from view {i + 1}) {NOT_FINITE.format(count=count)}")
        if is_black(references[-1]):
            raise InputError(f"the reference image (the solution seen from view {i + 1}) {BLACK}; is the scene lit, "
                             "and does the camera see it?")

    for i, (view, truth) in enumerate(zip(views, truths)):
        if truth is not None and is_black(truth.radiance):
            eye = ", ".join(f"{c:.4g}" for c in view.eye)
            where = "" if i == 0 else f", view 1 turned {ORBIT_DEGREES:g} degrees about its look-at point"
            raise InputError(f"the path-traced truth of view {i + 1} (eye at ({eye}){where}) {BLACK}; is that eye "
                             "outside the lit space, behind a wall? Views 2 and 3 turn view 1 about its look-at "
                             "point: an eye nearer to it keeps them inside")

    with staged_directory(out_dir) as stage:
        for i, (view, reference, truth) in enumerate(zip(views, references, truths)):
            fitted = shot(view, "fitted")
            mask = renderer.object_mask(view, glossy)
            numbers, error = metrics(reference, fitted, exposure, mask)
            results["figure5"][f"view{i + 1}"] = numbers | {"eye": list(view.eye)}
            panels = [tonemap(reference, exposure), tonemap(fitted, exposure), error]
            labels = ["solution display", _fitted_words(renderer),
                      f"FLIP error (0 = identical), mean {numbers['flip_mean']:.3f}"]
            errors = (2,)
            if truth is not None:
                against, against_errors = truth_numbers(
                    truth, {"reference": reference, "fitted": fitted, "diffuse": shot(view, "diffuse")}, exposure, mask)
                results.setdefault("truth", {})[f"view{i + 1}"] = against
                spp = f"{truth.spp} spp" if truth.spp else "from a file"
                panels = [tonemap(truth.radiance, exposure)] + panels + [against_errors["fitted"]]
                labels = [f"path-traced truth ({spp})"] + labels + [
                    f"fitted against the truth: FLIP {against['fitted']['flip_mean']:.3f}"]
                errors = (3, 4)
            _panel_row(panels, labels, stage / f"figure5_view{i + 1}.png", errors=errors)

        view, reference = views[0], references[0]
        mask = renderer.object_mask(view, glossy)
        few = min(2, k_max)
        panels, labels = [tonemap(reference, exposure)], ["reference"]
        for k in (few, k_max):
            image = shot(view, "fitted", lights=k)
            numbers, error = metrics(reference, image, exposure, mask)
            results["figure6"][f"{k}_lights"] = numbers
            panels += [tonemap(image, exposure), error]
            labels += [f"{k} virtual lights", f"FLIP error, mean {numbers['flip_mean']:.3f}"]
        _panel_row(panels, labels, stage / "figure6.png", errors=(2, 4))

        fitted, diffuse = shot(view, "fitted"), shot(view, "diffuse")
        with_lights, error_with = metrics(reference, fitted, exposure, mask)
        without, error_without = metrics(reference, diffuse, exposure, mask)
        results["figure7"] = {"with_virtual_lights": with_lights, "diffuse_only": without}
        results["glossy_flip"] = glossy_flip(with_lights, without)
        _panel_row([tonemap(fitted, exposure), tonemap(diffuse, exposure), error_with, error_without],
                   ["fitted model", "diffuse walkthrough",
                    f"FLIP fitted: glossy {_glossy(with_lights):.3f}, image {with_lights['flip_mean']:.3f}",
                    f"FLIP diffuse: glossy {_glossy(without):.3f}, image {without['flip_mean']:.3f}"],
                   stage / "figure7.png", errors=(2, 3))

        if reference_image is not None:
            camera = reference_image.camera
            if truths[0] is not None and truths[0].radiance.shape != reference_image.radiance.shape:
                raise ValueError("the truth of view 1 is not at the reference image's size")
            mask = renderer.object_mask(camera, glossy)
            images = {"reference": shot(camera, "reference"), "fitted": shot(camera, "fitted"),
                      "diffuse": shot(camera, "diffuse")}
            if truths[0] is not None:
                images["path_tracer"] = truths[0].radiance
            displays = _against_reference(reference_image, images, exposure, mask, stage)
            if truths[0] is not None:
                displays["path_tracer"] |= {"spp": truths[0].spp, "seed": truths[0].stats.get("seed"),
                                            "noise_flip": truths[0].noise_flip}
            results["reference_image"] = {
                "file": reference_image.file, "width": camera.width, "height": camera.height,
                "downsampled_by": reference_image.factor, "camera": camera.to_dict(),
                "mean": float(np.mean(reference_image.radiance, dtype=np.float64)),
                "means": "each display (and the path tracer, when traced) against the image at its camera and size: "
                         "FLIP (0 identical, 1 as different as can be), PSNR of the tone-mapped pictures, relative "
                         "MSE, and mean_ratio = mean of the display / mean of the image (1: as much light)",
                "displays": displays,
            }

        with atomic_output(stage / "compare.json") as f:
            f.write(json_text(results).encode())
    return results
