"""Named callbacks, as Isaac's World keeps its physics and render callbacks."""

from __future__ import annotations

from collections.abc import Callable


class NamedCallbacks(dict):
    """``{name: callable}`` whose ``add`` checks the callable and ``remove`` names the ones there."""

    def __init__(self, kind: str):
        super().__init__()
        self.kind = kind
        """What the callbacks are for ("physics", "render"), in messages."""

    def add(self, name: str, fn: Callable) -> None:
        if not callable(fn):
            raise TypeError(f"{self.kind} callback {name!r} must be callable")
        self[name] = fn

    def remove(self, name: str) -> None:
        if name not in self:
            raise KeyError(f"no {self.kind} callback named {name!r}; have {sorted(self)}")
        del self[name]


__all__ = ["NamedCallbacks"]
