"""The only module that creates OpenGL contexts, and what an image may cost.

Headless rendering uses a standalone context through EGL (Mesa llvmpipe on machines
without a GPU); the walkthrough window gets its context from moderngl-window.

``check_image_size`` refuses an image larger than the context can draw (its largest
texture, renderbuffer and viewport); ``check_image_memory`` refuses one whose float
framebuffers and images would not fit in the memory this machine has free. Both
raise ``InputError`` with one line naming the limit or the estimate.

Antialiasing: every picture averages ``samples`` samples per pixel, all inside the
pixel, with equal weights: a box filter over the pixel, as a path tracer integrating
over the pixel has. ``sample_plan`` says how: up to the context's multisampling
(``ctx.max_samples``; 4 for float colour on llvmpipe) by MSAA alone; beyond it, the
image is also drawn ``factor`` times larger on each side and each factor x factor
block averaged (supersampling). ``check_samples`` refuses a count outside 1 to
``MAX_SAMPLES``, one whose larger image the context cannot draw, and one whose largest
buffer (the multisampled float colour buffer of the larger image) reaches
``MAX_BUFFER_BYTES``, which the driver refuses however much memory is free: on
llvmpipe 2048x2048 with 32 samples is a 6144x6144 image of 4 samples a pixel, 2.4 GB
in one buffer ("framebuffer incomplete"). ``framebuffer_refusals`` turns a framebuffer
a driver still refuses into the same one line.

Depth (``depth_control``): the renderer draws with reversed Z into a floating-point depth
buffer, the precision that holds at any scale. Its projection maps the near plane to
depth 1 and an infinite far plane to 0 (``display.renderer.Depth``); ``glClipControl(
GL_LOWER_LEFT, GL_ZERO_TO_ONE)`` keeps that mapping as it is (the default, -1 to 1,
would halve it and add 0.5, losing a float's precision near 0), and the depth buffers
are GL_DEPTH_COMPONENT32F: a float's relative precision (2^-24) at every distance, so
two surfaces a millionth of their distance apart stay apart. moderngl exposes neither,
so ``DepthControl`` gets both entry points from the context's own loader through ctypes
(EGL's ``eglGetProcAddress`` for the headless context, GLX's or WGL's for a window's)
and re-specifies the storage of moderngl's depth renderbuffers as GL_DEPTH_COMPONENT32F.
Where the context has no clip control (OpenGL below 4.5 without ARB_clip_control,
macOS), ``depth_control`` is None and the renderer falls back to the conventional
depth range (``display.renderer.Depth``).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import sys
from typing import NamedTuple

import moderngl

from radiosity.files.errors import InputError
from radiosity.policies.limits import available_memory

REQUIRED_VERSION = 330

# Bytes per pixel at DEFAULT_SAMPLES, measured (peak resident memory against image size)
# and rounded up: one picture is a 4x multisample RGBA float32 colour renderbuffer and
# depth buffer, the float texture its samples are averaged into, on the GL side, then
# the read-back, the (H, W, 3) float32 image and tone mapping's float64 intermediates
# (~210 measured; ~135 with one sample); a comparison adds the one-sample framebuffer
# of the object masks, FLIP's working images and the error maps (~420 measured).
# Other sample counts add or save what their framebuffers differ by (framebuffer_bytes):
# a picture of 16 samples is estimated at 544, of 64 at 1696 (430 and 1590 measured).
RENDER_BYTES_PER_PIXEL = 240
COMPARE_BYTES_PER_PIXEL = 480

# The largest single texture or renderbuffer, in bytes: llvmpipe makes none of 2 GiB or
# more (LP_MAX_TEXTURE_SIZE; offsets are signed 32-bit), after rounding each side up to
# BUFFER_ALIGN texels; measured: 5792x5792 of 4 samples (RGBA float32) is made, 5792x5793
# and 5793x5793 are not; an 11584-square float texture is, 11585 is not.
MAX_BUFFER_BYTES = 1 << 31
BUFFER_ALIGN = 32
COLOUR_BYTES = 16  # an RGBA float32 colour sample

DEFAULT_SAMPLES = 4  # samples per pixel unless told otherwise: 4x MSAA
MAX_SAMPLES = 64     # a ceiling: 64 samples' colour and depth are ~1.5 kB a pixel, 1.4 GB at 1280 x 720


class SamplePlan(NamedTuple):
    """How ``samples`` per pixel are drawn: the image ``factor`` times larger on each side
    (supersampling), ``msaa`` samples in each of its pixels; ``per_pixel`` samples in all
    (at least ``samples``), averaged with equal weights."""

    samples: int
    msaa: int
    factor: int

    @property
    def per_pixel(self):
        return self.factor * self.factor * self.msaa


def check_sample_count(samples, flag="--samples"):
    """Refuse a number of samples per pixel outside 1 to MAX_SAMPLES."""
    if not 1 <= samples <= MAX_SAMPLES:
        raise InputError(f"{flag} must be 1 to {MAX_SAMPLES} (samples per pixel), got {samples}")


def sample_plan(samples, max_msaa=DEFAULT_SAMPLES):
    """The plan for ``samples`` per pixel on a context multisampling at most ``max_msaa``
    (``ctx.max_samples``): MSAA alone (a power of two, as moderngl takes) up to
    ``max_msaa``; beyond it, the largest MSAA in each pixel of an image the smallest
    ``factor`` larger that reaches ``samples``. 1 -> one sample; 4 -> MSAA 4;
    16 -> 2 x 2 of MSAA 4; 8 -> 2 x 2 of MSAA 4 (16). A driver may round an MSAA count
    up to one it has (llvmpipe: 2 -> 4)."""
    check_sample_count(samples)
    top = 1 << (max(int(max_msaa), 1).bit_length() - 1)
    if samples <= top:
        msaa = 1
        while msaa < samples:
            msaa *= 2
        return SamplePlan(samples, msaa, 1)
    factor = 2
    while factor * factor * top < samples:
        factor += 1
    return SamplePlan(samples, top, factor)


def framebuffer_bytes(samples):
    """GL bytes per image pixel of the framebuffers ``samples`` are drawn through (a context
    with 4x MSAA): per sample an RGBA float32 colour and a depth value, then the MSAA
    samples averaged (RGBA float32 per supersampled pixel), then the image itself."""
    plan = sample_plan(samples)
    sub_pixels = plan.factor * plan.factor
    total = sub_pixels * plan.msaa * (16 + 4)
    if plan.msaa > 1:
        total += sub_pixels * 16
    if plan.factor > 1:
        total += 16
    return total


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


def _beyond_limits(ctx, width, height):
    """What a ``width`` x ``height`` image exceeds in ``ctx`` ("at most N pixels wide (NAME = N)"), or None."""
    (max_w, name_w), (max_h, name_h) = image_limits(ctx)
    for side, limit, name, what in ((width, max_w, name_w, "wide"), (height, max_h, name_h, "high")):
        if limit is not None and side > limit:
            return f"at most {limit} pixels {what} ({name} = {limit})"
    return None


def check_image_size(ctx, width, height, flag="--size"):
    """Refuse a ``width`` x ``height`` image beyond what ``ctx`` can draw, naming the limit."""
    beyond = _beyond_limits(ctx, width, height)
    if beyond is not None:
        raise InputError(f"{flag} {width}x{height}: this OpenGL draws images {beyond}")


def held_samples(ctx, msaa):
    """The samples a pixel of a buffer asked for ``msaa`` samples really holds: llvmpipe
    multisamples with 4 alone (a request for 2 gets 4); other drivers as asked."""
    if msaa <= 1:
        return 1
    return max(msaa, 4) if "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")) else msaa


def largest_buffer_bytes(plan, width, height, held=None):
    """Bytes of the largest buffer ``plan`` draws a ``width`` x ``height`` image through:
    the float colour buffer of the (factor times larger) image, ``held`` samples a pixel
    (default: the plan's MSAA), each side rounded up to BUFFER_ALIGN."""
    held = plan.msaa if held is None else held
    w, h = (-(-side * plan.factor // BUFFER_ALIGN) * BUFFER_ALIGN for side in (width, height))
    return w * h * COLOUR_BYTES * max(held, 1)


def _fits(ctx, samples, width, height):
    plan = sample_plan(samples, ctx.max_samples)
    return (_beyond_limits(ctx, width * plan.factor, height * plan.factor) is None
            and largest_buffer_bytes(plan, width, height, held_samples(ctx, plan.msaa)) < MAX_BUFFER_BYTES)


def most_samples(ctx, width, height):
    """The most samples per pixel (up to MAX_SAMPLES) ``ctx`` draws a ``width`` x
    ``height`` image with; 0 if none."""
    return max((n for n in range(1, MAX_SAMPLES + 1) if _fits(ctx, n, width, height)), default=0)


def check_samples(ctx, samples, width, height, flag="--samples"):
    """Refuse ``samples`` per pixel outside 1 to MAX_SAMPLES, whose supersampled image
    (``width`` x ``height`` times the plan's factor) ``ctx`` cannot draw, or whose
    largest buffer reaches MAX_BUFFER_BYTES; returns the plan."""
    check_sample_count(samples, flag)
    plan = sample_plan(samples, ctx.max_samples)
    w, h = width * plan.factor, height * plan.factor
    beyond = _beyond_limits(ctx, w, h)
    if beyond is not None:
        raise InputError(
            f"{flag} {samples} draws the {width}x{height} image {plan.factor} times larger on each side "
            f"({w}x{h}, {plan.msaa}x MSAA), and this OpenGL draws images {beyond}; use fewer samples or a smaller size"
        )
    held = held_samples(ctx, plan.msaa)
    need = largest_buffer_bytes(plan, width, height, held)
    if need >= MAX_BUFFER_BYTES:
        most = most_samples(ctx, width, height)
        advice = f"use {flag} {most} or fewer at this size, or a smaller size" if most else "choose a smaller size"
        drawn = f"a {w}x{h} image of {held} sample{'s' if held > 1 else ''} a pixel" + (f" ({plan.factor} times larger on each side)"
                                                                 if plan.factor > 1 else "")
        raise InputError(
            f"{flag} {samples} at {width}x{height} draws {drawn}: one float colour buffer of {_size(need)}, "
            f"and OpenGL here makes none of {_size(MAX_BUFFER_BYTES)} or more; {advice}"
        )
    return plan


@contextlib.contextmanager
def framebuffer_refusals(size, samples):
    """Inside: a framebuffer the driver refuses ("not complete", which a limit no query
    tells may cause) is an InputError naming the image, not a traceback."""
    try:
        yield
    except moderngl.Error as exc:
        if "framebuffer is not complete" not in str(exc):
            raise
        raise InputError(f"OpenGL here cannot make the framebuffers of a {size[0]}x{size[1]} image with {samples} "
                         f"samples per pixel ({' '.join(str(exc).split())}); use fewer samples or a smaller size") from None


def _size(n):
    for unit, scale in (("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 1e3:.0f} kB"


def check_image_memory(width, height, bytes_per_pixel=RENDER_BYTES_PER_PIXEL, flag="--size", samples=DEFAULT_SAMPLES):
    """Refuse a ``width`` x ``height`` image whose float framebuffers and images would
    not fit in the free memory, with the estimate; returns the estimate in bytes.

    ``bytes_per_pixel`` is measured at DEFAULT_SAMPLES; other ``samples`` add (or save)
    the difference of their framebuffers (``framebuffer_bytes``)."""
    bytes_per_pixel += framebuffer_bytes(samples) - framebuffer_bytes(DEFAULT_SAMPLES)
    need = int(width) * int(height) * bytes_per_pixel
    free = available_memory()
    if free is not None and need > free:
        raise InputError(
            f"{flag} {width}x{height} needs about {_size(need)} of memory for its float framebuffers and images "
            f"({bytes_per_pixel} bytes a pixel), but only {_size(free)} is free; choose a smaller size"
        )
    return need


# ---------------------------------------------------------------------------------- depth

GL_RENDERBUFFER = 0x8D41
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_LOWER_LEFT = 0x8CA1
GL_NEGATIVE_ONE_TO_ONE = 0x935E  # the GL's default depth mode: clip z in [-w, w]
GL_ZERO_TO_ONE = 0x935F          # clip z in [0, w], depth = z / w as it is
CLIP_CONTROL_VERSION = 450       # glClipControl is core in OpenGL 4.5 (else GL_ARB_clip_control)


@functools.cache
def _library(*names):
    """The first of the shared libraries ``names`` (ctypes.util names or file names) that loads, or None."""
    for name in names:
        path = ctypes.util.find_library(name) or name
        try:
            return ctypes.CDLL(path)
        except OSError:
            continue
    return None


def _loader():
    """The current context's ``GetProcAddress`` (bytes name -> address or 0): EGL's where
    an EGL context is current (``headless_context``), else GLX's (a window on X), WGL's
    on Windows; None where there is none (macOS has no clip control anyway)."""
    egl = _library("EGL", "libEGL.so.1")
    if egl is not None and hasattr(egl, "eglGetCurrentContext"):
        egl.eglGetCurrentContext.restype = ctypes.c_void_p
        if egl.eglGetCurrentContext():
            egl.eglGetProcAddress.restype = ctypes.c_void_p
            egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
            return egl.eglGetProcAddress
    if sys.platform == "win32":
        wgl = getattr(ctypes, "WinDLL", ctypes.CDLL)("opengl32")
        wgl.wglGetProcAddress.restype = ctypes.c_void_p
        wgl.wglGetProcAddress.argtypes = [ctypes.c_char_p]
        return wgl.wglGetProcAddress
    glx = _library("GL", "libGL.so.1")
    if glx is not None and hasattr(glx, "glXGetProcAddressARB"):
        glx.glXGetProcAddressARB.restype = ctypes.c_void_p
        glx.glXGetProcAddressARB.argtypes = [ctypes.c_char_p]
        return glx.glXGetProcAddressARB
    return None


class DepthControl:
    """Reversed Z for a context whose moderngl exposes no clip control and no float depth
    buffer: ``glClipControl`` and ``glRenderbufferStorageMultisample`` called through
    ctypes (``depth_control`` makes one)."""

    def __init__(self, ctx, functions):
        self.ctx = ctx
        self._clip_control, self._bind_renderbuffer, self._storage = functions

    def float_depth(self, renderbuffer):
        """Re-specify moderngl's depth ``renderbuffer`` (its size and samples kept) as
        GL_DEPTH_COMPONENT32F: float depth, before it is attached to a framebuffer."""
        width, height = renderbuffer.size
        self.ctx.error  # noqa: B018 -- reading it clears an error an earlier call left, not this one's
        self._bind_renderbuffer(GL_RENDERBUFFER, renderbuffer.glo)
        self._storage(GL_RENDERBUFFER, renderbuffer.samples, GL_DEPTH_COMPONENT32F, width, height)
        self._bind_renderbuffer(GL_RENDERBUFFER, 0)
        self._check("glRenderbufferStorageMultisample(GL_DEPTH_COMPONENT32F)")

    @contextlib.contextmanager
    def zero_to_one(self):
        """Inside: clip z from 0 to w maps to depth 0 to 1 as it is (glClipControl
        GL_LOWER_LEFT, GL_ZERO_TO_ONE); after: the GL's default again (-1 to 1), for
        whatever else draws with the context (a window's text)."""
        self.ctx.error  # noqa: B018 -- reading it clears an error an earlier call left, not this one's
        self._clip_control(GL_LOWER_LEFT, GL_ZERO_TO_ONE)
        self._check("glClipControl")
        try:
            yield
        finally:
            self._clip_control(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE)

    def _check(self, call):
        error = self.ctx.error
        if error != "GL_NO_ERROR":
            raise RuntimeError(f"{call} failed: {error}")


def depth_control(ctx):
    """A ``DepthControl`` for ``ctx`` (current), or None where it has no clip control
    (below OpenGL 4.5 without GL_ARB_clip_control) or its entry points are not found."""
    if ctx.version_code < CLIP_CONTROL_VERSION and "GL_ARB_clip_control" not in ctx.extensions:
        return None
    loader = _loader()
    if loader is None:
        return None
    prototypes = (
        (b"glClipControl", ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint)),
        (b"glBindRenderbuffer", ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint)),
        (b"glRenderbufferStorageMultisample",
         ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_int, ctypes.c_int)),
    )
    functions = []
    for name, prototype in prototypes:
        address = loader(name)
        if not address:
            return None
        functions.append(prototype(address))
    return DepthControl(ctx, functions)
