"""Cameras for the display commands. The camera type itself is
``radiosity.files.camera.Camera``; this module adds the display's own choices: a view
that frames a box, and the camera the command-line flags ask for.
"""

from __future__ import annotations

import os

import numpy as np

from radiosity.files.camera import Camera, camera_from_dict, load_views
from radiosity.files.errors import InputError

__all__ = ["Camera", "framing_view", "resolve_camera"]


def framing_view(lo, hi, width, height, fov_y_deg=39.3):
    """A view of the box [lo, hi] from its -z side, the whole box in frame."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * np.linalg.norm(hi - lo), 1e-9)
    distance = radius / np.sin(np.radians(fov_y_deg) / 2) * 1.05
    eye = centre - np.array([0.0, 0.0, distance])
    return Camera(tuple(eye), tuple(centre), (0.0, 1.0, 0.0), fov_y_deg, width, height)


MIN_FOV_DEG = 1e-3  # 1 / tan(fov / 2) in float32 stays far from overflow (radiosity's Camera takes any fov > 0)
VIEWS_BYTES = 16 * 2**20  # a views file is a few named cameras: far below this


def _read_views(path):
    """``radiosity.files.camera.load_views(path)`` after the checks that keep it from
    blocking or growing without end (a FIFO, /dev/zero, a directory, a file of
    gigabytes), and with a document nested too deep as one line, not a RecursionError."""
    import stat

    shown = str(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"views file {shown!r} not found") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"views file {shown!r} cannot be read: {getattr(exc, 'strerror', None) or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file (a device, a FIFO or a socket)"
        raise InputError(f"views file {shown!r} is {kind}")
    if info.st_size > VIEWS_BYTES:
        raise InputError(f"views file {shown!r} is {info.st_size:,} bytes; a views file is at most {VIEWS_BYTES:,}")
    try:
        return load_views(path)
    except RecursionError:
        raise InputError(f"views file {shown!r} is JSON nested too deep to read") from None


def resolve_camera(args, bounds, default=None):
    """The camera from the flags (``--eye --look-at --up --fov --fov-axis --size``), a
    named view (``--view NAME --views FILE``), or ``default`` (a Camera, the scene's),
    else a view framing ``bounds`` ((2, 3): min and max corner), at ``--size``. The
    field of view stays along its axis (a Mitsuba sensor's ``fov_axis``): the vertical
    one is the base camera's at that size; ``--fov DEG`` is vertical, or along
    ``--fov-axis``."""
    width, height = args.size
    axis = getattr(args, "fov_axis", None)
    if axis is not None and args.fov is None:
        raise InputError(f"--fov-axis {axis} says which extent of the image --fov spans; give --fov DEG too")
    if args.view is not None:
        if args.views is None:
            raise InputError("--view needs --views FILE")
        views = _read_views(args.views)
        if args.view not in views:
            raise InputError(f"no view {args.view!r} in {args.views} (views: {', '.join(views)})")
        base = camera_from_dict(views[args.view], width, height, where=f"view {args.view!r} in {args.views}")
    elif default is not None:
        base = default.sized(width, height)
    else:
        base = framing_view(bounds[0], bounds[1], width, height)
    camera = Camera(
        tuple(args.eye) if args.eye else base.eye,
        tuple(args.look_at) if args.look_at else base.look_at,
        tuple(args.up) if args.up else base.up,
        args.fov if args.fov is not None else base.fov_deg,
        width,
        height,
        (axis or "y") if args.fov is not None else base.fov_axis,
    )
    if camera.fov_y_deg < MIN_FOV_DEG:
        raise InputError(f"the field of view must be at least {MIN_FOV_DEG:g} degrees for the display, got "
                         f"{camera.fov_y_deg:g} (vertical, at {width}x{height}: a narrower one overflows its float32 "
                         "projection)")
    return camera
