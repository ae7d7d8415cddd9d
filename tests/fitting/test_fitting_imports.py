"""The fitting stage imports nothing of the radiosity stage but its shared core (files,\nphysics, policies: the README's stage rule) and nothing of the display stage."""

from pathlib import Path

from source_imports import imported_modules, in_shared_core

import fitting


def test_fitting_imports_only_the_shared_core():
    sources = sorted(Path(fitting.__file__).parent.glob("*.py"))
    assert len(sources) > 5
    wrong = [
        f"{path.name}: {module}"
        for path in sources
        for module in imported_modules(path)
        if module.split(".")[0] in ("radiosity", "display")
        and not in_shared_core(module)
    ]
    assert wrong == []
