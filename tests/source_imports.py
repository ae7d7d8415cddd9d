"""What a source file imports: the import-boundary tests of each stage read it."""

import ast


def imported_modules(path):
    """The absolute module names ``path`` (a ``pathlib.Path``) imports, anywhere in it."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module
