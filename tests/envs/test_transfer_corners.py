"""The robustness table's corner rows: a transfer range of one value fixes that term in every world
(gains all at 0.8, latency at 20 ms, the CoM at one corner of the +-3 cm cube)."""

import pytest
import torch

import ambulo.envs as envs
from ambulo.core.randomize.fields import entity_body_ids
from ambulo.envs.transfer import TransferCfg

CORNER_M = (0.03, -0.03, 0.03)


def test_a_corner_config_puts_every_world_on_that_corner():
    nominal = envs.make("humanoid-walk", num_envs=3, seed=0, num_threads=1, play=True)
    corner = TransferCfg(kp_scale_range=(0.8, 0.8), kd_scale_range=(0.8, 0.8), action_latency_range_s=(0.02, 0.02),
                         com_offset_box_m=(CORNER_M, CORNER_M))
    env = envs.make("humanoid-walk", num_envs=3, seed=0, num_threads=1, play=True, transfer=corner)
    ids = entity_body_ids(env.robot, list(corner.com_bodies))
    ipos = env.engine.model_field("body_ipos")[:, ids]
    ipos0 = nominal.engine.model_field("body_ipos")[:, ids]
    torch.testing.assert_close(ipos - ipos0, torch.tensor(CORNER_M, dtype=ipos.dtype).expand_as(ipos))
    kp = -env.engine.model_field("actuator_biasprm")[:, env.robot.actuator_idx, 1]
    kp0 = -nominal.engine.model_field("actuator_biasprm")[:, nominal.robot.actuator_idx, 1]
    torch.testing.assert_close(kp, 0.8 * kp0)
    assert env.transfer.latency_steps == (4, 4) and env.transfer.action_delay.delay.tolist() == [4, 4, 4]


def test_com_box_is_checked():
    with pytest.raises(ValueError, match="low must be <= its high"):
        TransferCfg(com_offset_box_m=((0.03, 0.0, 0.0), (0.0, 0.0, 0.0)))
    with pytest.raises(ValueError, match="not both"):
        TransferCfg(com_offset_m=0.03, com_offset_box_m=((0.0,) * 3, (0.0,) * 3))
