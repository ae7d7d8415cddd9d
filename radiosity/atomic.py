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
``.<name>.<random>.tmp``.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from typing import BinaryIO

__all__ = ["atomic_output"]


def _create_temporary(directory: str, name: str) -> tuple[str, int]:
    """Create a new, empty file beside the target; returns (path, descriptor)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        tmp = os.path.join(directory, f".{name}.{secrets.token_hex(6)}.tmp")
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

    See the module docstring. Errors of the final flush, fsync or rename (full disk,
    ``path`` being a directory, ...) propagate too, after the temporary file is removed.
    """
    target = os.path.abspath(os.fspath(path))
    directory, name = os.path.split(target)
    tmp, fd = _create_temporary(directory, name)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    _fsync_directory(directory)
