"""A walkthrough video: the camera glides along a smooth path through the scene, the
paper's "live walkthrough" as an MP4 (H.264, by the ffmpeg executable imageio-ffmpeg ships)."""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import tempfile
from dataclasses import replace

import numpy as np

from radiosity.files.atomic import OutputError, temporary_name
from radiosity.files.errors import InputError

from .renderer import tonemap


def walkthrough_path(view, frames):
    """``frames`` views from ``view``: a swing of 60 degrees about the vertical through the
    look-at point, moving in to 55 % of the distance halfway and back out, with a slight
    rise; every quantity is a smooth (C-infinity) function of time, so the motion has no
    jolt. The look-at point stays fixed."""
    eye, centre, up = (np.asarray(v, np.float64) for v in (view.eye, view.look_at, view.up))
    axis = up / np.linalg.norm(up)
    offset = eye - centre
    out = []
    for t in np.linspace(0.0, 1.0, frames):
        s = 0.5 - 0.5 * np.cos(np.pi * t)  # ease in and out
        angle = np.radians(-30.0 + 60.0 * s)
        radial = offset * np.cos(angle) + np.cross(axis, offset) * np.sin(angle) + axis * (axis @ offset) * (1 - np.cos(angle))
        shrink = 1.0 - 0.45 * np.sin(np.pi * t)
        rise = 0.08 * np.linalg.norm(offset) * np.sin(np.pi * t)
        out.append(replace(view, eye=tuple(centre + radial * shrink + axis * rise)))  # its fov, axis and size
    return out


def _ffmpeg_exe():
    import imageio_ffmpeg

    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:  # neither its own binary nor one on the PATH
        raise InputError(f"no ffmpeg to encode the video with: {' '.join(str(exc).split())}") from None


def _ffmpeg_command(path, width, height, fps):
    """H.264 (yuv420p, crf 10, as imageio's quality 8) from raw RGB frames on stdin.
    yuv420p needs even sides: an odd one gets a black line of padding."""
    command = [_ffmpeg_exe(), "-y", "-hide_banner", "-loglevel", "error",
               "-f", "rawvideo", "-vcodec", "rawvideo", "-s", f"{width}x{height}", "-pix_fmt", "rgb24", "-r", str(fps),
               "-i", "-", "-an", "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", "10"]
    if width % 2 or height % 2:
        command += ["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"]
    return command + ["-f", "mp4", os.fspath(path)]


def _ffmpeg_reason(log):
    """ffmpeg's error, on one line: its last message but the closing "Conversion failed!",
    without the "[muxer @ 0x...]" prefix."""
    log.seek(0)
    lines = [line.strip() for line in log.read().decode(errors="replace").splitlines()]
    lines = [line for line in lines if line and line != "Conversion failed!"]
    if not lines:
        return "it failed without saying why"
    return re.sub(r"^\[[^]]*\]\s*", "", lines[-1])


def write_video(renderer, path, base_view, *, frames=120, fps=30, mode="fitted", shading="pixel", exposure=1.0,
                progress=False):
    """Render the walkthrough and encode it; returns the number of frames written.

    ffmpeg (imageio-ffmpeg's executable) writes to a temporary name beside ``path``,
    renamed into place once ffmpeg has finished without error: a failure (a full disk,
    ffmpeg's own error) raises ``OutputError`` (one line, with ffmpeg's reason), and
    any failure, Ctrl-C included, stops ffmpeg and removes the temporary file, so
    no truncated video is ever left behind.
    """
    views = walkthrough_path(base_view, frames)
    if progress:
        from tqdm import tqdm

        views = tqdm(views, desc="video", unit="frame", disable=None, dynamic_ncols=True)
    target = os.path.abspath(path)
    directory, name = os.path.split(target)
    temporary = os.path.join(directory, temporary_name(directory, name, ".partial.mp4"))
    shown = os.fspath(path)
    process = None
    with tempfile.TemporaryFile() as log:
        try:
            command = _ffmpeg_command(temporary, base_view.width, base_view.height, fps)
            try:  # its own session: a Ctrl-C reaches us, and we stop ffmpeg, rather than ffmpeg finishing the file
                process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=log,
                                           start_new_session=True)
            except OSError as exc:
                raise InputError(f"cannot run ffmpeg {command[0]!r}: {exc.strerror or exc}") from None
            stopped = False
            try:
                for view in views:
                    process.stdin.write(tonemap(renderer.render(view, mode, shading), exposure).tobytes())
                process.stdin.close()
            except BrokenPipeError:  # ffmpeg stopped reading: it failed, and says why in its log
                stopped = True
            if process.wait() != 0 or stopped:
                raise OutputError(f"cannot write {shown!r}: ffmpeg: {_ffmpeg_reason(log)}")
            os.replace(temporary, target)
        except BaseException as exc:
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
            with contextlib.suppress(OSError):
                os.remove(temporary)
            if isinstance(exc, OSError) and not isinstance(exc, InputError):
                raise OutputError(f"cannot write {shown!r}: {exc.strerror or exc}") from None
            raise
        finally:
            if process is not None and process.stdin and not process.stdin.closed:
                with contextlib.suppress(OSError):
                    process.stdin.close()
            if hasattr(views, "close"):  # the progress bar, before any error line
                views.close()
    return frames
