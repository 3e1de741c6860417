"""WalkingPolicy: a shipped velocity-tracking policy driving a robot's ``Entity``.

The pattern of Isaac Sim's policy examples (``H1FlatTerrainPolicy``): build it on the robot's
entity, call ``reset()`` to stand the robot in the policy's default pose, then call
``forward(step_size, command)`` every physics step. Every ``control_dt_s / physics_dt`` calls it
builds the observation the policy was trained on (``contract.json``: projected gravity, scaled
command, joint positions relative to the default pose, scaled joint and base angular velocities,
the last action) with the humanoid-walk task's own function
(``policies.velocity_obs.velocity_policy_terms``) and sets the joint position targets
``default + action_scale * action``; the robot's own PD drives track them.

It works on ``core.Entity`` alone, so anything that holds one (an RL task's robot, a
``core.Simulation``, the Isaac-style ``sim.Robot`` through ``sim.HumanoidWalkingPolicy``) can run
the shipped network. Every fact of the policy (joint order, default pose, scales, command ranges,
physics and control periods) is read from its ``contract.json``.

``command`` is ``(vx, vy, yaw_rate)``: m/s forward and leftward in the robot's heading frame,
rad/s about world z, for every world (shape (3,)) or each (N, 3). Commands outside the ranges
the policy was trained on are clipped to them, with one warning.
"""

from __future__ import annotations

import warnings

import torch

from ..core.entity import Entity
from ..robots.humanoid import POLICY_TASK
from .shipped import ShippedPolicy, contract_terms, load_policy
from .velocity_obs import VELOCITY_POLICY_TERMS, velocity_policy_terms

_COMMAND_RANGES = ("lin_vel_x_m_s", "lin_vel_y_m_s", "yaw_rate_rad_s")
"""The contract's ``command_ranges`` keys, in ``command`` order."""


