"""The one way the display commands write images: every PNG, .npy and plotted figure
goes through here, each atomically (``radiosity.files.atomic.atomic_output``: the file is
whole or absent, a failure or Ctrl-C leaves nothing).

    write_png(path, image)            (H, W, 3) uint8 or a PIL image -> PNG
    write_npy(path, array)            an array -> .npy (a short write names its reason)
    write_figure(path, figure)        a matplotlib figure -> PNG
    write_pictures(radiance, ...)     linear radiance -> its .npy and/or its tone-mapped
                                      PNG, both files or neither

and the one way they read an image of linear radiance (``vlights compare --reference``),
re-exported from ``radiosity.files.images`` (the scene loaders read environment maps with it):

    read_hdr_image(path)              OpenEXR, Radiance HDR (RGBE), PFM or .npy ->
                                      (H, W, 3) float32 RGB, row 0 at the top, checked

The tone map itself (exposure, then sRGB) is ``display.renderer.tonemap``.
"""

from __future__ import annotations

import contextlib

import numpy as np

from radiosity.files.atomic import atomic_output
from radiosity.files.images import HDR_EXTENSIONS, read_hdr_image

__all__ = ["HDR_EXTENSIONS", "read_hdr_image", "write_figure", "write_npy", "write_pictures", "write_png"]


class _Writer:
    """A file object numpy writes an .npy through ``write`` (a short write is then an
    OSError with its reason, "No space left on device"; numpy's own fwrite path only
    says how many bytes it wrote)."""

    def __init__(self, f):
        self.write = f.write


def _save_png(f, image):
    from PIL import Image

    picture = image if isinstance(image, Image.Image) else Image.fromarray(np.asarray(image))
    picture.save(f, format="PNG")


def _save_npy(f, array):
    np.save(_Writer(f), np.asarray(array))


def write_png(path, image):
    """Write ``image`` ((H, W, 3) or (H, W) uint8, or a PIL image) as a PNG at ``path``."""
    with atomic_output(path) as f:
        _save_png(f, image)


def write_npy(path, array):
    """Write ``array`` as an .npy file at ``path``."""
    with atomic_output(path) as f:
        _save_npy(f, array)


def write_figure(path, figure, dpi=110):
    """Write a matplotlib ``figure`` as a PNG at ``path``."""
    with atomic_output(path) as f:
        figure.savefig(f, format="png", dpi=dpi)


def write_pictures(radiance, *, hdr=None, png=None, exposure=1.0):
    """Write linear ``radiance`` ((H, W, 3)) as float32 .npy at ``hdr`` and tone-mapped
    (``exposure``, then sRGB) as PNG at ``png``; either may be None. Both files or
    neither: each is committed only when both are written."""
    from display.renderer import tonemap

    with contextlib.ExitStack() as stack:
        if hdr is not None:
            _save_npy(stack.enter_context(atomic_output(hdr)), np.asarray(radiance, np.float32))
        if png is not None:
            _save_png(stack.enter_context(atomic_output(png)), tonemap(radiance, exposure))
