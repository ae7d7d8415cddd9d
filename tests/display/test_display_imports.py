"""The display stage imports of the radiosity stage only its file formats (the demo,
which runs the whole pipeline, and the ground truth, which path-traces scenes with the
light transport's path tracer, also the scene and the light transport)."""

from pathlib import Path

from source_imports import imported_modules

import display


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
