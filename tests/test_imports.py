"""The import graph of the three stages (every module of radiosity/, fitting/ and
display/, imports at the top and inside functions alike): no circle, and data flowing
one way, radiosity -> fitting -> display.

The finer rules of each stage stay in its own test: what fitting may take of radiosity
(tests/fitting/test_fitting_imports.py) and what display may (tests/display/
test_display_imports.py: the shared core, and the scene and the transport through
display/pipeline.py alone); the shared core's own rule and the README's statement of
the rule are checked here."""

from source_imports import PACKAGES, REPOSITORY, SHARED_CORE, cycles, import_graph, in_shared_core, module_name

# which stages each stage may import: data flows one way
MAY_IMPORT = {"radiosity": {"radiosity"}, "fitting": {"radiosity", "fitting"}, "display": set(PACKAGES)}


def test_the_graph_sees_every_module():
    graph = import_graph()
    for package in PACKAGES:
        assert package in graph
    assert {"display.cli", "display.commands.truth", "display.pipeline", "radiosity.transport.solve",
            "fitting.fit"} <= set(graph)
    assert "display.pipeline" in graph["display.truth"]  # a function-level import is an edge
    assert "display.commands.truth" in graph["display.commands"]  # so is a relative one


def test_no_import_circle():
    assert cycles(import_graph()) == []


def test_a_circle_is_found(tmp_path):
    """The check sees a circle made of a function-level and a relative import."""
    package = tmp_path / "display"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .b import thing\n")
    (package / "b.py").write_text("def f():\n    from display import a\n")
    (package / "c.py").write_text("import display.a\n")
    graph = import_graph(tmp_path, packages=("display",))
    assert cycles(graph) == [["display.a", "display.b"]]
    assert module_name(package / "__init__.py", tmp_path) == "display"


def test_each_stage_imports_only_the_stages_before_it():
    graph = import_graph()
    wrong = [f"{module} -> {target}" for module, targets in graph.items() for target in sorted(targets)
             if target.split(".")[0] not in MAY_IMPORT[module.split(".")[0]]]
    assert wrong == []



def test_the_shared_core_imports_nothing_else_of_its_stage():
    """files, physics and policies import neither the scene loaders, the transport nor a
    command: what another stage may import stands on its own."""
    graph = import_graph()
    core = [name for name in graph if in_shared_core(name)]
    assert {"radiosity.files.solution", "radiosity.physics.ltc", "radiosity.policies.presets"} <= set(core)
    wrong = [f"{name} -> {target}" for name in core for target in graph[name]
             if target.startswith("radiosity.") and not in_shared_core(target)]
    assert wrong == []


def test_the_readme_states_the_stage_rule():
    text = " ".join((REPOSITORY / "README.md").read_text().split())
    assert all(f"`{core}`" in text for core in SHARED_CORE if core != "radiosity.jit_cache")
    assert "`display/pipeline.py`" in text and "stage rule" in text
