"""Atomic file output: a file is either fully written or not touched at all.

``atomic_output(path)`` is a context manager that yields a binary file object opened
on a new temporary file in the target's directory. When the ``with`` block ends
normally the data is flushed and fsync'ed and the temporary file is renamed onto
``path`` with ``os.replace`` (atomic on POSIX and Windows within one file system), then
the directory is fsync'ed where the platform allows it. If the block raises anything,
KeyboardInterrupt included, the temporary file is removed, ``path`` is left as it was
(absent, or its old content), and the exception propagates::

    with atomic_output("solution.npz") as f:
        numpy.savez_compressed(f, **arrays)

The new file gets the permissions a plain ``open(path, "wb")`` would give it (0o666
minus the umask), unlike ``tempfile``'s private 0o600. Temporary files are named
``.<name>.<random>.tmp``, ``<name>`` shortened where the whole would pass the file
system's limit on a name (NAME_MAX, 255 bytes), so any name the file system takes as
an output gets a temporary name too. A symlink as ``path`` is followed: the file it
names is replaced (as ``open(path, "wb")`` would write it), not the link.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from radiosity.files.errors import InputError

__all__ = ["OutputError", "atomic_output", "check_output"]


class OutputError(InputError, OSError):
    """An output file could not be written (full disk, no permission, ...)."""


def check_output(path, suffix=None, inputs=(), flag="output"):
    """Refuse an output path before any work goes into it; returns it as a Path.

    Refused: a directory, a missing parent directory or one that is a file, a
    directory we may not write into, a name not ending in ``suffix`` (a string or a
    tuple of them), and a path that is one of ``inputs`` (the same file through any
    path or link: overwriting the input would lose it). ``flag`` names the option in
    the message.
    """
    out = Path(path)
    shown = str(path)
    if "\0" in shown:
        raise InputError(f"{flag} {shown!r} holds a NUL character, which no file name may")
    for name, directory in ((out.name, os.path.dirname(os.path.abspath(out))),
                            (os.path.basename(_target(path)), os.path.dirname(_target(path)))):
        limit = _name_max(directory if os.path.isdir(directory) else ".")
        if len(os.fsencode(name)) > limit:
            raise InputError(
                f"{flag} {shown!r}: the name is {len(os.fsencode(name))} bytes long, more than the {limit} "
                "the file system allows"
            )
    if out.is_dir():
        raise InputError(f"{flag} {shown!r} is a directory; give a file name")
    real = Path(_target(path))  # where the data goes: a symlink's target
    linked = "" if real == Path(os.path.abspath(path)) else f" (a symlink to {str(real)!r})"
    if real.is_dir():
        raise InputError(f"{flag} {shown!r}{linked} is a directory; give a file name")
    parent = real.parent
    if parent.exists() and not parent.is_dir():
        raise InputError(f"{flag} {shown!r}{linked}: {str(parent)!r} is a file, not a directory")
    if not parent.exists():
        raise InputError(f"{flag} {shown!r}{linked}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {shown!r}: cannot write into directory {str(parent)!r} (permission denied)")
    if real.exists() and not real.is_file():
        raise InputError(f"{flag} {shown!r}{linked} exists and is not a regular file")
    if suffix is not None:
        suffixes = (suffix,) if isinstance(suffix, str) else tuple(suffix)
        if not shown.lower().endswith(tuple(x.lower() for x in suffixes)):
            raise InputError(f"{flag} {shown!r} must end in {' or '.join(suffixes)}")
    for given in inputs:
        if given is None:
            continue
        same = False
        try:
            same = out.exists() and os.path.samefile(out, given)
        except (OSError, ValueError):
            same = False
        if same or os.path.realpath(out) == os.path.realpath(given):
            raise InputError(f"{flag} {shown!r} is the input file {str(given)!r}; writing it would destroy the input")
    _probe(str(parent), real.name, shown, flag)
    return out


def _target(path) -> str:
    """The absolute path the data of ``path`` goes to: through every symlink, a
    dangling one included (its target is created)."""
    return os.path.realpath(os.path.abspath(os.fspath(path)))


def _name_max(directory: str) -> int:
    try:
        return int(os.pathconf(directory, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def temporary_name(directory: str, name: str, suffix: str = ".tmp") -> str:
    """``.<name>.<12 hex><suffix>``, ``name`` cut (by whole characters) so the whole fits
    the directory's NAME_MAX: any name the file system takes gets a temporary name too."""
    room = _name_max(directory) - len(".") - len(".0123456789ab") - len(os.fsencode(suffix))
    while len(os.fsencode(name)) > room:
        name = name[:-1]
    return f".{name}.{secrets.token_hex(6)}{suffix}"


def _probe(directory: str, name: str, shown: str, flag: str) -> None:
    """Create and remove the temporary file the write will use: the one test of
    writability that knows what the file system will say (read-only mounts, ACLs,
    quotas on inodes, names too long), before any work is done."""
    try:
        tmp, fd = _create_temporary(directory, name)
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise InputError(f"{flag} {shown!r}: cannot create a file in directory {directory!r} ({reason})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)


def _create_temporary(directory: str, name: str) -> tuple[str, int]:
    """Create a new, empty file beside the target; returns (path, descriptor)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        tmp = os.path.join(directory, temporary_name(directory, name))
        try:
            return tmp, os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
    raise FileExistsError(f"could not create a temporary file in {directory!r}")


def _fsync_directory(directory: str) -> None:
    """Make the rename durable; a no-op where directories cannot be opened (Windows)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """Yield a binary file object whose content replaces ``path`` only on success.

    See the module docstring. An OSError while writing (full disk, ``path`` being a
    directory, no permission, ...) becomes ``OutputError`` (an ``InputError``: one
    line naming the file and the reason), after the temporary file is removed.
    """
    target = _target(path)
    directory, name = os.path.split(target)
    if os.path.exists(target) and not os.path.isfile(target):
        # a rename would replace a directory's entry, a device (/dev/null) or a pipe
        raise OutputError(f"cannot write {os.fspath(path)!r}: it exists and is not a regular file")
    try:
        tmp, fd = _create_temporary(directory, name)
    except OSError as exc:
        raise OutputError(_cannot_write(path, exc)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, InputError):
            raise OutputError(_cannot_write(path, exc)) from None
        raise
    _fsync_directory(directory)


def _cannot_write(path, exc: OSError) -> str:
    reason = exc.strerror or str(exc) or type(exc).__name__
    return f"cannot write {os.fspath(path)!r}: {reason}"
