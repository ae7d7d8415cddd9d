"""``vlights``: the one command. Each stage registers its own subcommands; this
module, the only one that sees all three stages, dispatches to them.

A user's mistake (InputError) prints one line and exits with status 2; Ctrl-C
exits with 130; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import warnings

import numpy as np

import fitting.cli
import radiosity.cli
from display.export import add_export_command
from display.gl import DEFAULT_SAMPLES, MAX_SAMPLES, check_sample_count
from display.serve import add_serve_command
from display.truth import add_truth_command, check_spp
from fitting.model import PARTS
from radiosity.formats import InputError, presets
from radiosity.formats.limits import check_exposure, check_seed

PROG = "vlights"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def not_built(command, what):
    """A handler for a subcommand whose stage does not exist yet: says so, exits 2."""

    def handler(_args):
        print(f"{PROG} {command}: not available yet: {what} is not built in this version", file=sys.stderr)
        return 2

    return handler


def _size(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes WIDTHxHEIGHT, e.g. 800x600, got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"takes WIDTHxHEIGHT of at least 1x1, got {text!r}")
    return w, h


def add_camera_flags(parser, size):
    """The camera flags (eye, look-at, up, field of view, size, named views); the
    default camera is the scene's."""
    parser.add_argument("--eye", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--look-at", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--up", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--fov", type=float, metavar="DEG", help="vertical field of view")
    parser.add_argument("--size", type=_size, default=size, metavar="WxH", help=f"image size (default: {size[0]}x{size[1]})")
    parser.add_argument("--view", metavar="NAME", help="a named view from --views")
    parser.add_argument("--views", metavar="FILE", help='JSON of named views: {"name": {"eye": [..], "look_at": [..], "up": [..], "fov_y_deg": d}}')


def add_samples_flag(parser):
    """--samples N: antialiasing, samples per pixel averaged with equal weights."""
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES, metavar="N",
                        help="samples per pixel, averaged with equal weights (a box filter over the pixel: "
                        "antialiasing); MSAA up to what the OpenGL offers, then also supersampled; 1 samples the "
                        f"pixel centre alone; 1 to {MAX_SAMPLES} (default: %(default)s)")


