"""numba's on-disk cache keyed on every file a kernel may inline (radiosity/jit_cache.py).

The first test shows the problem and the fix on a package of its own: a cached kernel
calling a helper of another file keeps the helper's old code under numba's default
stamp, and gets the new code under ``ProjectCacheLocator``.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
import pytest
from numba.core import caching
from source_imports import imported_modules

import fitting
import radiosity
from radiosity import jit_cache

HELPER = textwrap.dedent(
    """\
    import numba


    @numba.njit(inline="always")
    def value():
        return {value}
    """
)

KERNEL = textwrap.dedent(
    """\
    import numba

    from inlinedemo.helper import value


    @numba.njit(cache=True)
    def kernel():
        return value()
    """
)

# prints the kernel's result and how many times its machine code came from the cache
RUN = textwrap.dedent(
    """\
    import sys
    if sys.argv[1] == "project":
        from radiosity import jit_cache
        jit_cache.cover(sys.argv[2])
    from inlinedemo.kernel import kernel
    print(kernel(), sum(kernel.stats.cache_hits.values()))
    """
)


def _make_package(where):
    package = where / "inlinedemo"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "helper.py").write_text(HELPER.format(value="1.0"))
    (package / "kernel.py").write_text(KERNEL)
    return package


def _run(mode, package, cache_dir):
    """Run the kernel in a fresh process: (its result, its cache hits)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), PYTHONDONTWRITEBYTECODE="1")
    env["PYTHONPATH"] = os.pathsep.join([str(package.parent), str(Path(radiosity.__file__).parents[1])])
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    done = subprocess.run(
        [sys.executable, "-c", RUN, mode, str(package)], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    value, hits = done.stdout.split()
    return float(value), int(hits)


@pytest.mark.subprocess
@pytest.mark.parametrize(("mode", "after_edit"), [("default", (1.0, 1)), ("project", (2.0, 0))])
def test_an_edit_to_an_inlined_helper_reaches_the_cached_caller(tmp_path, mode, after_edit):
    """default: numba's own stamp (kernel.py only) keeps the stale 1.0 (the problem);
    project: the package's stamp covers helper.py, so the kernel is recompiled (the fix)."""
    package = _make_package(tmp_path / "src")
    cache_dir = tmp_path / "cache"
    assert _run(mode, package, cache_dir) == (1.0, 0)  # compiled, written to the cache
    assert _run(mode, package, cache_dir) == (1.0, 1)  # read from the cache: caching still works
    assert any(cache_dir.rglob("kernel.kernel-*.nbi"))  # in NUMBA_CACHE_DIR
    (package / "helper.py").write_text(HELPER.format(value="2.0"))
    assert _run(mode, package, cache_dir) == after_edit
    if mode == "project":
        assert _run(mode, package, cache_dir) == (2.0, 1)  # and cached again


# a first import of a process: the command, a kernel module of fitting, one of radiosity
ENTRIES = ["display.cli", "fitting.lobes", "radiosity.physics.emitters"]

CHECK_ALL = textwrap.dedent(
    """\
    import importlib, pkgutil, sys
    importlib.import_module(sys.argv[1])
    import display, fitting, radiosity
    from radiosity.jit_cache import ProjectCacheLocator
    for package in (radiosity, fitting, display):
        for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            importlib.import_module(module.name)
    cached = wrong = 0
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] not in ("radiosity", "fitting", "display"):
            continue
        for attr, value in vars(module).items():
            cache = getattr(value, "_cache", None)
            if cache is None or not hasattr(cache, "_impl"):
                continue
            cached += 1
            if not isinstance(cache._impl.locator, ProjectCacheLocator):
                wrong += 1
                print(f"{name}.{attr}")
    print(cached, wrong)
    """
)


@pytest.mark.subprocess
@pytest.mark.parametrize("entry", ENTRIES)
def test_every_cached_kernel_of_the_project_is_keyed_on_its_packages(entry):
    """Whatever module a process imports first, every ``cache=True`` kernel of the three
    packages gets the project's stamp (the packages' ``__init__`` install it in time)."""
    env = dict(os.environ)
    env.pop("NUMBA_CACHE_LOCATOR_CLASSES", None)
    done = subprocess.run(
        [sys.executable, "-c", CHECK_ALL, entry], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    *wrong_kernels, counts = done.stdout.split("\n")[:-1]
    cached, wrong = map(int, counts.split())
    assert cached > 50
    assert (wrong, wrong_kernels) == (0, [])


def test_the_stamps_follow_the_packages_a_kernel_may_import():
    """radiosity's kernels are keyed on radiosity, fitting's on radiosity and fitting,
    display's on all three; this holds while radiosity imports neither fitting nor
    display, and fitting not display (checked here: the stamps rely on it)."""
    root = Path(radiosity.__file__).parent
    names = {package: [name for name, _ in jit_cache._group_digest(package)] for package in jit_cache._groups}
    assert names[root] == ["radiosity"]
    assert sorted(names[root.parent / "fitting"]) == ["fitting", "radiosity"]
    assert sorted(names[root.parent / "display"]) == ["display", "fitting", "radiosity"]
    for package, banned in ((radiosity, ("fitting", "display")), (fitting, ("display",))):
        sources = sorted(Path(package.__file__).parent.rglob("*.py"))
        assert len(sources) > 10
        wrong = [f"{p.name}: {m}" for p in sources for m in imported_modules(p) if m.split(".")[0] in banned]
        assert wrong == []


def test_source_digest_changes_with_any_source_file_and_nothing_else(tmp_path):
    top = tmp_path / "pkg"
    (top / "sub" / "__pycache__").mkdir(parents=True)
    (top / "a.py").write_text("x = 1\n")
    (top / "sub" / "b.py").write_text("y = 2\n")
    first = jit_cache.source_digest(top)
    (top / "notes.txt").write_text("not python")
    (top / "sub" / "__pycache__" / "b.cpython-311.pyc").write_bytes(b"\0")
    assert jit_cache.source_digest(top) == first
    (top / "sub" / "b.py").write_text("y = 3\n")
    second = jit_cache.source_digest(top)
    assert second != first
    (top / "sub" / "b.py").rename(top / "sub" / "c.py")
    assert jit_cache.source_digest(top) not in (first, second)


@pytest.fixture
def own_registry(monkeypatch):
    """jit_cache's registry as it is, restored after the test."""
    monkeypatch.setattr(jit_cache, "_groups", dict(jit_cache._groups))
    monkeypatch.setattr(jit_cache, "_owners", {})
    monkeypatch.setattr(jit_cache, "_digests", {})


def _function_in(path):
    path.write_text("def f():\n    return 1\n")
    namespace = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    return namespace["f"]


def test_cache_files_go_where_numba_would_put_them(tmp_path, monkeypatch, own_registry):
    """NUMBA_CACHE_DIR first, else __pycache__ beside the source, else the user's cache
    directory (a read-only installed package); files outside covered packages keep
    numba's default locator."""
    package = tmp_path / "pkg"
    package.mkdir()
    source = package / "mod.py"
    f = _function_in(source)
    jit_cache.cover(package)

    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(tmp_path / "numba-cache-dir"))
    locator = jit_cache.ProjectCacheLocator.from_function(f, str(source))
    assert Path(locator.get_cache_path()).parent == tmp_path / "numba-cache-dir"

    monkeypatch.setattr(numba.core.config, "CACHE_DIR", "")
    locator = jit_cache.ProjectCacheLocator.from_function(f, str(source))
    assert Path(locator.get_cache_path()) == package / "__pycache__"

    monkeypatch.setattr(caching.InTreeCacheLocator, "from_function", classmethod(lambda cls, *args: None))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "user-cache"))
    locator = jit_cache.ProjectCacheLocator.from_function(f, str(source))
    assert Path(locator.get_cache_path()).is_relative_to(tmp_path / "user-cache")
    stamp = locator.get_source_stamp()
    (package / "other.py").write_text("z = 1\n")
    jit_cache._digests.clear()  # a new process
    assert locator.get_source_stamp() != stamp

    outside = tmp_path / "elsewhere.py"
    assert jit_cache.ProjectCacheLocator.from_function(_function_in(outside), str(outside)) is None
    assert jit_cache._CacheImpl._locator_classes[0] is jit_cache.ProjectCacheLocator
