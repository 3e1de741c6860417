"""gymutil's command line and SimParams, and the xyzw rotation helpers scripts use."""

import math
import sys

import pytest
import torch

from ambulo.isaac.gym import gymapi, gymutil, torch_utils


def test_parse_arguments_gives_isaac_gyms_flags_and_the_scripts_own(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["train.py", "--sim_device", "cuda:1", "--pipeline", "cpu", "--num_threads", "3",
                                      "--num_envs", "64", "--headless"])
    args = gymutil.parse_arguments(headless=True, custom_parameters=[{"name": "--num_envs", "type": int, "default": 8}])
    assert (args.sim_device_type, args.compute_device_id, args.use_gpu_pipeline) == ("cuda", 1, False)
    assert args.num_envs == 64 and args.headless and args.physics_engine == gymapi.SIM_PHYSX
    params = gymutil.parse_sim_params(args, {"sim": {"dt": 0.005, "physx": {"num_position_iterations": 8}}})
    assert params.physx.num_threads == 3 and not params.use_gpu_pipeline
    assert params.dt == 0.005 and params.physx.num_position_iterations == 8
    with pytest.raises(ValueError, match="'cpu' or 'cuda"):
        gymutil.parse_device_str("tpu:0")


def test_quaternions_are_x_y_z_w_in_structs_and_tensors():
    q = gymapi.Quat.from_axis_angle(gymapi.Vec3(0, 0, 1), math.pi / 2)
    assert (q.x, q.y, q.z) == pytest.approx((0.0, 0.0, math.sin(math.pi / 4))) and q.w == pytest.approx(math.cos(math.pi / 4))
    v = q.rotate(gymapi.Vec3(1, 0, 0))
    assert (v.x, v.y, v.z) == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)
    qt = torch.tensor([[q.x, q.y, q.z, q.w]])
    torch.testing.assert_close(torch_utils.quat_rotate(qt, torch.tensor([[1.0, 0.0, 0.0]])), torch.tensor([[0.0, 1.0, 0.0]]))
    torch.testing.assert_close(torch_utils.quat_rotate_inverse(qt, torch.tensor([[0.0, 1.0, 0.0]])),
                               torch.tensor([[1.0, 0.0, 0.0]]))
    roll, pitch, yaw = gymapi.Quat.from_euler_zyx(0.1, -0.2, 0.3).to_euler_zyx()
    assert (roll, pitch, yaw) == pytest.approx((0.1, -0.2, 0.3))
    t = gymapi.Transform(gymapi.Vec3(1, 2, 3), q)
    back = t.inverse().transform_point(t.transform_point(gymapi.Vec3(0.5, -0.5, 2.0)))
    assert (back.x, back.y, back.z) == pytest.approx((0.5, -0.5, 2.0))
