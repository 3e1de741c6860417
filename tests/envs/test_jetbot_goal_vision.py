"""jetbot-goal-vision: the policy's image shows the goal where it is (warp engine, Warp's CPU device)."""

import math

import pytest
import torch

import ambulo.envs as envs
from ambulo.utils.math import yaw_from_quat

pytest.importorskip("mujoco_warp")

NUM_ENVS = 2


def place_goal_b(env, offset_b):
    """Put every env's goal at ``offset_b`` (x forward, y left, m) in its robot's base frame."""
    yaw = yaw_from_quat(env.robot.data.root_quat_w.float())
    cos, sin = torch.cos(yaw), torch.sin(yaw)
    x, y = offset_b
    base = env.robot.data.root_pos_w.float()
    env.goal_pos_w[:, 0] = base[:, 0] + cos * x - sin * y
    env.goal_pos_w[:, 1] = base[:, 1] + sin * x + cos * y
    env.engine.mocap_pos[:, 0] = env.goal_pos_w.to(env.engine.mocap_pos.dtype)


def redness(image_obs, env):
    """(N,) mean of red minus the other channels over the pooled image."""
    side = env.cfg.image_size_px // env.cfg.image_pool_px
    rgb = image_obs.reshape(-1, 3, side, side)
    return (rgb[:, 0] - (rgb[:, 1] + rgb[:, 2]) / 2).mean(dim=(1, 2))


def test_the_image_observation_shows_the_goal_ahead_and_not_behind():
    env = envs.make("jetbot-goal-vision", num_envs=NUM_ENVS, seed=0)
    side = env.cfg.image_size_px // env.cfg.image_pool_px
    num_image = 3 * side * side
    assert env.engine.device.type == "cpu" and hasattr(env.engine, "wp_model")
    assert env.num_obs == num_image + 6  # image, forward velocity, yaw rate, wheel speeds (2), actions (2)
    assert env.num_privileged_obs == env.num_obs + 3  # the critic adds the goal (x, y) and distance
    zero = torch.zeros(NUM_ENVS, env.num_actions)
    seen = {}
    for where, offset_b in {"ahead": (0.6, 0.0), "left": (0.6, 0.3), "behind": (-0.6, 0.0)}.items():
        place_goal_b(env, offset_b)
        obs, _, dones, _ = env.step(zero)
        assert not dones.any() and torch.isfinite(obs).all()
        seen[where] = obs[:, :num_image].clone()
    red = {where: redness(image, env) for where, image in seen.items()}
    assert (red["ahead"] > red["behind"] + 0.01).all(), red
    assert ((seen["ahead"] - seen["behind"]).abs().amax(dim=1) > 0.2).all()
    # a goal to the left shows in the left half of the image
    diff = (seen["left"] - seen["behind"]).reshape(NUM_ENVS, 3, side, side).abs().sum(dim=1)
    assert (diff[:, :, : side // 2].sum(dim=(1, 2)) > diff[:, :, side // 2:].sum(dim=(1, 2))).all()
    # the critic still gets the goal position in the base frame
    critic = env.get_privileged_observations()
    assert torch.allclose(critic[:, -3:-1], torch.tensor([-0.6, 0.0]).expand(NUM_ENVS, 2), atol=0.05)
    assert math.isclose(float(critic[0, -1]), 0.6, abs_tol=0.05)
