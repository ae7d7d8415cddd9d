"""The only module that creates OpenGL contexts, and what an image may cost.

Headless rendering uses a standalone context through EGL (Mesa llvmpipe on machines
without a GPU); the walkthrough window gets its context from moderngl-window.

``check_image_size`` refuses an image larger than the context can draw (its largest
texture, renderbuffer and viewport); ``check_image_memory`` refuses one whose float
framebuffers and images would not fit in the memory this machine has free. Both
raise ``InputError`` with one line naming the limit or the estimate.
"""

from __future__ import annotations

import os

import moderngl

from radiosity.formats.errors import InputError

REQUIRED_VERSION = 330

# Bytes per pixel, measured (peak resident memory against image size) and rounded up:
# one picture is an RGBA float32 colour texture and a depth buffer on the GL side,
# then the read-back, the (H, W, 3) float32 image and tone mapping's float64
# intermediates (~135 measured); a comparison adds FLIP's working images and the
# error maps (~275 measured).
RENDER_BYTES_PER_PIXEL = 160
COMPARE_BYTES_PER_PIXEL = 320


def headless_context():
    """A standalone OpenGL 3.3+ context through EGL; InputError (one line) if none."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=REQUIRED_VERSION)
    except Exception as exc:  # moderngl raises plain Exception when EGL is missing
        raise InputError(f"no headless OpenGL context (EGL): {' '.join(str(exc).split())}") from None
    return ctx


def image_limits(ctx):
    """The largest (width, height) the context can render into, and the limit that sets
    each: ((max_width, name), (max_height, name)). A framebuffer here is float colour
    textures, a depth renderbuffer and a viewport over them."""
    info = ctx.info
    viewport = info.get("GL_MAX_VIEWPORT_DIMS") or (None, None)
    limits = []
    for axis in (0, 1):
        candidates = [(info.get("GL_MAX_TEXTURE_SIZE"), "GL_MAX_TEXTURE_SIZE"),
                      (info.get("GL_MAX_RENDERBUFFER_SIZE"), "GL_MAX_RENDERBUFFER_SIZE"),
                      (viewport[axis], "GL_MAX_VIEWPORT_DIMS")]
        known = [(int(v), name) for v, name in candidates if v]
        limits.append(min(known) if known else (None, None))
    return tuple(limits)


def check_image_size(ctx, width, height, flag="--size"):
    """Refuse a ``width`` x ``height`` image beyond what ``ctx`` can draw, naming the limit."""
    (max_w, name_w), (max_h, name_h) = image_limits(ctx)
    for side, limit, name, what in ((width, max_w, name_w, "wide"), (height, max_h, name_h, "high")):
        if limit is not None and side > limit:
            raise InputError(
                f"{flag} {width}x{height}: this OpenGL draws images at most {limit} pixels {what} ({name} = {limit})"
            )


def available_memory():
    """Bytes of memory this process may still use: the kernel's MemAvailable, lowered
    to what is left under a cgroup (container) limit; None where unknown."""
    candidates = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    candidates.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            used = int(f.read().strip())
        if limit != "max":
            candidates.append(max(int(limit) - used, 0))
    except (OSError, ValueError):
        pass
    return min(candidates) if candidates else None


def _size(n):
    for unit, scale in (("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 1e3:.0f} kB"


def check_image_memory(width, height, bytes_per_pixel=RENDER_BYTES_PER_PIXEL, flag="--size"):
    """Refuse a ``width`` x ``height`` image whose float framebuffers and images would
    not fit in the free memory, with the estimate; returns the estimate in bytes."""
    need = int(width) * int(height) * bytes_per_pixel
    free = available_memory()
    if free is not None and need > free:
        raise InputError(
            f"{flag} {width}x{height} needs about {_size(need)} of memory for its float framebuffers and images "
            f"({bytes_per_pixel} bytes a pixel), but only {_size(free)} is free; choose a smaller size"
        )
    return need
