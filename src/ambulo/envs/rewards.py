"""Reward terms shared by tasks: plain functions of state tensors returning (N,) values.

Each term is unweighted; a task's config holds the weights, and the env sums
``weight * term * step_dt_s`` so that weights are per second of simulated time and do not
change meaning with the control rate (the legged_gym / Isaac Lab convention). Kernel in the
name: ``_exp`` is exp(-error^2 / std^2) in (0, 1], ``_l2`` a sum of squares, ``_l1`` of
absolute values.
"""

from __future__ import annotations

import torch


def track_lin_vel_xy_exp(command_xy: torch.Tensor, lin_vel_xy: torch.Tensor,
                         std: float) -> torch.Tensor:
    """exp(-|v_cmd - v|^2 / std^2) for planar velocities (N, 2) in one frame, m/s."""
    error_sq = torch.sum(torch.square(command_xy - lin_vel_xy), dim=-1)
    return torch.exp(-error_sq / std**2)


def track_ang_vel_z_exp(command_z: torch.Tensor, ang_vel_z: torch.Tensor,
                        std: float) -> torch.Tensor:
    """exp(-(w_cmd - w)^2 / std^2) for yaw rates (N,), rad/s."""
    return torch.exp(-torch.square(command_z - ang_vel_z) / std**2)


def upright(projected_gravity_b: torch.Tensor) -> torch.Tensor:
    """cos(tilt) of the base from vertical, (N,): 1 upright, 0 lying, -1 upside down."""
    return -projected_gravity_b[..., 2]


def torques_l2(torque: torch.Tensor) -> torch.Tensor:
    """Sum of squared actuator torques, (N, nu) N m -> (N,) N^2 m^2."""
    return torch.sum(torch.square(torque), dim=-1)


def action_rate_l2(action: torch.Tensor, prev_action: torch.Tensor) -> torch.Tensor:
    """Sum of squared changes of the policy action between two policy steps, (N,)."""
    return torch.sum(torch.square(action - prev_action), dim=-1)


def l2(value: torch.Tensor) -> torch.Tensor:
    """Sum of squares over the last dimension, (N, K) -> (N,)."""
    return torch.sum(torch.square(value), dim=-1)


def joint_pos_limits(joint_pos: torch.Tensor, soft_lower: torch.Tensor,
                     soft_upper: torch.Tensor) -> torch.Tensor:
    """Total violation of soft joint limits, (N, J) rad -> (N,) rad (0 inside the limits)."""
    below = torch.clamp(soft_lower - joint_pos, min=0.0)
    above = torch.clamp(joint_pos - soft_upper, min=0.0)
    return torch.sum(below + above, dim=-1)


def feet_air_time(air_time_s: torch.Tensor, first_contact: torch.Tensor, threshold_s: float,
                  command_xy: torch.Tensor, min_command: float = 0.1) -> torch.Tensor:
    """Reward steps that lift a foot longer than ``threshold_s`` (legged_gym's air time term).

    At the policy step a foot touches down (``first_contact``, (N, F) bool) it adds
    ``air_time_s - threshold_s`` (its last flight duration minus the threshold), so short
    shuffles are penalised and long strides rewarded. Zero while the planar command is
    below ``min_command`` m/s, so a standing robot is not pushed to step.
    """
    reward = torch.sum((air_time_s - threshold_s) * first_contact, dim=-1)
    moving = torch.linalg.vector_norm(command_xy, dim=-1) > min_command
    return reward * moving


def feet_air_time_single_stance(air_time_s: torch.Tensor, contact_time_s: torch.Tensor, in_contact: torch.Tensor,
                                threshold_s: float, command_xy: torch.Tensor, min_command: float = 0.1) -> torch.Tensor:
    """Reward time spent on one foot, every step, up to ``threshold_s`` (Isaac Lab's biped air time term).

    While exactly one foot of (N, 2) ``in_contact`` touches the ground, the reward is the time, s,
    both feet have been in their current mode (``contact_time_s`` for the stance foot,
    ``air_time_s`` for the swing foot; the smaller of the two), capped at ``threshold_s``; zero
    in double support, in flight and while the planar command is below ``min_command`` m/s.
    Never negative: unlike ``feet_air_time``, whose touchdowns add ``air_time - threshold`` and so
    penalise the short steps of a slow walk (a robot told to walk at 0.25 m/s earns more by
    standing, which touches down never), quick steps here earn less, not below zero.
    """
    mode_time = torch.where(in_contact, contact_time_s, air_time_s)
    single_stance = in_contact.sum(dim=-1) == 1
    reward = torch.where(single_stance, mode_time.min(dim=-1).values, 0.0).clamp(max=threshold_s)
    moving = torch.linalg.vector_norm(command_xy, dim=-1) > min_command
    return reward * moving


def feet_slide(foot_vel_w: torch.Tensor, in_contact: torch.Tensor) -> torch.Tensor:
    """Planar speed of feet that touch the ground, summed: (N, F, 3) m/s, (N, F) bool -> (N,) m/s."""
    speed = torch.linalg.vector_norm(foot_vel_w[..., :2], dim=-1)
    return torch.sum(speed * in_contact, dim=-1)


def joint_deviation_l1(joint_pos_rel: torch.Tensor) -> torch.Tensor:
    """Sum of |q - q_default| over the given joints, (N, K) rad -> (N,) rad."""
    return torch.sum(torch.abs(joint_pos_rel), dim=-1)


def flat_orientation_l2(projected_gravity_b: torch.Tensor) -> torch.Tensor:
    """gx^2 + gy^2 of gravity in the base frame, (N, 3) -> (N,): 0 level, sin^2(tilt)."""
    return torch.sum(torch.square(projected_gravity_b[..., :2]), dim=-1)


__all__ = [
    "feet_air_time_single_stance",
    "action_rate_l2",
    "feet_slide",
    "flat_orientation_l2",
    "joint_deviation_l1",
    "feet_air_time",
    "joint_pos_limits",
    "l2",
    "torques_l2",
    "track_ang_vel_z_exp",
    "track_lin_vel_xy_exp",
    "upright",
]
