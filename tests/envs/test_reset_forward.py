"""EnvCfg.reset_forward="kinematics" gives humanoid-walk the observations and the trajectory of
"full": a reset's observations read qpos/qvel, poses and body velocities, which the kinematics
pass computes, and the next physics step recomputes everything. The one documented difference:
the critic's ``feet_contact`` reads 0 on a world reset in that step (no contacts computed yet).

CPU engine: equal to the bit. MuJoCo Warp on Warp's CPU device: the same kernels on the same
state, within float32 noise (equal to the bit on this machine). The default ("full") is held bit-identical to the step before this
option by tests/envs/test_graph_step.py's EAGER_50_STEPS_SHA256.
"""

import importlib.util

import pytest
import torch

import ambulo.envs


def _feet_columns(env) -> slice:
    """The critic's ``feet_contact`` columns: the critic is the clean policy terms, then the
    privileged terms in order (``RLEnv._compute_observations``)."""
    start = env.num_obs
    for name, term in env._privileged_terms().items():
        if name == "feet_contact":
            return slice(start, start + term.shape[1])
        start += term.shape[1]
    raise AssertionError("no feet_contact term in the critic")


def _run(engine: str, mode: str, num_envs: int, steps: int, task: str = "humanoid-walk"):
    """``steps`` steps of random actions with frequent resets: 0.3 s episodes (15 steps), large
    actions (falls), and a random third of the envs reset by hand every 4th step, so resets come
    at different steps in different worlds. Returns per step what the test compares."""
    env = ambulo.envs.make(task, num_envs=num_envs, device="cpu", engine=engine, seed=3,
                           episode_length_s=0.3, reset_forward=mode)
    gen = torch.Generator().manual_seed(0)
    out, feet = [], _feet_columns(env)
    for i in range(steps):
        obs, rewards, dones, extras = env.step(torch.randn(num_envs, env.num_actions, generator=gen) * 2.0)
        reset = dones.clone()
        if i % 4 == 3:
            by_hand = torch.rand(num_envs, generator=gen) < 0.34
            obs = env.reset(by_hand).clone()
            reset |= by_hand
        critic = env.get_privileged_observations()
        data = env.robot.data
        out.append(dict(obs=obs.clone(), critic=critic.clone(), rewards=rewards.clone(), dones=dones.clone(),
                        reset=reset, feet=feet, body_pos_w=data.body_pos_w.clone(), body_lin_vel_w=data.body_lin_vel_w.clone()))
    return out


def _compare(full, kin, atol):
    resets = torch.stack([s["reset"] for s in full])
    assert resets.any(0).all() and not resets.all(1).all()  # every env reset, not all at once
    for step, (a, b) in enumerate(zip(full, kin)):
        assert torch.equal(a["dones"], b["dones"]), step
        assert torch.equal(a["reset"], b["reset"]), step
        for key in ("obs", "rewards", "body_pos_w", "body_lin_vel_w"):
            torch.testing.assert_close(b[key], a[key], atol=atol, rtol=0, msg=f"{key} at step {step}")
        feet = a["feet"]
        other = torch.ones(a["critic"].shape[1], dtype=torch.bool)
        other[feet] = False
        torch.testing.assert_close(b["critic"][:, other], a["critic"][:, other], atol=atol, rtol=0,
                                   msg=f"critic at step {step}")
        feet_full, feet_kin, reset = a["critic"][:, feet], b["critic"][:, feet], a["reset"]
        assert torch.equal(feet_kin[~reset], feet_full[~reset]), step
        assert not feet_kin[reset].any(), step  # documented: no contacts computed at a reset
    # the difference is real: some reset env stood on a foot under the full forward
    assert any(s["critic"][s["reset"], s["feet"]].any() for s in full)


def test_kinematics_reset_forward_equals_full_on_the_cpu_engine():
    _compare(_run("mujoco", "full", 8, 50), _run("mujoco", "kinematics", 8, 50), atol=0.0)


# the tasks built on humanoid_walk_cfg inherit its "kinematics" default: each critic ends with the
# same two feet_contact columns, and nothing their policies see may change
@pytest.mark.parametrize("task", ["humanoid-footsteps", "humanoid-rough", "g1-walk"])
def test_kinematics_reset_forward_equals_full_for_the_tasks_built_on_humanoid_walk(task):
    if task == "g1-walk":
        from ambulo.envs.g1_walk import g1_urdf_path
        try:
            g1_urdf_path()
        except Exception as err:  # the G1 URDF comes with the robots extra
            pytest.skip(f"needs the G1 URDF: {err}")
    _compare(_run("mujoco", "full", 6, 40, task), _run("mujoco", "kinematics", 6, 40, task), atol=0.0)


def test_humanoid_walk_and_its_derived_tasks_default_to_the_kinematics_pass():
    for task in ("humanoid-walk", "humanoid-footsteps", "humanoid-rough"):
        assert ambulo.envs.make(task, num_envs=1, device="cpu").cfg.reset_forward == "kinematics", task


@pytest.mark.skipif(importlib.util.find_spec("mujoco_warp") is None, reason="needs mujoco_warp")
def test_kinematics_reset_forward_equals_full_on_mujoco_warp():
    _compare(_run("warp", "full", 6, 50), _run("warp", "kinematics", 6, 50), atol=1e-5)
