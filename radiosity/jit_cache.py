"""numba's on-disk cache keyed on every source file a kernel may inline.

numba's ``cache=True`` stamps a kernel's cache with the content of the one file the
kernel is defined in. A kernel's compiled code also holds every jitted function it
calls (inlined or linked), and those may live in other files: the solver's kernels
call ``radiosity.scene.material_kernels``, ``radiosity.transport.embree`` and
``radiosity.physics``; after an edit there, numba would keep running the old code.

``install()`` (run when this module is first imported: every module of the project that
decorates a kernel imports it first) puts ``ProjectCacheLocator`` first among numba's cache locators. For a kernel
defined under a covered package directory it stamps the cache with a digest of the
content of every ``.py`` file of that package and of the packages it may import
(the README's stage rule: radiosity imports neither fitting nor display; fitting imports
radiosity; display imports both):

    kernels in radiosity/   stamped with radiosity/**.py
    kernels in fitting/     stamped with radiosity/**.py and fitting/**.py
    kernels in display/     stamped with all three

So an edit to any file a kernel could inline recompiles it on its next use, and an edit
to display/ recompiles no solver kernel. Where the cache files go is left to numba's own
locators (tried in numba's order): ``NUMBA_CACHE_DIR`` when set, else ``__pycache__``
beside the source, else the user's cache directory (an installed, read-only package).
Functions outside the covered directories keep numba's default behaviour, and a
``NUMBA_CACHE_LOCATOR_CLASSES`` setting replaces this (as it replaces numba's own list).

Each package's digest is computed once per process, the first time a kernel of a group
that covers it is decorated (SHA-256 of its files: a few ms each). ``cover(root, inlines_from=...)``
registers another package (the tests use it on a package of their own).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from numba.core import caching

__all__ = ["ProjectCacheLocator", "cover", "install", "source_digest"]

_CacheLocator = getattr(caching, "_CacheLocator", None) or caching.CacheLocator  # numba renames
_CacheImpl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # numba >= 0.60 / < 0.60

_groups: dict[Path, tuple[Path, ...]] = {}  # covered package dir -> the dirs its kernels' stamp covers
_digests: dict[Path, str] = {}  # package dir -> digest of its sources (computed once per process)
_owners: dict[str, Path | None] = {}  # a kernel's source file -> its covered package dir (or None)


def source_digest(top):
    """SHA-256 (hex) of the relative path and content of every ``.py`` file under directory
    ``top`` (``__pycache__`` left out), in a fixed order: changes with any edit, addition,
    removal or rename of a source file there, and with nothing else."""
    files = []
    for folder, subdirs, names in os.walk(top):
        subdirs[:] = [d for d in subdirs if d != "__pycache__"]
        files.extend(Path(folder, n) for n in names if n.endswith(".py"))
    digest = hashlib.sha256()
    for path in sorted(files, key=lambda p: p.relative_to(top).as_posix()):
        digest.update(path.relative_to(top).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def cover(root, *, inlines_from=()):
    """Stamp the cache of every kernel defined under package directory ``root`` with the
    sources of ``root`` and of the package directories ``inlines_from``: every file
    its kernels may inline. Register before the package's kernels are imported."""
    root = Path(root).resolve()
    _groups[root] = (root, *sorted({Path(d).resolve() for d in inlines_from} - {root}))
    _owners.clear()


def _owner(py_file):
    """The covered package directory ``py_file`` lies under (the innermost), or None."""
    if py_file not in _owners:
        path = Path(py_file).resolve()
        roots = [root for root in _groups if path.is_relative_to(root)]
        _owners[py_file] = max(roots, key=lambda r: len(r.parts)) if roots else None
    return _owners[py_file]


def _group_digest(root):
    """The digests of the sources of ``root``'s group, each directory's computed once per process."""
    for top in _groups[root]:
        if top not in _digests:
            _digests[top] = source_digest(top)
    return tuple((top.name, _digests[top]) for top in _groups[root])


class ProjectCacheLocator(_CacheLocator):
    """numba's locator for a kernel's source file (the first of numba's own that accepts
    it, which decides where the cache goes), with the source stamp widened to the
    kernel's whole group of packages (``cover``)."""

    def __init__(self, inner, root):
        self._inner = inner
        self._root = root
        self._py_file = inner._py_file  # numba names it in its "cannot cache" warnings

    @classmethod
    def from_function(cls, py_func, py_file):
        root = _owner(py_file)
        if root is None:
            return None
        for other in _CacheImpl._locator_classes:
            if other is cls:
                continue
            inner = other.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, root)
        return None

    def ensure_cache_path(self):
        self._inner.ensure_cache_path()

    def get_cache_path(self):
        return self._inner.get_cache_path()

    def get_disambiguator(self):
        return self._inner.get_disambiguator()

    def get_source_stamp(self):
        return ("vlights-sources", self._inner.get_source_stamp(), _group_digest(self._root))


def install():
    """Put ``ProjectCacheLocator`` first among numba's cache locators (idempotent)."""
    if ProjectCacheLocator not in _CacheImpl._locator_classes:
        _CacheImpl._locator_classes.insert(0, ProjectCacheLocator)


def _cover_project():
    here = Path(__file__).resolve().parent  # radiosity/
    radiosity, fitting, display = here, here.parent / "fitting", here.parent / "display"
    cover(radiosity)
    cover(fitting, inlines_from=(radiosity,))
    cover(display, inlines_from=(radiosity, fitting))


_cover_project()
install()
