"""Which ambulo module answers each ``isaacgym`` module name under ``ambulo run`` (merged into
``ambulo.isaac.names.MODULES``, the table the import hook reads)."""

from __future__ import annotations

import importlib

_GYM = "ambulo.isaac.gym"


def _all_of(module: str) -> dict[str, str]:
    return {name: f"{module}:{name}" for name in importlib.import_module(module).__all__}


MODULES: dict[str, dict[str, str]] = {
    "isaacgym": {},
    "isaacgym.gymapi": _all_of(f"{_GYM}.gymapi"),
    "isaacgym.gymtorch": _all_of(f"{_GYM}.gymtorch"),
    "isaacgym.gymutil": _all_of(f"{_GYM}.gymutil"),
    "isaacgym.torch_utils": _all_of(f"{_GYM}.torch_utils"),
    "isaacgym.terrain_utils": _all_of(f"{_GYM}.terrain_utils"),
}
"""Isaac Gym module -> {name it provides: "ambulo.module:attribute"}."""

ROOTS = ("isaacgym",)

HINTS: dict[str, str] = {
    "SIM_FLEX": "not supported: ambulo runs gymapi.SIM_PHYSX scripts on MuJoCo",
    "FlexParams": "not supported: ambulo runs gymapi.SIM_PHYSX scripts on MuJoCo",
    "draw_lines": "the viewer is headless under ambulo run; record video with ambulo.render",
}
"""What to use instead of an Isaac Gym module name ambulo lacks."""

__all__ = ["HINTS", "MODULES", "ROOTS"]