def register(subparsers, not_built):
    p = subparsers.add_parser(
        "render",
        help="render a fitted model or a solution to an image",
        description="Draw fit.npz (modes fitted, diffuse) and/or solution.npz (modes reference, diffuse) "
        "from a camera, headless (EGL). --hdr writes linear radiance (H, W, 3) float32, row 0 at the "
        "top, background 0; -o writes the tone-mapped picture (exposure, then sRGB).",
    )
    p.add_argument("file", help="fit.npz or solution.npz")
    p.add_argument("--solution", metavar="FILE", help="also a solution.npz, for --mode reference next to a fit.npz")
    p.add_argument("--mode", choices=("fitted", "reference", "diffuse"), help="default: fitted for a fit.npz, reference for a solution.npz")
    p.add_argument("--shading", choices=("gouraud", "pixel"), default="pixel", help="default: %(default)s")
    add_camera_flags(p, (800, 800))
    p.add_argument("--hdr", metavar="FILE.npy", help="write linear radiance")
    p.add_argument("-o", "--output", metavar="FILE.png", help="write the tone-mapped picture (default: render.png if no --hdr)")
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.add_argument("--lights", type=int, metavar="K", help="use only the first K lights of each object")
    p.add_argument("--off", nargs="+", default=[], metavar="PART", choices=PARTS,
                   help="draw the model without these parts: emitters (their highlights), probe, lights")
    add_samples_flag(p)
    p.set_defaults(func=_render)

    p.add_argument("--video", metavar="FILE.mp4", help="instead of one picture, a walkthrough video along a smooth path from the camera")
    p.add_argument("--frames", type=int, default=120, help="video frames (default: %(default)s)")
    p.add_argument("--fps", type=int, default=30, help="video frame rate (default: %(default)s)")

    p = subparsers.add_parser(
        "compare",
        help="the paper's comparison figures with error images and numbers",
        description="Figures 5 (reference against fitted, three viewpoints), 6 (2 against 8 lights) and 7 "
        "(with and without virtual lights) as PNG files, each with a FLIP error image, and FLIP mean, PSNR "
        "and relative MSE in compare.json.",
    )
    p.add_argument("fit", help="fit.npz")
    p.add_argument("solution", help="the solution.npz it was fitted to")
    p.add_argument("--out", default="compare", metavar="DIR", help="output directory, created if missing (default: %(default)s)")
    add_camera_flags(p, (512, 512))
    p.add_argument("--exposure", type=float, default=1.0, help="default: %(default)s")
    p.add_argument("--shading", choices=("gouraud", "pixel"), default="pixel", help="default: %(default)s")
    add_samples_flag(p)
    p.add_argument("--truth", nargs="+", metavar="FILE.npy",
                   help="path-traced images of figure 5's views, in order (from 'vlights truth --hdr' with the same "
                   "camera and size): every display is also measured against them")
    p.add_argument("--truth-spp", type=int, default=0, metavar="N",
                   help="path-trace the truth of every view without a --truth file, N samples per pixel (default: none)")
    p.add_argument("--seed", type=int, default=1, help="the path tracer's seed, with --truth-spp (default: %(default)s)")
    p.set_defaults(func=_compare)

    p = subparsers.add_parser(
        "view",
        help="walk through a scene in a window",
        description="The walkthrough window: WASD (Q/E down/up) and mouse-look with the left button held; "
        "M mode, G Gouraud/per-pixel, L 2/all lights, +/- exposure, P screenshot, ESC quit.",
    )
    p.add_argument("file", help="fit.npz or solution.npz")
    p.add_argument("--solution", metavar="FILE", help="also a solution.npz, for the reference mode next to a fit.npz")
    p.add_argument("--mode", choices=("fitted", "reference", "diffuse"))
    add_camera_flags(p, (1280, 720))
    p.add_argument("--exposure", type=float, default=1.0)
    p.add_argument("--frames", type=int, metavar="N", help="draw N frames and close (scripted runs)")
    p.add_argument("--screenshot", metavar="FILE.png", help="with --frames: save the last frame")
    p.add_argument("--press", default="", metavar="KEYS", help="press these keys (m g l + - p 1 2 3) after the first frame")
    add_samples_flag(p)
    p.set_defaults(func=_view)

    p = subparsers.add_parser(
        "demo",
        help="solve, fit and compare the built-in scenes cornell-teapot and plates",
        description="The whole pipeline on the built-in scenes cornell-teapot and plates: for each, solution.npz, "
        "fit.npz, the paper's figures 5-7 with error images and numbers against a path-traced truth, and the "
        "WebGL walkthrough; then a plot of each glossy object's models (error against floats stored), "
        "report.md and summary.json.",
    )
    p.add_argument("--quality", choices=presets.QUALITIES, default=presets.DEFAULT_QUALITY, help="every knob of every stage at once (default: %(default)s)")
    p.add_argument("--out", default="vlights-demo", metavar="DIR", help="output directory, created if missing (default: %(default)s)")
    p.add_argument("--size", type=_size, default=(512, 512), metavar="WxH", help="figure size (default: 512x512)")
    p.add_argument("--view", action="store_true", help="open the walkthrough at the end, where a display exists")
    add_samples_flag(p)
    p.add_argument("--truth-spp", type=int, metavar="N",
                   help="path-trace the first view with N samples per pixel and measure every display against it "
                   "(default: the preset's, " + ", ".join(f"{q} {presets.preset(q).truth_spp}" for q in presets.QUALITIES)
                   + "; 0: no truth)")
    p.set_defaults(func=_demo)


FIT, SOLUTION = "vlights.fit", "vlights.solution"
_FILE_NAMES = {FIT: "fit.npz", SOLUTION: "solution.npz"}


