"""``vlights serve DIR``: a local static web server for an exported walkthrough.

Browsers load ES modules (three.js) only over HTTP, not from ``file://``, so a page
next to ``scene.glb`` needs a server. This one is Python's own ``http.server``, bound
to 127.0.0.1 (nothing outside this machine reaches it), serving ``DIR`` and nothing
above it (no ``..``, and no symlink inside ``DIR`` to anything outside it: 404), with
the MIME types a page of modules and a binary glTF need. It prints the
URL and runs until Ctrl-C. The command itself is ``display.commands.serve``.
"""

from __future__ import annotations

import functools
import http.server
import os
import threading

from radiosity.files.errors import InputError

__all__ = ["Server", "serve_until_interrupted", "start"]

HOST = "127.0.0.1"
TYPES = {".js": "text/javascript", ".mjs": "text/javascript", ".glb": "model/gltf-binary",
         ".gltf": "model/gltf+json", ".json": "application/json", ".html": "text/html"}


def inside(path, root):
    """True if ``path``, every link in it followed, is ``root`` or lies under it (both
    resolved: a symlink inside ``root`` to a file outside it is outside)."""
    target, top = os.path.realpath(path), os.path.realpath(root)
    return target == top or target.startswith(top.rstrip(os.sep) + os.sep)


class _Handler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map, **TYPES}

    def send_head(self):
        """404 for any path whose resolved target leaves the served directory (a symlink
        out of it); ``..`` and absolute paths never leave it (``translate_path`` drops
        them)."""
        if not inside(self.translate_path(self.path), self.directory):
            self.send_error(404, "File not found")
            return None
        return super().send_head()

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass  # quiet: a walkthrough page fetches many files


class Server:
    """A running server: ``url``, and ``close()`` (also on leaving a ``with``)."""

    def __init__(self, httpd):
        self._httpd = httpd
        self.url = f"http://{HOST}:{httpd.server_address[1]}/"
        self._thread = threading.Thread(target=httpd.serve_forever, daemon=True)
        self._thread.start()

    def close(self):
        self._httpd.shutdown()
        self._httpd.server_close()
        self._thread.join()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def start(directory, port=0, must_exist=True):
    """Serve ``directory`` on 127.0.0.1:``port`` (0: any free port) in a background
    thread; a ``Server``. InputError (one line) for a missing directory or a port that
    cannot be had. ``must_exist=False``: the directory may appear later (the port is
    had before a command writes what it serves)."""
    directory = os.fspath(directory)
    if must_exist and not os.path.isdir(directory):
        what = "not found" if not os.path.exists(directory) else "is not a directory"
        raise InputError(f"directory {directory!r} {what}")
    if not (isinstance(port, int) and 0 <= port <= 65535):
        raise InputError(f"--port must be a whole number from 0 to 65535, got {port}")
    handler = functools.partial(_Handler, directory=directory)
    try:
        httpd = http.server.ThreadingHTTPServer((HOST, port), handler)
    except OSError as exc:
        raise InputError(f"cannot serve on {HOST}:{port}: {exc.strerror or exc}") from None
    return Server(httpd)


def serve_until_interrupted(server, directory):
    """Print the URL and serve until Ctrl-C (KeyboardInterrupt reaches the caller)."""
    print(f"serving {os.path.abspath(directory)} at {server.url} (Ctrl-C stops)", flush=True)
    threading.Event().wait()
