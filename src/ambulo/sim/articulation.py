"""Articulation/Robot: joints of a referenced robot, driven by implicit PD drives.

Joint arrays are (N, num_dof) -- (num_dof,) with one world -- in ``dof_names``
order: revolute joints in rad, rad/s, N*m; prismatic joints in stage units, stage
units/s (``World.stage_units_in_meters``, as Isaac scales them) and N. Before the first
``world.reset()`` the articulation properties (``num_dof``, ``dof_names``) are None, as in
Isaac.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
import torch

from ..utils.checks import Described, InvalidValueError
from .actions import ArticulationAction
from .controller import ArticulationController
from .prims import RigidPrim, XFormPrim
from .states import JointsState, XFormPrimState

if TYPE_CHECKING:
    from .world import World


class JointIndexError(InvalidValueError, IndexError):
    """A joint index out of range (an ``IndexError`` too, as before this check was one line)."""


class Articulation(RigidPrim):
    """The joints under ``prim_path`` (a referenced robot), with world pose of its root body."""

    _requires_drives = True

    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None,
                 articulation_controller: ArticulationController | None = None, translation=None):
        super().__init__(prim_path, name, position, orientation, translation)
        self.num_dof: int | None = None
        self.dof_names: list[str] | None = None
        self._controller = articulation_controller or ArticulationController()
        self._default_joints: dict[str, torch.Tensor] = {}
        """"positions"/"velocities"/"efforts" -> (N, dof) SI values restored by ``post_reset``."""
        self._initial_joints: tuple[torch.Tensor, torch.Tensor] | None = None
        self._dof_scale: torch.Tensor | None = None
        """(dof,) metres per user unit of each joint: stage units for prismatic joints, 1 for revolute."""
        self._gravity_disabled = False

    def initialize(self, world: World | None = None) -> None:
        super().initialize(world)
        world = self._world
        if self.entity.num_joints == 0:
            raise ValueError(f"{self.prim_path} has no hinge or slide joints: not an articulation")
        self.dof_names = list(self.entity.joint_names)
        self.num_dof = self.entity.num_joints
        slide = world.model.jnt_type[self.entity._joint_ids] == mujoco.mjtJoint.mjJNT_SLIDE
        self._dof_scale = torch.as_tensor(np.where(slide, self._units, 1.0), dtype=world.engine.dtype,
                                          device=self.entity.device)
        data = self.entity.data
        self._initial_joints = (data.joint_pos.clone(), data.joint_vel.clone())
        self._controller._initialize(self, world)

    def post_reset(self) -> None:
        super().post_reset()
        defaults = self._default_joints
        if "positions" in defaults or "velocities" in defaults:
            self.entity.write_joint_state(pos=defaults.get("positions"), vel=defaults.get("velocities"))
            self.entity.engine.forward()
        self._controller._reset()
        if "efforts" in defaults:
            self._controller._command(efforts=defaults["efforts"], joint_idx=self._indices(None))
        if self._gravity_disabled:
            self._write_gravity_compensation(True)

    # -- units -------------------------------------------------------------------
    def _joint_in(self, value, idx: torch.Tensor, what: str) -> torch.Tensor:
        """Joint positions/velocities given in user units (rad; stage units for prismatic
        joints) as an (N, len(idx)) tensor in rad or m."""
        return self._world._in(value, (len(idx),), what) * self._dof_scale[idx]

    def _joint_out(self, tensor: torch.Tensor, idx: torch.Tensor):
        """(N, len(idx)) joint positions/velocities in rad or m as the user's array."""
        return self._world._out(tensor / self._dof_scale[idx])

    # -- names -------------------------------------------------------------------
    def get_dof_index(self, dof_name: str) -> int:
        self._require_initialized()
        return self.entity.find_joints(dof_name)[0]

    def _indices(self, joint_indices) -> torch.Tensor:
        """``joint_indices`` (None: all) as a long tensor of distinct indices into ``dof_names``.

        Floats, bools and text are refused (a float index would be truncated silently), and so
        are duplicates (which of two values would win is undefined). Values of a CUDA tensor are
        not read (a GPU->CPU sync): only its dtype is checked."""
        self._require_initialized()
        if joint_indices is None:
            return torch.arange(self.num_dof, device=self.entity.device)
        fix = (f"pass whole-number indices into dof_names (0..{self.num_dof - 1}), each once; "
               "get_dof_index(name) finds one")
        if torch.is_tensor(joint_indices):
            if joint_indices.is_floating_point() or joint_indices.is_complex() or joint_indices.dtype == torch.bool:
                raise InvalidValueError("joint_indices", Described(f"a {joint_indices.dtype} tensor"), "not integers", fix)
            if joint_indices.device.type != "cpu":
                return joint_indices.to(self.entity.device, torch.long).reshape(-1)
            array = joint_indices.numpy()
        else:
            try:
                array = np.asarray(joint_indices)
            except (TypeError, ValueError):
                raise InvalidValueError("joint_indices", joint_indices, "not a list of integers", fix) from None
            if array.size == 0:
                array = array.astype(np.int64)
        if array.dtype.kind not in "iu":
            raise InvalidValueError("joint_indices", joint_indices, "not all whole numbers", fix)
        array = array.reshape(-1).astype(np.int64)
        bad = array[(array < 0) | (array >= self.num_dof)]
        if bad.size:
            raise JointIndexError("joint_indices", joint_indices,
                                    f"index {int(bad[0])} is out of range for {self.num_dof} joints of "
                                    f"{self.prim_path}", fix)
        values, counts = np.unique(array, return_counts=True)
        if (counts > 1).any():
            raise InvalidValueError("joint_indices", joint_indices,
                                    f"index {int(values[counts > 1][0])} appears more than once", fix)
        return torch.as_tensor(array, device=self.entity.device)

    # -- joint state -------------------------------------------------------------
    def get_joint_positions(self, joint_indices=None):
        """(.., J) rad (prismatic: stage units)."""
        idx = self._indices(joint_indices)
        return self._joint_out(self._data.joint_pos[:, idx], idx)

    def get_joint_velocities(self, joint_indices=None):
        """(.., J) rad/s (prismatic: stage units/s)."""
        idx = self._indices(joint_indices)
        return self._joint_out(self._data.joint_vel[:, idx], idx)

    def get_measured_joint_efforts(self, joint_indices=None):
        """N*m the drives exert on the joints (after force limits)."""
        return self._world._out(self._data.joint_effort[:, self._indices(joint_indices)])

    def get_applied_joint_efforts(self, joint_indices=None):
        return self.get_measured_joint_efforts(joint_indices)

    def set_joint_positions(self, positions, joint_indices=None) -> None:
        """Teleport joints (no drive involved); the drives keep their targets."""
        idx = self._indices(joint_indices)
        self.entity.write_joint_state(pos=self._joint_in(positions, idx, "joint positions"), joint_ids=idx)
        self.entity.engine.forward()

    def set_joint_velocities(self, velocities, joint_indices=None) -> None:
        idx = self._indices(joint_indices)
        self.entity.write_joint_state(vel=self._joint_in(velocities, idx, "joint velocities"), joint_ids=idx)
        self.entity.engine.forward()

    def set_joint_efforts(self, efforts, joint_indices=None) -> None:
        """Feed-forward efforts (N m, prismatic N) added to the drives' PD output from now on
        (clipped to each drive's effort limit); for pure effort control switch the joints to
        ``controller.switch_control_mode("effort")`` first, as Isaac asks for zero gains."""
        idx = self._indices(joint_indices)
        efforts = self._controller._as_targets(efforts, len(idx), "joint efforts")
        self._controller._command(efforts=efforts, joint_idx=idx)

    def get_joints_state(self) -> JointsState:
        """Current joint positions and velocities (``efforts`` None, as in Isaac)."""
        return JointsState(self.get_joint_positions(), self.get_joint_velocities(), None)

    def set_joints_state(self, positions=None, velocities=None, efforts=None) -> None:
        """Set any of joint positions, velocities (teleport) and feed-forward efforts at once."""
        if positions is not None:
            self.set_joint_positions(positions)
        if velocities is not None:
            self.set_joint_velocities(velocities)
        if efforts is not None:
            self.set_joint_efforts(efforts)

    def get_joints_default_state(self) -> JointsState:
        """The joint state ``world.reset()`` restores: set by ``set_joints_default_state``, else
        the state at initialization (``efforts`` None, as in Isaac)."""
        self._require_initialized()
        idx = self._indices(None)
        start_pos, start_vel = self._initial_joints
        pos = self._default_joints.get("positions", start_pos)
        vel = self._default_joints.get("velocities", start_vel)
        return JointsState(self._joint_out(pos, idx), self._joint_out(vel, idx), None)

    def set_joints_default_state(self, positions=None, velocities=None, efforts=None) -> None:
        """Joint positions, velocities and feed-forward efforts restored by every ``world.reset()``."""
        self._require_initialized()
        idx = self._indices(None)
        if positions is not None:
            self._default_joints["positions"] = self._joint_in(positions, idx, "default joint positions").clone()
        if velocities is not None:
            self._default_joints["velocities"] = self._joint_in(velocities, idx, "default joint velocities").clone()
        if efforts is not None:
            self._default_joints["efforts"] = self._controller._as_targets(efforts, len(idx), "default joint efforts")

    def get_dof_limits(self):
        """(num_dof, 2) lower/upper joint limits (rad; prismatic stage units); +-inf where unlimited."""
        self._require_initialized()
        limits = self.entity.joint_pos_limits / self._dof_scale.unsqueeze(-1)
        return limits.cpu().numpy() if self._world.backend == "numpy" else limits

    # -- root and bodies -------------------------------------------------------------
    def get_default_state(self) -> XFormPrimState:
        """The root pose ``world.reset()`` restores (Isaac's articulations report no velocities)."""
        return XFormPrim.get_default_state(self)

    @property
    def num_bodies(self) -> int | None:
        """Bodies (links) of the articulation; None before the first ``world.reset()``."""
        return None if self.entity is None else len(self.entity.body_names)

    @property
    def body_names(self) -> list[str] | None:
        """Body (link) names relative to ``prim_path``; None before the first ``world.reset()``."""
        return None if self.entity is None else list(self.entity.body_names)

    def get_articulation_body_count(self) -> int:
        self._require_initialized()
        return self.num_bodies

    def get_world_velocity(self):
        """(.., 6): root linear (stage units/s) then angular (rad/s) velocity, world frame."""
        data = self._data
        lin = data.root_lin_vel_w / self._units
        return self._world._out(torch.cat([lin, data.root_ang_vel_w], dim=-1))

    def set_world_velocity(self, velocity) -> None:
        """Set the root's (.., 6) linear (stage units/s) and angular (rad/s) velocity, world frame."""
        value = self._world._in(velocity, (6,), "velocity")
        self._require_initialized()
        self.entity.write_root_velocity(lin_vel_w=value[:, :3] * self._units, ang_vel_w=value[:, 3:])
        self.entity.engine.forward()

    def disable_gravity(self) -> None:
        """Keep gravity from affecting the robot's bodies (until ``enable_gravity``, across resets):
        each body gets an external force of -m g at its centre of mass (``xfrc_applied``)."""
        self._require_initialized()
        self._gravity_disabled = True
        self._write_gravity_compensation(True)

    def enable_gravity(self) -> None:
        self._require_initialized()
        self._gravity_disabled = False
        self._write_gravity_compensation(False)

    def _write_gravity_compensation(self, on: bool) -> None:
        engine, ids = self.entity.engine, self.entity.body_ids
        force = engine.field("xfrc_applied")
        if on:
            gravity = torch.as_tensor(engine.model.opt.gravity, dtype=force.dtype, device=force.device)
            force[:, ids, :3] = -engine.model_field("body_mass")[:, ids].unsqueeze(-1) * gravity
        else:
            force[:, ids, :3] = 0.0

    # -- control -------------------------------------------------------------------
    def get_articulation_controller(self) -> ArticulationController:
        return self._controller

    def apply_action(self, control_actions: ArticulationAction) -> None:
        self._controller.apply_action(control_actions)

    def get_applied_action(self) -> ArticulationAction:
        return self._controller.get_applied_action()


class Robot(Articulation):
    """A robot: an Articulation (sensors attach to its prims)."""
