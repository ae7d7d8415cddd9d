"""Ground truth: the path tracer's picture of what the display shows, and every
display mode's error against it.

The path tracer (``radiosity.transport.pathtrace``) renders the solution's own meshes
and materials (or a scene's), from the same Contract 3 camera, integrating over each
pixel with a box filter as the antialiased display does. What it cannot know is its
own noise; ``ground_truth`` therefore traces two independent halves of the samples
(samples 0 .. N/2 - 1 and N/2 .. N - 1 of each pixel: together exactly the N-sample
image) and reports FLIP between the halves, the noise floor below which no error
against the truth means anything.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from radiosity.formats import InputError
from radiosity.formats.limits import check_exposure, check_seed

__all__ = ["GroundTruth", "against_truth", "ground_truth", "load_truth", "scene_for_truth"]


def scene_for_truth(path):
    """The ``Scene`` to path-trace: a solution.npz's meshes and materials (what its
    displays show), or a scene (TOML, OBJ, glTF or a built-in name). A fit.npz holds no
    materials and is refused (InputError)."""
    from radiosity.formats import file_format, load_solution
    from radiosity.scene.loaders import load_scene

    text = str(path)
    if not (text.endswith(".npz") or (os.path.isfile(text) and file_format(text) is not None)):
        return load_scene(text)  # a scene file or a built-in; the loader names what is wrong
    fmt = file_format(text)  # InputError if missing
    if fmt == "vlights.fit":
        raise InputError(f"{text!r} is a fit.npz, which holds no materials to path-trace; give the "
                         "solution.npz it was fitted to, or the scene")
    if fmt != "vlights.solution":
        raise InputError(f"{text!r} is not a solution.npz (nor a scene)")
    return load_solution(text)


@dataclass(frozen=True)
class GroundTruth:
    """A path-traced image and how much to trust it.

    radiance   : (H, W, 3) float32 linear radiance, the mean of all samples
    spp        : samples per pixel
    noise_flip : FLIP between the two independent halves of the samples (the error the
                 path tracer's own noise would show against the truth), None for 1 spp
    stats      : the path tracer's, both halves together (paths, rays, seconds, rates)
    """

    radiance: np.ndarray
    spp: int
    noise_flip: float | None
    stats: dict


def ground_truth(source, camera, spp, seed=1, threads=None, progress=False):
    """Path-trace ``camera`` (a ``Camera``) of ``source`` (a ``Solution`` or a ``Scene``)
    with ``spp`` samples per pixel, as two independent halves; a ``GroundTruth``."""
    from display.compare import is_black, metrics
    from radiosity.formats.solution import Solution
    from radiosity.transport.pathtrace import PathTracer, scene_of_solution

    scene = scene_of_solution(source) if isinstance(source, Solution) else source
    first = spp // 2
    with PathTracer(scene, threads=threads) as tracer:
        halves = [tracer.render(camera, n, seed, progress, first_sample=start)
                  for n, start in ((first, 0), (spp - first, first)) if n > 0]
    total = sum(h.radiance.astype(np.float64) * h.spp for h in halves)
    radiance = (total / spp).astype(np.float32)
    noise = None
    if len(halves) == 2 and not is_black(halves[0].radiance):
        noise = metrics(halves[0].radiance, halves[1].radiance)[0]["flip_mean"]
    seconds = sum(h.stats["seconds"] for h in halves)
    rays = sum(h.stats["rays"] for h in halves)
    stats = halves[0].stats | {
        "spp": spp, "paths": spp * camera.width * camera.height, "rays": rays,
        "shadow_rays": sum(h.stats["shadow_rays"] for h in halves), "seconds": round(seconds, 4),
        "rays_per_s": rays / seconds if seconds > 0 else 0.0,
        "paths_per_s": spp * camera.width * camera.height / seconds if seconds > 0 else 0.0,
    }
    return GroundTruth(radiance, spp, noise, stats)


def check_spp(value, flag="--spp", low=1):
    """Refuse (InputError) a sample count outside low .. the path tracer's maximum."""
    from radiosity.transport.pathtrace import check_samples

    check_samples(value, flag, low)


def load_truth(path, camera):
    """A path-traced image from ``--truth FILE.npy`` for ``camera``: (H, W, 3) float32,
    finite, not negative, of the camera's size; InputError naming the problem."""
    try:
        image = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError(f"--truth {str(path)!r} not found") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"--truth {str(path)!r} is not a .npy image: {' '.join(str(exc).split())}") from None
    want = (camera.height, camera.width, 3)
    if image.shape != want:
        raise InputError(f"--truth {str(path)!r} is {image.shape}, but the view is {camera.width}x{camera.height}: "
                         f"give an image of shape {want} (render it with the same --size and camera)")
    if image.dtype.kind != "f" or not np.isfinite(image).all() or (image < 0).any():
        raise InputError(f"--truth {str(path)!r} must hold finite, non-negative linear radiance")
    return image.astype(np.float32)


