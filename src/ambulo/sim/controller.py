"""ArticulationController: joint targets -> drive controls, with gains and control modes.

A drive's ctrl is ``kp * q_target + kd * qd_target + tau_ff`` (see ``drives.py``),
so position, velocity and effort commands combine in one implicit PD per joint.
Control modes set the gains an Isaac user expects: "position" uses (kp, kd),
"velocity" (0, kd), "effort" (0, 0).

Out-of-range commands: efforts beyond a drive's effort limit (its MuJoCo ``forcerange``) are
clipped to it, as Isaac clips to max effort, and ``get_applied_action`` reports the clipped
values. Position targets beyond a joint's limits are kept as given (and reported so): the
joint limit holds the joint at the limit while the drive pushes towards the target with
``kp * (target - limit)``, which MuJoCo caps at the effort limit too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from ..utils.checks import Described, InvalidValueError, check_all_finite, check_real_dtype
from .actions import ArticulationAction

if TYPE_CHECKING:
    from .articulation import Articulation
    from .world import World

_MODES = ("position", "velocity", "effort")


class ArticulationController:
    def __init__(self):
        self._art: Articulation | None = None

    def _initialize(self, articulation: Articulation, world: World) -> None:
        self._art, self._world = articulation, world
        self._entity = articulation.entity
        self._kp = self._entity.data.joint_stiffness.clone()
        """(N, dof) stiffness the user set, restored by "position" mode."""
        self._kd = self._entity.data.joint_damping.clone()
        self._modes = ["position"] * articulation.num_dof
        self._reset()

    def _reset(self) -> None:
        # hold the pose the robot starts in, rather than yank it to zero
        self._q_target = self._entity.data.joint_pos.clone()
        self._qd_target = torch.zeros_like(self._q_target)
        self._tau_ff = torch.zeros_like(self._q_target)
        self._write_ctrl()

    # -- commands ---------------------------------------------------------------
    def apply_action(self, control_actions: ArticulationAction) -> None:
        art = self._require()
        idx = art._indices(control_actions.joint_indices)
        for value, target, what in (
            (control_actions.joint_positions, self._q_target, "joint_positions"),
            (control_actions.joint_velocities, self._qd_target, "joint_velocities"),
            (control_actions.joint_efforts, self._tau_ff, "joint_efforts"),
        ):
            if value is None:
                continue
            given, commanded = self._as_targets(value, len(idx), what, allow_none=True)
            if target is self._tau_ff:  # Isaac clips commanded efforts to the drive's max effort
                limits = self._entity.joint_effort_limits[idx]
                given = torch.clamp(given, limits[:, 0], limits[:, 1])
            target[:, idx] = torch.where(commanded, given, target[:, idx])
        self._write_ctrl()

    def _as_targets(self, value, count: int, what: str, allow_none: bool = False):
        """``value`` as an (N, count) float64 tensor; with ``allow_none`` also the mask of
        commanded entries (None inside a list leaves that joint uncommanded)."""
        commanded = None
        if allow_none and isinstance(value, (list, tuple)) and any(v is None for v in value):
            commanded = torch.tensor([v is not None for v in value], device=self._entity.device)
            value = [0.0 if v is None else v for v in value]
        n = self._world.num_worlds
        fix = (f"pass finite real numbers of shape ({count},) or ({n}, {count}), one per commanded joint "
               f"({self._art.num_dof} joints in dof_names order, or set joint_indices); None, or None "
               "inside a list, leaves a joint uncommanded")
        check_real_dtype(what, value, fix)
        try:
            source = value if torch.is_tensor(value) else np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidValueError(what, value, "not an array of real numbers", fix) from None
        check_all_finite(what, torch.as_tensor(source), fix)  # CPU values only: no GPU sync
        tensor = torch.as_tensor(source, dtype=torch.float64, device=self._entity.device)
        if tensor.shape == (count,):
            tensor = tensor.expand(n, count)
        if tuple(tensor.shape) != (n, count):
            raise InvalidValueError(f"{what} for {self._art.prim_path}", Described(f"of shape {tuple(tensor.shape)}"),
                                    f"expected shape ({count},) or ({n}, {count})", fix)
        if not allow_none:
            return tensor
        mask = torch.ones_like(tensor, dtype=torch.bool) if commanded is None else commanded.expand_as(tensor)
        return tensor, mask

    def _write_ctrl(self) -> None:
        self._entity.set_joint_targets(self._q_target, self._qd_target, self._tau_ff)

    def get_applied_action(self) -> ArticulationAction:
        """The targets in effect: positions and velocities as commanded, efforts after clipping
        to each drive's effort limit (``Entity.joint_effort_limits``)."""
        out = self._world._out
        return ArticulationAction(joint_positions=out(self._q_target), joint_velocities=out(self._qd_target),
                                  joint_efforts=out(self._tau_ff))

    # -- gains and modes ------------------------------------------------------------
    def set_gains(self, kps=None, kds=None, joint_indices=None) -> None:
        """Drive stiffness kp (N*m/rad) and damping kd (N*m*s/rad), per joint (and per world)."""
        art = self._require()
        idx = art._indices(joint_indices)
        if kps is not None:
            kp = self._as_targets(kps, len(idx), "kps")
            if (kp < 0).any():
                raise InvalidValueError("kps", kps, "stiffness must be >= 0", "pass N m/rad >= 0 (0: no position hold)")
            self._kp[:, idx] = kp
        if kds is not None:
            kd = self._as_targets(kds, len(idx), "kds")
            if (kd < 0).any():
                raise InvalidValueError("kds", kds, "damping must be >= 0", "pass N m s/rad >= 0")
            self._kd[:, idx] = kd
        self._apply_gains(idx)

    def get_gains(self):
        """(kps, kds) in effect, (N, dof) or (dof,)."""
        self._require()
        data = self._entity.data
        return self._world._out(data.joint_stiffness), self._world._out(data.joint_damping)

    def switch_control_mode(self, mode: str, joint_indices=None) -> None:
        """Make joints position-, velocity- or effort-controlled (Isaac's control modes)."""
        if mode not in _MODES:
            raise InvalidValueError("control mode", mode, "not a control mode", f"use one of {_MODES}")
        idx = self._require()._indices(joint_indices)
        for i in idx.tolist():
            self._modes[i] = mode
        self._apply_gains(idx)

    def switch_dof_control_mode(self, dof_index: int, mode: str) -> None:
        self.switch_control_mode(mode, [dof_index])

    def get_control_modes(self) -> list[str]:
        return list(self._modes)

    def _apply_gains(self, idx: torch.Tensor) -> None:
        modes = [self._modes[i] for i in idx.tolist()]
        dev = self._entity.device
        keep_kp = torch.tensor([m == "position" for m in modes], device=dev)
        keep_kd = torch.tensor([m != "effort" for m in modes], device=dev)
        self._entity.write_gains(kp=self._kp[:, idx] * keep_kp, kd=self._kd[:, idx] * keep_kd, joint_ids=idx)
        self._write_ctrl()

    def _require(self) -> Articulation:
        if self._art is None:
            raise RuntimeError("the articulation is not initialized: add it to world.scene and call world.reset()")
        return self._art
