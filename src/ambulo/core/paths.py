"""Prim paths -> model elements.

Element names in the model are prim paths (``/World/Fancy_Robot/chassis``). A path
that names no element but prefixes some (``/World/Fancy_Robot``) denotes the
subtree referenced there; its root body is the one whose parent lies outside it.
"""

from __future__ import annotations

import difflib
import fnmatch

import mujoco


class PrimNotFoundError(KeyError):
    def __str__(self) -> str:  # KeyError quotes its message; show it plainly
        return str(self.args[0])


def _not_found(prim_path: str, names: list[str]) -> PrimNotFoundError:
    close = difflib.get_close_matches(prim_path, names, n=3, cutoff=0.5)
    hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
    return PrimNotFoundError(
        f"no prim at {prim_path!r}.{hint} Create it first (scene.add / "
        f"add_reference_to_stage) or check the path; prim paths look like '/World/Name/child'."
    )


def body_names(model: mujoco.MjModel) -> list[str]:
    return [model.body(i).name for i in range(model.nbody)]


def subtree_body_ids(model: mujoco.MjModel, prim_path: str) -> list[int]:
    """Ids of the bodies named ``prim_path`` or under ``prim_path/``."""
    prefix = prim_path.rstrip("/") + "/"
    return [i for i, n in enumerate(body_names(model)) if n == prim_path or n.startswith(prefix)]


def resolve_body(model: mujoco.MjModel, prim_path: str) -> int:
    """Body id of ``prim_path``: the body of that name, or the root of the subtree there."""
    ids = subtree_body_ids(model, prim_path)
    if not ids:
        names = body_names(model) + [model.geom(i).name for i in range(model.ngeom)]
        raise _not_found(prim_path, [n for n in names if n])
    inside = set(ids)
    roots = [i for i in ids if model.body_parentid[i] not in inside]
    if len(roots) != 1:
        raise ValueError(
            f"{prim_path!r} holds {len(roots)} separate bodies, not one articulation/rigid body; "
            f"use the path of one of them: {[model.body(i).name for i in roots][:5]}"
        )
    return roots[0]


def resolve_spec_body(stage: mujoco.MjSpec, prim_path: str) -> mujoco.MjsBody:
    """The stage body of ``prim_path`` (named so, or the root of the subtree there)."""
    body = stage.body(prim_path)
    if body is not None:
        return body
    prefix = prim_path.rstrip("/") + "/"
    inside = [b for b in stage.bodies if b.name.startswith(prefix)]
    names = {b.name for b in inside}
    roots = [b for b in inside if b.parent.name not in names]
    if not roots:
        raise _not_found(prim_path, [b.name for b in stage.bodies if b.name])
    if len(roots) > 1:
        raise ValueError(
            f"{prim_path!r} holds {len(roots)} separate bodies; use the path of one of them: "
            f"{[b.name for b in roots][:5]}"
        )
    return roots[0]


def resolve_spec_prim(stage: mujoco.MjSpec, prim_path: str):
    """What holds the pose of the prim at ``prim_path`` on the stage: a referenced file's frame,
    else the body there (``resolve_spec_body``, with its did-you-mean error)."""
    return stage.frame(prim_path) or resolve_spec_body(stage, prim_path)


def match_names(names: list[str], pattern: str) -> list[int]:
    """Indices of ``names`` matching glob ``pattern``, by the whole name or its last path
    component (so ``*_foot`` matches ``/World/robot/left_foot``)."""
    return [i for i, name in enumerate(names)
            if name and (fnmatch.fnmatchcase(name, pattern)
                         or fnmatch.fnmatchcase(name.rsplit("/", 1)[-1], pattern))]
