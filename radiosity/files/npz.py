"""The one reader and writer of the project's ``.npz`` files (both file contracts).

Every file is a ``numpy.savez_compressed`` archive, readable with
``allow_pickle=False``, whose ``meta`` entry is a 0-d string of JSON with at least
``format`` and ``version``. ``write_archive`` writes one atomically;
``open_archive`` opens one, checks that it is the format and a version the caller
reads, and hands out its arrays checked by key, dtype kind and shape, so every
problem becomes one ``InputError`` naming the file and the key. ``file_format``
says what a file is without reading its arrays.
"""

from __future__ import annotations

import json
import os
import unicodedata
import zipfile
import zlib
from typing import Any

import numpy as np

from radiosity.files.atomic import atomic_output
from radiosity.files.errors import InputError
from radiosity.files.inputs import NPZ_BYTES, check_input_file, loads_json
from radiosity.policies.limits import available_memory

__all__ = [
    "KNOWN_FORMATS",
    "Archive",
    "check_member_name",
    "file_format",
    "json_default",
    "one_line",
    "open_archive",
    "write_archive",
]

KNOWN_FORMATS = {"vlights.solution": "solution file", "vlights.fit": "fit file"}

# Errors numpy / zipfile raise on a file that is not a readable npz or a damaged member.
READ_ERRORS = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error)


def one_line(text: object) -> str:
    return " ".join(str(text).split())