def _input_format(path, accepted, label):
    """The format of the input file ``path`` (FIT or SOLUTION), which must be one of
    ``accepted``; InputError naming ``label`` (the argument) and what is wrong otherwise.
    What a file is comes from ``radiosity.formats.file_format``."""
    import os

    from radiosity.formats import file_format

    shown = str(path)
    want = " or a ".join(_FILE_NAMES[f] for f in accepted)
    if not os.path.exists(path):
        raise InputError(f"{label} {shown!r} not found")
    if os.path.isdir(path):
        raise InputError(f"{label} {shown!r} is a directory, not a {want}")
    fmt = file_format(path)
    if fmt in accepted:
        return fmt
    if fmt in _FILE_NAMES:
        raise InputError(f"{label} {shown!r} is a {_FILE_NAMES[fmt]}, not a {want}")
    found = f"an .npz file of format {fmt!r}" if fmt is not None else "not one of this program's .npz files"
    raise InputError(f"{label} {shown!r} is not a {want}: it is {found}")


def _check_model_files(path, extra_solution=None):
    """The format of ``path`` (a fit or a solution), and ``extra_solution`` (--solution)
    checked to be a solution next to a fit; cheap: reads no arrays."""
    fmt = _input_format(path, (FIT, SOLUTION), "input")
    if extra_solution is not None:
        _input_format(extra_solution, (SOLUTION,), "--solution")
        if fmt == SOLUTION:
            raise InputError(f"--solution goes next to a fit.npz; {str(path)!r} is already a solution.npz")
    return fmt


def _read_model_files(path, extra_solution=None):
    """(fit or None, solution or None) from a file that is either, plus an optional solution."""
    from fitting import load_fit
    from radiosity.formats import load_solution

    if _check_model_files(path, extra_solution) == FIT:
        fit, solution = load_fit(path), None
    else:
        fit, solution = None, load_solution(path)
    if extra_solution is not None:
        solution = load_solution(extra_solution)
    return fit, solution


def resolve_view(args, bounds, fit=None, solution=None):
    """The camera from flags, a named view, or the files' scene camera (else a framing view)."""
    from display.camera import resolve_camera

    default = None
    for model in (solution, fit):
        if model is not None and getattr(model, "camera", None) is not None:
            default = model.camera
            break
    return resolve_camera(args, bounds, default)


def _render(args):
    import numpy as np
    from PIL import Image

    from display.renderer import tonemap
    from radiosity.formats import atomic_output, check_output

    if args.video is not None:
        if args.output is not None or args.hdr is not None:
            raise InputError("--video writes a video, -o and --hdr a picture: give one or the other")
        return _video(args)
    if args.lights is not None and args.lights < 0:
        raise InputError(f"--lights must be >= 0, got {args.lights}")
    check_exposure(args.exposure)
    check_sample_count(args.samples)
    inputs = (args.file, args.solution)
    png = args.output or (None if args.hdr else "render.png")
    # every output refused before any work: no file half written, no context made for nothing
    if png is not None:
        check_output(png, ".png", inputs, flag="-o")
    if args.hdr is not None:
        check_output(args.hdr, ".npy", inputs, flag="--hdr")
    with _rendering(args) as (renderer, view, mode):
        hdr = renderer.render(view, mode, args.shading, args.lights, parts=tuple(p for p in PARTS if p not in args.off))
    # both files or neither: each is committed only when both are written
    with contextlib.ExitStack() as stack:
        if args.hdr:
            np.save(_Writer(stack.enter_context(atomic_output(args.hdr))), hdr.astype(np.float32))
        if png:
            Image.fromarray(tonemap(hdr, args.exposure)).save(stack.enter_context(atomic_output(png)), format="PNG")
    if args.hdr:
        print(f"wrote {args.hdr} (linear radiance {hdr.shape[1]}x{hdr.shape[0]}, max {hdr.max():.4g}, "
              f"{args.samples} samples per pixel)")
    if png:
        print(f"wrote {png} ({mode}, {args.shading} shading, exposure {args.exposure:g}, {args.samples} samples per pixel)")
    return 0


