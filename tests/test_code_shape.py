"""Shapes of the code a maintainer can rely on: no function takes more than
MAX_POSITIONAL positional parameters (records, tuples and keyword-only parameters
instead), in the packages, the tests and the benchmarks alike."""

import ast
from pathlib import Path

MAX_POSITIONAL = 8
ROOT = Path(__file__).resolve().parent.parent
TREES = ("radiosity", "fitting", "display", "tests", "benchmarks")


def positional_counts(root, trees):
    """(file:line name, its positional parameters but self/cls) of every function,
    method and lambda under the ``trees`` folders of ``root``."""
    for tree in trees:
        for path in sorted((root / tree).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                    names = [a.arg for a in node.args.posonlyargs + node.args.args]
                    count = len(names) - (1 if names and names[0] in ("self", "cls") else 0)
                    yield f"{path.relative_to(root)}:{node.lineno} {getattr(node, 'name', 'lambda')}", count


def test_no_function_takes_more_than_eight_positional_arguments():
    counts = list(positional_counts(ROOT, TREES))
    assert len(counts) > 1000  # the scan sees the whole tree
    assert [f"{where} ({n})" for where, n in counts if n > MAX_POSITIONAL] == []


def test_the_scan_counts_positional_parameters_only(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "m.py").write_text(
        "def f(a, b, c, d, e, f, g, h, i): pass\n"
        "def g(a, b, *, c, d, e, f, g, h, i, j): pass\n"
        "class C:\n    def m(self, a, b, c, d, e, f, g, h): pass\n"
        "k = lambda a, /, b, c, d, e, f, g, h, i: 0\n"
    )
    assert dict(positional_counts(tmp_path, ["pkg"])) == {
        "pkg/m.py:1 f": 9, "pkg/m.py:2 g": 2, "pkg/m.py:4 m": 8, "pkg/m.py:5 lambda": 9,
    }
