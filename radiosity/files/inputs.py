"""Reading an input file safely: what may be opened, how much may be read, how deep it may nest.

Every input file (a scene, a mesh and the files it names, a views file, a solution or
fit archive) goes through here before a parser sees it:

- ``check_input_file(path, what, limit)``: the path, after its symlinks are resolved,
  is a regular file of at most ``limit`` bytes. A FIFO (opening one blocks until a
  writer comes), a device (``/dev/zero`` never ends), a socket or a directory is
  refused, and so is a file too large for its kind, before anything is opened.
- ``read_input_bytes(path, what, limit)``: its bytes, opened without blocking and
  checked again on the open descriptor (the path may change between the two), and
  never more than ``limit`` read.
- ``loads_json`` / ``loads_toml``: a parse that names a document nested too deep in one
  line (Python's parsers recurse and would raise RecursionError), and refuses one
  deeper than ``MAX_NESTING`` (no file of ours nests a tenth of that) so that no code
  walking the result recurses too far either.

Each refusal is an ``InputError``: one line naming the file and the problem.
"""

from __future__ import annotations

import json
import os
import stat
import tomllib

from radiosity.files.errors import InputError

__all__ = [
    "MAX_NESTING",
    "MESH_BYTES",
    "NPZ_BYTES",
    "TEXT_BYTES",
    "check_input_file",
    "check_nesting",
    "loads_json",
    "loads_toml",
    "read_input_bytes",
]

# Size limits per kind of file. A scene or views file is a few kilobytes and an MTL a
# few more: 64 MiB of text is far beyond any hand-written or exported one. A mesh is
# read whole and trimesh holds several copies, so a mesh file beyond 2 GiB would not
# load on these machines anyway. A solution or fit archive's arrays are each checked
# against the free memory before they are read (``npz``); the file itself may be
# large (a high-quality solution of a big scene), so only an absurd size is refused.
TEXT_BYTES = 64 * 2**20
MESH_BYTES = 2 * 2**30
NPZ_BYTES = 64 * 2**30
MAX_NESTING = 100

_KINDS = (
    (stat.S_ISDIR, "is a directory, not a file"),
    (stat.S_ISFIFO, "is a named pipe (FIFO), not a regular file"),
    (stat.S_ISCHR, "is a character device, not a regular file"),
    (stat.S_ISBLK, "is a block device, not a regular file"),
    (stat.S_ISSOCK, "is a socket, not a regular file"),
)


def _size(n: int) -> str:
    for unit, factor in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= factor:
            return f"{n / factor:.3g} {unit}"
    return f"{n} bytes"


def _check_stat(st: os.stat_result, shown: str, what: str, limit: int | None) -> None:
    for test, problem in _KINDS:
        if test(st.st_mode):
            raise InputError(f"{what} {shown!r} {problem}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{what} {shown!r} is not a regular file")
    if limit is not None and st.st_size > limit:
        raise InputError(
            f"{what} {shown!r} is {_size(st.st_size)}, more than the {_size(limit)} a {what} may be"
        )


def check_input_file(path: str | os.PathLike, what: str = "input", limit: int | None = None) -> str:
    """``path`` as a string if it is (through its symlinks) a regular file of at most
    ``limit`` bytes; InputError naming ``what`` and the problem otherwise. Opens nothing."""
    shown = os.fspath(path)
    try:
        st = os.stat(shown)  # follows symlinks; never opens, so a FIFO cannot block here
    except FileNotFoundError:
        dangling = os.path.islink(shown)
        raise InputError(f"{what} {shown!r} {'is a symlink to nothing' if dangling else 'not found'}") from None
    except OSError as exc:
        raise InputError(f"{what} {shown!r} cannot be read ({exc.strerror or exc})") from None
    except ValueError:  # an embedded NUL
        raise InputError(f"{what} {shown!r} is not a valid path") from None
    _check_stat(st, shown, what, limit)
    return shown


def read_input_bytes(path: str | os.PathLike, what: str = "input", limit: int | None = TEXT_BYTES) -> bytes:
    """The bytes of the regular file ``path`` (``check_input_file``), at most ``limit``."""
    shown = check_input_file(path, what, limit)
    try:
        fd = os.open(shown, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise InputError(f"{what} {shown!r} cannot be read ({exc.strerror or exc})") from None
    try:
        _check_stat(os.fstat(fd), shown, what, limit)  # the file that was opened, not the one stat saw
        chunks, total = [], 0
        cap = limit if limit is not None else 2**62
        while True:
            chunk = os.read(fd, min(1 << 24, cap + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > cap:
                raise InputError(f"{what} {shown!r} grew beyond the {_size(cap)} a {what} may be while it was read")
    except OSError as exc:
        raise InputError(f"{what} {shown!r} cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def _too_deep(where: str) -> InputError:
    return InputError(f"{where}: nested too deep (more than {MAX_NESTING} levels of arrays or tables)")


def check_nesting(value, where: str):
    """``value`` (parsed JSON or TOML) if it nests at most ``MAX_NESTING`` deep; an
    iterative walk, so it cannot itself recurse too far."""
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        if depth > MAX_NESTING:
            raise _too_deep(where)
        stack.extend((child, depth + 1) for child in children if isinstance(child, (dict, list)))
    return value


def loads_json(text: str | bytes, where: str):
    """``json.loads(text)`` with its nesting bounded; json.JSONDecodeError as json's
    own for the caller to word, InputError for a document nested too deep."""
    try:
        value = json.loads(text)
    except RecursionError:
        raise _too_deep(where) from None
    return check_nesting(value, where)


def loads_toml(text: str, where: str):
    """``tomllib.loads(text)`` with its nesting bounded; tomllib.TOMLDecodeError for
    the caller to word, InputError for a document nested too deep."""
    try:
        value = tomllib.loads(text)
    except RecursionError:
        raise _too_deep(where) from None
    return check_nesting(value, where)
