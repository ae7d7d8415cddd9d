"""``vlights truth``: the path-traced ground truth of a view of a solution.npz (or a
scene), with its noise floor (``display.truth``). A pipeline command: it runs the
light transport's path tracer, reached through ``display.pipeline`` as the demo's is."""

from __future__ import annotations

import os

import numpy as np

from radiosity.files.errors import InputError
from radiosity.files.sniff import scene_words
from radiosity.policies import presets
from radiosity.policies.limits import available_memory, check_exposure, check_seed

from .common import DefaultSize, add_camera_flags, check_drawable, check_output_file, sniff

__all__ = ["TRUTH_BYTES_PER_PIXEL", "add_command", "run", "truth_camera"]

TRUTH_BYTES_PER_PIXEL = 4 * 3 * 8 + 3 * 4  # the running sums of both halves (float64) and the image
MAX_THREADS = 1024  # a thread pool of more would be reported, not run (the path tracer's tiles are fewer)


def add_command(subparsers):

    p = subparsers.add_parser(
        "truth",
        help="path-trace the ground truth of a view (to compare the walkthrough against)",
        description="Path-trace a view of a solution.npz's meshes and materials (or a scene's): next-event "
        "estimation and BRDF sampling combined by MIS, Russian roulette, a box filter over each pixel. The "
        "image depends on the seed and the samples alone, not on threads. Prints the time, rays and paths per "
        "second, and the noise floor: FLIP between the two independent halves of the samples (an error "
        "against the truth near it is the truth's own noise). The camera: the flags', else the solution's or scene's "
        "own (a scene's at its film's size, a Mitsuba sensor's, unless --size), else a view framing the scene. A fit.npz "
        "holds no materials and is refused.",
    )
    p.add_argument("input", help="a solution.npz (its meshes and materials, what its displays show) or a scene: "
                   + scene_words())
    add_camera_flags(p, (512, 512))
    p.add_argument("--spp", type=int, help="samples per pixel (default: the --quality preset's truth_spp)")
    p.add_argument("--quality", choices=presets.QUALITIES, default=presets.DEFAULT_QUALITY,
                   help="sets --spp: " + ", ".join(f"{q} {presets.preset(q).truth_spp}" for q in presets.QUALITIES)
                   + " (default: %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="default: %(default)s")
    p.add_argument("--threads", type=int,
                   help=f"worker threads, 1 to {MAX_THREADS} (default: one per core); the image does not depend on them")
    p.add_argument("--hdr", metavar="FILE.npy", help="write linear radiance (H, W, 3) float32")
    p.add_argument("-o", "--output", metavar="FILE.png", help="write the tone-mapped picture (default: truth.png if no --hdr)")
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.set_defaults(func=run)


def truth_camera(args, source):
    """The camera of ``vlights truth``: from the flags, else the source's own camera
    (a solution's or a scene's), else a view framing it; without --size, at the size of
    the scene's film if it gives one (a Mitsuba sensor's)."""
    from display.camera import resolve_camera

    film = getattr(source, "film", None)
    if film is not None and isinstance(args.size, DefaultSize):
        args.size = DefaultSize(film)
    positions = np.concatenate([o.positions for o in source.objects])
    return resolve_camera(args, np.stack([positions.min(axis=0), positions.max(axis=0)]), source.camera)


def run(args):
    from display.images import write_pictures
    from display.pipeline import check_spp
    from display.truth import ground_truth, scene_for_truth

    spp = args.spp if args.spp is not None else presets.preset(args.quality).truth_spp
    check_spp(spp)
    if args.threads is not None and not 1 <= args.threads <= MAX_THREADS:
        raise InputError(f"--threads must be a whole number from 1 to {MAX_THREADS}, got {args.threads}")
    check_seed(args.seed)
    check_exposure(args.exposure)
    inputs = (args.input,) if os.path.exists(args.input) else ()
    png = args.output if args.output is not None else (None if args.hdr is not None else "truth.png")
    if png is not None:
        check_output_file(png, ".png", inputs, flag="-o")
    if args.hdr is not None:
        check_output_file(args.hdr, ".npy", inputs, flag="--hdr")
    if os.path.isfile(args.input):
        sniff(args.input)  # a meta nested too deep is one line here, not a RecursionError in the reader
    source = check_drawable(scene_for_truth(args.input), args.input)
    camera = truth_camera(args, source)
    need, free = camera.width * camera.height * TRUTH_BYTES_PER_PIXEL, available_memory()
    if free is not None and need > free:
        raise InputError(f"--size {camera.width}x{camera.height} needs about {need / 1e9:.3g} GB for the path "
                         f"tracer's sums, more than the {free / 1e9:.3g} GB available; choose a smaller size")
    truth = ground_truth(source, camera, spp, args.seed, args.threads, progress=True)
    write_pictures(truth.radiance, hdr=args.hdr, png=png, exposure=args.exposure)
    s = truth.stats
    for path in (args.hdr, png):
        if path:
            print(f"wrote {path}")
    noise = "n/a (one sample)" if truth.noise_flip is None else f"{truth.noise_flip:.4f}"
    print(f"path traced {camera.width}x{camera.height} at {spp} samples per pixel in {s['seconds']:.1f} s on "
          f"{s['threads']} threads: {s['paths_per_s'] / 1e6:.3g} M paths/s, {s['rays_per_s'] / 1e6:.3g} M rays/s")
    print(f"noise floor (FLIP between the two halves of the samples): {noise}")
    return 0
