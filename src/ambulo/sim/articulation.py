"""Articulation/Robot: joints of a referenced robot, driven by implicit PD drives.

Joint arrays are (N, num_dof) -- (num_dof,) with one world -- in ``dof_names``
order: radians (or m), rad/s, N*m. Before the first ``world.reset()`` the
articulation properties (``num_dof``, ``dof_names``) are None, as in Isaac.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from ..utils.checks import Described, InvalidValueError
from .actions import ArticulationAction
from .controller import ArticulationController
from .prims import RigidPrim

if TYPE_CHECKING:
    from .world import World


class JointIndexError(InvalidValueError, IndexError):
    """A joint index out of range (an ``IndexError`` too, as before this check was one line)."""


class Articulation(RigidPrim):
    """The joints under ``prim_path`` (a referenced robot), with world pose of its root body."""

    _requires_drives = True

    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None,
                 articulation_controller: ArticulationController | None = None):
        super().__init__(prim_path, name, position, orientation)
        self.num_dof: int | None = None
        self.dof_names: list[str] | None = None
        self._controller = articulation_controller or ArticulationController()
        self._default_joint_positions: torch.Tensor | None = None
        self._default_joint_velocities: torch.Tensor | None = None

    def initialize(self, world: World) -> None:
        super().initialize(world)
        if self.entity.num_joints == 0:
            raise ValueError(f"{self.prim_path} has no hinge or slide joints: not an articulation")
        self.dof_names = list(self.entity.joint_names)
        self.num_dof = self.entity.num_joints
        self._controller._initialize(self, world)

    def post_reset(self) -> None:
        super().post_reset()
        if self._default_joint_positions is not None:
            self.set_joint_positions(self._default_joint_positions)
        if self._default_joint_velocities is not None:
            self.set_joint_velocities(self._default_joint_velocities)
        self._controller._reset()

    # -- names -------------------------------------------------------------------
    def get_dof_index(self, dof_name: str) -> int:
        self._data  # raises if not initialized
        return self.entity.find_joints(dof_name)[0]

    def _indices(self, joint_indices) -> torch.Tensor:
        """``joint_indices`` (None: all) as a long tensor of distinct indices into ``dof_names``.

        Floats, bools and text are refused (a float index would be truncated silently), and so
        are duplicates (which of two values would win is undefined). Values of a CUDA tensor are
        not read (a GPU->CPU sync): only its dtype is checked."""
        self._data  # raises if not initialized
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
        return self._world._out(self._data.joint_pos[:, self._indices(joint_indices)])

    def get_joint_velocities(self, joint_indices=None):
        return self._world._out(self._data.joint_vel[:, self._indices(joint_indices)])

    def get_measured_joint_efforts(self, joint_indices=None):
        """N*m the drives exert on the joints (after force limits)."""
        return self._world._out(self._data.joint_effort[:, self._indices(joint_indices)])

    def get_applied_joint_efforts(self, joint_indices=None):
        return self.get_measured_joint_efforts(joint_indices)

    def set_joint_positions(self, positions, joint_indices=None) -> None:
        idx = self._indices(joint_indices)
        self.entity.write_joint_state(pos=self._world._in(positions, (len(idx),), "joint positions"), joint_ids=idx)
        self.entity.engine.forward()

    def set_joint_velocities(self, velocities, joint_indices=None) -> None:
        idx = self._indices(joint_indices)
        self.entity.write_joint_state(vel=self._world._in(velocities, (len(idx),), "joint velocities"),
                                      joint_ids=idx)
        self.entity.engine.forward()

    def set_joints_default_state(self, positions=None, velocities=None) -> None:
        """Joint state restored by every ``world.reset()``."""
        self._data
        n = (self.num_dof,)
        if positions is not None:
            self._default_joint_positions = self._world._in(positions, n, "default joint positions").clone()
        if velocities is not None:
            self._default_joint_velocities = self._world._in(velocities, n, "default joint velocities").clone()

    def get_dof_limits(self):
        """(num_dof, 2) lower/upper joint limits (rad or m); +-inf where unlimited."""
        self._data  # raises if not initialized
        limits = self.entity.joint_pos_limits.clone()
        return limits.cpu().numpy() if self._world.backend == "numpy" else limits

    # -- control -------------------------------------------------------------------
    def get_articulation_controller(self) -> ArticulationController:
        return self._controller

    def apply_action(self, control_actions: ArticulationAction) -> None:
        self._controller.apply_action(control_actions)

    def get_applied_action(self) -> ArticulationAction:
        return self._controller.get_applied_action()


class Robot(Articulation):
    """A robot: an Articulation (sensors attach to its prims)."""
