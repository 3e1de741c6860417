"""HumanoidWalkingPolicy: the shipped humanoid-walk policy driving a humanoid in a ``World``.

The pattern of Isaac Sim's policy examples (``H1FlatTerrainPolicy``): build it on the robot,
call ``initialize()`` after ``world.reset()`` to put the robot in the policy's default pose, then
call ``forward(step_size, command)`` from a physics callback every physics step. Every
``control_dt_s / physics_dt`` calls it builds the observation the policy was trained on
(``contract.json``: projected gravity, scaled command, joint positions relative to the default
pose, scaled joint and base angular velocities, the last action) with the humanoid-walk task's
own function (``core.observations.velocity_policy_terms``) and sets the joint position
targets ``default + action_scale * action``; the robot's own PD drives track them.

``command`` is ``(vx, vy, yaw_rate)``: m/s forward and leftward in the robot's heading frame,
rad/s about world z, for every world (shape (3,)) or each (N, 3). Commands outside the ranges
the policy was trained on are clipped to them, with one warning.
"""

from __future__ import annotations

import warnings

import torch

from ..assets.policies import ShippedPolicy, load_policy
from ..core.observations import VELOCITY_POLICY_TERMS, velocity_policy_terms


class HumanoidWalkingPolicy:
    """Velocity commands in, joint targets out, for the bundled humanoid (see the module doc)."""

    def __init__(self, robot, task: str = "humanoid-walk", policy: ShippedPolicy | None = None):
        self.robot = robot
        self.policy = policy or load_policy(task)
        c = self.policy.contract
        self.contract = c
        self._decimation: int | None = None
        self._count = 0
        self._warned = False
        terms = [t["name"] for t in c["observation_terms"]]
        if tuple(terms) != VELOCITY_POLICY_TERMS:
            raise ValueError(f"the {self.policy.task} policy's contract lists observation terms {terms}; "
                             f"HumanoidWalkingPolicy builds {list(VELOCITY_POLICY_TERMS)} (the humanoid-walk "
                             "task's): re-export the policy from a humanoid-walk run")
        names = {t["name"]: t for t in c["observation_terms"]}
        self._cmd_scale = torch.tensor(names["velocity_commands"]["scale"], dtype=torch.float32)
        self._joint_vel_scale = float(names["joint_vel"]["scale"])
        self._ang_vel_scale = float(names["base_ang_vel"]["scale"])
        ranges = c["command_ranges"]
        self._cmd_low = torch.tensor([ranges[k][0] for k in ("lin_vel_x_m_s", "lin_vel_y_m_s", "yaw_rate_rad_s")])
        self._cmd_high = torch.tensor([ranges[k][1] for k in ("lin_vel_x_m_s", "lin_vel_y_m_s", "yaw_rate_rad_s")])

    def initialize(self) -> None:
        """Check the robot is the one the policy drives and stand it in the default pose."""
        entity = self.robot.entity
        if entity is None:
            raise RuntimeError("HumanoidWalkingPolicy.initialize() needs the world reset first: call "
                               "world.reset() before initialize()")
        expected = self.contract["joint_names"]
        if list(entity.joint_names) != expected:
            raise ValueError(f"the {self.policy.task} policy drives joints {expected}; "
                             f"{self.robot.prim_path} has {list(entity.joint_names)}: load the bundled "
                             "humanoid (assets.path('humanoid'))")
        dev, dt = entity.device, entity.engine.dtype
        self.device = dev
        self.default_joint_pos = torch.tensor(self.contract["default_joint_pos"], dtype=dt, device=dev)
        n = entity.num_worlds
        self.actions = torch.zeros(n, self.policy.num_actions, dtype=torch.float32)
        root = entity.data.root_pos_w.clone()
        root[:, 2] = self.contract["default_root_height_m"]
        entity.write_root_pose(pos_w=root)
        entity.write_joint_state(pos=self.default_joint_pos.expand(n, -1),
                                 vel=torch.zeros(n, entity.num_joints, dtype=dt, device=dev))
        entity.set_joint_targets(self.default_joint_pos.expand(n, -1))
        entity.engine.forward()
        self._count = 0

    def _period(self, step_size: float) -> int:
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
        """(N, num_obs) float32 observations in the contract's order."""
        terms = velocity_policy_terms(self.robot.entity.data, self.command_tensor(command), self.actions,
                                      command_scale=self._cmd_scale, joint_vel_scale=self._joint_vel_scale,
                                      ang_vel_scale=self._ang_vel_scale, default_joint_pos=self.default_joint_pos)
        return torch.cat([t.float().cpu() for t in terms.values()], dim=1)

    def forward(self, step_size: float, command) -> None:
        """Call every physics step (``step_size`` s): runs the policy every control period."""
        if self._count % self._period(step_size) == 0:
            self.actions = self.policy(self.observation(command))
            targets = self.default_joint_pos + self.contract["action_scale"] * self.actions.to(
                self.default_joint_pos)
            self.robot.entity.set_joint_targets(targets.to(self.device))
        self._count += 1

    @property
    def heading_rad(self) -> float:
        """Yaw of world 0's base, rad."""
        return float(self.robot.entity.data.heading_w[0])


__all__ = ["HumanoidWalkingPolicy"]
