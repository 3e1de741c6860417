"""transfer_blocks: the robustness table's rows side by side in one env (``--batched``), each block of
worlds under its own TransferCfg, and ``run_episodes`` reporting each block."""

import torch

import ambulo.envs as envs
from ambulo.core.randomize.fields import entity_body_ids
from ambulo.envs.transfer import TransferCfg
from ambulo.rl.evaluate import run_episodes
from ambulo.rl.vecenv import RslRlVecEnv

CORNER_M = (0.03, 0.03, 0.03)


def corner(gain: float, latency_s: float, com_m=None) -> TransferCfg:
    return TransferCfg(kp_scale_range=(gain, gain), kd_scale_range=(gain, gain),
                       action_latency_range_s=(latency_s, latency_s),
                       com_offset_box_m=None if com_m is None else (com_m, com_m))


def test_each_block_of_worlds_runs_under_its_own_terms_and_is_reported_alone():
    nominal = envs.make("humanoid-walk", num_envs=1, seed=0, num_threads=1, play=True)
    blocks = (corner(0.8, 0.0), corner(1.2, 0.02, CORNER_M))
    env = envs.make("humanoid-walk", num_envs=4, seed=0, num_threads=1, play=True, transfer_blocks=blocks,
                    episode_length_s=0.1)
    kp = -env.engine.model_field("actuator_biasprm")[:, env.robot.actuator_idx, 1]
    kp0 = -nominal.engine.model_field("actuator_biasprm")[0, nominal.robot.actuator_idx, 1]
    # block 1 scales the nominal gains, not block 0's (world 0 is written last)
    torch.testing.assert_close(kp, torch.stack([0.8 * kp0, 0.8 * kp0, 1.2 * kp0, 1.2 * kp0]))
    ids = entity_body_ids(env.robot, list(blocks[1].com_bodies))
    shift = env.engine.model_field("body_ipos")[:, ids] - nominal.engine.model_field("body_ipos")[0, ids]
    torch.testing.assert_close(shift[2:], torch.tensor(CORNER_M, dtype=shift.dtype).expand_as(shift[2:]))
    assert shift[:2].abs().max() == 0
    assert torch.isnan(env.transfer.factors["com_w"][:2]).all()
    env.reset()
    assert env.transfer.latency_steps == (0, 4) and env.transfer.action_delay.delay.tolist() == [0, 0, 4, 4]

    spec = envs.spec("humanoid-walk")
    result = run_episodes(env, RslRlVecEnv(env), lambda obs: torch.zeros(4, env.num_actions), spec, blocks=2)
    parts = result["blocks"]
    assert [p["episodes"] for p in parts] == [2, 2]
    for key in ("fall_rate", "mean_abs_vel_error_m_s", "mean_return"):
        assert abs(sum(p[key] for p in parts) / 2 - result[key]) < 1e-9
    assert parts[0]["mean_abs_vel_error_m_s"] != parts[1]["mean_abs_vel_error_m_s"]
