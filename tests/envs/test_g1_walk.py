"""g1-walk: the Unitree G1 URDF with drive gains derived from its limits and inertias."""

import math

import pytest
import torch

from ambulo import envs

pytest.importorskip("cmeel")  # the robots extra (example-robot-data) brings the G1 URDF


@pytest.fixture(scope="module")
def env():
    return envs.make("g1-walk", num_envs=4, device="cpu", seed=0)


def test_gains_follow_the_urdf_limits(env):
    """kp = effort / 0.5 rad; kd = min(2 * 0.7 * sqrt(kp I), effort / velocity), from the URDF's
    <limit effort velocity> (hand-copied here) and the joint's reflected inertia."""
    gains = dict(zip(env.robot.joint_names, zip(*env.drive_gains.values())))
    kp, kd, inertia = gains["left_knee_joint"]  # <limit effort="139" velocity="20"/>
    assert kp == pytest.approx(278.0)
    assert kd == pytest.approx(min(1.4 * math.sqrt(278.0 * inertia), 139.0 / 20.0))
    kp, kd, _ = gains["left_hip_pitch_joint"]  # effort 88, velocity 32: the velocity cap binds
    assert (kp, kd) == (pytest.approx(176.0), pytest.approx(2.75))
    kp, kd, inertia = gains["left_ankle_roll_joint"]  # effort 35, velocity 30: critical-ish damping
    assert kp == pytest.approx(70.0) and kd == pytest.approx(1.4 * math.sqrt(70.0 * inertia))
    # the drives carry those gains in every world: tau = -kp q - kd qd in the actuator bias
    bias = env.engine.model_field("actuator_biasprm")
    knee = env.robot._act_idx_t[env.robot.find_joints("left_knee_joint")[0]]
    assert torch.allclose(bias[:, knee, 1].double(), torch.full((4,), -278.0, dtype=torch.float64))


def test_only_the_feet_touch_the_ground(env):
    model = env.engine.model
    touching = [model.geom(g).name or model.body(model.geom_bodyid[g]).name
                for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    bodies = {model.body(model.geom_bodyid[g]).name for g in range(model.ngeom)
              if (model.geom_contype[g] or model.geom_conaffinity[g])
              and model.body(model.geom_bodyid[g]).name.startswith("/World/robot/")}
    assert bodies == {"/World/robot/left_ankle_roll_link", "/World/robot/right_ankle_roll_link"}
    assert len(touching) == 9  # 4 spheres per sole and the ground


def test_g1_steps_and_its_observations_have_the_task_layout(env):
    obs = env.reset()
    assert obs.shape == (4, 3 + 3 + 29 * 3 + 3) and env.num_actions == 29
    for _ in range(10):
        obs, rewards, dones, _ = env.step(torch.zeros(4, 29))
    assert torch.isfinite(obs).all() and torch.isfinite(rewards).all()
    assert (env.robot.data.root_pos_w[:, 2] > 0.6).all()  # the default pose stands for 0.2 s
