"""The only module that creates OpenGL contexts.

Headless rendering uses a standalone context through EGL (Mesa llvmpipe on machines
without a GPU); the walkthrough window gets its context from moderngl-window.
"""

from __future__ import annotations

import moderngl

from radiosity.formats.errors import InputError

REQUIRED_VERSION = 330


def headless_context():
    """A standalone OpenGL 3.3+ context through EGL; InputError (one line) if none."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=REQUIRED_VERSION)
    except Exception as exc:  # moderngl raises plain Exception when EGL is missing
        raise InputError(f"no headless OpenGL context (EGL): {' '.join(str(exc).split())}") from None
    return ctx
