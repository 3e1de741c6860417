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

NUM_FEET = 2  # humanoid-walk's critic ends with one feet_contact column per foot


def _run(engine: str, mode: str, num_envs: int, steps: int):
    """``steps`` steps of random actions with frequent resets: 0.3 s episodes (15 steps), large
    actions (falls), and a random third of the envs reset by hand every 4th step, so resets come
    at different steps in different worlds. Returns per step what the test compares."""
    env = ambulo.envs.make("humanoid-walk", num_envs=num_envs, device="cpu", engine=engine, seed=3,
                           episode_length_s=0.3, reset_forward=mode)
    gen = torch.Generator().manual_seed(0)
    out = []
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
                        reset=reset, body_pos_w=data.body_pos_w.clone(), body_lin_vel_w=data.body_lin_vel_w.clone()))
    return out


def _compare(full, kin, atol):
    resets = torch.stack([s["reset"] for s in full])
    assert resets.any(0).all() and not resets.all(1).all()  # every env reset, not all at once
    for step, (a, b) in enumerate(zip(full, kin)):
        assert torch.equal(a["dones"], b["dones"]), step
        assert torch.equal(a["reset"], b["reset"]), step
        for key in ("obs", "rewards", "body_pos_w", "body_lin_vel_w"):
            torch.testing.assert_close(b[key], a[key], atol=atol, rtol=0, msg=f"{key} at step {step}")
        torch.testing.assert_close(b["critic"][:, :-NUM_FEET], a["critic"][:, :-NUM_FEET], atol=atol, rtol=0,
                                   msg=f"critic at step {step}")
        feet_full, feet_kin, reset = a["critic"][:, -NUM_FEET:], b["critic"][:, -NUM_FEET:], a["reset"]
        assert torch.equal(feet_kin[~reset], feet_full[~reset]), step
        assert not feet_kin[reset].any(), step  # documented: no contacts computed at a reset
    # the difference is real: some reset env stood on a foot under the full forward
    assert any(s["critic"][s["reset"], -NUM_FEET:].any() for s in full)


def test_kinematics_reset_forward_equals_full_on_the_cpu_engine():
    _compare(_run("mujoco", "full", 8, 50), _run("mujoco", "kinematics", 8, 50), atol=0.0)


@pytest.mark.skipif(importlib.util.find_spec("mujoco_warp") is None, reason="needs mujoco_warp")
def test_kinematics_reset_forward_equals_full_on_mujoco_warp():
    _compare(_run("warp", "full", 6, 50), _run("warp", "kinematics", 6, 50), atol=1e-5)
