"""The Replicator graph of one script run: what the script declares, kept until the orchestrator runs.

Replicator builds an OmniGraph: ``rep.create.*`` author prims, and the calls inside
``with rep.trigger.on_frame():`` do not act when they are made; they add nodes that the
orchestrator evaluates on every frame it renders. ambulo keeps the same split: ``Graph`` holds
the declared prims (shapes, camera, lights), the nodes (pose, colour, scatter, ...) of each
trigger, the render product, the writers and the seed; ``orchestrator.run()``/``step()``
turn it into an ``ambulo.replicator.DatasetConfig`` and render it (``scene.py``).

A graph belongs to one run of a script: the import hook makes a fresh ``omni.replicator.core``
module per run, and a graph whose module is no longer the imported one is replaced.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

SHAPES = ("cube", "sphere", "cylinder", "cone", "torus", "disk", "plane")
"""Replicator primitives ambulo builds (Replicator's 100 cm shapes as 1 m ones; ``shapes.py``)."""
ONCE = 1 << 62
"""``every_n_frames`` of nodes outside a trigger: drawn once per run, the same on every frame."""


@dataclass
class PrimDecl:
    """A prim ``rep.create`` authored: a shape, the camera or a light."""

    path: str
    """Body name in the scene (``/Replicator/Cube_Xform``), the prim path scripts see."""
    kind: str
    """One of ``SHAPES``, ``"camera"`` or ``"light"``."""
    position: np.ndarray
    rotation_deg: np.ndarray
    """XYZ Euler angles (deg), Replicator's ``rotation``: R = Rz Ry Rx."""
    scale: np.ndarray
    semantics: list[tuple[str, str]] = field(default_factory=list)
    color: tuple[float, float, float] | None = None
    layer: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    """Camera: focal_length, horizontal_aperture, clipping_range, look_at. Light: light_type,
    intensity, color."""

    @property
    def label(self) -> str | None:
        """The ``class`` semantic label (what BasicWriter's default ``semantic_types`` keeps)."""
        for kind, value in self.semantics:
            if kind == "class":
                return value
        return None


@dataclass
class Node:
    """An operation the orchestrator runs every frame (or once, outside a trigger)."""

    kind: str
    """"pose", "color", "light", "scatter_2d" (see ``nodes.py``)."""
    targets: list[str]
    params: dict[str, Any]
    every_n_frames: int
    layer: str | None = None


@dataclass
class Trigger:
    """``rep.trigger.on_frame(num_frames, interval)``: its nodes run every ``interval`` frames."""

    num_frames: int | None
    interval: int
    nodes: list[Node] = field(default_factory=list)

    def __enter__(self) -> Trigger:
        graph = current_graph()
        if graph.trigger is not None:
            raise RuntimeError("rep.trigger.on_frame blocks do not nest; close the outer one first")
        graph.trigger = self
        return self

    def __exit__(self, *exc) -> None:
        current_graph().trigger = None


@dataclass
class Graph:
    owner: object
    prims: dict[str, PrimDecl] = field(default_factory=dict)
    static_nodes: list[Node] = field(default_factory=list)
    triggers: list[Trigger] = field(default_factory=list)
    render_products: list = field(default_factory=list)
    writers: list = field(default_factory=list)
    annotators: list = field(default_factory=list)
    """``rep.AnnotatorRegistry`` annotators attached to a render product (``annotators.py``)."""
    materials: list = field(default_factory=list)
    registered: dict = field(default_factory=dict)
    """Functions of ``rep.randomizer.register``, by name."""
    seed: int = 0
    layer: str | None = None
    trigger: Trigger | None = None
    targets: list[list[str]] = field(default_factory=list)
    """Stack of ``with item:`` blocks: the prims modify/randomizer calls act on."""
    frames_done: int = 0
    """Frames the orchestrator has rendered in this run (``step`` continues from here)."""
    previewed: bool = False
    """``rep.orchestrator.preview()`` was called (``orchestrator.finish_script``)."""
    ran: bool = False
    """``run``/``step`` was called: the script drives its own frames."""
    session: Any = None
    """The running frame producer and writers (``orchestrator.py``), made on the first frame."""

    def add_node(self, kind: str, targets: list[str], params: dict[str, Any]) -> Node:
        """Add a node to the open trigger, or (outside one) a node that runs once."""
        if self.session is not None:
            raise RuntimeError(f"rep.{kind} after the orchestrator started: declare the whole graph "
                               "before rep.orchestrator.run()/step()")
        if self.trigger is None:
            node = Node(kind, targets, params, ONCE, self.layer)
            self.static_nodes.append(node)
        else:
            node = Node(kind, targets, params, self.trigger.interval, self.layer)
            self.trigger.nodes.append(node)
        return node

    def add_prim(self, prim: PrimDecl) -> None:
        if self.session is not None:
            raise RuntimeError("rep.create after the orchestrator started: create every prim before "
                               "rep.orchestrator.run()/step()")
        if self.trigger is not None and prim.kind == "camera":
            raise RuntimeError("rep.create.camera inside rep.trigger.on_frame: create the camera before the "
                               "trigger and move it with rep.modify.pose in it")
        # a shape or light created inside a trigger is created once (Replicator evaluates the
        # create node's prims once); its distributions become the trigger's nodes, drawn every frame
        prim.layer = self.layer
        self.prims[prim.path] = prim

    def unique_path(self, base: str) -> str:
        """Replicator's naming: ``/Replicator/Cube_Xform``, then ``_01``, ``_02``, ..."""
        if base not in self.prims:
            return base
        k = 1
        while f"{base}_{k:02d}" in self.prims:
            k += 1
        return f"{base}_{k:02d}"

    def clear_layer(self, name: str) -> None:
        """What re-entering ``rep.new_layer(name)`` does: drop what that layer authored."""
        self.prims = {p: d for p, d in self.prims.items() if d.layer != name}
        self.static_nodes = [n for n in self.static_nodes if n.layer != name]
        for trigger in self.triggers:
            trigger.nodes = [n for n in trigger.nodes if n.layer != name]

    def current_targets(self, input_prims, what: str) -> list[str]:
        """The prims a modify/randomizer call acts on: ``input_prims`` or the innermost ``with item:``."""
        if input_prims is not None:
            return paths_of(input_prims)
        if not self.targets:
            raise RuntimeError(f"rep.{what} has no prims to act on: call it inside `with prims:` "
                               "(an item from rep.create/rep.get) or pass input_prims=")
        return list(self.targets[-1])

    def prim(self, path: str) -> PrimDecl:
        try:
            return self.prims[path]
        except KeyError:
            raise KeyError(f"no Replicator prim at {path!r}; prims: {sorted(self.prims)}") from None


class Item:
    """What ``rep.create``/``rep.get`` return (Replicator's ``ReplicatorItem``): a set of prims.

    ``with item:`` makes the prims the targets of the modify/randomizer calls inside; ``.node``
    is the item itself, so functions registered with ``rep.randomizer.register`` can return it.
    """

    def __init__(self, paths: list[str]):
        self.paths = list(paths)

    @property
    def node(self) -> Item:
        return self

    def __enter__(self) -> Item:
        current_graph().targets.append(self.paths)
        return self

    def __exit__(self, *exc) -> None:
        current_graph().targets.pop()

    def __repr__(self) -> str:
        return f"ReplicatorItem({self.paths})"


def paths_of(value) -> list[str]:
    """Prim paths of an item, a path, or a list of either."""
    if isinstance(value, Item):
        return list(value.paths)
    if isinstance(value, str):
        current_graph().prim(value)
        return [value]
    if isinstance(value, (list, tuple)):
        return [p for v in value for p in paths_of(v)]
    raise TypeError(f"expected Replicator prims (an item from rep.create/rep.get, or prim paths), got {value!r}")


_graph: Graph | None = None


def current_graph() -> Graph:
    """This run's graph; a fresh one once the script run that made the last one has ended."""
    global _graph
    owner = sys.modules.get("omni.replicator.core")
    if _graph is None or _graph.owner is not owner:
        if _graph is not None and _graph.session is not None:
            _graph.session.close()
        _graph = Graph(owner=owner)
    return _graph
