"""What several display commands share: the camera and sample flags, the checks of
their input files (which must be a fit.npz or a solution.npz, named plainly when not),
and a headless renderer for the files."""

from __future__ import annotations

import argparse
import contextlib
import sys

from display import gl
from radiosity.files.camera import FOV_AXES
from radiosity.files.errors import InputError

__all__ = [
    "FIT", "SOLUTION", "add_camera_flags", "add_glass_flag", "add_samples_flag", "check_drawable", "check_model_files", "check_output_file",
    "input_format", "read_model_files", "rendering", "resolve_view", "size", "sniff",
]

FIT, SOLUTION = "vlights.fit", "vlights.solution"
_FILE_NAMES = {FIT: "fit.npz", SOLUTION: "solution.npz"}



def display_mode(name):
    """argparse's type of --mode: a display's name (``display.renderer.MODE_NAMES``) -> its id."""
    from display.choices import MODE_NAMES

    if name not in MODE_NAMES:
        raise argparse.ArgumentTypeError(f"{name!r} is not a display: choose fitted, solution or diffuse")
    return MODE_NAMES[name]

def size(text):
    """The argparse type of --size: "WIDTHxHEIGHT" -> (width, height), at least 1x1."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes WIDTHxHEIGHT, e.g. 800x600, got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"takes WIDTHxHEIGHT of at least 1x1, got {text!r}")
    return w, h


class DefaultSize(tuple):
    """``--size``'s default: a (width, height) that says it was not given
    (``isinstance(args.size, DefaultSize)``), so a scene's film size can stand in."""


def add_camera_flags(parser, default_size):
    """The camera flags (eye, look-at, up, field of view, size, named views); the
    default camera is the scene's."""
    default_size = DefaultSize(default_size)
    parser.add_argument("--eye", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--look-at", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--up", type=float, nargs=3, metavar=("X", "Y", "Z"))
    parser.add_argument("--fov", type=float, metavar="DEG",
                        help="field of view, vertical unless --fov-axis says otherwise (default: the scene camera's, "
                        "kept along its own axis, e.g. a Mitsuba sensor's fov_axis, at every --size)")
    parser.add_argument("--fov-axis", choices=FOV_AXES, metavar="AXIS",
                        help="the extent of the image --fov spans: x (its width), y (its height), diagonal, smaller "
                        "or larger (its smaller or larger side), as Mitsuba's fov_axis (default: y)")
    parser.add_argument("--size", type=size, default=default_size, metavar="WxH",
                        help=f"image size (default: {default_size[0]}x{default_size[1]})")
    parser.add_argument("--view", metavar="NAME", help="a named view from --views")
    parser.add_argument("--views", metavar="FILE", help='JSON of named views: {"name": {"eye": [..], "look_at": [..], '
                        '"up": [..], "fov_y_deg": d}} (or "fov_deg": d, "fov_axis": "x" for a fov along the width)')


def add_glass_flag(parser):
    """--glass APPROACH: how glass objects are drawn (``display.glass``); --near-mirrors: flat
    sharp plastics drawn as mirrors (``display.mirror.near_mirror_of``)."""
    from display.choices import APPROACHES

    parser.add_argument("--glass", choices=APPROACHES, default=APPROACHES[0],
                        help="how glass is drawn: blend (reflections and refractions from a probe of the scene "
                        "around it, sheets and slabs blended over what is behind them; the default), probe (what "
                        "is behind a sheet from the probe too), none (left out, as clear glass)")
    parser.add_argument("--near-mirrors", action=argparse.BooleanOptionalAction, default=True,
                        help="draw a flat microfacet surface at most 0.03 rough (a polished floor) from the scene "
                        "reflected in its plane, as a mirror, over its own part (sharper than its grid; the emitters' "
                        "reflections lose their lobe's blur); --no-near-mirrors: from its grid or fit (default: on)")


def add_samples_flag(parser):
    """--samples N: antialiasing, samples per pixel averaged with equal weights."""
    parser.add_argument("--samples", type=int, default=gl.DEFAULT_SAMPLES, metavar="N",
                        help="samples per pixel, averaged with equal weights (a box filter over the pixel: "
                        "antialiasing); MSAA up to what the OpenGL offers, then also supersampled; 1 samples the "
                        f"pixel centre alone; 1 to {gl.MAX_SAMPLES} (default: %(default)s)")


def sniff(path, label="input"):
    """What the file ``path`` is (``radiosity.files.npz.file_format``: its meta's format,
    or None), with a meta nested too deep to parse an InputError naming ``label``
    rather than Python's RecursionError."""
    from radiosity.files.npz import file_format

    try:
        return file_format(path)
    except RecursionError:
        raise InputError(f"{label} {str(path)!r}: its meta is JSON nested too deep to read") from None


