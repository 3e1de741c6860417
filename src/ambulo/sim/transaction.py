"""Constructors that fail leave the stage as it was.

An Isaac-style constructor edits the stage as it goes (``WheeledRobot(create_robot=True)``
references a file, then checks its wheel names; ``DynamicCuboid`` adds a body, then sets its
colour). ``stage_unchanged_on_error`` remembers the stage's elements, frame and body poses and
the World's components, and on an exception deletes what was added and restores the rest, so a
script that catches the error and retries finds no half-built prim in its way. Nested
constructors (a subclass calling ``super().__init__``) roll back once, in the outermost.
"""

from __future__ import annotations

import contextlib
import functools
import re
from collections.abc import Iterator

from .current import current_world_or_none

_GROUPS = ("frames", "bodies", "geoms", "joints", "sites", "cameras", "lights", "actuators", "sensors",
           "tendons", "equalities", "excludes", "keys", "texts", "materials", "textures", "meshes")
"""MjSpec element lists, parents first: deleting a body deletes what it holds."""

_depth = 0


class _Snapshot:
    def __init__(self, world):
        self.world = world
        spec = world.stage
        self.elements = {group: list(getattr(spec, group)) for group in _GROUPS}
        self.poses = [(e, list(e.pos), list(e.quat)) for group in ("frames", "bodies") for e in getattr(spec, group)]
        self.components = dict(world.sim.components)

    def restore(self) -> None:
        spec = self.world.stage
        # ``add_robot`` attaches a file at a new frame with the prefix "<frame name>/", which its
        # default classes carry too: those are the defaults to remove (listing every default
        # takes a full XML write, so it is done here, on failure, not in every snapshot)
        prefixes = tuple(f.name + "/" for f in spec.frames if f not in self.elements["frames"] and f.name)
        for group in _GROUPS:
            while True:  # re-read after each delete: a deleted parent took its children along
                new = [e for e in getattr(spec, group) if e not in self.elements[group]]
                if not new:
                    break
                spec.delete(new[0])
        if prefixes:  # the deepest first
            for name in reversed([n for n in _default_classes(spec) if n.startswith(prefixes)]):
                spec.delete(spec.find_default(name))
        for element, pos, quat in self.poses:
            element.pos, element.quat = pos, quat
        self.world.sim.components.clear()
        self.world.sim.components.update(self.components)


def _default_classes(spec) -> list[str]:
    """Names of the spec's default classes, parents before children (MjSpec lists no defaults)."""
    return re.findall(r'<default class="([^"]+)"', spec.to_xml())


@contextlib.contextmanager
def stage_unchanged_on_error() -> Iterator[None]:
    """Undo the current World's stage edits made inside the block if it raises."""
    global _depth
    world = current_world_or_none()
    if world is None or _depth:
        yield
        return
    snapshot = _Snapshot(world)
    _depth += 1
    try:
        yield
    except BaseException:
        snapshot.restore()
        raise
    finally:
        _depth -= 1


def atomic_constructor(cls: type) -> type:
    """Wrap ``cls.__init__`` (if it defines one) in ``stage_unchanged_on_error``."""
    init = cls.__dict__.get("__init__")
    if init is None or getattr(init, "_atomic", False):
        return cls

    @functools.wraps(init)
    def wrapped(self, *args, **kwargs):
        with stage_unchanged_on_error():
            init(self, *args, **kwargs)

    wrapped._atomic = True
    cls.__init__ = wrapped
    return cls


__all__ = ["atomic_constructor", "stage_unchanged_on_error"]
