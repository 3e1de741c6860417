"""Placing bodies without overlap: MuJoCo's own collision check inside one rejection loop.

``place_without_overlap`` draws poses for the bodies still to place, checks the whole ``qpos``
with ``CollisionChecker`` (``mj_collision`` on a private ``MjData``), and redraws only the
bodies in penetrating contacts, up to ``max_tries`` rounds. Bodies still colliding are the
caller's to park out of sight (``park_z``), so a crowded region degrades instead of
overlapping. The replicator's ``Scatter2D`` and Isaac's ``rep.randomizer.scatter_2d`` both
place through it; they differ only in how a pose is drawn.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

_PENETRATION_M = 1e-4


def park_z(body_id: int) -> float:
    """Height (m) where an unused body waits: under the floor, 3 m apart per body, so none touch."""
    return -10.0 - 3.0 * body_id


class CollisionChecker:
    """Which free bodies penetrate anything but the ignored geoms, for a full qpos."""

    def __init__(self, model: mujoco.MjModel, ignore_geoms: np.ndarray):
        self._ignore = np.zeros(model.ngeom, bool)
        self._ignore[np.asarray(ignore_geoms, int)] = True
        # a private copy in which the ignored geoms collide with nothing: their contacts (the
        # support surface with every parked body and the robot's feet) are never made, only to
        # be dropped; every other pair collides exactly as in ``model``
        self.model = copy.copy(model)
        self.model.geom_contype[self._ignore] = 0
        self.model.geom_conaffinity[self._ignore] = 0
        self.data = mujoco.MjData(self.model)
        self._root = model.body_rootid

    def colliding_roots(self, qpos: np.ndarray) -> set[int]:
        """Root bodies (of geoms) in penetrating contacts."""
        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_collision(self.model, d)
        n = d.ncon
        if n == 0:
            return set()
        geoms = d.contact.geom[:n]
        hit = (d.contact.dist[:n] < -_PENETRATION_M) & ~self._ignore[geoms].any(1)
        bodies = self.model.geom_bodyid[geoms[hit]]
        return {int(b) for b in self._root[bodies].ravel()}


def place_without_overlap(candidates: Sequence[int], root_body_of: Sequence[int], qpos: np.ndarray,
                          draw: Callable[[list[int]], None], checker: CollisionChecker | None,
                          max_tries: int) -> list[int]:
    """Rejection-place ``candidates`` (indices of objects); returns those still colliding.

    ``draw(todo)`` writes new poses of the objects ``todo`` into ``qpos`` (the world's full
    configuration, with everything else where it stands); ``root_body_of[i]`` is object ``i``'s
    root body id. Each round redraws every candidate in a penetrating contact (so one placed
    earlier and hit by a newcomer moves too). Without a checker one draw places everything.
    """
    todo = list(candidates)
    for _ in range(max_tries):
        if not todo:
            break
        draw(todo)
        if checker is None:
            return []
        hits = checker.colliding_roots(qpos)
        todo = [i for i in candidates if root_body_of[i] in hits]
    return todo


__all__ = ["CollisionChecker", "park_z", "place_without_overlap"]
