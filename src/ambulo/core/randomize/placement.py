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
    """Which free bodies penetrate anything but the ignored geoms, for a full qpos.

    ``movers`` (geom ids, optional): the geoms of the bodies being placed. Given, only contacts
    with one of them are made at all: a scatterer asks only whether its own bodies collide, and
    the pairs it never asks about (the robot with itself, the scenery with the robot) cost half
    of every ``mj_collision`` in a warehouse scene. Contacts that are made are exactly those of
    ``model``, so the bodies reported for the movers do not change."""

    def __init__(self, model: mujoco.MjModel, ignore_geoms: np.ndarray, movers: np.ndarray | None = None):
        self._ignore = np.zeros(model.ngeom, bool)
        self._ignore[np.asarray(ignore_geoms, int)] = True
        # a private copy in which the ignored geoms collide with nothing: their contacts (the
        # support surface with every parked body and the robot's feet) are never made, only to
        # be dropped; every other pair collides exactly as in ``model``
        self.model = copy.copy(model)
        self.model.geom_contype[self._ignore] = 0
        self.model.geom_conaffinity[self._ignore] = 0
        if movers is not None:
            _collide_only_with(self.model, np.asarray(movers, int))
        self.data = mujoco.MjData(self.model)
        self._qpos = self.data.qpos  # a view of the private data's buffer, looked up once
        self._root = model.body_rootid
        self._geom_root = model.body_rootid[model.geom_bodyid]

    def colliding_roots(self, qpos: np.ndarray) -> set[int]:
        """Root bodies (of geoms) in penetrating contacts."""
        m, d = self.model, self.data
        self._qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        n = d.ncon
        if n == 0:
            return set()
        contact = d.contact
        geoms = contact.geom[:n]
        hit = contact.dist[:n] < -_PENETRATION_M
        hit &= ~(self._ignore[geoms[:, 0]] | self._ignore[geoms[:, 1]])
        return set(self._geom_root[geoms[hit]].ravel().tolist())


_MASK_BITS = 16


def _collide_only_with(model: mujoco.MjModel, movers: np.ndarray) -> None:
    """Rewrite ``model``'s collision masks so that only pairs with a geom of ``movers`` pass the
    contype/conaffinity test, each exactly when it passed before.

    MuJoCo collides two geoms when ``contype1 & conaffinity2 or contype2 & conaffinity1``. The
    other geoms' contype moves to the upper 16 bits, where no other geom's conaffinity reaches;
    the movers' conaffinity is copied there too, so an other/mover pair tests the same bits as
    before, shifted, and a mover/mover pair is untouched. Masks wider than 16 bits are left as
    they are (every pair is then made, as without ``movers``)."""
    contype, conaffinity = model.geom_contype, model.geom_conaffinity
    if contype.max(initial=0) >> _MASK_BITS or conaffinity.max(initial=0) >> _MASK_BITS:
        return
    is_mover = np.zeros(model.ngeom, bool)
    is_mover[movers] = True
    contype[~is_mover] = contype[~is_mover] << _MASK_BITS
    conaffinity[is_mover] = conaffinity[is_mover] | (conaffinity[is_mover] << _MASK_BITS)


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
