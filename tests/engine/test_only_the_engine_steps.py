"""Physics advances in one place: only ``ambulo.engine`` calls MuJoCo's step functions (issue 23).

Every app steps through ``core.Simulation`` / an ``Engine``, so they share its batch, its GPU path
and its divergence handling; a raw ``mj_step`` on a private ``MjData`` would be a second stepping
path with its own settings. The check reads the source's syntax tree: a call of ``mj_step``,
``mj_step1`` or ``mj_step2`` (as ``mujoco.mj_step(...)``, ``mj_step(...)`` after a ``from``
import, or through an alias) anywhere under ``src/ambulo`` outside ``engine/``; names in
docstrings and comments do not count.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "ambulo"
STEP_FUNCTIONS = {"mj_step", "mj_step1", "mj_step2"}


def step_calls(source: str, name: str = "<source>") -> list[int]:
    """Lines of ``source`` that call (or import, to call under another name) a MuJoCo step function."""
    lines = []
    for node in ast.walk(ast.parse(source, name)):
        if isinstance(node, ast.Call):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if called in STEP_FUNCTIONS:
                lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and any(alias.name in STEP_FUNCTIONS for alias in node.names):
            lines.append(node.lineno)
        elif isinstance(node, ast.Attribute) and node.attr in STEP_FUNCTIONS and not isinstance(node.ctx, ast.Store):
            lines.append(node.lineno)  # step = mujoco.mj_step; step(m, d)
    return sorted(set(lines))


def test_no_mj_step_outside_the_engine():
    engine = SRC / "engine"
    found = [f"{path.relative_to(SRC.parent)}:{line}"
             for path in sorted(SRC.rglob("*.py")) if engine not in path.parents
             for line in step_calls(path.read_text(), str(path))]
    assert not found, "MuJoCo is stepped outside ambulo.engine (step through core.Simulation): " + ", ".join(found)


def test_the_check_finds_every_spelling_and_ignores_prose():
    assert step_calls("import mujoco\nmujoco.mj_step(m, d)\n") == [2]
    assert step_calls("from mujoco import mj_step2 as s\ns(m, d)\n") == [1]
    assert step_calls("import mujoco as mj\nstep = mj.mj_step1\nstep(m, d)\n") == [2]
    assert step_calls('"""as after ``mj_step``"""\n# mj_step(m, d)\nx = 1\n') == []
