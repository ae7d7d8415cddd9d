"""The fitting stage imports nothing of the radiosity stage but its file formats."""

from pathlib import Path

from source_imports import imported_modules

import fitting


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