def against_truth(truth, images, exposure=1.0, mask=None):
    """Each of ``images`` ({label: (H, W, 3) linear}) against the path-traced ``truth``:
    {label: FLIP, PSNR and relative MSE, whole image and (with ``mask``) glossy pixels},
    and {label: its FLIP error image}."""
    from display.compare import metrics

    numbers, errors = {}, {}
    for label, image in images.items():
        numbers[label], errors[label] = metrics(truth, image, exposure, mask)
    return numbers, errors


def truth_camera(args, source):
    """The camera of ``vlights truth``: from the flags, else the source's own camera
    (a solution's or a scene's), else a view framing it."""
    from display.camera import resolve_camera

    positions = np.concatenate([o.positions for o in source.objects])
    return resolve_camera(args, np.stack([positions.min(axis=0), positions.max(axis=0)]), source.camera)


TRUTH_BYTES_PER_PIXEL = 4 * 3 * 8 + 3 * 4  # the running sums of both halves (float64) and the image


def add_truth_command(subparsers, add_camera_flags):
    """``vlights truth``: the path-traced ground truth of a solution's (or scene's) view."""
    from radiosity.formats import presets

    p = subparsers.add_parser(
        "truth",
        help="path-trace the ground truth of a view (to compare the walkthrough against)",
        description="Path-trace a view of a solution.npz's meshes and materials (or a scene's): next-event "
        "estimation and BRDF sampling combined by MIS, Russian roulette, a box filter over each pixel. The "
        "image depends on the seed and the samples alone, not on threads. Prints the time, rays and paths per "
        "second, and the noise floor: FLIP between the two independent halves of the samples.",
    )
    p.add_argument("input", help="solution.npz, or a scene (TOML, OBJ, glTF, or a built-in name such as cornell-teapot)")
    add_camera_flags(p, (512, 512))
    p.add_argument("--spp", type=int, help="samples per pixel (default: the --quality preset's truth_spp)")
    p.add_argument("--quality", choices=presets.QUALITIES, default=presets.DEFAULT_QUALITY,
                   help="sets --spp: " + ", ".join(f"{q} {presets.preset(q).truth_spp}" for q in presets.QUALITIES)
                   + " (default: %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="default: %(default)s")
    p.add_argument("--threads", type=int, help="worker threads (default: one per core); the image does not depend on it")
    p.add_argument("--hdr", metavar="FILE.npy", help="write linear radiance (H, W, 3) float32")
    p.add_argument("-o", "--output", metavar="FILE.png", help="write the tone-mapped picture (default: truth.png if no --hdr)")
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.set_defaults(func=run_truth_command)


def run_truth_command(args):
    import contextlib

    from PIL import Image

    from display.cli import _Writer
    from display.renderer import tonemap
    from radiosity.formats import atomic_output, check_output, presets
    from radiosity.formats.limits import available_memory

    spp = args.spp if args.spp is not None else presets.preset(args.quality).truth_spp
    check_spp(spp)
    if args.threads is not None and args.threads < 1:
        raise InputError(f"--threads must be a whole number >= 1, got {args.threads}")
    check_seed(args.seed)
    check_exposure(args.exposure)
    inputs = (args.input,) if os.path.exists(args.input) else ()
    png = args.output or (None if args.hdr else "truth.png")
    if png is not None:
        check_output(png, ".png", inputs, flag="-o")
    if args.hdr is not None:
        check_output(args.hdr, ".npy", inputs, flag="--hdr")
    source = scene_for_truth(args.input)
    camera = truth_camera(args, source)
    need, free = camera.width * camera.height * TRUTH_BYTES_PER_PIXEL, available_memory()
    if free is not None and need > free:
        raise InputError(f"--size {camera.width}x{camera.height} needs about {need / 1e9:.3g} GB for the path "
                         f"tracer's sums, more than the {free / 1e9:.3g} GB available; choose a smaller size")
    truth = ground_truth(source, camera, spp, args.seed, args.threads, progress=True)
    with contextlib.ExitStack() as stack:  # both files or neither
        if args.hdr:
            np.save(_Writer(stack.enter_context(atomic_output(args.hdr))), truth.radiance)
        if png:
            Image.fromarray(tonemap(truth.radiance, args.exposure)).save(
                stack.enter_context(atomic_output(png)), format="PNG")
    s = truth.stats
    for path in (args.hdr, png):
        if path:
            print(f"wrote {path}")
    noise = "n/a (one sample)" if truth.noise_flip is None else f"{truth.noise_flip:.4f}"
    print(f"path traced {camera.width}x{camera.height} at {spp} samples per pixel in {s['seconds']:.1f} s on "
          f"{s['threads']} threads: {s['paths_per_s'] / 1e6:.3g} M paths/s, {s['rays_per_s'] / 1e6:.3g} M rays/s")
    print(f"noise floor (FLIP between the two halves of the samples): {noise}")
    return 0
