"""No runtime import cycle between the modules of ``ambulo.replicator`` (issue 23).

``generate`` once imported ``processes`` at module level while ``processes`` imported ``generate``
inside its worker functions: a cycle that only ran in a spawned worker. So every import that can run
counts here, at module level or inside a function; only ``if TYPE_CHECKING:`` blocks, which never
run, are left out. The package's ``__init__`` is not a node: importing a submodule runs it first
anyway, and it imports every submodule by design.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "ambulo.replicator"
FOLDER = Path(__file__).resolve().parents[2] / "src" / "ambulo" / "replicator"


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` except those under ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            test = getattr(child, "test", None)
            if isinstance(child, ast.If) and getattr(test, "id", getattr(test, "attr", None)) == "TYPE_CHECKING":
                stack.extend(child.orelse)
                continue
            stack.append(child)


def import_graph(folder: Path, package: str) -> dict[str, set[str]]:
    """{module: modules of the same package it imports}, for the ``*.py`` files directly in ``folder``."""
    modules = {path.stem for path in folder.glob("*.py")} - {"__init__"}
    graph: dict[str, set[str]] = {}
    for name in sorted(modules):
        path = folder / f"{name}.py"
        found: set[str] = set()
        for node in _runtime_nodes(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level > 1:
                    continue  # above the package
                base = (f"{package}.{node.module}" if node.module else package) if node.level else (node.module or "")
                targets = [base] + [f"{base}.{alias.name}" for alias in node.names]  # from . import sub
            else:
                continue
            for target in targets:
                head, _, rest = target.partition(package + ".")
                if not head and rest.split(".")[0] in modules:
                    found.add(rest.split(".")[0])
        graph[name] = found - {name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as [a, b, ..., a], or None (depth-first search, three colours)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_replicator_modules_import_each_other_without_a_cycle():
    graph = import_graph(FOLDER, PACKAGE)
    assert {"generate", "producer", "processes", "ray_workers"} <= graph.keys()
    assert "producer" in graph["processes"] and "producer" in graph["ray_workers"]
    cycle = find_cycle(graph)
    assert cycle is None, "runtime import cycle in ambulo.replicator: " + " -> ".join(cycle)


def test_the_check_sees_function_level_absolute_and_from_package_imports(tmp_path):
    (tmp_path / "__init__.py").write_text("from .a import x\nfrom .b import y\n")
    (tmp_path / "a.py").write_text("from .b import y\n")
    (tmp_path / "b.py").write_text("def f():\n    from .a import x\n")  # the old generate <-> processes shape
    assert find_cycle(import_graph(tmp_path, "pkg")) == ["a", "b", "a"]
    (tmp_path / "b.py").write_text("def f():\n    import pkg.c\n")
    (tmp_path / "c.py").write_text("from pkg import a\n")
    assert find_cycle(import_graph(tmp_path, "pkg")) == ["a", "b", "c", "a"]
    (tmp_path / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import a\n")
    assert find_cycle(import_graph(tmp_path, "pkg")) is None
