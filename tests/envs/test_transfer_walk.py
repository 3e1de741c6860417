"""humanoid-walk carries the transfer randomization too (the robustness table evaluates its policy
under it); its play variant has none."""

import torch

import ambulo.envs as envs
from ambulo.envs.transfer import transfer_cfg_wide


def test_humanoid_walk_steps_under_the_wide_transfer_ranges():
    env = envs.make("humanoid-walk", num_envs=4, seed=0, num_threads=1, transfer=transfer_cfg_wide())
    kp = -env.engine.model_field("actuator_biasprm")[:, env.robot.actuator_idx, 1]
    assert not torch.equal(kp[0], kp[1])
    assert env.transfer.action_delay is not None and env.transfer.latency_steps == (0, 4)
    for _ in range(5):
        obs, rewards, _, _ = env.step(torch.zeros(4, env.num_actions))
        assert torch.isfinite(obs).all() and torch.isfinite(rewards).all()
    assert env.engine.num_diverged == 0


def test_play_variants_have_no_transfer_randomization():
    for task in ("humanoid-walk", "humanoid-rough"):
        cfg = envs.make_cfg(task, play=True)
        assert all(getattr(cfg.transfer, f) is None for f in cfg.transfer.__dataclass_fields__ if f != "com_bodies")
