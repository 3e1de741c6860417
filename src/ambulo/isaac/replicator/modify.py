"""``rep.modify``: pose, attribute and semantics of the prims in the current ``with item:`` block.

Inside ``rep.trigger.on_frame`` each call adds a node drawn anew every frame (every ``interval``
frames); outside a trigger it runs once, as Replicator's first graph evaluation would.
"""

from __future__ import annotations

import numpy as np

from .create import _look_at, _semantics, _vec3, check_scale
from .distribution import Choice, Normal, Uniform, is_random
from .errors import Namespace, unsupported
from .graph import current_graph

_COLOR_ATTRS = ("primvars:displayColor", "displayColor")
_LIGHT_ATTRS = {"intensity": "intensity", "inputs:intensity": "intensity", "color": "color", "inputs:color": "color",
                "colorTemperature": "temperature", "inputs:colorTemperature": "temperature"}


def pose(position=None, rotation=None, rotation_order: str = "XYZ", scale=None, size=None, pivot=None,
         look_at=None, look_at_up_axis=None, input_prims=None):
    """Set (or draw, per prim) position, rotation (XYZ Euler, deg) and scale; cameras may ``look_at``
    a point or a prim."""
    graph = current_graph()
    targets = graph.current_targets(input_prims, "modify.pose")
    for arg, value in (("size", size), ("pivot", pivot), ("look_at_up_axis", look_at_up_axis)):
        if value is not None:
            raise unsupported(f"modify.pose({arg}=...)", "set position, rotation, scale or (cameras) look_at")
    if rotation_order != "XYZ":
        raise unsupported(f"modify.pose(rotation_order={rotation_order!r})", "rotations are XYZ Euler angles")
    kinds = {graph.prim(t).kind for t in targets}
    if "light" in kinds:
        raise unsupported("modify.pose on lights", "lights keep the pose they were created with")
    if look_at is not None and kinds - {"camera"}:
        raise unsupported("modify.pose(look_at=...) on shapes", "aim cameras with look_at; turn shapes with rotation")
    for kind in kinds:
        check_scale(kind, scale, "modify")
    if scale is not None and kinds & {"cylinder", "disk"} and not _keeps_round(scale):
        raise ValueError("rep.modify.pose: cylinders and disks scale x and y together; "
                         "give scale one number (or a distribution of one number)")
    params = {}
    for key, value in (("position", position), ("rotation", rotation), ("scale", scale)):
        if value is not None:
            params[key] = _vec3(value, key, None) if not is_random(value) else value
    if look_at is not None:
        params["look_at"] = _look_at(look_at)
    if not params:
        raise ValueError("rep.modify.pose needs position, rotation, scale or look_at")
    return graph.add_node("pose", targets, params)


def _keeps_round(scale) -> bool:
    if isinstance(scale, (Uniform, Normal)):
        return all(np.ndim(v) == 0 for v in vars(scale).values())
    if isinstance(scale, Choice):
        return all(np.ndim(c) == 0 or (np.shape(c) == (3,) and c[0] == c[1]) for c in scale.choices)
    value = np.asarray(scale, float)
    return value.ndim == 0 or (value.shape == (3,) and value[0] == value[1])


def attribute(name: str, value, attribute_type=None, input_prims=None):
    """Set a prim attribute: ``primvars:displayColor`` of shapes, ``intensity``/``color`` of lights."""
    graph = current_graph()
    targets = graph.current_targets(input_prims, "modify.attribute")
    kinds = {graph.prim(t).kind for t in targets}
    if name in _COLOR_ATTRS and "light" not in kinds and "camera" not in kinds:
        colors = value
        if not is_random(value):
            colors = np.asarray(value, float).reshape(-1, 3)[0]  # displayColor is a list of one colour
        return graph.add_node("color", targets, {"colors": colors})
    if name in _LIGHT_ATTRS and kinds == {"light"}:
        return graph.add_node("light", targets, {_LIGHT_ATTRS[name]: value})
    raise unsupported(f"modify.attribute({name!r})",
                      "ambulo maps primvars:displayColor of shapes and intensity/color/colorTemperature of lights")


def semantics(semantics=None, input_prims=None, mode: str = "add"):
    """Label the prims (``[("class", "cube")]``). Labels are part of the scene, so they are set once."""
    graph = current_graph()
    if graph.trigger is not None:
        raise unsupported("modify.semantics inside a trigger",
                          "labels are fixed for a run; call rep.modify.semantics before rep.trigger.on_frame")
    if mode not in ("add", "replace"):
        raise ValueError(f"rep.modify.semantics: mode must be 'add' or 'replace', got {mode!r}")
    labels = _semantics(semantics)
    for path in graph.current_targets(input_prims, "modify.semantics"):
        prim = graph.prim(path)
        prim.semantics = labels if mode == "replace" else [s for s in prim.semantics if s not in labels] + labels


modify = Namespace("modify", {"pose": pose, "attribute": attribute, "semantics": semantics}, {
    "visibility": "create only the prims the camera should see, or scatter them out of view",
    "material": "use rep.randomizer.materials or rep.randomizer.color",
    "variant": "USD variants do not exist in ambulo scenes",
    "animation": "Replicator frames are independent draws; there is no animation",
    "projection_material": "not supported",
})
