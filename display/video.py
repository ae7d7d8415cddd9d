"""A walkthrough video: the camera glides along a smooth path through the scene, the
paper's "live walkthrough" as an MP4 (imageio-ffmpeg, H.264)."""

from __future__ import annotations

import os

import numpy as np

from radiosity.formats import Camera

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
        out.append(Camera(tuple(centre + radial * shrink + axis * rise), view.look_at, view.up, view.fov_y_deg, view.width, view.height))
    return out


def write_video(renderer, path, base_view, frames=120, fps=30, mode="fitted", shading="pixel", exposure=1.0, progress=False):
    """Render the walkthrough and encode it; returns the number of frames written."""
    import imageio.v2 as imageio

    views = walkthrough_path(base_view, frames)
    if progress:
        from tqdm import tqdm

        views = tqdm(views, desc="video", unit="frame", disable=None, dynamic_ncols=True)
    # ffmpeg writes to a path, not a file object: a temporary name beside the target,
    # renamed into place at the end (an interrupted run leaves no truncated video)
    target = os.path.abspath(path)
    temporary = os.path.join(os.path.dirname(target), f".{os.path.basename(target)}.{os.getpid()}.partial.mp4")
    try:
        writer = imageio.get_writer(temporary, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=8,
                                    macro_block_size=2)
        try:
            for view in views:
                writer.append_data(tonemap(renderer.render(view, mode, shading), exposure))
        finally:
            writer.close()
        os.replace(temporary, target)
    except BaseException:
        if os.path.exists(temporary):
            os.remove(temporary)
        raise
    return frames
