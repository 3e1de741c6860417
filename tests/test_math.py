"""Batched quaternion math against MuJoCo's own functions."""

import mujoco
import numpy as np
import torch

from ambulo.utils.math import quat_from_axis_angle, quat_rotate, quat_rotate_inverse, yaw_from_quat


def test_rotations_match_mujoco():
    gen = torch.Generator().manual_seed(0)
    quat = torch.nn.functional.normalize(torch.randn(20, 4, generator=gen, dtype=torch.float64), dim=-1)
    vec = torch.randn(20, 3, generator=gen, dtype=torch.float64)
    rotated, back = quat_rotate(quat, vec), quat_rotate_inverse(quat, vec)
    for i in range(20):
        want = np.zeros(3)
        mujoco.mju_rotVecQuat(want, vec[i].numpy(), quat[i].numpy())
        np.testing.assert_allclose(rotated[i].numpy(), want, atol=1e-12)
    torch.testing.assert_close(quat_rotate_inverse(quat, rotated), vec)
    torch.testing.assert_close(quat_rotate(quat, back), vec)


def test_axis_angle_and_yaw():
    yaw = torch.tensor([0.3, -2.0, 3.0], dtype=torch.float64)
    quat = quat_from_axis_angle(torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand(3, 3), yaw)
    torch.testing.assert_close(yaw_from_quat(quat), yaw)
    x_axis = quat_rotate(quat, torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64).expand(3, 3))
    torch.testing.assert_close(x_axis[:, 0], torch.cos(yaw))
