"""ArticulationController: joint targets -> drive controls, with gains and control modes.

A drive's ctrl is ``kp * q_target + kd * qd_target + tau_ff`` (see ``drives.py``),
so position, velocity and effort commands combine in one implicit PD per joint.
Control modes set the gains an Isaac user expects: "position" uses (kp, kd),
"velocity" (0, kd), "effort" (0, 0).

Units: position and velocity targets of prismatic joints are in stage units
(``World.stage_units_in_meters``), of revolute joints rad and rad/s; efforts, gains and max
efforts stay SI (N m or N; N m/rad; N m s/rad).

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
    """The implicit PD drives of one articulation (Isaac's ``ArticulationController``)."""

    def __init__(self):
        self._art: Articulation | None = None

    def initialize(self, articulation_view=None) -> None:
        """Bind to an articulation (an ``Articulation`` or a one-prim ``ArticulationView``); the
        articulation binds its own controller at ``world.reset()``, so scripts rarely call this."""
        target = articulation_view
        if target is not None and hasattr(target, "_prims"):  # a view: its one articulation
            if len(target._prims) != 1:
                raise ValueError(f"an ArticulationController drives one articulation; the view has "
                                 f"{len(target._prims)}: use view.apply_action instead")
            target = target._prims[0]
        if target is None:
            target = self._require()
        if target.entity is None:
            target._controller = self  # bound when the articulation initializes
            return
        target._controller = self
        self._initialize(target, target._world)

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
        """Set the targets given in ``control_actions`` (others keep theirs) for the next steps."""
        art = self._require()
        if not isinstance(control_actions, ArticulationAction):
            raise TypeError(f"apply_action takes an ArticulationAction, got {type(control_actions).__name__}; "
                            "wrap the arrays: ArticulationAction(joint_positions=...)")
        idx = art._indices(control_actions.joint_indices)
        scale = art._dof_scale[idx]
        commands = {}
        for value, key, what, factor in (
            (control_actions.joint_positions, "positions", "joint_positions", scale),
            (control_actions.joint_velocities, "velocities", "joint_velocities", scale),
            (control_actions.joint_efforts, "efforts", "joint_efforts", 1.0),
        ):
            if value is not None:
                given, commanded = self._as_targets(value, len(idx), what, allow_none=True)
                commands[key] = (given * factor, commanded)
        self._command(joint_idx=idx, masked=commands)

    def _command(self, joint_idx: torch.Tensor, positions=None, velocities=None, efforts=None,
                 env_ids: torch.Tensor | None = None, masked: dict | None = None) -> None:
        """Write (n, J) SI targets (rad or m, rad/s or m/s, N m or N) of joints ``joint_idx`` for
        worlds ``env_ids`` (None: all N); ``masked`` maps the same keys to (values, mask) pairs
        where only masked entries change. Efforts are clipped to the drives' effort limits."""
        self._require()
        masked = dict(masked or {})
        for key, value in (("positions", positions), ("velocities", velocities), ("efforts", efforts)):
            if value is not None:
                masked[key] = (value, None)
        where = (slice(None), joint_idx) if env_ids is None else (env_ids.unsqueeze(1), joint_idx.unsqueeze(0))
        for key, (value, mask) in masked.items():
            target = {"positions": self._q_target, "velocities": self._qd_target, "efforts": self._tau_ff}[key]
            if key == "efforts":  # Isaac clips commanded efforts to the drive's max effort
                limits = self._entity.joint_effort_limits[joint_idx]
                value = torch.clamp(value, limits[:, 0], limits[:, 1])
            target[where] = value if mask is None else torch.where(mask, value, target[where])
        self._write_ctrl()

    def _as_targets(self, value, count: int, what: str, allow_none: bool = False):
        """``value`` as an (N, count) tensor in the engine's dtype; with ``allow_none`` also the mask of
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
        tensor = torch.as_tensor(source, dtype=self._entity.engine.dtype, device=self._entity.device)
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
        art, out = self._require(), self._world._out
        scale = art._dof_scale
        return ArticulationAction(joint_positions=out(self._q_target / scale),
                                  joint_velocities=out(self._qd_target / scale), joint_efforts=out(self._tau_ff))

    # -- limits ---------------------------------------------------------------------
    def get_joint_limits(self):
        """(num_dof, 2) lower/upper position limits (rad; prismatic stage units); +-inf if none."""
        return self._require().get_dof_limits()

    def get_max_efforts(self):
        """(num_dof,) largest effort each drive exerts, N m (prismatic N); inf where unlimited."""
        self._require()
        limits = self._entity.joint_effort_limits
        value = torch.maximum(limits[:, 1], -limits[:, 0])
        return value.cpu().numpy() if self._world.backend == "numpy" else value.clone()

    def set_max_efforts(self, values, joint_indices=None) -> None:
        """Cap the drives of ``joint_indices`` (default all) at +-``values`` N m (prismatic N)."""
        art = self._require()
        idx = art._indices(joint_indices)
        value = torch.as_tensor(np.broadcast_to(np.asarray(values, dtype=np.float64), (len(idx),)).copy(),
                                dtype=self._entity.engine.dtype, device=self._entity.device)
        check_all_finite("max efforts", value, "pass finite N m > 0, one per joint (or one for all)")
        if (value <= 0).any():
            raise InvalidValueError("max efforts", values, "they must be > 0", "pass N m > 0, e.g. 10.0")
        act = self._entity._act_idx_t[idx]
        engine = self._entity.engine
        engine.model_field("actuator_forcelimited")[:, act] = 1
        engine.model_field("actuator_forcerange")[:, act] = torch.stack([-value, value], -1)
        self._entity.joint_effort_limits[idx] = torch.stack([-value, value], -1)
        self._tau_ff[:, idx] = self._tau_ff[:, idx].clamp(-value, value)
        self._write_ctrl()

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