@contextlib.contextmanager
def _rendering(args):
    """(renderer, camera, mode) for the input files of ``args``, after their size and
    memory checks; the GL context is released on the way out."""
    from display.gl import check_image_memory, check_image_size, check_samples, headless_context
    from display.renderer import Renderer

    _check_model_files(args.file, args.solution)
    ctx = headless_context()
    try:
        check_image_size(ctx, *args.size)
        check_samples(ctx, args.samples, *args.size)
        check_image_memory(*args.size, samples=args.samples)
        fit, solution = _read_model_files(args.file, args.solution)
        mode = args.mode or ("fitted" if fit is not None else "reference")
        renderer = Renderer(ctx, fit=fit, solution=solution, samples=args.samples)
        try:
            yield renderer, resolve_view(args, renderer.bounds, fit, solution), mode
        finally:
            renderer.release()
    finally:
        ctx.release()


class _Writer:
    """A file object numpy writes an .npy through ``write`` (a short write is then an
    OSError with its reason, "No space left on device"; numpy's own fwrite path only
    says how many bytes it wrote)."""

    def __init__(self, f):
        self.write = f.write


def _video(args):
    from display.video import write_video
    from radiosity.formats import check_output

    if not 2 <= args.frames <= 100_000 or not 1 <= args.fps <= 240:
        raise InputError("--frames must be 2 to 100000 and --fps 1 to 240")
    check_exposure(args.exposure)
    check_sample_count(args.samples)
    check_output(args.video, ".mp4", (args.file, args.solution), flag="--video")
    with _rendering(args) as (renderer, view, mode):
        if mode not in renderer.modes:
            raise InputError(f"mode {mode!r} is not available for this input ({', '.join(renderer.modes)})")
        frames = write_video(renderer, args.video, view, args.frames, args.fps, mode, args.shading, args.exposure,
                             progress=True)
    print(f"wrote {args.video} ({frames} frames at {args.fps} fps, {view.width}x{view.height}, {mode}, "
          f"{args.samples} samples per pixel)")
    return 0


def _view(args):
    from display.gl import check_image_memory
    from display.window import display_problem
    from radiosity.formats import check_output

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
        check_output(args.screenshot, ".png", (args.file, args.solution), flag="--screenshot")
    _check_model_files(args.file, args.solution)
    check_image_memory(*args.size, samples=args.samples)
    fit, solution = _read_model_files(args.file, args.solution)

    import moderngl_window as mglw

    from display.window import Walkthrough

    positions = np.concatenate([o.positions for o in (fit or solution).objects])
    view = resolve_view(args, np.stack([positions.min(axis=0), positions.max(axis=0)]), fit, solution)
    Walkthrough.configure(fit, solution, view, args.exposure, args.frames, args.screenshot, args.mode, args.press,
                          args.samples)
    try:
        mglw.run_window_config(Walkthrough, args=["--window", "pyglet"])
    except Exception as exc:  # the window library's own failure to open a window (pyglet's NoSuchDisplayException)
        said = f"{type(exc).__name__} {exc}".lower()
        if "display" in said or "xlib" in said:
            raise InputError(f"cannot open a window: {' '.join(str(exc).split())}") from None
        raise
    if Walkthrough.failure is not None:
        raise Walkthrough.failure
    return 0


def _demo(args):
    from display.demo import FILES, key_numbers, run_demo
    from display.outputs import check_output_dir

    check_sample_count(args.samples)
    if args.truth_spp is not None:
        check_spp(args.truth_spp, "--truth-spp", low=0)
    out = check_output_dir(args.out, "--out", files=FILES)
    summary = run_demo(out, args.quality, args.size, samples=args.samples, truth_spp=args.truth_spp)
    print(key_numbers(summary, out))
    if args.view:
        from display.window import display_problem

        problem = display_problem()
        if problem is not None:
            print(f"no display ({problem}): skipping the walkthrough (run 'vlights view' where there is one)")
        else:
            import moderngl_window as mglw

            from display.window import Walkthrough
            from fitting import load_fit
            from radiosity.formats import load_solution

            solution = load_solution(out / "cornell-teapot" / "solution.npz")
            Walkthrough.configure(load_fit(out / "cornell-teapot" / "fit.npz"), solution,
                                  solution.camera.sized(1280, 720), samples=args.samples)
            mglw.run_window_config(Walkthrough, args=["--window", "pyglet"])
    return 0


