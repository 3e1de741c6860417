"""Semantic labels that travel inside the model.

A label is stored in the spec as a custom text element ``semantic:<body name>`` whose
data is the class name, so any compiled ``MjModel`` (and so any engine, renderer or
writer holding it) can recover body -> class without a side table.
"""

from __future__ import annotations

import mujoco

_PREFIX = "semantic:"


def set_semantic_label(spec: mujoco.MjSpec, body_name: str, label: str) -> None:
    """Label body ``body_name`` (and all its geoms) with class ``label``."""
    if not label or not isinstance(label, str):
        raise ValueError(f"semantic label must be a non-empty string, got {label!r}")
    name = _PREFIX + body_name
    for text in spec.texts:
        if text.name == name:
            text.data = label
            return
    spec.add_text(name=name, data=label)


def semantic_labels(model: mujoco.MjModel) -> dict[int, str]:
    """Body id -> class label, for the bodies that carry one."""
    labels: dict[int, str] = {}
    for i in range(model.ntext):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TEXT, i)
        if name and name.startswith(_PREFIX):
            adr, size = model.text_adr[i], model.text_size[i]
            body = model.body(name[len(_PREFIX):]).id
            labels[body] = bytes(model.text_data[adr : adr + size - 1]).decode()
    return labels
