"""Output directories of the display commands (``compare --out``, ``demo --out``).

``check_output_dir`` refuses a directory that cannot take the files before any work
starts; ``staged_directory`` makes a run's files appear together or not at all: they
are written into a hidden directory inside the output directory and moved into place
when the run succeeds; on any failure (a full disk, an error, Ctrl-C) the hidden
directory is removed, and so is the output directory if the run created it.
Single files go through ``radiosity.files.atomic.atomic_output`` / ``check_output``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from radiosity.files.atomic import OutputError, check_output
from radiosity.files.errors import InputError

__all__ = ["check_output_dir", "staged_directory"]


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output_dir(path, flag="--out", files=(), inputs=()):
    """Refuse an output directory before any work goes into it; returns it as a Path.

    Refused: an empty path, one with a NUL or a name too long, a path that exists and
    is not a directory, a symlink to nothing, a missing parent (the directory itself
    is created, its parents are not: a mistyped path should not grow a tree), a parent
    that is a file, a directory we may not write into (by its permissions, then by
    the file system's own answer: a directory is made there and removed); and for each
    of ``files`` (paths relative to the directory, e.g. "compare/figure6.png") a
    directory in its way, a subdirectory that is a file or unwritable, or one of
    ``inputs``.
    """
    shown = str(path)
    if not shown:
        raise InputError(f"{flag} is empty; give a directory ('.' for the current one)")
    if "\0" in shown:
        raise InputError(f"{flag} {shown!r} holds a NUL character, which no file name may")
    out = Path(path)
    try:
        exists = out.exists()
    except OSError as exc:  # os.stat's own refusal, e.g. ENAMETOOLONG
        raise InputError(f"{flag} {shown!r}: {exc.strerror or exc}") from None
    if exists and not out.is_dir():
        raise InputError(f"{flag} {shown!r} exists and is not a directory")
    if not exists:
        if out.is_symlink():
            raise InputError(f"{flag} {shown!r} is a symlink to {os.readlink(out)!r}, which does not exist")
        check_output(out, flag=flag)  # its parent: exists, is a directory, writable
        _probe(out, shown, flag, new=True)
        return out
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {shown!r}: cannot write into directory {shown!r} (permission denied)")
    _probe(out, shown, flag, new=False)
    for name in files:
        target = out / name
        parts = Path(name).parts
        for i in range(1, len(parts)):
            folder = out.joinpath(*parts[:i])
            if folder.exists() and not folder.is_dir():
                raise InputError(f"{flag} {shown!r}: {str(folder)!r} is a file, and a directory is written there")
            if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
                raise InputError(f"{flag} {shown!r}: cannot write into directory {str(folder)!r} (permission denied)")
        if target.exists() and not target.is_file():
            raise InputError(f"{flag} {shown!r}: {str(target)!r} exists and is not a file, and a file is written there")
        for given in inputs:
            if given is not None and target.exists() and _same_file(target, given):
                raise InputError(f"{flag} {shown!r}: writing {str(target)!r} would destroy the input {str(given)!r}")
    return out


def _probe(out, shown, flag, new):
    """Ask the file system itself whether the run's directory can be made: create it
    (``new``) or the hidden directory a run stages its files in, and remove it again.
    The permission bits do not tell everything (a read-only mount, an immutable
    directory, /proc, a name too long): what would fail at the end fails now."""
    try:
        if new:
            out.mkdir()
            out.rmdir()
        else:
            os.rmdir(tempfile.mkdtemp(prefix=".vlights-", suffix=".probe", dir=out))
    except OSError as exc:
        what = "the directory" if new else "a directory inside it"
        raise InputError(f"{flag} {shown!r}: cannot create {what} ({exc.strerror or exc})") from None


def _move_into(stage: Path, out: Path) -> None:
    """Move everything in ``stage`` into ``out``, replacing files and merging directories."""
    for entry in sorted(stage.iterdir()):
        target = out / entry.name
        if entry.is_dir() and target.is_dir():
            _move_into(entry, target)
            entry.rmdir()
        else:
            os.replace(entry, target)


@contextlib.contextmanager
def staged_directory(out):
    """Yield a new hidden directory inside ``out`` (``out`` is created if missing, not
    its parents) to write a run's files into; see the module docstring.

    An OSError on the way (full disk, no permission) becomes ``OutputError``: one line.
    """
    out = Path(out)
    created = False
    try:
        if not out.is_dir():
            out.mkdir()
            created = True
        stage = Path(tempfile.mkdtemp(prefix=".vlights-", suffix=".partial", dir=out))
    except OSError as exc:
        raise OutputError(f"cannot create the output directory {str(out)!r}: {exc.strerror or exc}") from None
    try:
        yield stage
        _move_into(stage, out)
        stage.rmdir()
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if nothing of ours reached it
        if isinstance(exc, OutputError) and str(stage) in str(exc):  # name the file where it was going
            raise OutputError(str(exc).replace(str(stage), str(out))) from None
        if isinstance(exc, OSError) and not isinstance(exc, InputError):
            raise OutputError(f"cannot write into {str(out)!r}: {exc.strerror or exc}") from None
        raise
