"""The display stage reads the earlier stages' files through the radiosity stage's
shared core (``radiosity.files``, ``.physics``, ``.policies``: the README's stage rule; and
fitting's API) and imports nothing else of the radiosity stage; the pipeline commands
(demo, truth), which run the earlier stages themselves, reach ``radiosity.scene`` and
``radiosity.transport`` through ``display/pipeline.py`` alone (its docstring states the
rule); the dispatcher (``display/cli.py``) imports each stage's ``cli`` to register its
commands."""

from pathlib import Path

from source_imports import imported_modules, in_shared_core

import display

ROOT = Path(display.__file__).parent
PIPELINE = ROOT / "pipeline.py"
DISPATCHER = ROOT / "cli.py"


def allowed(path, module):
    top, _, rest = module.partition(".")
    if top == "radiosity":
        part = rest.split(".")[0]
        if in_shared_core(module):
            return True
        if part in ("scene", "transport"):
            return path == PIPELINE
        return path == DISPATCHER and module == "radiosity.cli"
    if module == "fitting.cli":  # a stage's commands: the dispatcher's alone
        return path == DISPATCHER
    return True


def test_display_imports_only_the_shared_core():
    sources = sorted(ROOT.rglob("*.py"))
    assert len(sources) > 5 and ROOT / "commands" / "truth.py" in sources
    wrong = [f"{path.relative_to(ROOT)}: {module}" for path in sources for module in imported_modules(path)
             if not allowed(path, module)]
    assert wrong == []


def test_the_rule_is_stated_where_it_is_kept():
    text = PIPELINE.read_text()
    assert "radiosity.scene" in text and "radiosity.transport" in text and "this module alone" in text


def test_the_check_sees_a_breach(tmp_path):
    """The rule refuses what it should: a command reaching the transport directly."""
    command = ROOT / "commands" / "truth.py"
    assert not allowed(command, "radiosity.transport.pathtrace")
    assert not allowed(command, "radiosity.scene.loaders")
    assert not allowed(ROOT / "demo.py", "radiosity.transport.adaptive")
    assert allowed(PIPELINE, "radiosity.transport.pathtrace") and allowed(command, "radiosity.policies.limits")
    (tmp_path / "late.py").write_text("def f():\n    from radiosity.transport import pathtrace\n")
    assert list(imported_modules(tmp_path / "late.py")) == ["radiosity.transport.pathtrace"]  # function-level imports count
