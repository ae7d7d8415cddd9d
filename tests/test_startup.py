"""Each command imports what it needs: parsing the command line loads neither numba,
trimesh nor scipy (``vlights serve --help`` starts in a fraction of the solver's
import), and every module that decorates a numba kernel imports ``radiosity.jit_cache``
first, so numba's cache is keyed on every source a kernel inlines without the package's
own import loading numba."""

import ast
import subprocess
import sys

import pytest
from source_imports import PACKAGES, REPOSITORY, source_files

HEAVY = ("numba", "trimesh", "scipy")

_PROBE = """
import sys
from display.cli import build_parser
parser = build_parser()
try:
    parser.parse_args(sys.argv[1:])
except SystemExit:
    pass
print("loaded:", *(name for name in {heavy} if name in sys.modules))
"""


@pytest.mark.subprocess
@pytest.mark.parametrize("argv", [["serve", "--help"], ["--help"], ["render", "--help"], ["solve", "--help"],
                                  ["fit", "--help"], ["export", "--help"]])
def test_parsing_the_command_line_loads_no_heavy_module(argv):
    out = subprocess.run([sys.executable, "-c", _PROBE.format(heavy=HEAVY), *argv], capture_output=True, text=True,
                         cwd=REPOSITORY, check=True).stdout
    assert out.splitlines()[-1] == "loaded:", f"{' '.join(argv)}: {out.splitlines()[-1]}"


@pytest.mark.subprocess
def test_the_probe_sees_a_heavy_import():
    """The check above can fail: the solver's scene stack loads all three."""
    code = _PROBE.format(heavy=HEAVY).replace("from display.cli import build_parser",
                                              "import radiosity.scene.loaders\nfrom display.cli import build_parser")
    out = subprocess.run([sys.executable, "-c", code, "serve", "--help"], capture_output=True, text=True,
                         cwd=REPOSITORY, check=True).stdout
    assert out.splitlines()[-1].split() == ["loaded:", "numba", "trimesh", "scipy"]


def _decorates_kernels(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "numba" \
                and node.attr in ("njit", "jit", "cfunc", "vectorize"):
            return True
    return False


def _imports_jit_cache(tree):
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module == "radiosity" and any(a.name == "jit_cache" for a in node.names):
            return True
        if isinstance(node, ast.Import) and any(a.name == "radiosity.jit_cache" for a in node.names):
            return True
    return False


def test_every_kernel_module_imports_the_cache_locator():
    files = source_files(REPOSITORY, PACKAGES)
    kernels = {name: path for name, path in files.items() if _decorates_kernels(ast.parse(path.read_text()))}
    assert {"radiosity.transport.gather", "radiosity.physics.ltc", "fitting.lobes"} <= set(kernels)
    missing = [name for name, path in kernels.items()
               if name != "radiosity.jit_cache" and not _imports_jit_cache(ast.parse(path.read_text()))]
    assert missing == []


def test_the_check_sees_a_kernel_module_without_it():
    tree = ast.parse("import numba\n\n@numba.njit(cache=True)\ndef f(x):\n    return x\n")
    assert _decorates_kernels(tree) and not _imports_jit_cache(tree)
    assert _imports_jit_cache(ast.parse("from radiosity import jit_cache\n"))
