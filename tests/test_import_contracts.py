"""The import contracts of pyproject.toml ``[tool.importlinter]`` (DESIGN.md "Layers"; CI runs them
through ``make lint`` too): the real tree keeps them, and a copy of it with a wrong-way import, an
import cycle and a package without a layer breaks each one, by name.

``make lint`` leaves out imports under ``TYPE_CHECKING`` (they never run, and sim/ has cycles made
of them only). A type-only import must still not point upward, so the layers are checked here a
second time with them counted.

Every check is ``lint-imports`` in a subprocess (about a second each): it finds ``ambulo`` through
PYTHONPATH, so a copy of the sources is checked instead of the installed tree.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PYPROJECT = REPO / "pyproject.toml"
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"
LAYERS = "ambulo layers (DESIGN.md): nothing imports upward"
ACYCLIC = "no import cycles between the modules or subpackages of any package"


def lint_imports(src: Path, config: Path = PYPROJECT, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(LINT_IMPORTS), "--config", str(config), "--no-cache", *args],
        cwd=src.parent, env={**os.environ, "PYTHONPATH": str(src)}, capture_output=True, text=True, timeout=120,
    )


def counting_type_checking_imports(tmp_path: Path) -> Path:
    """pyproject.toml's contracts with the imports under ``TYPE_CHECKING`` counted."""
    text = PYPROJECT.read_text()
    setting = "exclude_type_checking_imports = true"
    assert text.count(setting) == 1, f"pyproject.toml [tool.importlinter] no longer says {setting!r}"
    config = tmp_path / "pyproject.toml"
    config.write_text(text.replace(setting, "exclude_type_checking_imports = false"))
    return config


def copy_sources(dst: Path) -> Path:
    """``src/ambulo`` as Python files only (no bundled assets, no caches)."""

    def not_python(folder: str, names: list[str]) -> list[str]:
        return [n for n in names if n == "__pycache__" or not (n.endswith(".py") or (Path(folder) / n).is_dir())]

    shutil.copytree(REPO / "src" / "ambulo", dst / "ambulo", ignore=not_python)
    return dst


def test_the_tree_keeps_every_contract():
    result = lint_imports(REPO / "src")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Contracts: 2 kept, 0 broken." in result.stdout, result.stdout


def folders_without_init(package: Path) -> list[str]:
    """Folders under ``package`` that hold Python files but no ``__init__.py``."""
    folders = {p.parent for p in package.rglob("*.py") if "__pycache__" not in p.parts}
    return sorted(str(f.relative_to(package.parent)) for f in folders if not (f / "__init__.py").is_file())


def test_every_source_folder_is_a_package(tmp_path):
    """lint-imports (grimp) sees only packages: the modules of a folder without ``__init__.py``
    escape every contract, silently."""
    assert folders_without_init(REPO / "src" / "ambulo") == []
    (tmp_path / "ambulo" / "vo").mkdir(parents=True)
    (tmp_path / "ambulo" / "__init__.py").write_text("")
    (tmp_path / "ambulo" / "vo" / "odometry.py").write_text("")
    assert folders_without_init(tmp_path / "ambulo") == ["ambulo/vo"]


def test_no_type_only_import_points_upward(tmp_path):
    result = lint_imports(REPO / "src", counting_type_checking_imports(tmp_path), "--contract", "layers")
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"{LAYERS} KEPT" in result.stdout, result.stdout


def test_each_contract_names_what_breaks_it(tmp_path):
    src = copy_sources(tmp_path / "src")
    ambulo = src / "ambulo"
    # core (below sim) imports the Isaac-style sim API, inside a function: a lazy import still runs
    (ambulo / "core" / "wrong_way.py").write_text("def world():\n    from ambulo.sim import World\n")
    # sensors (below envs) names an env type for annotations only
    (ambulo / "sensors" / "type_only.py").write_text(
        "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from ambulo.envs import RLEnv\n")
    # two utils modules that import each other, one of them lazily
    (ambulo / "utils" / "ping.py").write_text("from . import pong\n")
    (ambulo / "utils" / "pong.py").write_text("def ping():\n    from . import ping\n")
    # a new top-level package that no layer names
    (ambulo / "unplaced").mkdir()
    (ambulo / "unplaced" / "__init__.py").write_text("")

    result = lint_imports(src)
    out = result.stdout + result.stderr
    assert result.returncode == 1, out
    assert "Contracts: 0 kept, 2 broken." in out, out
    # the layers contract names the arrow and its line, and the package that has no layer
    assert f"{LAYERS} BROKEN" in out, out
    assert "ambulo.core is not allowed to import ambulo.sim" in out, out
    assert "ambulo.core.wrong_way -> ambulo.sim (l.2)" in out, out
    assert "ambulo.unplaced" in out, out
    assert "ambulo.sensors is not allowed" not in out, out  # make lint counts what runs
    # the cycle contract names the package and an import that would break the cycle
    assert f"{ACYCLIC} BROKEN" in out, out
    assert "No cycles are allowed in ambulo.utils." in out, out
    assert ".ping -> .pong" in out or ".pong -> .ping" in out, out

    typed = lint_imports(src, counting_type_checking_imports(tmp_path), "--contract", "layers")
    assert typed.returncode == 1, typed.stdout + typed.stderr
    assert "ambulo.sensors.type_only -> ambulo.envs (l.4)" in typed.stdout, typed.stdout
