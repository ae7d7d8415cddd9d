"""``vlights render``: a picture of a fit.npz or a solution.npz from a camera, headless;
with --video, a walkthrough video instead."""

from __future__ import annotations

import numpy as np

from display.gl import check_sample_count
from fitting.options import PARTS
from radiosity.files.errors import InputError
from radiosity.policies.limits import check_exposure

from .common import add_camera_flags, add_glass_flag, add_samples_flag, check_output_file, display_mode, rendering

__all__ = ["add_command", "run"]


def add_command(subparsers):
    p = subparsers.add_parser(
        "render",
        help="a picture (or a video) of a fitted model or a solution",
        description="Draw fit.npz (modes fitted, diffuse) and/or solution.npz (modes solution, diffuse) "
        "from a camera, headless (EGL): by default the scene's camera, else a view framing the scene. --hdr "
        "writes linear radiance (H, W, 3) float32, row 0 at the top, where no object is the scene's "
        "environment or 0; -o writes the tone-mapped picture (exposure, then sRGB).",
    )
    p.add_argument("file", help="fit.npz or solution.npz")
    p.add_argument("--solution", metavar="FILE", help="also a solution.npz, for the solution display (--mode solution) next to a fit.npz")
    p.add_argument("--mode", type=display_mode, metavar="{fitted,solution,diffuse}",
                   help="fitted: the fitted model, what the walkthrough shows; solution: the solution display, the "
                   "solution drawn directly ('reference', its first name, is read too); diffuse: a diffuse "
                   "walkthrough (default: fitted for a fit.npz, solution for a solution.npz)")
    p.add_argument("--shading", choices=("gouraud", "pixel"), default="pixel",
                   help="gouraud: per vertex, as in 1997; pixel: per pixel (default: %(default)s)")
    add_camera_flags(p, (800, 800))
    p.add_argument("--hdr", metavar="FILE.npy", help="write linear radiance")
    p.add_argument("-o", "--output", metavar="FILE.png", help="write the tone-mapped picture (default: render.png if no --hdr)")
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.add_argument("--lights", type=int, metavar="K", help="use only the first K virtual lights of each object")
    p.add_argument("--off", nargs="+", default=[], metavar="PART", choices=PARTS,
                   help="draw the model without these parts: emitters (their highlights), probe, lights")
    add_samples_flag(p)
    add_glass_flag(p)
    p.set_defaults(func=run)

    p.add_argument("--video", metavar="FILE.mp4", help="instead of one picture, a walkthrough video along a smooth path from the camera")
    p.add_argument("--frames", type=int, default=120, help="video frames, 2 to 100,000 (default: %(default)s)")
    p.add_argument("--fps", type=int, default=30, help="video frame rate, 1 to 240 (default: %(default)s)")


def run(args):
    from display.images import write_pictures

    if args.video is not None:
        if args.output is not None or args.hdr is not None:
            raise InputError("--video writes a video, -o and --hdr a picture: give one or the other")
        return run_video(args)
    if args.lights is not None and args.lights < 0:
        raise InputError(f"--lights must be >= 0, got {args.lights}")
    check_exposure(args.exposure)
    check_sample_count(args.samples)
    inputs = (args.file, args.solution)
    png = args.output if args.output is not None else (None if args.hdr is not None else "render.png")
    # every output refused before any work: no file half written, no context made for nothing
    if png is not None:
        check_output_file(png, ".png", inputs, flag="-o")
    if args.hdr is not None:
        check_output_file(args.hdr, ".npy", inputs, flag="--hdr")
    with rendering(args) as (renderer, view, mode):
        hdr = renderer.render(view, mode, args.shading, args.lights, parts=tuple(p for p in PARTS if p not in args.off))
    if not np.isfinite(hdr).all():  # finite float32 radiance whose samples overflow when summed
        raise InputError(f"the picture of {str(args.file)!r} has {int(np.sum(~np.isfinite(hdr)))} values beyond "
                         "float32 (its radiance overflows when the samples of a pixel are added); nothing written")
    write_pictures(hdr, hdr=args.hdr, png=png, exposure=args.exposure)
    if args.hdr:
        print(f"wrote {args.hdr} (linear radiance {hdr.shape[1]}x{hdr.shape[0]}, max {hdr.max():.4g}, "
              f"{args.samples} samples per pixel)")
    if png:
        print(f"wrote {png} ({mode}, {args.shading} shading, exposure {args.exposure:g}, {args.samples} samples per pixel)")
    return 0


def run_video(args):
    from display.video import write_video

    if not 2 <= args.frames <= 100_000:
        raise InputError(f"--frames must be 2 to 100000 for a video, got {args.frames}")
    if not 1 <= args.fps <= 240:
        raise InputError(f"--fps must be 1 to 240, got {args.fps}")
    check_exposure(args.exposure)
    check_sample_count(args.samples)
    check_output_file(args.video, ".mp4", (args.file, args.solution), flag="--video")
    with rendering(args) as (renderer, view, mode):
        if mode not in renderer.modes:
            raise InputError(f"mode {mode!r} is not available for this input ({', '.join(renderer.modes)})")
        frames = write_video(renderer, args.video, view, frames=args.frames, fps=args.fps, mode=mode,
                             shading=args.shading, exposure=args.exposure, progress=True)
    print(f"wrote {args.video} ({frames} frames at {args.fps} fps, {view.width}x{view.height}, {mode}, "
          f"{args.samples} samples per pixel)")
    return 0