class WalkingPolicy:
    """Velocity commands in, joint targets out, on an ``Entity`` (see the module doc).

    Args:
      entity: the robot to drive; None to bind one later with ``bind`` (the Isaac-style runner
        has no entity before ``world.reset()``). Its joints must be the contract's, in order.
      task: the shipped policy's task, when ``policy`` is not given.
      policy: a loaded ``ShippedPolicy``; its contract must list ``VELOCITY_POLICY_TERMS``.
    """

    TERMS = VELOCITY_POLICY_TERMS
    """The observation terms this runner builds, in order (the contract must list them)."""
    SOURCE_TASK = "humanoid-walk"
    """The task whose runs export a policy with ``TERMS`` (named in the error when they differ)."""

    def __init__(self, entity: Entity | None = None, task: str = POLICY_TASK, policy: ShippedPolicy | None = None):
        self.policy = policy or load_policy(task)
        self.contract = self.policy.contract
        by_name = contract_terms(self.policy, self.TERMS, type(self).__name__, self.SOURCE_TASK)
        self._joint_vel_scale = float(by_name["joint_vel"]["scale"])
        self._ang_vel_scale = float(by_name["base_ang_vel"]["scale"])
        self._read_command_terms(by_name)
        self._decimation: int | None = None
        self._count = 0
        self._warned = False
        self.entity: Entity | None = None
        if entity is not None:
            self.bind(entity)

    def _read_command_terms(self, by_name: dict[str, dict]) -> None:
        """The command's scale and trained ranges from the contract's terms (``by_name``) and ranges."""
        self._cmd_scale = torch.tensor(by_name["velocity_commands"]["scale"], dtype=torch.float32)
        ranges = self.contract["command_ranges"]
        self._cmd_low = torch.tensor([ranges[k][0] for k in _COMMAND_RANGES])
        self._cmd_high = torch.tensor([ranges[k][1] for k in _COMMAND_RANGES])

    def bind(self, entity: Entity) -> None:
        """Drive ``entity`` (checked to have the contract's joints, in order) from now on."""
        expected = self.contract["joint_names"]
        if list(entity.joint_names) != expected:
            raise ValueError(f"the {self.policy.task} policy drives joints {expected}; "
                             f"{entity.prim_path} has {list(entity.joint_names)}: load the bundled "
                             "humanoid (assets.path('humanoid'))")
        self.entity = entity
        self.device = entity.device
        self.default_joint_pos = torch.tensor(self.contract["default_joint_pos"], dtype=entity.engine.dtype,
                                              device=entity.device)
        """(J,) rad, the contract's default pose in the engine's dtype and device."""
        self.actions = torch.zeros(entity.num_worlds, self.policy.num_actions, dtype=torch.float32)
        """(N, A) float32 on the CPU: the last policy output (the observation's ``actions`` term)."""

    def reset(self) -> None:
        """Stand the robot in the policy's default pose at its default height, in every world."""
        entity = self._bound()
        n, dt, dev = entity.num_worlds, entity.engine.dtype, entity.device
        root = entity.data.root_pos_w.clone()
        root[:, 2] = self.contract["default_root_height_m"]
        entity.write_root_pose(pos_w=root)
        entity.write_joint_state(pos=self.default_joint_pos.expand(n, -1),
                                 vel=torch.zeros(n, entity.num_joints, dtype=dt, device=dev))
        entity.set_joint_targets(self.default_joint_pos.expand(n, -1))
        entity.engine.forward()
        self.actions.zero_()
        self._count = 0

    def _bound(self) -> Entity:
        if self.entity is None:
            raise RuntimeError(f"{type(self).__name__} has no robot yet: give it an Entity (bind(entity))")
        return self.entity

    def _period(self, step_size: float) -> int:
        """Physics steps per policy step; refuses a physics step other than the contract's."""
        if self._decimation is None:
            ratio = self.contract["control_dt_s"] / step_size
            if abs(ratio - round(ratio)) > 1e-6 or abs(step_size - self.contract["physics_dt_s"]) > 1e-9:
                raise ValueError(f"the {self.policy.task} policy was trained with physics_dt "
                                 f"{self.contract['physics_dt_s']} s and control every "
                                 f"{self.contract['control_dt_s']} s; this world steps {step_size} s: "
                                 f"create the World with physics_dt={self.contract['physics_dt_s']}")
            self._decimation = int(round(ratio))
        return self._decimation

    def command_tensor(self, command) -> torch.Tensor:
        """(N, 3) float32 command clipped to the trained ranges (one warning when clipped)."""
        n = self.actions.shape[0]
        cmd = torch.as_tensor(command, dtype=torch.float32).reshape(-1, 3).expand(n, 3)
        if not torch.isfinite(cmd).all():
            raise ValueError(f"walking command {command!r} is not finite; give (vx, vy, yaw_rate) numbers")
        clipped = torch.minimum(torch.maximum(cmd, self._cmd_low), self._cmd_high)
        if not self._warned and not torch.equal(clipped, cmd):
            warnings.warn(f"walking command {cmd[0].tolist()} is outside the trained ranges "
                          f"{self.contract['command_ranges']}; clipped", stacklevel=3)
            self._warned = True
        return clipped

    def observation(self, command) -> torch.Tensor:
        """(N, num_obs) float32 observations on the CPU, in the contract's order."""
        terms = velocity_policy_terms(self._bound().data, self.command_tensor(command), self.actions,
                                      command_scale=self._cmd_scale, joint_vel_scale=self._joint_vel_scale,
                                      ang_vel_scale=self._ang_vel_scale, default_joint_pos=self.default_joint_pos)
        return torch.cat([t.float().cpu() for t in terms.values()], dim=1)

    def joint_targets(self) -> torch.Tensor:
        """(N, J) position targets of the last action, rad, on the entity's device."""
        return (self.default_joint_pos + self.contract["action_scale"] * self.actions.to(self.default_joint_pos)).to(
            self.device)

    def forward(self, step_size: float, command) -> None:
        """Call every physics step (``step_size`` s): runs the policy every control period."""
        if self._count % self._period(step_size) == 0:
            self.actions = self.policy(self.observation(command))
            self._bound().set_joint_targets(self.joint_targets())
        self._count += 1

    @property
    def heading_rad(self) -> float:
        """Yaw of world 0's base, rad."""
        return float(self._bound().data.heading_w[0])


__all__ = ["WalkingPolicy"]
