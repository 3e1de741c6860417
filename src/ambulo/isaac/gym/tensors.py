"""Isaac Gym's tensor API on a ``Sim``: the buffers ``acquire_*_tensor`` hands out, in Isaac's layouts.

Layouts (float32, rows env-major: env 0's actors, then env 1's, ...; within an env, actors in
creation order, and each actor's DOFs/bodies in the asset's order):

- root states ``(num_actors, 13)``: position (3, sim frame, m), quaternion (x, y, z, w), linear
  velocity (3, m/s), angular velocity (3, rad/s), both in the sim frame;
- DOF states ``(num_dofs, 2)``: position (rad or m), velocity;
- rigid body states ``(num_bodies, 13)``: as root states, for every body (velocity of the body
  frame's origin);
- net contact forces ``(num_bodies, 3)``: the contact force on each body, sim frame, N;
- DOF forces ``(num_dofs,)``: the force each DOF's drive applies, N m or N.

As in Isaac Gym these buffers are the script's view of the sim, not the sim itself: ``refresh_*``
fills them from the engine and ``set_*_tensor`` writes a tensor back (which is why they are
refreshed copies: MuJoCo keeps quaternions w-first, a free joint's angular velocity in the body
frame and positions per world without the env origin, so no zero-copy view has Isaac's layout).
"""

from __future__ import annotations

import math

import torch

from ambulo.utils.math import quat_rotate

from .sim import Sim


def _xyzw(quat_wxyz: torch.Tensor) -> torch.Tensor:
    return quat_wxyz[..., [1, 2, 3, 0]]


def _wxyz(quat_xyzw: torch.Tensor) -> torch.Tensor:
    return quat_xyzw[..., [3, 0, 1, 2]]


class GymTensor:
    """What ``acquire_*_tensor`` and ``gymtorch.unwrap_tensor`` return: a handle on a torch tensor."""

    __slots__ = ("tensor",)

    def __init__(self, tensor: torch.Tensor):
        self.tensor = tensor


