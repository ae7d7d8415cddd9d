"""The fitting stage imports nothing of the radiosity stage but its file formats."""

import ast
from pathlib import Path

import fitting


def imported_modules(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module


def test_fitting_imports_only_radiosity_formats():
    sources = sorted(Path(fitting.__file__).parent.glob("*.py"))
    assert len(sources) > 5
    wrong = [
        f"{path.name}: {module}"
        for path in sources
        for module in imported_modules(path)
        if module.split(".")[0] in ("radiosity", "display")
        and not (module == "radiosity.formats" or module.startswith("radiosity.formats."))
    ]
    assert wrong == []
