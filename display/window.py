"""``vlights view``: the walkthrough window (moderngl-window).

The renderer draws the HDR image into its float framebuffers, antialiased as every
picture is (``--samples``: MSAA, then supersampling, averaged in linear radiance); a
full-screen pass applies exposure and sRGB into the window (the renderer's ``show``:
display/shaders/tonemap.glsl, the tone map the web page uses too). moderngl-window's
KeyboardCamera does the walking (WASD, Q/E down/up, mouse-look while the left button
is held). Keys:

    M  cycle mode (fitted, diffuse, solution)     G  Gouraud / per-pixel shading
    L  2 lights / all lights (the paper's figure 6)   + / -  exposure x 2 / x 0.5
    1  the emitters' highlights on / off          2  the reflection probe on / off
    3  the virtual lights on / off                P  screenshot (PNG, tone-mapped)
    ESC  quit

A status line shows mode, shading, lights, the parts switched off, exposure, samples per
pixel ("spp") and frame time. ``--frames N`` draws N frames and closes (for tests and
scripted captures); ``--screenshot FILE`` writes the last frame; ``--press KEYS``
presses keys (m g l + - p 1 2 3) after the first frame.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import re
import socket
import sys
import time
import warnings

import numpy as np

from radiosity.files.camera import Camera, fov_y_deg
from radiosity.files.errors import InputError

from .gl import DEFAULT_SAMPLES
from .renderer import MODE_WORDS, PARTS, Renderer

with warnings.catch_warnings():  # moderngl-window imports PyGLM by its old name, which warns
    warnings.simplefilter("ignore", PendingDeprecationWarning)
    import moderngl_window as mglw
    from moderngl_window.scene.camera import KeyboardCamera

X11_SOCKET_DIR = "/tmp/.X11-unix"
X11_TCP_PORT = 6000


def quiet_window_library():
    """moderngl-window logs INFO lines ("Context Version", ...) to stderr: keep its warnings only."""
    logging.getLogger("moderngl_window").setLevel(logging.WARNING)


class Walkthrough(mglw.WindowConfig):
    """Settings come from ``configure`` (the renderer knows nothing of windows)."""

    gl_version = (3, 3)
    title = "vlights view"
    window_size = (1280, 720)
    aspect_ratio = None
    resizable = True
    vsync = False
    log_level = logging.WARNING  # moderngl-window's own default, INFO, prints a line per context detail
    setup = {}
    failure = None  # an InputError met while the window ran (--screenshot could not be written)

    @classmethod
    def configure(cls, fit, solution, view, *, exposure=1.0, frames=None, screenshot=None, mode=None, press="",
                  samples=DEFAULT_SAMPLES, glass="blend", near_mirrors=True):
        """The window's settings: the model (``fit`` and/or ``solution``), the start
        ``view`` (its size the window's), and by keyword the rest."""
        settings = dict(exposure=exposure, frames=frames, screenshot=screenshot, mode=mode, press=press, samples=samples,
                        glass=glass, near_mirrors=near_mirrors)
        cls.setup = dict(fit=fit, solution=solution, view=view, **settings)
        cls.window_size = (view.width, view.height)
        cls.failure = None
        quiet_window_library()

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        s = self.setup
        self.renderer = Renderer(self.ctx, fit=s["fit"], solution=s["solution"], samples=s["samples"])
        self.renderer.glass_approach = s.get("glass", self.renderer.glass_approach)
        self.renderer.near_mirrors = s.get("near_mirrors", self.renderer.near_mirrors)
        self.modes = self.renderer.modes
        self.mode = s["mode"] or self.modes[0]
        self.shading = "pixel"
        self.all_lights = True
        self.parts = set(PARTS)  # the parts of the model drawn (keys 1, 2, 3)
        self.exposure = s["exposure"]
        self.frames_left = s["frames"]
        self.screenshot_path = s["screenshot"]
        self.press = s["press"]
        view = s["view"]
        self.fov_along = (view.fov_deg, view.fov_axis)  # the field of view, along its axis as the window resizes
        radius = float(np.linalg.norm(self.renderer.bounds[1] - self.renderer.bounds[0]))
        # its projection is unused: the renderer draws with its own depth range and convention
        # (display.renderer.depth_range, Depth), from the view current_view gives it
        self.camera = KeyboardCamera(self.wnd.keys, fov=view.fov_y_deg, aspect_ratio=self.wnd.aspect_ratio,
                                     near=radius * 1e-3, far=radius * 10)
        self.camera.velocity = radius * 0.25
        self.camera.mouse_sensitivity = 0.15
        eye = np.asarray(view.eye, float)
        forward = np.subtract(view.look_at, view.eye)
        forward /= np.linalg.norm(forward)
        self.camera.set_position(*eye)
        self.camera.set_rotation(math.degrees(math.atan2(forward[2], forward[0])), math.degrees(math.asin(forward[1])))
        from moderngl_window.text.bitmapped import TextWriter2D

        self.text = TextWriter2D()
        self.text.text = ""
        self.last_frame_ms = 0.0

    def current_view(self):
        yaw, pitch = math.radians(self.camera.yaw), math.radians(self.camera.pitch)
        forward = np.array([math.cos(yaw) * math.cos(pitch), math.sin(pitch), math.sin(yaw) * math.cos(pitch)])
        eye = np.array(self.camera.position, float)
        w, h = self.wnd.buffer_size
        fov, axis = self.fov_along
        return Camera(tuple(eye), tuple(eye + forward), (0.0, 1.0, 0.0), fov, max(int(w), 1), max(int(h), 1), axis)

    def on_render(self, time_s, frame_time):
        start = time.perf_counter()
        view = self.current_view()
        lights = None if self.all_lights else 2
        fbo = self.renderer.draw(view, self.mode, self.shading, lights, parts=tuple(sorted(self.parts)))
        self.wnd.use()
        self.renderer.show(fbo, self.exposure)  # exposure and sRGB: tonemap.glsl
        off = [p for p in PARTS if p not in self.parts]
        self.text.text = (f"{MODE_WORDS[self.mode]} | {self.shading} | lights {'all' if self.all_lights else 2} | "
                          + (f"off: {', '.join(off)} | " if off else "")
                          + f"exposure {self.exposure:g} | {self.renderer.samples} spp | {self.last_frame_ms:.1f} ms")
        self.text.draw((10, self.wnd.buffer_size[1] - 24), size=14)
        self.ctx.finish()
        self.last_frame_ms = 1000 * (time.perf_counter() - start)
        if self.press:  # scripted key presses, through the same handler as the keyboard's
            keys = self.wnd.keys
            table = {"m": keys.M, "g": keys.G, "l": keys.L, "+": keys.EQUAL, "-": keys.MINUS, "p": keys.P,
                     "1": keys.NUMBER_1, "2": keys.NUMBER_2, "3": keys.NUMBER_3}
            for char in self.press:
                self.on_key_event(table[char], keys.ACTION_PRESS, None)
            self.press = ""
        if self.frames_left is not None:
            self.frames_left -= 1
            if self.frames_left <= 0:
                if self.screenshot_path:
                    self.save_screenshot(self.screenshot_path)
                self.wnd.close()

    def save_screenshot(self, path=None):
        """The window's picture as a PNG, written atomically. A failure to write (a full
        disk, ...) is one line on stderr, and the walkthrough goes on; for --screenshot,
        it is kept in ``failure`` for the command to report after the window closes."""
        from display.images import write_png

        w, h = self.wnd.buffer_size
        data = np.frombuffer(self.wnd.fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1]
        path = path or os.path.abspath(f"vlights-{time.strftime('%Y%m%d-%H%M%S')}.png")
        try:
            write_png(path, data)
        except InputError as exc:
            if path == self.screenshot_path:  # --screenshot: the run's output; its failure is the run's
                type(self).failure = exc
            else:
                print(f"vlights view: screenshot not saved: {exc}", file=sys.stderr)
            return None
        print(f"screenshot: {path}")
        return path

    def on_key_event(self, key, action, modifiers):
        keys = self.wnd.keys
        self.camera.key_input(key, action, modifiers)
        if action != keys.ACTION_PRESS:
            return
        if key == keys.M:
            self.mode = self.modes[(self.modes.index(self.mode) + 1) % len(self.modes)]
        elif key == keys.G:
            self.shading = "gouraud" if self.shading == "pixel" else "pixel"
        elif key == keys.L:
            self.all_lights = not self.all_lights
        elif key == keys.EQUAL:
            self.exposure *= 2.0
        elif key == keys.MINUS:
            self.exposure *= 0.5
        elif key == keys.P:
            self.save_screenshot()
        elif key in (keys.NUMBER_1, keys.NUMBER_2, keys.NUMBER_3):
            part = {keys.NUMBER_1: "emitters", keys.NUMBER_2: "probe", keys.NUMBER_3: "lights"}[key]
            self.parts ^= {part}

    def on_mouse_drag_event(self, x, y, dx, dy):
        self.camera.rot_state(-dx, -dy)

    def on_resize(self, width, height):
        fov, axis = self.fov_along
        self.camera.projection.update(aspect_ratio=self.wnd.aspect_ratio,
                                      fov=fov_y_deg(fov, axis, max(int(width), 1), max(int(height), 1)))


def _parse_display(name):
    """(host, display number) of an X display name "[host]:number[.screen]"; None if it is not one."""
    match = re.fullmatch(r"(?P<host>[^:]*):(?P<number>\d+)(\.\d+)?", name.strip())
    return (match["host"], int(match["number"])) if match else None


def _x_server_answers(host, number, timeout=1.0):
    """Whether something accepts a connection where an X server of display ``number``
    listens: its Unix socket (the file, then Linux's abstract name) for a local
    display, TCP port 6000 + number for a remote one. Nothing is sent."""
    if host in ("", "unix"):
        path = f"{X11_SOCKET_DIR}/X{number}"
        addresses = [path] + (["\0" + path] if sys.platform.startswith("linux") else [])
        for address in addresses:
            with contextlib.closing(socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)) as s:
                s.settimeout(timeout)
                try:
                    s.connect(address)
                    return True
                except OSError:
                    continue
        return False
    try:
        with socket.create_connection((host, X11_TCP_PORT + number), timeout=timeout):
            return True
    except OSError:
        return False


def display_problem(environ=None):
    """Why no window can be opened here (a phrase), or None if one can.

    On Linux and the BSDs the window (pyglet) needs an X server: DISPLAY must be set
    and a server must answer there (Wayland sessions provide one through XWayland).
    macOS and Windows always have a display."""
    env = os.environ if environ is None else environ
    if sys.platform in ("darwin", "win32"):
        return None
    display = env.get("DISPLAY", "")
    if not display:
        if env.get("WAYLAND_DISPLAY"):
            return "DISPLAY is not set; the window needs X, and this Wayland session offers no XWayland"
        return "DISPLAY is not set"
    parsed = _parse_display(display)
    if parsed is None:
        return f"DISPLAY={display} is not an X display name such as :0"
    if not _x_server_answers(*parsed):
        return f"no X server answers on DISPLAY={display}"
    return None


def has_display(environ=None):
    """True if a window can be opened here (see ``display_problem``)."""
    return display_problem(environ) is None
