"""Batched quaternion math (torch and NumPy) against MuJoCo's own functions."""

import mujoco
import numpy as np
import torch

from ambulo.utils import rotations
from ambulo.utils.math import (
    quat_from_axis_angle,
    quat_rotate,
    quat_rotate_inverse,
    rotate_yaw,
    rotate_yaw_inverse,
    yaw_from_quat,
)


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


def test_numpy_rotations_match_mujoco_and_the_torch_versions():
    rng = np.random.default_rng(0)
    quat = rng.normal(size=(20, 4))
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    quat[quat[:, 0] < 0] *= -1  # mat_to_quat returns w >= 0
    mats = rotations.quat_to_mat(quat)
    for q, m in zip(quat, mats):
        want = np.zeros(9)
        mujoco.mju_quat2Mat(want, q)
        np.testing.assert_allclose(m.ravel(), want, atol=1e-12)
        np.testing.assert_allclose(rotations.mat_to_quat(m), q, atol=1e-12)  # one matrix: MuJoCo's routine
    np.testing.assert_allclose(rotations.mat_to_quat(mats), quat, atol=1e-12)  # batched: Shepperd's method
    axis = rng.normal(size=(20, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = rng.uniform(-np.pi, np.pi, 20)
    q = rotations.quat_from_axis_angle(axis, angle)
    np.testing.assert_allclose(q, quat_from_axis_angle(torch.from_numpy(axis), torch.from_numpy(angle)).numpy(),
                               atol=1e-15)
    np.testing.assert_allclose(rotations.rot_about_axes(axis * angle[:, None]), rotations.quat_to_mat(q), atol=1e-12)
    np.testing.assert_array_equal(rotations.rot_about_axes(np.zeros(3)), np.eye(3))


def test_rotate_yaw_turns_heading_frame_vectors_into_the_world_and_back():
    yaw = torch.tensor([0.0, np.pi / 2, np.pi])
    forward = torch.tensor([1.0, 0.0])  # broadcast against the three yaws
    torch.testing.assert_close(rotate_yaw(yaw, forward), torch.tensor([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]),
                               atol=1e-6, rtol=0)
    vec = torch.randn(3, 2, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(rotate_yaw_inverse(yaw, rotate_yaw(yaw, vec)), vec, atol=1e-6, rtol=0)
