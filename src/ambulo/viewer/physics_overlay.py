"""Overlays recomputed from the watched world's copied state on the viewer thread: contact forces
(one arrow per contact) and the balance of a biped (CoM, measured ZMP, capture point).

The simulation thread only copies the world's state rows (qpos, qvel, ctrl, ...; a few hundred
floats) when the streaming thread asks; here a private ``MjData`` is filled from them and
``mj_forward`` recomputes contacts and their forces, so the simulation never pays for an overlay.
The forces are those of a forward pass at that state (the solver starts cold), which match the
step's to the solver's tolerance. The balance quantities are ``locomotion.balance``'s: the CoP of
the robot's contacts with the world's geoms (``CenterOfPressure``, the measured ZMP) and the
instantaneous capture point (``capture_point``) of its subtree CoM; the ground is the floor's
geoms only (``ground_geoms``), not every geom welded to the world.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from ..locomotion.balance import CenterOfPressure, capture_point

FORCE_SCALE_M_PER_N = 1e-3
"""Arrow length per newton of contact force: a 60 kg humanoid standing (590 N) draws 0.6 m."""
MIN_FORCE_N = 1.0
"""Contacts pushing less than this draw no arrow (resting touches, numerical chatter)."""


class StateReplay:
    """A private ``MjData`` (and ``MjModel`` copy) of ``model`` filled from copied state rows and run
    through ``mj_forward``."""

    def __init__(self, model: mujoco.MjModel):
        self.model = copy.copy(model)  # per-world model rows (a camera sensor's pose) are written here
        self.data = mujoco.MjData(self.model)

    def load(self, state: dict[str, np.ndarray]) -> mujoco.MjData:
        """Write ``state`` (field name -> the world's row: qpos, qvel, act, ctrl, mocap_pos, ...;
        "model.<field>" -> that world's row of a per-world model field, e.g. ``model.cam_pos``) and
        recompute every derived field (contacts, forces, CoM, subtree velocities)."""
        data = self.data
        for name, row in state.items():
            owner, field = (self.model, name[6:]) if name.startswith("model.") else (data, name)
            target = getattr(owner, field)
            target[...] = np.asarray(row).reshape(target.shape)
        mujoco.mj_forward(self.model, data)
        mujoco.mj_subtreeVel(self.model, data)
        return data


def contact_arrows_w(model: mujoco.MjModel, data: mujoco.MjData, *, scale_m_per_n: float = FORCE_SCALE_M_PER_N,
                     min_force_n: float = MIN_FORCE_N) -> tuple[np.ndarray, np.ndarray]:
    """The force each contact applies to its second geom (MuJoCo's contact normal points from geom1
    to geom2; on a foot touching the floor, the floor's push, up) as arrows.

    Returns:
      (K, 2, 3) arrow start (the contact point) and end (start + force * ``scale_m_per_n``), world
      frame, m; and (K,) force magnitudes, N.
    """
    starts, forces = [], []
    wrench = np.zeros(6)
    for i in range(data.ncon):
        mujoco.mj_contactForce(model, data, i, wrench)
        frame = np.asarray(data.contact.frame[i]).reshape(3, 3)  # rows: normal, tangent 1, tangent 2
        force_w = frame.T @ wrench[:3]
        if np.linalg.norm(force_w) < min_force_n:
            continue
        starts.append(np.asarray(data.contact.pos[i], dtype=float).copy())
        forces.append(force_w)
    if not starts:
        return np.zeros((0, 2, 3)), np.zeros(0)
    start, force = np.array(starts), np.array(forces)
    return np.stack([start, start + scale_m_per_n * force], axis=1), np.linalg.norm(force, axis=1)


@dataclass(frozen=True)
class BalancePoints:
    """A robot's balance at one instant, world frame, m (NaN where undefined)."""

    com_w: np.ndarray
    """(3,) centre of mass of the robot's bodies."""
    zmp_w: np.ndarray
    """(3,) measured ZMP: the centre of pressure of its contacts with the world, on the ground."""
    capture_point_w: np.ndarray
    """(3,) instantaneous capture point, on the ground (at the ZMP's ground height)."""


GROUND_STEP_M = 0.05
"""A world-fixed geom is ground when its top is at most this far above the floor (a rug, a door
sill); walls, furniture, a table or door frame the robot touches are not (their pushes are not the
ground's, and the measured ZMP lies on the floor)."""


def ground_geoms(model: mujoco.MjModel) -> tuple[np.ndarray, float]:
    """The geoms a robot stands on, and the floor's height, m: the first upward-facing plane welded to
    the world (the ground plane, added first by scenes; else the lowest top of a world-fixed geom), and
    every world-fixed geom whose top is within ``GROUND_STEP_M`` of it. Raises ``ValueError`` when
    nothing is welded to the world."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    tops, floor_m = {}, None
    for g in np.flatnonzero(model.body_weldid[model.geom_bodyid] == 0):
        rot = data.geom_xmat[g].reshape(3, 3)
        if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_PLANE:
            if rot[2, 2] > 0.99:  # facing up: a floor (walls' and pictures' planes face sideways)
                tops[g] = float(data.geom_xpos[g][2])
                floor_m = tops[g] if floor_m is None else floor_m
            continue
        box = model.geom_aabb[g]  # centre, half sizes in the geom's frame
        tops[g] = float(((box[:3] + corners * box[3:]) @ rot.T + data.geom_xpos[g])[:, 2].max())
    if not tops:
        raise ValueError("balance overlay: no geom is welded to the world (no ground)")
    floor_m = min(tops.values()) if floor_m is None else floor_m
    return np.array([g for g, top in tops.items() if top <= floor_m + GROUND_STEP_M]), floor_m


class BalanceProbe:
    """``BalancePoints`` of the robot whose root body is ``root_body``: every geom of its subtree
    (``robot_bodies``) counts as a foot, the floor's geoms (``ground_geoms``) as ground. Raises
    ``ValueError`` for a scene with nothing to stand on."""

    def __init__(self, model: mujoco.MjModel, root_body: int, robot_bodies: list[int]):
        self.root_body = root_body
        ground, floor_m = ground_geoms(model)
        self.cop = CenterOfPressure(model, robot_bodies, ground_geoms=ground.tolist(), ground_height_m=floor_m)

    def __call__(self, data: mujoco.MjData) -> BalancePoints:
        com_w = np.asarray(data.subtree_com[self.root_body], dtype=float).copy()
        com_vel_w = np.asarray(data.subtree_linvel[self.root_body], dtype=float)
        ground_m = self.cop.ground_height_m
        zmp_w = self.cop(data).cop_w
        height_m = com_w[2] - ground_m
        if height_m > 0:
            xi_xy = capture_point(com_w, com_vel_w, height_m)
            cp_w = np.array([xi_xy[0], xi_xy[1], ground_m])
        else:
            cp_w = np.full(3, np.nan)
        return BalancePoints(com_w=com_w, zmp_w=zmp_w, capture_point_w=cp_w)
