"""``world.stage``: one object that is both the ``MjSpec`` ambulo builds and Isaac's USD stage.

ambulo code and scripts written for ambulo call the ``MjSpec``'s members (``worldbody``,
``bodies``, ``attach``: snake_case); Isaac scripts call ``world.stage.GetPrimAtPath(...)`` and
other ``Usd.Stage`` methods (CamelCase). USD's API names all start with a capital and MjSpec's
never do, so the view sends each attribute to the one that has it; the USD stage is synced
with the objects the API made before it answers.
"""

from __future__ import annotations


class StageView:
    def __init__(self, world):
        object.__setattr__(self, "_world", world)

    @property
    def mjspec(self):
        """The ``MjSpec`` itself (for code that needs the object, not its members)."""
        return self._world.sim.spec

    @property
    def usd_stage(self):
        """The ``Usd.Stage`` itself, with the API objects mirrored on it."""
        return self._world.synced_usd().stage

    def __getattr__(self, name: str):
        if name[:1].isupper():
            return getattr(self.usd_stage, name)
        return getattr(self._world.sim.spec, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._world.sim.spec, name, value)

    def __repr__(self) -> str:
        return f"<stage of {self._world!r}: MjSpec members and Usd.Stage methods>"


__all__ = ["StageView"]
