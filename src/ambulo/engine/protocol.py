"""The engine contract: N worlds of one compiled MjModel, state as torch tensors.

Every engine owns the changing state of ``num_worlds`` copies of one static
``mujoco.MjModel``. State fields are live ``torch`` tensors of shape
``(num_worlds, ...)`` on ``device``: writing ``engine.qpos[i] = ...`` changes world
``i`` at its next step; derived fields (body poses, sensor data) are refreshed by
``step``/``forward``. Env, reward and sensor code is written once against this
protocol and runs on the CPU engine and on a GPU engine alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import mujoco
import torch

# MjData fields that are simulation state (writable) rather than derived outputs.
STATE_FIELDS = (
    "qpos", "qvel", "act", "ctrl", "qfrc_applied", "xfrc_applied", "mocap_pos",
    "mocap_quat", "time",
)

# MjData fields that ``forward(kinematics_only=True)`` recomputes: the position stage's
# kinematics (MuJoCo's mj_fwdKinematics: mj_kinematics, mj_comPos, mj_camlight, mj_flex,
# mj_tendon; MuJoCo Warp's fwd_kinematics) and the com velocities (mj_comVel). Every other
# derived field (collisions and contacts, sensordata, actuation, qacc, constraint forces, ...)
# keeps its previous value there (see ``Engine.forward``).
KINEMATIC_FIELDS = (
    "xpos", "xquat", "xmat", "xipos", "ximat", "xanchor", "xaxis", "geom_xpos", "geom_xmat",
    "site_xpos", "site_xmat", "subtree_com", "cinert", "cdof", "cam_xpos", "cam_xmat",
    "light_xpos", "light_xdir", "flexvert_xpos", "flexelem_aabb", "flexedge_J", "flexedge_length",
    "ten_wrapadr", "ten_wrapnum", "ten_J", "ten_length", "wrap_obj", "wrap_xpos", "cvel", "cdof_dot",
)


def sim_time_s(engine: Engine, world: int = 0) -> float:
    """World ``world``'s simulated time, s. MuJoCo Warp keeps time in float32, which drifts
    from whole multiples of the timestep (0.0020000001 after one 2 ms step); time only ever
    advances by whole steps, so it is rounded to the nearest one there."""
    t = float(engine.field("time")[world])
    if engine.dtype == torch.float64:
        return t
    step = float(engine.model.opt.timestep)
    return round(t / step) * step


@runtime_checkable
class Engine(Protocol):
    """N parallel worlds of one ``mujoco.MjModel``.

    Attributes:
      model: the compiled model all worlds share (per-world overrides live in
        ``model_field``).
      num_worlds: N.
      device: where the tensors live.
    """

    model: mujoco.MjModel
    num_worlds: int
    device: torch.device
    dtype: torch.dtype
    """Floating dtype of state and model tensors: float64 on the CPU engine (MuJoCo's),
    float32 on the GPU engine (MuJoCo Warp's). Task code allocates its buffers with it."""
    num_diverged: int
    """Total number of world divergences detected (and reset) so far."""

    # MjData fields as attributes (``engine.qpos`` is ``engine.field("qpos")``), each a live
    # (N, ...) tensor on ``device``. State (writable): qpos (N, nq), qvel (N, nv), act, ctrl
    # (N, nu), time (N,), mocap_pos (N, nmocap, 3), mocap_quat, qfrc_applied, xfrc_applied.
    # Derived (read-only, lag one substep after step(refresh=False)): xpos (N, nbody, 3),
    # xquat (N, nbody, 4), xmat (N, nbody, 9), cvel (N, nbody, 6: angular, linear at the
    # tree's subtree CoM), subtree_com (N, nbody, 3), site_xpos, site_xmat, sensordata
    # (N, nsensordata), qfrc_actuator (N, nv), actuator_force (N, nu).
    qpos: torch.Tensor
    qvel: torch.Tensor
    ctrl: torch.Tensor
    time: torch.Tensor
    mocap_pos: torch.Tensor
    xpos: torch.Tensor
    xquat: torch.Tensor
    cvel: torch.Tensor
    subtree_com: torch.Tensor
    qfrc_actuator: torch.Tensor

    def field(self, name: str) -> torch.Tensor:
        """Live (N, ...) tensor of an MjData field: state is writable, outputs read-only."""

    def model_field(self, name: str) -> torch.Tensor:
        """Live, writable (N, ...) per-world values of an MjModel field (e.g. ``geom_friction``)."""

    def step(self, num_substeps: int = 1, refresh: bool = False) -> torch.Tensor:
        """Advance every world by ``num_substeps`` physics steps; return the (N,) bool mask
        of worlds that diverged (NaN/instability) and were reset. Derived fields lag one
        substep (as after ``mj_step``) unless ``refresh``."""

    acc_stale: torch.Tensor | None
    """None until a ``forward(kinematics_only=True)``; then (N,) bool on ``device``: the worlds
    whose fields outside ``KINEMATIC_FIELDS`` (sensordata, contacts, forces, qacc) predate their
    state. A kinematics-only forward sets its worlds, a full forward clears them, ``step`` clears all."""

    def forward(self, world_ids: Sequence[int] | torch.Tensor | None = None, kinematics_only: bool = False) -> None:
        """Recompute derived fields from the current state (no time advance). ``kinematics_only``
        recomputes ``KINEMATIC_FIELDS`` alone (no collision, actuation or constraint solve: a
        reset's cheap pass, as the next step recomputes everything) and marks ``acc_stale``."""

    def reset(self, world_ids: Sequence[int] | torch.Tensor | None = None, forward: bool = True) -> None:
        """Restore worlds to their initial state and, if ``forward``, recompute derived fields
        (callers that edit the state further pass False and call ``forward`` once)."""

    def set_const(self, world_ids: Sequence[int] | torch.Tensor | None = None) -> None:
        """Recompute derived model constants after writing per-world masses or inertias."""

    def ray(self, pnt, vec, **kwargs):
        """Batched ray casts against each world's geometry: ``pnt``/``vec`` (N, R, 3), world
        frame; returns (distances (N, R), geom ids (N, R)), -1 distance/id for no hit."""

    def capture_initial_state(self, world_ids: Sequence[int] | torch.Tensor | None = None) -> None:
        """Make the worlds' current state the one ``reset`` restores."""

    def get_data(self, world: int, data: mujoco.MjData | None = None) -> mujoco.MjData:
        """World ``world`` as a full ``MjData`` (derived fields current), for rendering or mj_ calls."""

    def get_model(self, world: int, model: mujoco.MjModel | None = None) -> mujoco.MjModel:
        """World ``world``'s model with its per-world field values."""
