"""``World(viewer="web")``: the viewers a World can open by name.

A viewer is an app (``ambulo.viewer``, a layer above this one), so the World cannot import it;
the viewer package registers its opener here when it is imported, and ``open_viewer`` says how to
get it when it has not been. ``viewer_for_new_worlds`` opens one on every World a block creates
without asking (``ambulo run --viewer web``: an Isaac script's World, the script unchanged).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from ..utils.checks import InvalidValueError

_OPENERS: dict[str, Callable] = {}
_FOR_NEW_WORLDS: list[tuple[str, int, list]] = []
"""(kind, port, viewers opened) of each ``viewer_for_new_worlds`` block, innermost last."""


def register_viewer(kind: str, opener: Callable) -> None:
    """Make ``World(viewer=kind)`` call ``opener(world, port)`` (what it returns is ``world.viewer``)."""
    _OPENERS[kind] = opener


def open_viewer(world, kind: str | None, port: int):
    """``world``'s viewer: ``kind`` on ``port``; for ``kind`` None, the one a ``viewer_for_new_worlds``
    block asks for, else none (None)."""
    opened = None
    if kind is None:
        if not _FOR_NEW_WORLDS:
            return None
        kind, port, opened = _FOR_NEW_WORLDS[-1]
    if kind not in _OPENERS:
        raise InvalidValueError("viewer", kind, "no viewer of that name is loaded",
                                "import ambulo.viewer first (it adds viewer='web'), or call "
                                "ambulo.viewer.serve(world)")
    viewer = _OPENERS[kind](world, port)
    if opened is not None:
        opened.append(viewer)
    return viewer


@contextlib.contextmanager
def viewer_for_new_worlds(kind: str, port: int) -> Iterator[list]:
    """Inside the block, a World created without ``viewer=`` opens ``kind`` on ``port`` (a second
    World: the next free port). Yields the viewers opened so far; each is closed when the block
    ends, however it ends (Ctrl-C frees the ports)."""
    if kind not in _OPENERS:
        open_viewer(None, kind, port)  # the one-line error, before any script runs
    opened: list = []
    _FOR_NEW_WORLDS.append((kind, port, opened))
    try:
        yield opened
    finally:
        _FOR_NEW_WORLDS.remove((kind, port, opened))
        for viewer in opened:
            viewer.close()