def _check_compare_inputs(fit_path, solution_path):
    """compare takes a fit.npz, then a solution.npz: say so plainly when they are swapped."""
    fmt_fit = _input_format(fit_path, (FIT, SOLUTION), "the fit")
    fmt_solution = _input_format(solution_path, (FIT, SOLUTION), "the solution")
    if fmt_fit == SOLUTION and fmt_solution == FIT:
        raise InputError(f"the files are the wrong way round: {str(fit_path)!r} is a solution.npz and "
                         f"{str(solution_path)!r} a fit.npz; give the fit.npz first")
    if fmt_fit != FIT:
        raise InputError(f"the fit {str(fit_path)!r} is a solution.npz, not a fit.npz (compare takes a fit.npz, then "
                         "the solution.npz it was fitted to)")
    if fmt_solution != SOLUTION:
        raise InputError(f"the solution {str(solution_path)!r} is a fit.npz, not a solution.npz (compare takes a "
                         "fit.npz, then the solution.npz it was fitted to)")


def _compare(args):
    from display.compare import FILES, compare, figure5_views
    from display.gl import (
        COMPARE_BYTES_PER_PIXEL,
        check_image_memory,
        check_image_size,
        check_samples,
        headless_context,
    )
    from display.outputs import check_output_dir
    from display.renderer import Renderer
    from fitting import load_fit
    from radiosity.formats import load_solution

    check_exposure(args.exposure)
    check_sample_count(args.samples)
    _check_truth_flags(args)
    _check_compare_inputs(args.fit, args.solution)
    out = check_output_dir(args.out, "--out", files=FILES, inputs=(args.fit, args.solution))
    ctx = headless_context()
    try:
        check_image_size(ctx, *args.size)
        check_samples(ctx, args.samples, *args.size)
        check_image_memory(*args.size, COMPARE_BYTES_PER_PIXEL, samples=args.samples)
        fit, solution = load_fit(args.fit), load_solution(args.solution)
        renderer = Renderer(ctx, fit=fit, solution=solution, samples=args.samples)
        view = resolve_view(args, renderer.bounds, fit, solution)
        views = figure5_views(view)
        truths = _compare_truths(args, solution, views)
        results = compare(renderer, out, view, args.exposure, args.shading, views=views, truths=truths)
        renderer.release()
    finally:
        ctx.release()
    print(f"wrote figures 5, 6, 7 and compare.json to {out}/ ({args.samples} samples per pixel)")
    print(f"  {'':<32} {'whole image':^28} {'glossy objects only':^28}")
    print(f"  {'':<32} {'FLIP':>8} {'PSNR dB':>8} {'rel.MSE':>10} {'FLIP':>8} {'PSNR dB':>8} {'rel.MSE':>10}")
    rows = [(f"figure 5, view {i}", results["figure5"][f"view{i}"]) for i in range(1, 4)]
    rows += [(f"figure 6, {k.replace('_', ' ')}", m) for k, m in results["figure6"].items()]
    rows += [(f"figure 7, {k.replace('_', ' ')}", m) for k, m in results["figure7"].items() if isinstance(m, dict)]
    for label, m in rows:
        glossy = (f"{m['flip_mean_glossy']:>8.4f} {m['psnr_db_glossy']:>8.2f} {m['relative_mse_glossy']:>10.4g}"
                  if "flip_mean_glossy" in m else "")
        print(f"  {label:<32} {m['flip_mean']:>8.4f} {m['psnr_db']:>8.2f} {m['relative_mse']:>10.4g} {glossy}")
    if any(m[k] == float("inf") for _, m in rows for k in ("psnr_db", "psnr_db_glossy") if k in m):
        print("  (PSNR inf: the pictures are identical; compare.json has null there, explained in its notes)")
    for name, t in results.get("truth", {}).items():
        noise = "" if t["noise_flip"] is None else f", noise floor FLIP {t['noise_flip']:.4f}"
        source = f"{t['spp']} spp" if t["spp"] else "from a file"
        print(f"  against the path-traced truth, {name.replace('view', 'view ')} ({source}{noise}):")
        for mode in ("reference", "fitted", "diffuse"):
            m = t[mode]
            glossy = (f"{m['flip_mean_glossy']:>8.4f} {m['psnr_db_glossy']:>8.2f} {m['relative_mse_glossy']:>10.4g}"
                      if "flip_mean_glossy" in m else "")
            print(f"    {mode + ' display':<30} {m['flip_mean']:>8.4f} {m['psnr_db']:>8.2f} {m['relative_mse']:>10.4g} {glossy}")
    return 0


