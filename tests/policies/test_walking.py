"""The walking policy that ships with ambulo drives the bundled humanoid on the CPU, no training."""

import json
import math

import numpy as np
import pytest
import torch

from ambulo import assets
from ambulo.policies.shipped import load_policy, policy_dir
from ambulo.rl.export import _run_torchscript_in_fresh_process
from ambulo.sim import HumanoidWalkingPolicy, Robot, World, add_reference_to_stage

pytest.importorskip("onnxruntime")


def humanoid_with_policy(physics_dt: float = 0.005, task: str = "humanoid-walk"):
    """A World with the bundled humanoid on a ground plane and ``task``'s shipped policy's runner."""
    world = World(physics_dt=physics_dt, rendering_dt=0.02)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid"), prim_path="/World/Humanoid")
    robot = world.scene.add(Robot(prim_path="/World/Humanoid", name="humanoid"))
    world.reset()
    walker = HumanoidWalkingPolicy(robot, task=task)
    walker.initialize()
    return world, robot, walker


def walk(command, seconds: float, physics_dt: float = 0.005, task: str = "humanoid-walk"):
    world, robot, walker = humanoid_with_policy(physics_dt, task)
    world.add_physics_callback("walk", lambda dt: walker.forward(dt, command))
    start = robot.get_world_pose()[0].copy()
    lowest = math.inf
    for _ in range(int(round(seconds / 0.02))):
        world.step(render=False)
        lowest = min(lowest, float(robot.get_world_pose()[0][2]))
    return robot.get_world_pose()[0] - start, walker.heading_rad, lowest


@pytest.mark.parametrize("task", ["humanoid-walk", "humanoid-walk-robust"])  # the same observations and joints
def test_forward_command_walks_forward_without_falling(task):
    moved, heading, lowest = walk((0.5, 0.0, 0.0), 4.0, task=task)
    # 0.5 m/s for 4 s less the first step or two: the shipped policy tracks within ~0.1 m/s
    assert 1.6 < moved[0] < 2.2
    assert abs(moved[1]) < 0.4 and abs(heading) < 0.3
    assert lowest > 0.8  # the pelvis stands at 0.9 m: no fall, no crouch-walk


def test_yaw_command_turns_in_place():
    moved, heading, lowest = walk((0.0, 0.0, 0.8), 3.0)
    assert 1.7 < heading < 2.9  # 0.8 rad/s for 3 s = 2.4 rad
    assert np.linalg.norm(moved[:2]) < 0.5 and lowest > 0.8


def test_standing_command_stays_put():
    moved, heading, lowest = walk((0.0, 0.0, 0.0), 3.0)
    assert np.linalg.norm(moved[:2]) < 0.25 and abs(heading) < 0.2 and lowest > 0.8


def test_a_world_at_another_physics_rate_is_one_clear_error():
    with pytest.raises(ValueError, match="physics_dt=0.005"):
        walk((0.3, 0.0, 0.0), 0.1, physics_dt=1 / 60)


def test_out_of_range_commands_are_clipped_with_a_warning():
    with pytest.warns(UserWarning, match="outside the trained ranges"):
        moved, _, lowest = walk((3.0, 0.0, 0.0), 2.0)
    assert moved[0] < 2.4 and lowest > 0.8  # at most the trained 1 m/s


def test_contract_matches_the_exported_networks():
    """contract.json's sizes are the networks'; both exports give the same actions."""
    contract = json.loads((policy_dir("humanoid-walk") / "contract.json").read_text())
    assert sum(t["size"] for t in contract["observation_terms"]) == contract["num_obs"] == 72
    assert len(contract["joint_names"]) == len(contract["default_joint_pos"]) == contract["num_actions"] == 21
    assert contract["eval_cpu"]["walks"] is True and contract["trained"]["commit"]
    obs = torch.randn(5, 72, generator=torch.Generator().manual_seed(0))
    onnx_actions = load_policy("humanoid-walk")(obs)
    # TorchScript in a fresh process, as a deployment loads it (torch.jit.load aborts in a
    # process that imported mujoco.usd: see ambulo.rl.export)
    jit_actions = _run_torchscript_in_fresh_process(policy_dir("humanoid-walk") / "policy.pt", obs.numpy())
    assert np.allclose(onnx_actions.numpy(), jit_actions, atol=1e-4)


def test_runner_observation_is_the_training_envs_for_the_same_state():
    """HumanoidWalkingPolicy feeds the shipped network exactly what humanoid-walk trained it on:
    the env, stepped into an arbitrary state, and a World humanoid put into that state give the
    same 72 numbers (state, command and last action copied over)."""
    from ambulo import envs

    env = envs.make("humanoid-walk", play=True, num_envs=2, seed=3)
    gen = torch.Generator().manual_seed(0)
    for _ in range(6):  # off the default pose: joints and base moving, a non-zero last action
        env.step(0.5 * torch.randn(2, env.num_actions, generator=gen))
    env.commands.command[:] = torch.tensor([[0.4, -0.1, 0.3], [0.0, 0.2, -0.5]])
    expected = env._compute_observations()
    src = env.robot.data

    world, robot, walker = humanoid_with_policy()
    assert list(robot.entity.joint_names) == list(env.robot.joint_names)
    for row in range(2):
        entity = robot.entity
        entity.write_root_pose(pos_w=src.root_pos_w[row:row + 1], quat_w=src.root_quat_w[row:row + 1])
        entity.write_joint_state(pos=src.joint_pos[row:row + 1], vel=src.joint_vel[row:row + 1])
        entity.write_root_velocity(lin_vel_w=src.root_lin_vel_w[row:row + 1], ang_vel_w=src.root_ang_vel_w[row:row + 1])
        entity.engine.forward()
        walker.actions = env.actions[row:row + 1].cpu().clone()
        got = walker.observation(env.commands.command[row].cpu())
        assert got.shape == (1, walker.contract["num_obs"]) == (1, env.num_obs)
        torch.testing.assert_close(got, expected[row:row + 1].cpu(), atol=1e-6, rtol=1e-6)
    env.close()


def test_a_contract_with_other_observation_terms_is_refused():
    """The runner builds the task's observation terms; a policy exported with others (an older
    or changed env) is one clear error, not a robot fed the wrong numbers."""
    policy = load_policy("humanoid-walk")
    policy.contract = json.loads(json.dumps(policy.contract))
    terms = policy.contract["observation_terms"]
    terms[3], terms[4] = terms[4], terms[3]  # joint_vel and base_ang_vel swapped
    with pytest.raises(ValueError, match="observation terms"):
        HumanoidWalkingPolicy(robot=None, policy=policy)


def test_initialize_before_the_world_is_reset_says_so():
    """sim.HumanoidWalkingPolicy binds the robot's entity at initialize(); before world.reset() there
    is none, and the error says what to call first."""
    from types import SimpleNamespace

    walker = HumanoidWalkingPolicy(SimpleNamespace(entity=None))
    with pytest.raises(RuntimeError, match=r"world.reset\(\) before initialize\(\)"):
        walker.initialize()
