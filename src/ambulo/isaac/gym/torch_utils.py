"""``isaacgym.torch_utils`` under ``ambulo run``: Isaac Gym's batched rotation helpers, quaternions
(x, y, z, w) as in its tensors. Each reorders to ambulo's (w, x, y, z) math (``utils.math``)."""

from __future__ import annotations

import numpy as np
import torch

from ambulo.utils import math as wxyz_math


def _wxyz(q: torch.Tensor) -> torch.Tensor:
    return q[..., [3, 0, 1, 2]]


def _xyzw(q: torch.Tensor) -> torch.Tensor:
    return q[..., [1, 2, 3, 0]]


def to_torch(x, dtype=torch.float, device="cuda:0", requires_grad=False) -> torch.Tensor:
    return torch.tensor(x, dtype=dtype, device=device, requires_grad=requires_grad)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return _xyzw(wxyz_math.quat_mul(_wxyz(a), _wxyz(b)))


def quat_conjugate(a: torch.Tensor) -> torch.Tensor:
    return torch.cat((-a[..., :3], a[..., 3:]), dim=-1)


def normalize(x: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    return x / x.norm(p=2, dim=-1).clamp(min=eps).unsqueeze(-1)


def quat_unit(a: torch.Tensor) -> torch.Tensor:
    return normalize(a)


def quat_rotate(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate (N, 3) vectors by (N, 4) xyzw quaternions."""
    return wxyz_math.quat_rotate(_wxyz(q), v)


def quat_rotate_inverse(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    return wxyz_math.quat_rotate_inverse(_wxyz(q), v)


def quat_apply(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Rotate vectors ``b`` (any shape (..., 3)) by xyzw quaternions ``a``, both read as flat lists
    of the same length, the result in ``b``'s shape: as Isaac Gym's, which legged_gym calls with
    (N * P, 4) quaternions and (N, P, 3) points."""
    shape = b.shape
    return wxyz_math.quat_rotate(_wxyz(a.reshape(-1, 4)), b.reshape(-1, 3)).view(shape)


def quat_from_angle_axis(angle: torch.Tensor, axis: torch.Tensor) -> torch.Tensor:
    return _xyzw(wxyz_math.quat_from_axis_angle(normalize(axis), angle))


def get_axis_params(value: float, axis_idx: int, x_value: float = 0.0, dtype=float, n_dims: int = 3) -> list:
    """A list of ``n_dims`` zeros (``x_value`` first) with ``value`` at ``axis_idx``."""
    params = np.zeros(n_dims)
    params[0] = x_value
    params[axis_idx] = value
    return list(params.astype(dtype))


def torch_rand_float(lower: float, upper: float, shape, device) -> torch.Tensor:
    return (upper - lower) * torch.rand(*shape, device=device) + lower


def tensor_clamp(t: torch.Tensor, min_t: torch.Tensor, max_t: torch.Tensor) -> torch.Tensor:
    return torch.max(torch.min(t, max_t), min_t)


def scale(x: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    return 0.5 * (x + 1.0) * (upper - lower) + lower


def unscale(x: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    return (2.0 * x - upper - lower) / (upper - lower)


def copysign(a: float, b: torch.Tensor) -> torch.Tensor:
    return torch.abs(torch.full_like(b, a)) * torch.sign(b)


def get_euler_xyz(q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(roll, pitch, yaw) in [0, 2 pi) of xyzw quaternions, as Isaac Gym's."""
    x, y, z, w = q.unbind(-1)
    roll = torch.atan2(2.0 * (w * x + y * z), w * w - x * x - y * y + z * z)
    pitch = torch.asin(torch.clamp(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = torch.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)
    two_pi = 2.0 * np.pi
    return roll % two_pi, pitch % two_pi, yaw % two_pi


__all__ = ["copysign", "get_axis_params", "get_euler_xyz", "normalize", "quat_apply", "quat_conjugate",
           "quat_from_angle_axis", "quat_mul", "quat_rotate", "quat_rotate_inverse", "quat_unit", "scale",
           "tensor_clamp", "to_torch", "torch_rand_float", "unscale"]
