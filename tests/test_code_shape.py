"""Shapes of the code a maintainer can rely on: no function takes more than
MAX_POSITIONAL positional parameters (records, tuples and keyword-only parameters
instead), in the packages, the tests and the benchmarks alike."""

import ast
import re
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


OUTSIDE = re.compile(r"Contract [0-9]|DESIGN\.md|shared/|\bissues? [0-9#]|\bthe issue's\b|another branch", re.IGNORECASE)
OWN_SUFFIXES = {".py", ".md", ".glsl", ".js", ".html", ".toml"}


def outside_references(root):
    """(file:line, the words) of every line of the project's own files (not the vendored
    three.js, not this test) that names what lies outside the repository: the founding
    design document and its contract numbers, an issue by number, another branch."""
    found = []
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        if path.suffix not in OWN_SUFFIXES or not path.is_file() or rel.parts[0].startswith(".") \
                or rel.parts[0] in ("build", "virtual_lights.egg-info") or "three" in rel.parts \
                or "__pycache__" in rel.parts or path.name == "test_code_shape.py":
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            match = OUTSIDE.search(line)
            if match:
                found.append(f"{rel}:{number}: {match.group(0)}")
    return found


def test_the_project_speaks_for_itself():
    """No code, message, test or document names a document outside the repository, a
    contract by its number there, an issue by number or another branch: the files
    name docs/formats.md's sections and the files themselves."""
    assert outside_references(ROOT) == []


def test_the_scan_finds_an_outside_reference(tmp_path):
    (tmp_path / "a.py").write_text('"""The solution (Contract 1)."""\nx = 1  # see issue 12\n')
    (tmp_path / "b.md").write_text("Fine words.\n")
    assert outside_references(tmp_path) == ["a.py:1: Contract 1", "a.py:2: issue 1"]
