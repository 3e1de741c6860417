"""The current World: Isaac's module-level helpers act on the most recently created one.

A leaf module (it imports nothing from ``sim``), so prims, objects and stage helpers import
it at the top instead of importing ``world`` inside functions to break a cycle.
"""

from __future__ import annotations

_current = None


def set_current_world(world) -> None:
    global _current
    _current = world


def current_world(needed_for: str):
    """The current World; a clear error naming what needed one if none exists yet."""
    if _current is None:
        raise RuntimeError(f"create a World (ambulo.sim.World()) before {needed_for}")
    return _current


def current_world_or_none():
    return _current
