"""The observation of the footstep-following policy (humanoid-footsteps), for runners outside the task.

The humanoid-footsteps task (``envs.humanoid_footsteps``) builds humanoid-walk's terms
(``velocity_obs.velocity_policy_terms``) with its footstep command, unscaled, in place of the
velocity command: ``footstep_policy_terms`` does the same from the same function, so the two
cannot drift apart in anything but the command itself. The command (the next two footsteps in the
base's heading frame) is built by the task's own ``footstep_command``; a runner above the task layer
(``navigation.footstep_walker``) calls it, this layer may not import the task.
"""

from __future__ import annotations

import torch

from ..core.entity import EntityData
from .velocity_obs import velocity_policy_terms

FOOTSTEP_POLICY_TERMS = ("projected_gravity", "footsteps", "joint_pos_rel", "joint_vel", "base_ang_vel", "actions")
"""Names of the terms, in the order the policy sees them concatenated (its ``contract.json``)."""

FOOTSTEP_COMMAND_SIZE = 10
"""Per footstep (the swing foot's target, then the next): x, y m, cos and sin of its yaw relative
to the heading, side (+1 left, -1 right)."""


def footstep_policy_terms(data: EntityData, footsteps: torch.Tensor, last_action: torch.Tensor, *,
                          joint_vel_scale: float, ang_vel_scale: float,
                          default_joint_pos: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """The policy's observation terms by name, in ``FOOTSTEP_POLICY_TERMS`` order, each (N, k):
    ``velocity_policy_terms``' with ``footsteps`` (N, 10) (``HumanoidFootstepsEnv.footstep_command``'s
    layout, scale 1) where its ``velocity_commands`` were."""
    if footsteps.ndim != 2 or footsteps.shape[1] != FOOTSTEP_COMMAND_SIZE:
        raise ValueError(f"footsteps has shape {tuple(footsteps.shape)}; pass (N, {FOOTSTEP_COMMAND_SIZE}): "
                         "the next two footsteps in the heading frame (x, y, cos yaw, sin yaw, side each)")
    terms = velocity_policy_terms(data, footsteps, last_action, command_scale=torch.ones(()),
                                  joint_vel_scale=joint_vel_scale, ang_vel_scale=ang_vel_scale,
                                  default_joint_pos=default_joint_pos)
    return {("footsteps" if k == "velocity_commands" else k): v for k, v in terms.items()}


__all__ = ["FOOTSTEP_COMMAND_SIZE", "FOOTSTEP_POLICY_TERMS", "footstep_policy_terms"]
