"""No module of a lower layer imports a higher one (docs: DESIGN.md "Layers"), for the arrows that
once ran the wrong way (issue 23, architecture review §1.2).

Every import in the source counts: module level, inside functions, under ``TYPE_CHECKING``, and
``importlib.import_module("...")`` with a literal name; relative imports are resolved first.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

FORBIDDEN = [
    ("ambulo.assets", "ambulo.core"),  # bundled files sit below the scene builder (Isaac paths: sim/isaac_assets.py)
    ("ambulo.assets", "ambulo.sim"),
    ("ambulo.assets", "ambulo.isaac"),
    ("ambulo.core", "ambulo.sim"),  # the core knows nothing of the Isaac-style API ...
    ("ambulo.core", "ambulo.isaac"),  # ... nor of Isaac scripts
    ("ambulo.sim", "ambulo.isaac"),  # the Isaac-style API sits below the Isaac script runner
]
"""(lower package, higher package it must not import)."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in the file at ``path``."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            found.append((node.lineno, module))
            found += [(node.lineno, f"{module}.{alias.name}") for alias in node.names]  # from pkg import sub
        elif (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            found.append((node.lineno, node.args[0].value))
    return found


def wrong_way_imports(lower: str, higher: str) -> list[str]:
    """``file:line imports module`` for each import of ``higher`` (or below it) by a module of ``lower``."""
    folder = SRC.joinpath(*lower.split("."))
    files = [folder.with_suffix(".py")] if folder.with_suffix(".py").is_file() else sorted(folder.rglob("*.py"))
    return [f"{path.relative_to(SRC)}:{line} imports {module}"
            for path in files for line, module in imported_modules(path)
            if module == higher or module.startswith(higher + ".")]


@pytest.mark.parametrize(("lower", "higher"), FORBIDDEN)
def test_no_wrong_way_import(lower, higher):
    found = wrong_way_imports(lower, higher)
    assert not found, f"{lower} must not import {higher}: " + "; ".join(found)


def test_the_check_sees_function_level_and_relative_imports(tmp_path, monkeypatch):
    package = tmp_path / "ambulo" / "sim"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("def f():\n    from ..isaac.semantics import x  # noqa\n")
    (package / "b.py").write_text("import importlib\nm = importlib.import_module('ambulo.isaac.names')\n")
    (package / "c.py").write_text("from .. import isaac\nfrom ..isaacish import y\n")
    monkeypatch.setitem(globals(), "SRC", tmp_path)
    assert wrong_way_imports("ambulo.sim", "ambulo.isaac") == [
        "ambulo/sim/a.py:2 imports ambulo.isaac.semantics", "ambulo/sim/a.py:2 imports ambulo.isaac.semantics.x",
        "ambulo/sim/b.py:2 imports ambulo.isaac.names", "ambulo/sim/c.py:1 imports ambulo.isaac"]
