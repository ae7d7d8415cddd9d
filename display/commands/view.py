"""``vlights view``: the walkthrough window (``display.window``) on a fit.npz or a
solution.npz."""

from __future__ import annotations

import numpy as np

from display.gl import check_image_memory, check_sample_count
from radiosity.files.errors import InputError
from radiosity.policies.limits import check_exposure

from .common import (
    add_camera_flags,
    add_glass_flag,
    add_samples_flag,
    check_model_files,
    check_output_file,
    display_mode,
    read_model_files,
    resolve_view,
)

__all__ = ["add_command", "open_window", "run"]


def add_command(subparsers):
    p = subparsers.add_parser(
        "view",
        help="the walkthrough window on a fit.npz or a solution.npz (needs a display)",
        description="The walkthrough window: WASD (Q/E down/up) and mouse-look with the left button held; "
        "M mode, G Gouraud/per-pixel, L 2/all lights, 1/2/3 the emitters' highlights/the probe/the "
        "virtual lights off and on, +/- exposure, P screenshot, ESC quit.",
    )
    p.add_argument("file", help="fit.npz or solution.npz")
    p.add_argument("--solution", metavar="FILE", help="also a solution.npz, for the solution display (mode solution) next to a fit.npz")
    p.add_argument("--mode", type=display_mode, metavar="{fitted,solution,diffuse}",
                   help="the display to start with (M cycles them): fitted, the fitted model; solution, the solution "
                   "display (the solution drawn directly; 'reference', its first name, is read too); diffuse, a "
                   "diffuse walkthrough (default: fitted for a fit.npz, diffuse for a solution.npz)")
    add_camera_flags(p, (1280, 720))
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.add_argument("--frames", type=int, metavar="N", help="draw N frames and close (scripted runs)")
    p.add_argument("--screenshot", metavar="FILE.png", help="with --frames: save the last frame")
    p.add_argument("--press", default="", metavar="KEYS", help="press these keys (m g l + - p 1 2 3) after the first frame")
    add_samples_flag(p)
    add_glass_flag(p)
    p.set_defaults(func=run)


def run(args):
    from display.window import display_problem

    problem = display_problem()
    if problem is not None:
        raise InputError(f"no display to open a window on ({problem}); use 'vlights render' for pictures")
    check_exposure(args.exposure)
    if args.frames is not None and args.frames < 1:
        raise InputError(f"--frames must be >= 1, got {args.frames}")
    if set(args.press) - set("mgl+-p123"):
        raise InputError(f"--press takes the keys m g l + - p 1 2 3, got {args.press!r}")
    check_sample_count(args.samples)
    if args.screenshot is not None:
        if args.frames is None:
            raise InputError("--screenshot saves the last of --frames N: give --frames too")
        check_output_file(args.screenshot, ".png", (args.file, args.solution), flag="--screenshot")
    check_model_files(args.file, args.solution)
    check_image_memory(*args.size, samples=args.samples)
    fit, solution = read_model_files(args.file, args.solution)

    from display.window import Walkthrough

    positions = np.concatenate([o.positions for o in (fit or solution).objects])
    view = resolve_view(args, np.stack([positions.min(axis=0), positions.max(axis=0)]), fit, solution)
    Walkthrough.configure(fit, solution, view, exposure=args.exposure, frames=args.frames, screenshot=args.screenshot,
                          mode=args.mode, press=args.press, samples=args.samples, glass=args.glass,
                          near_mirrors=args.near_mirrors)
    open_window()
    if Walkthrough.failure is not None:
        raise Walkthrough.failure
    return 0


def open_window():
    """Run the configured ``display.window.Walkthrough`` until it closes; the window
    library's own failure to open a window is an InputError (one line)."""
    import moderngl_window as mglw

    from display.window import Walkthrough

    try:
        mglw.run_window_config(Walkthrough, args=["--window", "pyglet"])
    except Exception as exc:  # the window library's own failure to open a window (pyglet's NoSuchDisplayException)
        said = f"{type(exc).__name__} {exc}".lower()
        if "display" in said or "xlib" in said:
            raise InputError(f"cannot open a window: {' '.join(str(exc).split())}") from None
        raise
