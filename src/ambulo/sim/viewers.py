"""``World(viewer="web")``: the viewers a World can open by name.

A viewer is an app (``ambulo.viewer``, a layer above this one), so the World cannot import it;
the viewer package registers its opener here when it is imported, and ``open_viewer`` says how to
get it when it has not been.
"""

from __future__ import annotations

from collections.abc import Callable

from ..utils.checks import InvalidValueError

_OPENERS: dict[str, Callable] = {}


def register_viewer(kind: str, opener: Callable) -> None:
    """Make ``World(viewer=kind)`` call ``opener(world, port)`` (what it returns is ``world.viewer``)."""
    _OPENERS[kind] = opener


def open_viewer(world, kind: str, port: int):
    if kind not in _OPENERS:
        raise InvalidValueError("viewer", kind, "no viewer of that name is loaded",
                                "import ambulo.viewer first (it adds viewer='web'), or call "
                                "ambulo.viewer.serve(world)")
    return _OPENERS[kind](world, port)
