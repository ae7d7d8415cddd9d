"""What a source file imports: the import-boundary tests of each stage read it, and
``tests/test_imports.py`` builds the whole import graph from it."""

import ast
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parent.parent
PACKAGES = ("radiosity", "fitting", "display")

# The stage rule (the README's "Code map" line, docs/layout.md): of the radiosity stage,
# the other stages import its shared core alone, and the core imports nothing else of it.
SHARED_CORE = ("radiosity.files", "radiosity.physics", "radiosity.policies", "radiosity.jit_cache")


def in_shared_core(module):
    """Whether module ``module`` (a dotted name) lies in the radiosity stage's shared core."""
    return any(module == core or module.startswith(core + ".") for core in SHARED_CORE)


def imported_modules(path):
    """The absolute module names ``path`` (a ``pathlib.Path``) imports, anywhere in it."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            for alias in node.names:  # "from radiosity.physics import ltc" imports radiosity.physics.ltc
                folder = REPOSITORY.joinpath(*node.module.split("."), alias.name)
                own = node.module.split(".")[0] in PACKAGES
                yield f"{node.module}.{alias.name}" if own and (folder.is_dir() or folder.with_suffix(".py").is_file()) else node.module


def module_name(path, root=REPOSITORY):
    """"display/commands/truth.py" -> "display.commands.truth"; a package's __init__.py
    is the package."""
    parts = list(Path(path).resolve().relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_files(root=REPOSITORY, packages=PACKAGES):
    """{module name: path} of every .py file of ``packages`` under ``root``."""
    return {module_name(path, root): path for package in packages for path in sorted((root / package).rglob("*.py"))}


def _imports_with_names(path, name):
    """(module, names imported from it) for every import in the file of module ``name``,
    top level and inside functions alike; relative imports made absolute."""
    is_package = Path(path).name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield target, tuple(alias.name for alias in node.names)


def import_graph(root=REPOSITORY, packages=PACKAGES):
    """{module: set of modules of ``packages`` it imports}, from every import statement
    of every file (top level and function level). ``from P import name`` is an edge to
    the module P.name where that is a module, else to P; an import of a module that is
    not a file is an edge to its nearest enclosing module. The implicit import of a
    module's parent packages is not an edge (every submodule would loop through its
    package's __init__)."""
    files = source_files(root, packages)

    def known(name):
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in files.items():
        edges = set()
        for target, names in _imports_with_names(path, name):
            if target.split(".")[0] not in packages:
                continue
            submodules = [f"{target}.{n}" for n in names if f"{target}.{n}" in files]
            plain = [n for n in names if f"{target}.{n}" not in files]
            edges.update(submodules)
            if plain or not names:
                edges.add(known(target))
        edges.discard(None)
        edges.discard(name)
        graph[name] = edges
    return graph


def cycles(graph):
    """The strongly connected components of ``graph`` with more than one module (each a
    sorted list), by Tarjan's algorithm: every import circle lies in one of them."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)
