"""Under ``ambulo run`` a bare parent import is enough, as in Kit: every Isaac module of the table
is an attribute of its parent once only the top-level package is imported."""

import importlib
import sys
from pathlib import Path

import pytest

from ambulo.isaac import isaac_names, run_script
from ambulo.isaac import names as table

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"


def _forget_isaac_modules() -> None:
    for name in [m for m in sys.modules if m.split(".")[0] in table.ROOTS]:
        del sys.modules[name]


def test_every_table_module_and_name_is_reachable_by_attribute_from_its_top_package():
    with isaac_names():
        for module, provided in sorted(table.MODULES.items()):
            _forget_isaac_modules()  # each walk starts from `import <top>` alone
            top, *path = module.split(".")
            found = importlib.import_module(top)
            for depth, part in enumerate(path, 1):
                assert hasattr(found, part), f"{'.'.join([top, *path[:depth]])} after only `import {top}`"
                found = getattr(found, part)
            assert found.__name__ == module
            for name in provided:
                assert getattr(found, name) is not None, f"{module}.{name}"


def test_dir_lists_submodules_and_from_imports_still_work():
    with isaac_names():
        import omni

        assert {"usd", "kit", "isaac", "physx"} <= set(dir(omni))
        assert "core" in dir(omni.isaac) and "utils" in dir(omni.isaac.core)
        from omni.isaac.core import World  # a name of the package itself
        from omni.isaac.core.utils import stage  # a submodule, by `from ... import`

        import ambulo.sim

        assert World is ambulo.sim.World
        assert stage.add_reference_to_stage is omni.isaac.core.utils.stage.add_reference_to_stage


def test_a_name_that_is_not_a_module_still_fails_with_the_alternative():
    with isaac_names():
        import omni

        with pytest.raises(ImportError, match="ambulo does not provide 'dynamic_control' from the Isaac module omni.isaac"):
            omni.isaac.dynamic_control  # noqa: B018


def test_bare_imports_tutorial_script_runs_under_ambulo_run(capsys):
    run_script(ISAAC_EXAMPLES / "bare_imports.py")
    out = capsys.readouterr().out
    assert "stage has /World/Jetbot: True" in out and "jetbot degrees of freedom: 2" in out
    height = float(out.split("cube at rest at height ")[1].split(" m")[0])
    assert height == pytest.approx(0.1, abs=2e-3)  # the 0.2 m cube rests on its half edge
