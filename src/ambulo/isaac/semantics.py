"""Isaac's semantic-label helpers on a ``Usd.Prim`` or a prim path.

An object made through the ambulo API carries its label in the model (``ambulo.core.semantics``);
a prim authored with pxr carries Isaac's ``Semantics`` attributes, which the World reads when it
imports the prim at reset (``ambulo.sim.usd_stage.authored_labels``, re-exported here).
"""

from __future__ import annotations

from ambulo.core.semantics import set_semantic_label
from ambulo.sim.current import current_world_or_none
from ambulo.sim.usd_stage import SEMANTIC_DATA, SEMANTIC_TYPE, authored_labels

from .stage_utils import synced_usd_stage


def _path(prim) -> str:
    return str(prim.GetPath()) if hasattr(prim, "GetPath") else str(prim)


def add_update_semantics(prim, semantic_label: str, type_label: str = "class", suffix: str = "") -> None:
    """Give ``prim`` (a ``Usd.Prim`` or path) the label ``semantic_label`` of ``type_label``.

    Only ``class`` labels reach the annotators (segmentation, boxes); others are stored on the prim.
    """
    if not semantic_label or not isinstance(semantic_label, str):
        raise ValueError(f"semantic_label must be a non-empty string, got {semantic_label!r}")
    path = _path(prim)
    usd = synced_usd_stage()
    usd_prim = usd.stage.GetPrimAtPath(path)
    if not usd_prim.IsValid():
        raise ValueError(f"no prim at {path!r} to label; check the path")
    world = current_world_or_none()
    if usd.is_mirrored(path) and world is not None:
        if type_label == "class":
            set_semantic_label(world.stage, path, semantic_label)
        return
    from pxr import Sdf

    usd_prim.CreateAttribute(SEMANTIC_TYPE, Sdf.ValueTypeNames.String).Set(type_label)
    usd_prim.CreateAttribute(SEMANTIC_DATA, Sdf.ValueTypeNames.String).Set(semantic_label)


def add_labels(prim, labels: list[str], instance_name: str = "class", overwrite: bool = True) -> None:
    """Isaac Sim 4.5+'s form: the first of ``labels`` becomes the prim's ``instance_name`` label."""
    if not labels:
        raise ValueError("labels must hold at least one label")
    add_update_semantics(prim, labels[0], instance_name)


__all__ = ["SEMANTIC_DATA", "SEMANTIC_TYPE", "add_labels", "add_update_semantics", "authored_labels"]
