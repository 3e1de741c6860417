"""The top level of ``omni.replicator.core``: layers and the global seed."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from .graph import current_graph


@contextlib.contextmanager
def new_layer(name: str | None = None) -> Iterator[None]:
    """Prims and nodes authored inside belong to layer ``name`` (default "Replicator"); entering a
    layer again first removes what it authored before, as Replicator clears a layer it re-creates."""
    graph = current_graph()
    name = name or "Replicator"
    graph.clear_layer(name)
    previous, graph.layer = graph.layer, name
    try:
        yield
    finally:
        graph.layer = previous


def set_global_seed(seed: int) -> None:
    """Seed of every draw: frame ``i`` of a run is the same for the same seed and graph."""
    if int(seed) < 0:
        raise ValueError(f"rep.set_global_seed needs a non-negative integer, got {seed}")
    current_graph().seed = int(seed)
