"""The observation of velocity-tracking locomotion policies, built in one place.

The humanoid-walk task (``envs.humanoid_walk``, and g1-walk through it) trains on these terms,
and ``policies.walking.WalkingPolicy`` rebuilds them to run the shipped policy; both call
``velocity_policy_terms``, so a change to the task's observation cannot silently leave the
runner feeding the shipped network something else. (Here, in the content layer below both: the
runner may not import the task layer.) The runner also checks the policy's ``contract.json``
lists ``VELOCITY_POLICY_TERMS`` in this order.
"""

from __future__ import annotations

import torch

from ..core.entity import EntityData

VELOCITY_POLICY_TERMS = ("projected_gravity", "velocity_commands", "joint_pos_rel", "joint_vel", "base_ang_vel",
                         "actions")
"""Names of the terms, in the order the policy sees them concatenated."""


def velocity_policy_terms(data: EntityData, command: torch.Tensor, last_action: torch.Tensor, *,
                          command_scale: torch.Tensor, joint_vel_scale: float, ang_vel_scale: float,
                          default_joint_pos: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """The policy's observation terms by name, in ``VELOCITY_POLICY_TERMS`` order, each (N, k):

    - ``projected_gravity`` (3): unit gravity direction in the base frame;
    - ``velocity_commands`` (3): ``command`` (N, 3) (vx, vy m/s in the heading frame, yaw rate
      rad/s) times ``command_scale`` (3,);
    - ``joint_pos_rel`` (J): joint positions minus ``default_joint_pos`` (J,) rad (None: the
      entity's own default pose);
    - ``joint_vel`` (J): joint velocities rad/s times ``joint_vel_scale``;
    - ``base_ang_vel`` (3): base angular velocity in the base frame rad/s times ``ang_vel_scale``;
    - ``actions`` (A): ``last_action``, the previous policy output (zeros at start).

    Terms keep their inputs' dtype and device; callers concatenate them as float32.
    """
    joint_pos_rel = data.joint_pos_rel if default_joint_pos is None else data.joint_pos - default_joint_pos
    return {
        "projected_gravity": data.projected_gravity_b,
        "velocity_commands": command * command_scale,
        "joint_pos_rel": joint_pos_rel,
        "joint_vel": data.joint_vel * joint_vel_scale,
        "base_ang_vel": data.root_ang_vel_b * ang_vel_scale,
        "actions": last_action,
    }


__all__ = ["VELOCITY_POLICY_TERMS", "velocity_policy_terms"]
