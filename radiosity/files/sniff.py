"""What an input file is: the one sniffer every command asks.

``input_kind(path)`` decides from the file's first bytes, then its name: one of our
archives (``SOLUTION``, ``FIT``: by the format its meta names, whatever the file is
called), another ``.npz`` / zip archive, a single ``.npy`` array, a scene file
(``.toml``), a mesh file (``MESH_SUFFIXES``) or ``"unknown"``. It opens only regular
files (``inputs.check_input_file``), reads no arrays, and refuses a file beyond the
size its kind may have. ``require_format(path, accepted, label)`` is the check of the
commands that take a solution or a fit: one line naming the argument and what the
file is instead.
"""

from __future__ import annotations

import os

from radiosity.files.errors import InputError
from radiosity.files.inputs import MESH_BYTES, NPZ_BYTES, TEXT_BYTES, check_input_file
from radiosity.files.npz import NPY_MAGIC, NPZ_MAGIC, file_format

__all__ = ["BUILTIN_SCENES", "FILE_NAMES", "FIT", "FORMAT_NAMES", "MESH_SUFFIXES", "SCENE_SUFFIXES", "SOLUTION", "input_kind",
           "require_format", "scene_words"]

SOLUTION, FIT = "vlights.solution", "vlights.fit"
FILE_NAMES = {FIT: "fit.npz", SOLUTION: "solution.npz"}
SCENE_SUFFIXES = (".toml", ".xml")
MESH_SUFFIXES = (".obj", ".gltf", ".glb", ".ply", ".stl", ".off")
BUILTIN_SCENES = ("cornell", "cornell-teapot", "plates")  # ``radiosity.scene.builtins`` builds them
FORMAT_NAMES = {
    ".toml": "a TOML scene", ".xml": "a Mitsuba XML scene, versions 0.4-0.6 and 2-3", ".obj": "OBJ/MTL",
    ".gltf": "glTF", ".glb": "glTF", ".ply": "PLY", ".stl": "STL", ".off": "OFF",
}
_LIMITS = {"scene": TEXT_BYTES, "mesh": MESH_BYTES}


def input_kind(path: str | os.PathLike, what: str = "input") -> str:
    """SOLUTION, FIT, another format our meta names, "npz", "npy", "scene", "mesh" or
    "unknown" (see the module docstring); InputError naming ``what`` if ``path`` is missing, not a regular file
    (after its symlinks) or too large for its kind."""
    shown = check_input_file(path, what, NPZ_BYTES)
    try:
        with open(shown, "rb") as f:  # a regular file: opening cannot block
            magic = f.read(len(NPY_MAGIC))
    except OSError as exc:
        raise InputError(f"{what} {shown!r} cannot be read ({exc.strerror or exc})") from None
    if magic.startswith(NPZ_MAGIC):
        return file_format(shown) or "npz"
    if magic.startswith(NPY_MAGIC):
        return "npy"
    suffix = os.path.splitext(shown)[1].lower()
    kind = "scene" if suffix in SCENE_SUFFIXES else "mesh" if suffix in MESH_SUFFIXES else "unknown"
    if kind in _LIMITS:
        check_input_file(shown, what if what != "input" else kind, _LIMITS[kind])
    return kind


def require_format(path: str | os.PathLike, accepted: tuple[str, ...], label: str = "input") -> str:
    """The format of ``path`` (one of ``accepted``: SOLUTION, FIT); InputError naming
    ``label`` (the argument) and what the file is otherwise. Reads no arrays."""
    shown = os.fspath(path)
    want = " or a ".join(FILE_NAMES[f] for f in accepted)
    if os.path.isdir(shown):
        raise InputError(f"{label} {shown!r} is a directory, not a {want}")
    kind = input_kind(shown, label)
    if kind in accepted:
        return kind
    if kind in FILE_NAMES:
        raise InputError(f"{label} {shown!r} is a {FILE_NAMES[kind]}, not a {want}")
    found = {
        "scene": "a scene file",
        "mesh": "a mesh file",
        "npy": "a single .npy array",
        "npz": "not one of this program's .npz files",
        "unknown": "not one of this program's .npz files",
    }.get(kind, f"an .npz file of format {kind!r}")
    raise InputError(f"{label} {shown!r} is not a {want}: it is {found}")


def scene_words():
    """What a scene argument takes, in words, for every help text that takes a scene:
    built from the tables the loaders read (``BUILTIN_SCENES``, the suffixes), so it
    cannot leave one out; a suffix missing from ``FORMAT_NAMES`` is a KeyError here."""

    def named(suffixes):
        groups = {}
        for suffix in suffixes:
            groups.setdefault(FORMAT_NAMES[suffix], []).append(suffix)
        return ", ".join(f"{name} ({', '.join(group)})" for name, group in groups.items())

    return (f"a built-in scene ({', '.join(BUILTIN_SCENES)}), {named(SCENE_SUFFIXES)}, "
            f"or a mesh file: {named(MESH_SUFFIXES)}")