def input_format(path, accepted, label):
    """The format of the input file ``path`` (FIT or SOLUTION), which must be one of
    ``accepted``; InputError naming ``label`` (the argument) and what the file is
    otherwise: the one sniffer, ``radiosity.files.sniff.require_format``."""
    from radiosity.files.sniff import require_format

    try:
        return require_format(path, accepted, label)
    except RecursionError:
        raise InputError(f"{label} {str(path)!r}: its meta is JSON nested too deep to read") from None


def check_model_files(path, extra_solution=None):
    """The format of ``path`` (a fit or a solution), and ``extra_solution`` (--solution)
    checked to be a solution next to a fit; cheap: reads no arrays."""
    fmt = input_format(path, (FIT, SOLUTION), "input")
    if extra_solution is not None:
        input_format(extra_solution, (SOLUTION,), "--solution")
        if fmt == SOLUTION:
            raise InputError(f"--solution goes next to a fit.npz; {str(path)!r} is already a solution.npz")
    return fmt


def read_model_files(path, extra_solution=None):
    """(fit or None, solution or None) from a file that is either, plus an optional solution."""
    from fitting import load_fit
    from radiosity.files.solution import load_solution

    if check_model_files(path, extra_solution) == FIT:
        fit, solution = load_fit(path), None
    else:
        fit, solution = None, check_drawable(load_solution(path), path)
    if extra_solution is not None:
        solution = check_drawable(load_solution(extra_solution), extra_solution)
    return fit, solution


def check_drawable(model, path):
    """``model`` (a solution or a fit read from ``path``) if every object has vertices
    and faces; InputError naming the first that has none (the reader of fit files
    refuses such an object, the reader of solutions lets it through, and it has
    nothing to draw or path-trace)."""
    for o in model.objects:
        if len(o.positions) == 0 or len(o.faces) == 0:
            what = "vertices" if len(o.positions) == 0 else "faces"
            raise InputError(f"{str(path)!r}: object {o.name!r} has no {what}, so nothing to draw")
    return model


def check_output_file(path, suffix, inputs=(), flag="-o"):
    """``radiosity.files.atomic.check_output`` for an output file of a display command, and
    two refusals more, in one line before any work: an empty name (an unset variable in
    a script, which would otherwise mean the default name or the current directory), and
    a name the system refuses to look at (too long for the file system, a NUL)."""
    from radiosity.files.atomic import check_output

    shown = str(path)
    if not shown:
        raise InputError(f"{flag} is empty; give a file name")
    if "\0" in shown:
        raise InputError(f"{flag} {shown!r} holds a NUL character, which no file name may")
    try:
        return check_output(path, suffix, inputs, flag=flag)
    except InputError:
        raise
    except OSError as exc:  # os.stat's own refusal, e.g. ENAMETOOLONG
        raise InputError(f"{flag} {shown!r}: {exc.strerror or exc}") from None


def resolve_view(args, bounds, fit=None, solution=None):
    """The camera from flags, a named view, or the files' scene camera (else a framing view)."""
    from display.camera import resolve_camera

    default = None
    for model in (solution, fit):
        if model is not None and getattr(model, "camera", None) is not None:
            default = model.camera
            break
    return resolve_camera(args, bounds, default)


@contextlib.contextmanager
def headless(size, samples, bytes_per_pixel=gl.RENDER_BYTES_PER_PIXEL):
    """A headless GL context for images of ``size`` with ``samples`` per pixel, after
    the checks of their size, samples, buffers and memory (InputError, one line, before
    any work); released on the way out. A framebuffer the driver still refuses is an
    InputError too (``display.gl.framebuffer_refusals``)."""
    ctx = gl.headless_context()
    try:
        gl.check_image_size(ctx, *size)
        gl.check_samples(ctx, samples, *size)
        gl.check_image_memory(*size, bytes_per_pixel, samples=samples)
        with gl.framebuffer_refusals(size, samples):
            yield ctx
    finally:
        ctx.release()


@contextlib.contextmanager
def rendering(args):
    """(renderer, camera, mode) for the input files of ``args``, after their size and
    memory checks; the GL context is released on the way out."""
    from display.renderer import Renderer

    check_model_files(args.file, args.solution)
    with headless(args.size, args.samples) as ctx:
        fit, solution = read_model_files(args.file, args.solution)
        mode = args.mode or ("fitted" if fit is not None else "reference")
        renderer = Renderer(ctx, fit=fit, solution=solution, samples=args.samples,
                            say=lambda line: print(line, file=sys.stderr))  # a large upload's estimate
        renderer.glass_approach = getattr(args, "glass", renderer.glass_approach)
        renderer.near_mirrors = getattr(args, "near_mirrors", renderer.near_mirrors)
        try:
            yield renderer, resolve_view(args, renderer.bounds, fit, solution), mode
        finally:
            renderer.release()
