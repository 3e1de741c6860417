"""FootstepPolicy: the shipped humanoid-footsteps policy driving a robot's ``Entity``.

``WalkingPolicy``'s runner (bind, ``reset`` to the default pose, ``forward(step_size, command)``
every physics step, joint targets ``default + action_scale * action``) with the footstep
observation (``footstep_obs.footstep_policy_terms``) in place of the velocity one: ``command`` is
the (N, 10) or (10,) footstep command of ``HumanoidFootstepsEnv.footstep_command`` (the next two
footsteps in the base's heading frame). Which footsteps to give, and when to move on to the next,
is the caller's (``navigation.footstep_walker`` applies the task's own rules).
"""

from __future__ import annotations

import torch

from ..core.entity import Entity
from .footstep_obs import FOOTSTEP_COMMAND_SIZE, FOOTSTEP_POLICY_TERMS, footstep_policy_terms
from .shipped import ShippedPolicy
from .walking import WalkingPolicy

FOOTSTEP_TASK = "humanoid-footsteps"
"""The shipped footstep policy's task (flat ground)."""


class FootstepPolicy(WalkingPolicy):
    """Footstep commands in, joint targets out, on an ``Entity`` (see the module doc).

    Args:
      entity: the robot to drive, or None to ``bind`` one later.
      task: the shipped policy's task, when ``policy`` is not given.
      policy: a loaded ``ShippedPolicy``; its contract must list ``FOOTSTEP_POLICY_TERMS``.
    """

    TERMS = FOOTSTEP_POLICY_TERMS
    SOURCE_TASK = "humanoid-footsteps"

    def __init__(self, entity: Entity | None = None, task: str = FOOTSTEP_TASK, policy: ShippedPolicy | None = None):
        super().__init__(entity, task, policy)

    def _read_command_terms(self, by_name: dict[str, dict]) -> None:
        """The footsteps are fed unscaled and have no trained ranges (a footstep is a place)."""
        if float(by_name["footsteps"]["scale"]) != 1.0:
            raise ValueError(f"the {self.policy.task} policy scales its footsteps by {by_name['footsteps']['scale']}; "
                             "the humanoid-footsteps task feeds them unscaled")

    def command_tensor(self, command) -> torch.Tensor:
        """(N, 10) float32 footstep command (no ranges to clip to: a footstep is a place)."""
        n = self.actions.shape[0]
        cmd = torch.as_tensor(command, dtype=torch.float32).reshape(-1, FOOTSTEP_COMMAND_SIZE).expand(n, -1)
        if not torch.isfinite(cmd).all():
            raise ValueError(f"footstep command {command!r} is not finite")
        return cmd

    def observation(self, command) -> torch.Tensor:
        """(N, num_obs) float32 observations on the CPU, in the contract's order."""
        terms = footstep_policy_terms(self._bound().data, self.command_tensor(command), self.actions,
                                      joint_vel_scale=self._joint_vel_scale, ang_vel_scale=self._ang_vel_scale,
                                      default_joint_pos=self.default_joint_pos)
        return torch.cat([t.float().cpu() for t in terms.values()], dim=1)


__all__ = ["FOOTSTEP_TASK", "FootstepPolicy"]
