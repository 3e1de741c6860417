"""``BaseController``: the base class of Isaac controllers that users subclass."""

from __future__ import annotations


class BaseController:
    """A controller named ``name`` whose ``forward(...)`` returns an ``ArticulationAction``.

    Subclasses implement ``forward`` (Isaac's tutorial "Adding a Controller" does); ``reset``
    clears their state after ``world.reset()``.
    """

    def __init__(self, name: str):
        self._name = name

    @property
    def name(self) -> str:
        return self._name

    def forward(self, *args, **kwargs):
        raise NotImplementedError(f"{type(self).__name__}.forward: a BaseController subclass implements "
                                  "forward(...) and returns an ArticulationAction")

    def reset(self) -> None:
        """Nothing to clear in the base class."""


__all__ = ["BaseController"]
