"""The parts of Kit's ``omni.usd`` that Isaac scripts use: the context that holds the stage."""

from __future__ import annotations

import os

from .stage_utils import create_new_stage, get_current_stage, open_stage


class UsdContext:
    """Kit's USD context: one per app, it holds the stage."""

    def get_stage(self):
        return get_current_stage()

    def get_stage_id(self) -> int:
        return id(get_current_stage())

    def new_stage(self) -> bool:
        create_new_stage()
        return True

    def open_stage(self, url: str | os.PathLike) -> bool:
        return open_stage(url)

    def get_stage_url(self) -> str:
        return get_current_stage().GetRootLayer().identifier


_CONTEXT = UsdContext()


def get_context(name: str = "") -> UsdContext:
    return _CONTEXT


def get_stage_next_free_path(stage, path: str, prepend_default_prim: bool = True) -> str:
    """``path``, or ``path_01``, ``path_02``, ... whichever is free on ``stage``; with
    ``prepend_default_prim``, under the default prim (``/Cube`` -> ``/World/Cube``) as Kit does."""
    path = str(path)
    root = str(stage.GetDefaultPrim().GetPath()) if stage.GetDefaultPrim() else ""
    if prepend_default_prim and root and path != root and not path.startswith(root + "/"):
        path = f"{root}/{path.lstrip('/')}"
    candidate, n = path, 0
    while stage.GetPrimAtPath(candidate).IsValid():
        n += 1
        candidate = f"{path}_{n:02d}"
    return candidate


__all__ = ["UsdContext", "get_context", "get_stage_next_free_path"]
