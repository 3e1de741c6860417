"""Per-world drive gains and motor strength reach MuJoCo's model and the torques it computes."""

import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.core import randomize

N = 4


@pytest.fixture(scope="module")
def env():
    return envs.make("humanoid-walk", num_envs=N, seed=0, num_threads=1)


def test_randomized_gains_reach_each_worlds_model_and_torques(env):
    robot, engine = env.robot, env.engine
    acts = randomize.entity_actuator_ids(robot)
    kp0 = -engine.model.actuator_biasprm[acts, 1].copy()
    kd0 = -engine.model.actuator_biasprm[acts, 2].copy()
    range0 = engine.model.actuator_forcerange[acts].copy()
    factors = randomize.drive_gains(robot, torch.Generator().manual_seed(1), kp_scale=randomize.uniform(0.8, 1.2),
                                    kd_scale=randomize.uniform(0.8, 1.2), strength=randomize.uniform(0.9, 1.1))
    kp = kp0 * (factors["kp_scale"] * factors["strength"]).numpy()
    kd = kd0 * (factors["kd_scale"] * factors["strength"]).numpy()
    assert kp.shape == (N, robot.num_joints) and np.ptp(kp[:, 0]) > 0  # each world its own
    for w in range(N):
        model = engine.get_model(w)
        np.testing.assert_allclose(-model.actuator_biasprm[acts, 1], kp[w], rtol=1e-12)
        np.testing.assert_allclose(-model.actuator_biasprm[acts, 2], kd[w], rtol=1e-12)
        np.testing.assert_allclose(model.actuator_forcerange[acts], range0 * factors["strength"][w].numpy()[:, None],
                                   rtol=1e-12)
    # the physics: joints 0.01 rad past their targets, at rest, push back with each world's kp
    engine.reset()
    offset = 0.01
    robot.write_joint_state(pos=robot.default_joint_pos.expand(N, -1) + offset,
                            vel=torch.zeros(N, robot.num_joints, dtype=engine.dtype))
    robot.set_joint_targets(robot.default_joint_pos.expand(N, -1))
    engine.forward()
    force = engine.field("actuator_force")[:, acts].numpy()
    np.testing.assert_allclose(force, -kp * offset, rtol=1e-9)


def test_drawing_again_does_not_compound(env):
    acts = randomize.entity_actuator_ids(env.robot)
    kp0 = -env.engine.model.actuator_biasprm[acts, 1]
    for _ in range(3):
        f = randomize.drive_gains(env.robot, torch.Generator().manual_seed(2), kp_scale=randomize.uniform(1.1, 1.2))
    np.testing.assert_allclose(-env.engine.model_field("actuator_biasprm")[:, acts, 1].numpy(),
                               kp0 * f["kp_scale"].numpy(), rtol=1e-12)


def test_nominal_world_scales_gains_written_after_compiling(env):
    """g1-walk writes its URDF gains per world after compiling: the factors apply to those."""
    robot, engine = env.robot, env.engine
    acts = randomize.entity_actuator_ids(robot)
    kp0 = -torch.as_tensor(engine.model.actuator_biasprm[acts, 1])
    robot.write_gains(kp=(3.0 * kp0).expand(N, -1))
    f = randomize.drive_gains(robot, torch.Generator().manual_seed(3), kp_scale=randomize.uniform(0.8, 1.2),
                              nominal_world=0)
    np.testing.assert_allclose(-engine.model_field("actuator_biasprm")[:, acts, 1].numpy(),
                               3.0 * kp0.numpy() * f["kp_scale"].numpy(), rtol=1e-12)
