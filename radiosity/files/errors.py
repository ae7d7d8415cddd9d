"""Errors and warnings that are the user's to fix, not the program's.

``InputError`` carries one line that names the problem; the command line prints it
and exits with status 2, without a traceback. Anything else that escapes is a bug.
"""

from __future__ import annotations


class InputError(Exception):
    """A problem with what the user gave us (file, scene, material, flag)."""


class SceneWarning(UserWarning):
    """Something in the input was repaired or dropped (degenerate triangles, ...)."""