def _check_truth_flags(args):
    """--truth files (at most one per view, .npy, existing) and --truth-spp, before any work."""
    files = args.truth or []
    if len(files) > 3:
        raise InputError(f"--truth takes at most 3 files (one per view of figure 5), got {len(files)}")
    for path in files:
        if not str(path).endswith(".npy"):
            raise InputError(f"--truth {path!r} must be an .npy file (from 'vlights truth --hdr')")
        if not os.path.isfile(path):
            raise InputError(f"--truth {path!r} not found")
    check_spp(args.truth_spp, "--truth-spp", low=0)
    check_seed(args.seed)


def _compare_truths(args, solution, views):
    """Per view: the --truth file's image, else (with --truth-spp) a path-traced one, else None."""
    from display.truth import GroundTruth, ground_truth, load_truth

    files = args.truth or []
    truths = []
    for i, view in enumerate(views):
        if i < len(files):
            truths.append(GroundTruth(load_truth(files[i], view), 0, None, {"file": files[i]}))
        elif args.truth_spp:
            print(f"path-tracing the truth of view {i + 1} ({args.truth_spp} samples per pixel)")
            truths.append(ground_truth(solution, view, args.truth_spp, args.seed, progress=True))
        else:
            truths.append(None)
    return truths


def build_parser():
    parser = _Parser(
        prog=PROG,
        description="virtual-lights: view-independent glossy global illumination, fitted with "
        "virtual Phong lights for real-time walkthroughs (after Walter et al. 1997).",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    radiosity.cli.register(subparsers, not_built)
    fitting.cli.register(subparsers, not_built)
    register(subparsers, not_built)
    add_truth_command(subparsers, add_camera_flags)
    add_export_command(subparsers)
    add_serve_command(subparsers)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: stop as Ctrl-C does (every ``with atomic_output`` removes its
    temporary file on the way out), then exit with 128 + the signal's number."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum, _frame):
    raise Terminated(signum)


def _install_signal_handlers():
    """SIGTERM and SIGHUP unwind like Ctrl-C; only possible from the main thread.
    Returns the previous handlers, to restore."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            previous[getattr(signal, name)] = signal.signal(getattr(signal, name), _raise_terminated)
    return previous


def _interruption(exc):
    """The KeyboardInterrupt behind ``exc``, if a Ctrl-C surfaced wrapped inside another
    exception (numba and scipy's Fortran can report one as a SystemError)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def main(argv=None):
    previous = _install_signal_handlers()
    try:
        return _run(argv)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _run(argv):
    args = build_parser().parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return args.func(args)
    except InputError as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        return _interrupted(args.command, exc)
    except Exception as exc:
        interrupt = _interruption(exc)
        if interrupt is None:
            raise
        return _interrupted(args.command, interrupt)


def _interrupted(command, exc):
    if isinstance(exc, Terminated):
        name = signal.Signals(exc.signum).name
        print(f"{PROG} {command}: stopped by {name}", file=sys.stderr)
        return 128 + exc.signum
    print(f"{PROG} {command}: interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