def json_default(value: Any) -> Any:
    """Let numpy scalars and arrays and paths in meta serialise as plain JSON."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def check_member_name(key: str) -> str:
    """``key`` if it survives a round trip as the name of an npz member; ValueError
    otherwise. A zip member's name ends at a NUL (zipfile cuts it there on reading),
    must be UTF-8 (no lone surrogates) and should hold no other control character (a
    name that cannot be shown on one line, nor typed)."""
    if not isinstance(key, str) or not key:
        raise ValueError(f"array name must be a non-empty string, got {key!r}")
    bad = next((c for c in key if unicodedata.category(c) in ("Cc", "Cs")), None)
    if bad is not None:
        raise ValueError(f"array name {key!r} holds the control character U+{ord(bad):04X}, which an .npz member name cannot keep")
    if zipfile.ZipInfo(key + ".npy").filename != key + ".npy":
        raise ValueError(f"array name {key!r} does not survive as an .npz member name")
    return key


def write_archive(path: str | os.PathLike, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """Write ``meta`` (JSON, strict: no NaN or infinity) and ``arrays`` atomically.

    Raises TypeError or ValueError before anything is written if meta cannot be
    represented or an array's name would not read back the same (``check_member_name``),
    OSError if the file cannot be written; ``path`` keeps its previous content and no
    temporary file is left behind in every case.
    """
    for key in arrays:
        check_member_name(key)
    if "meta" in arrays:
        raise ValueError("'meta' is the archive's own entry, not an array name")
    text = json.dumps(meta, default=json_default, allow_nan=False)
    payload = {"meta": np.array(text)}
    payload.update(arrays)
    with atomic_output(path) as f:
        np.savez_compressed(f, **payload)


NPZ_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")  # a zip archive's first record (an empty one's end record)
NPY_MAGIC = b"\x93NUMPY"


def _sniff(path: str, what: str) -> tuple[str | None, str]:
    """(problem, '') if ``path`` cannot be an npz archive, else (None, ''). InputError
    (naming ``what``) if it is missing or not a regular file of a sane size."""
    check_input_file(path, what, NPZ_BYTES)
    try:
        with open(path, "rb") as f:
            magic = f.read(6)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})", ""
    if magic.startswith(NPY_MAGIC):
        return "is a single .npy array, not an .npz archive", ""
    if not magic.startswith(NPZ_MAGIC):
        return ("is an empty file" if not magic else "is not a zip archive") + "; expected an .npz archive", ""
    return None, ""


def _size(n: int) -> str:
    return f"{n / 2**30:.3g} GiB" if n >= 2**30 else f"{n / 2**20:.3g} MiB" if n >= 2**20 else f"{n} bytes"


def _member_header(npz, key: str, fail):
    """(shape, dtype, the header's length, the zip entry) of array ``key`` of ``npz``,
    from its .npy header alone; ``fail(problem)`` makes the error of an unreadable one."""
    name = key + ".npy"
    try:
        info = npz.zip.getinfo(name)
        with npz.zip.open(name) as f:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, _, dtype = np.lib.format.read_array_header_2_0(f)
            else:
                raise ValueError(f"unsupported .npy format version {version[0]}.{version[1]}")
            return shape, dtype, f.tell(), info
    except READ_ERRORS as exc:
        raise fail(f"cannot read '{key}': {type(exc).__name__}: {exc}") from None


def _member(npz, key: str, fail) -> np.ndarray:
    """The array ``key`` of ``npz``, its header checked before any memory is given to
    it: the bytes its shape and dtype claim must be stored in the member (a header
    claiming 10^12 rows in a small file is refused) and fit in the free memory."""
    shape, dtype, header, info = _member_header(npz, key, fail)
    if dtype.hasobject:
        raise fail(f"cannot read '{key}': it holds Python objects, and this program reads no pickles")
    count = 1
    for n in shape:
        count *= int(n)
    needed = count * dtype.itemsize
    stored = info.file_size - header
    if needed > stored:
        raise fail(f"'{key}' claims shape {tuple(shape)} of {dtype} ({_size(needed)}) but stores {_size(max(stored, 0))}")
    free = available_memory()
    if free is not None and needed > free:
        raise fail(f"'{key}' needs {_size(needed)} of memory, more than the {_size(free)} available")
    try:
        return npz[key]
    except READ_ERRORS as exc:
        raise fail(f"cannot read '{key}': {type(exc).__name__}: {exc}") from None


def _read_meta(npz, fail) -> dict:
    if "meta" not in npz.files:
        raise fail("no 'meta' entry")
    raw = _member(npz, "meta", fail)
    if raw.ndim != 0 or raw.dtype.kind != "U":
        raise fail(f"'meta' is a {raw.dtype} array of shape {tuple(raw.shape)}, not a string")
    try:
        meta = loads_json(str(raw), "'meta'")
    except json.JSONDecodeError as exc:
        raise fail(f"'meta' is not JSON: {exc}") from None
    except InputError as exc:
        raise fail(str(exc)) from None
    if not isinstance(meta, dict):
        raise fail(f"'meta' is a JSON {type(meta).__name__}, not an object")
    return meta


def file_format(path: str | os.PathLike) -> str | None:
    """The ``meta.format`` of an npz file of ours ("vlights.solution", "vlights.fit"),
    or None if it is not one. Raises InputError if the file is missing or unreadable."""
    path = os.fspath(path)
    problem, _ = _sniff(path, "file")
    if problem is not None:
        return None
    try:
        with np.load(path, allow_pickle=False) as npz:
            meta = _read_meta(npz, lambda why: ValueError(why))
    except (*READ_ERRORS, ValueError, InputError):
        return None
    fmt = meta.get("format")
    return fmt if isinstance(fmt, str) else None


class Archive:
    """An open archive of one of our formats; use as a context manager.

    ``meta`` is the parsed JSON; ``array(key, kinds, shape)`` reads one array;
    ``fail(problem)`` makes the InputError naming the file.
    """

    def __init__(self, path: str, npz, meta: dict, what: str):
        self.path, self.npz, self.meta, self.what = path, npz, meta, what
        self.keys: frozenset[str] = frozenset(npz.files)  # the archive's members, once (a scene may have thousands)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        self.npz.close()

    def header(self, key: str) -> tuple[tuple[int, ...], np.dtype]:
        """(shape, dtype) of array ``key`` from its header alone (nothing else is read)."""
        if key not in self.keys:
            raise self.fail(f"no '{key}' array")
        shape, dtype, _, _ = _member_header(self.npz, key, self.fail)
        return tuple(int(n) for n in shape), dtype

    def fail(self, problem: str) -> InputError:
        return InputError(one_line(f"{self.what} '{self.path}': {problem}"))

    def stored_as(self, key: str) -> tuple[int, int]:
        """(CRC-32, size) of array ``key`` as the zip stores it: members that differ in
        either differ in content (equal ones may still differ: compare to be sure)."""
        info = self.npz.zip.getinfo(f"{key}.npy")
        return info.CRC, info.file_size

    def shared(self, key: str, read):
        """``read(key)``, or the very array an earlier ``shared`` call returned for a
        member of the same content: a scene's objects that share a texture store it
        once each, and each copy read apart would be its own array in memory (a
        staircase's 4.9 GB of textures, of a few distinct images). A candidate of the
        same CRC-32 and size is compared whole before it is shared; the arrays handed
        out are read-only."""
        cache = self.__dict__.setdefault("_shared", {})
        stamp = self.stored_as(key)
        array = read(key)
        for earlier in cache.get(stamp, ()):
            if earlier.shape == array.shape and earlier.dtype == array.dtype and np.array_equal(earlier, array):
                return earlier
        array.flags.writeable = False
        cache.setdefault(stamp, []).append(array)
        return array

    def array(self, key: str, kinds: str | None = None, shape: tuple | None = None) -> np.ndarray:
        """The array ``key``; ``kinds`` its allowed dtype kinds ("f", "iu", ...),
        ``shape`` its shape with None for any length. InputError naming the key."""
        if key not in self.npz.files:
            raise self.fail(f"no '{key}' array")
        a = _member(self.npz, key, lambda why: InputError(one_line(f"'{self.path}' is not a {self.what} ({why})")))
        if kinds is not None and a.dtype.kind not in kinds:
            expected = "integers" if kinds == "iu" else "numbers"
            raise self.fail(f"'{key}' has dtype {a.dtype}, expected {expected}")
        if shape is not None and (a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape))):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            raise self.fail(f"'{key}' has shape {tuple(a.shape)}, expected {want}")
        return a


def open_archive(path: str | os.PathLike, fmt: str, versions: tuple[int, ...]) -> Archive:
    """Open ``path`` as a file of format ``fmt`` in one of ``versions``; InputError
    (one line naming the file and the problem) otherwise."""
    path = os.fspath(path)
    what = KNOWN_FORMATS.get(fmt, "file")
    problem, _ = _sniff(path, what)

    def not_ours(why):
        return InputError(one_line(f"'{path}' is not a {what} ({why})"))

    if problem is not None:
        raise not_ours(problem.removeprefix("is "))
    try:
        npz = np.load(path, allow_pickle=False)
    except READ_ERRORS as exc:
        raise not_ours(f"{type(exc).__name__}: {exc}") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise not_ours("not an .npz archive")
    try:
        meta = _read_meta(npz, not_ours)
        found = meta.get("format")
        if found != fmt:
            other = KNOWN_FORMATS.get(found) if isinstance(found, str) else None
            raise not_ours(f"format {found!r}, expected {fmt!r}" + (f": it is a {other}" if other else ""))
        version = meta.get("version")
        if not (isinstance(version, int) and not isinstance(version, bool) and version in versions):
            raise InputError(one_line(
                f"{what} '{path}': version {version!r} is not supported; this program reads "
                f"version{'s' if len(versions) > 1 else ''} {', '.join(map(str, versions))}"
            ))
    except BaseException:
        npz.close()
        raise
    return Archive(path, npz, meta, what)
