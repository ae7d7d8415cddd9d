"""The display stage imports of the radiosity stage only its file formats (the demo,
which runs the whole pipeline, and the ground truth, which path-traces scenes with the
light transport's path tracer, also the scene and the light transport)."""

import ast
from pathlib import Path

import display


def imported_modules(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module


def allowed(path, module):
    if module.split(".")[0] != "radiosity":
        return True
    if module == "radiosity.formats" or module.startswith("radiosity.formats."):
        return True
    if path.name in ("demo.py", "truth.py") and module.split(".")[1] in ("scene", "transport"):
        return True
    return path.name == "cli.py" and module == "radiosity.cli"  # the dispatcher registers every stage's commands


def test_display_imports_only_radiosity_formats():
    sources = sorted(Path(display.__file__).parent.glob("*.py"))
    assert len(sources) > 5
    wrong = [f"{path.name}: {module}" for path in sources for module in imported_modules(path) if not allowed(path, module)]
    assert wrong == []