class SimTensors:
    """The Isaac-layout buffers of one prepared ``Sim`` and the reads/writes between them and it."""

    def __init__(self, sim: Sim):
        self.sim = sim
        engine = sim.engine
        self.num_envs = n = engine.num_worlds
        self.entities = sim.entities
        self.dofs = [e.num_joints for e in self.entities]
        self.bodies = [len(e.body_names) for e in self.entities]
        self.dofs_per_env, self.bodies_per_env = sum(self.dofs), sum(self.bodies)
        self.actors_per_env = len(self.entities)
        f32 = dict(dtype=torch.float32, device=sim.device)
        self.root = torch.zeros(n * self.actors_per_env, 13, **f32)
        self.dof_state = torch.zeros(n * self.dofs_per_env, 2, **f32)
        self.body_state = torch.zeros(n * self.bodies_per_env, 13, **f32)
        self.contact = torch.zeros(n * self.bodies_per_env, 3, **f32)
        self.dof_force = torch.zeros(n * self.dofs_per_env, **f32)
        fe = dict(dtype=engine.dtype, device=engine.device)
        self.pos_target = torch.zeros(n, self.dofs_per_env, **fe)
        self.vel_target = torch.zeros(n, self.dofs_per_env, **fe)
        self.effort = torch.zeros(n, self.dofs_per_env, **fe)
        self.forces_pending = False
        self._dof_cols = _spans(self.dofs)
        self._body_cols = _spans(self.bodies)
        for refresh in (self.refresh_root, self.refresh_dof_state, self.refresh_body_state,
                        self.refresh_contact, self.refresh_dof_force):
            refresh()

    # -- refresh: engine -> buffers ------------------------------------------------------------------
    def refresh_root(self) -> None:
        view = self.root.view(self.num_envs, self.actors_per_env, 13)
        for k, e in enumerate(self.entities):
            d = e.data
            view[:, k, 0:3] = (d.root_pos_w + self.sim.origins).to(view)
            view[:, k, 3:7] = _xyzw(d.root_quat_w).to(view)
            view[:, k, 7:10] = d.root_lin_vel_w.to(view)
            view[:, k, 10:13] = d.root_ang_vel_w.to(view)

    def refresh_dof_state(self) -> None:
        view = self.dof_state.view(self.num_envs, self.dofs_per_env, 2)
        for e, cols in zip(self.entities, self._dof_cols, strict=True):
            view[:, cols, 0] = e.data.joint_pos.to(view)
            view[:, cols, 1] = e.data.joint_vel.to(view)

    def refresh_body_state(self) -> None:
        view = self.body_state.view(self.num_envs, self.bodies_per_env, 13)
        for e, cols in zip(self.entities, self._body_cols, strict=True):
            d = e.data
            view[:, cols, 0:3] = (d.body_pos_w + self.sim.origins[:, None]).to(view)
            view[:, cols, 3:7] = _xyzw(d.body_quat_w).to(view)
            view[:, cols, 7:10] = d.body_lin_vel_w.to(view)
            view[:, cols, 10:13] = d.body_ang_vel_w.to(view)

    def refresh_contact(self) -> None:
        force = self.sim.contacts.get_current_frame().net_force_w  # (N, bodies_per_env, 3), env's body order
        self.contact.view(self.num_envs, self.bodies_per_env, 3)[:] = force.to(self.contact)

    def refresh_dof_force(self) -> None:
        view = self.dof_force.view(self.num_envs, self.dofs_per_env)
        for e, cols in zip(self.entities, self._dof_cols, strict=True):
            view[:, cols] = e.data.joint_effort.to(view)

    # -- set: buffers -> engine ----------------------------------------------------------------------
    def set_root(self, states: torch.Tensor, actor_ids: torch.Tensor | None = None) -> None:
        """Write root states ``(num_actors, 13)`` (all actors, or the rows ``actor_ids``)."""
        view = self._engine_view(states, self.actors_per_env, 13)
        for k, e, envs in self._per_actor(actor_ids):
            rows = view[:, k] if envs is None else view[envs, k]
            origin = self.sim.origins if envs is None else self.sim.origins[envs]
            e.write_root_pose(pos_w=rows[:, 0:3] - origin, quat_w=_wxyz(rows[:, 3:7]), env_ids=envs)
            e.write_root_velocity(lin_vel_w=rows[:, 7:10], ang_vel_w=rows[:, 10:13], env_ids=envs)
        self.sim.engine.forward()

    def set_dof_state(self, states: torch.Tensor, actor_ids: torch.Tensor | None = None) -> None:
        """Write DOF states ``(num_dofs, 2)`` of all actors (or of the actors ``actor_ids``)."""
        view = self._engine_view(states, self.dofs_per_env, 2)
        for k, e, envs in self._per_actor(actor_ids):
            cols = self._dof_cols[k]
            rows = view[:, cols] if envs is None else view[envs][:, cols]
            e.write_joint_state(pos=rows[..., 0], vel=rows[..., 1], env_ids=envs)
        self.sim.engine.forward()

    def set_dof_buffer(self, buffer: torch.Tensor, values: torch.Tensor, actor_ids: torch.Tensor | None = None) -> None:
        """Copy ``(num_dofs,)`` DOF targets or forces into ``buffer`` (N, dofs per env), all or some actors."""
        view = self._engine_view(values, self.dofs_per_env)
        if actor_ids is None:
            buffer[:] = view
            return
        for k, _, envs in self._per_actor(actor_ids):
            cols = self._dof_cols[k]
            buffer[envs[:, None], torch.arange(cols.start, cols.stop, device=buffer.device)] = view[envs][:, cols]

    def apply_controls(self, drive_modes: list[torch.Tensor]) -> None:
        """Drive every joint before a step: ``tau = kp (q* - q) + kd (qd* - qd) + effort``, where the
        gains already follow each DOF's drive mode and actuation forces apply in effort mode only."""
        for e, cols, effort_mode in zip(self.entities, self._dof_cols, drive_modes, strict=True):
            if e.num_joints:
                e.set_joint_targets(self.pos_target[:, cols], self.vel_target[:, cols],
                                    torch.where(effort_mode, self.effort[:, cols], 0.0))

    def apply_body_forces(self, force: torch.Tensor | None, torque: torch.Tensor | None, local: bool) -> None:
        """Push bodies for the next ``simulate`` only, as Isaac Gym does: ``force``/``torque``
        ``(num_bodies, 3)`` N and N m at each body's centre of mass, in the sim frame (``local``:
        the body's frame). MuJoCo's ``xfrc_applied`` holds them until ``clear_body_forces``."""
        xfrc = self.sim.engine.field("xfrc_applied")
        for values, cols in ((force, slice(0, 3)), (torque, slice(3, 6))):
            if values is None:
                continue
            view = self._engine_view(values, self.bodies_per_env, 3)
            for e, body_cols in zip(self.entities, self._body_cols, strict=True):
                part = view[:, body_cols]
                if local:
                    part = quat_rotate(e.data.body_quat_w, part)
                xfrc[:, e.body_ids, cols] = part
        self.forces_pending = True

    def clear_body_forces(self) -> None:
        if self.forces_pending:
            self.sim.engine.field("xfrc_applied")[:] = 0.0
            self.forces_pending = False

    # -- helpers -------------------------------------------------------------------------------------
    def _engine_view(self, values: torch.Tensor, per_env: int, *tail: int) -> torch.Tensor:
        values = torch.as_tensor(values)
        expected = self.num_envs * per_env
        # Isaac reads the tensor's memory as the flat buffer: (num_envs, dofs) works as (num_dofs,)
        if values.numel() != expected * math.prod(tail):
            raise ValueError(f"isaacgym: a tensor of shape {tuple(values.shape)} where the sim has {expected} rows "
                             f"({self.num_envs} envs x {per_env}); pass the whole tensor (indexed calls take indices)")
        return values.detach().to(self.sim.engine.device, self.sim.engine.dtype).reshape(self.num_envs, per_env, *tail)

    def _per_actor(self, actor_ids: torch.Tensor | None):
        """(actor index in env, its entity, env rows or None for all) for the actors written."""
        if actor_ids is None:
            for k, e in enumerate(self.entities):
                yield k, e, None
            return
        ids = torch.as_tensor(actor_ids).to(self.sim.engine.device).long().flatten()
        for k, e in enumerate(self.entities):
            envs = ids[ids % self.actors_per_env == k] // self.actors_per_env
            if envs.numel():
                yield k, e, envs


def _spans(counts: list[int]) -> list[slice]:
    out, start = [], 0
    for c in counts:
        out.append(slice(start, start + c))
        start += c
    return out


__all__ = ["GymTensor", "SimTensors"]
