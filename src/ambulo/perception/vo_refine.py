"""Gauss-Newton refinement of a world-to-camera pose over reprojection and 3-D (depth) residuals,
in torch: one implementation for the OpenCV and the kornia front ends, on any device.

Each inlier contributes two residuals: the reprojection error ``(pi(R p_w + t) - u) / pixel_sigma``
(2-D, px over px) and, where the current depth is valid, ``(R p_w + t - p_c) / sigma(z)`` (3-D, m over
m) with ``sigma(z) = max(depth_sigma_coeff z^2, depth_sigma_min_m)``. Both are weighted by a robust
loss (IRLS on the residual norm). The update is left-multiplied: ``R <- exp(dw) R``,
``t <- exp(dw) t + dt`` with ``delta = (dw, dt)`` from the 6x6 normal equations. The iteration count
is fixed (``VoCfg.refine_iterations``): no early exit, so the loop never reads the device.
IRLS with Tukey weights converges linearly here, each step ~20x smaller than the last (measured
on the head-camera walk: the 4th moves the pose by < 3 um, the 6th by < 0.01 um).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
import torch

if TYPE_CHECKING:
    from .vo import VoCfg


@functools.cache
def _skew_basis(device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    """(3, 9): ``p @ basis`` is ``skew(p)`` flattened row-major, one matrix product instead of nine
    stacked entries; made once per device (a copy to the GPU per call would cost more than the product)."""
    basis = torch.zeros(3, 9, dtype=dtype)
    basis[2, 1], basis[1, 2], basis[2, 3], basis[0, 5], basis[1, 6], basis[0, 7] = -1, 1, 1, -1, -1, 1
    return basis.to(device)


def skew(p: torch.Tensor) -> torch.Tensor:
    """(..., 3) -> (..., 3, 3) cross-product matrices: ``skew(p) @ q == cross(p, q)``."""
    return (p @ _skew_basis(p.device, p.dtype)).unflatten(-1, (3, 3))


def so3_exp(w: torch.Tensor) -> torch.Tensor:
    """(..., 3) rotation vectors (rad) -> (..., 3, 3) rotation matrices: Rodrigues'
    ``I + sin(t)/t K + (1 - cos(t))/t^2 K^2`` with both ratios as ``torch.sinc`` (exact at t = 0,
    no branch): ``sin(t)/t = sinc(t/pi)``, ``(1 - cos(t))/t^2 = sinc(t/(2 pi))^2 / 2``."""
    theta = w.norm(dim=-1)[..., None, None]
    k = skew(w)
    return (torch.eye(3, dtype=w.dtype, device=w.device) + torch.sinc(theta / torch.pi) * k
            + 0.5 * torch.sinc(theta / (2 * torch.pi)) ** 2 * (k @ k))


def robust_weight(r: torch.Tensor, loss: str) -> torch.Tensor:
    """IRLS weights of normalised residual norms: Huber (k = 1.345) or Tukey's biweight (c = 4.685),
    the 95 %-efficiency constants for Gaussian noise."""
    a = r.abs()
    if loss == "huber":
        return torch.where(a <= 1.345, 1.0, 1.345 / a.clamp_min(1e-12))
    return torch.where(a < 4.685, (1 - (a / 4.685) ** 2) ** 2, 0.0)


def refine_pose_torch(rot_cw: torch.Tensor, t_cw: torch.Tensor, points_w: torch.Tensor, pixels: torch.Tensor,
                      points_c: torch.Tensor, has_depth: torch.Tensor, use: torch.Tensor, k: torch.Tensor,
                      cfg: VoCfg) -> tuple[torch.Tensor, torch.Tensor]:
    """Refined ``(rot_cw (3, 3), t_cw (3,))``, float64, world-to-camera.

    ``points_w`` (N, 3) map points (world, m); ``pixels`` (N, 2) their keypoints in this frame (px);
    ``points_c`` (N, 3) the keypoints back-projected with this frame's depth (camera, m), used where
    ``has_depth`` (N,) bool; ``use`` (N,) bool selects the correspondences (the inliers) without
    indexing, so that nothing is read back from the device; ``k`` (3, 3) intrinsics.

    Written for few kernel launches per iteration (on a GPU each costs more than its arithmetic):
    the five residuals of a point are one (N, 5) tensor with one (N, 5, 6) Jacobian.
    """
    n = len(points_w)
    focal, centre = k.diagonal()[:2], k[:2, 2]
    eye2 = torch.eye(2, dtype=points_w.dtype, device=points_w.device).expand(n, 2, 2)
    eye3 = torch.eye(3, dtype=points_w.dtype, device=points_w.device).expand(n, 3, 3)
    use_f = use.to(points_w.dtype)
    depth_f = (use & has_depth).to(points_w.dtype) * float(cfg.use_depth_residual)
    damping = 1e-9 * torch.eye(6, dtype=points_w.dtype, device=points_w.device)
    for _ in range(cfg.refine_iterations):
        pc = torch.addmm(t_cw, points_w, rot_cw.T)  # (N, 3) camera frame
        z = pc[:, 2:].clamp_min(1e-6)
        xn = pc[:, :2] / z  # normalised image coordinates
        r_px = (xn * focal + centre - pixels) / cfg.pixel_sigma  # (N, 2)
        # d proj / d pc = f / z [I | -xn], d pc / d (dw, dt) = [-skew(pc) | I]
        jp = (focal / (z * cfg.pixel_sigma))[..., None] * torch.cat([eye2, -xn[..., None]], -1)  # (N, 2, 3)
        d_pc = torch.cat([skew(-pc), eye3], -1)  # (N, 3, 6)
        sigma = (cfg.depth_sigma_coeff * z**2).clamp_min(cfg.depth_sigma_min_m)  # (N, 1)
        # a keypoint without depth has points_c = 0: its 3-D residual is zeroed, not merely weighted 0
        r_3d = torch.where(depth_f[:, None] > 0, (pc - points_c) / sigma, 0.0)
        residual = torch.cat([r_px, r_3d], 1)  # (N, 5)
        jac = torch.cat([jp @ d_pc, d_pc / sigma[..., None]], 1)  # (N, 5, 6)
        w_px = robust_weight(r_px.norm(dim=1), cfg.robust_loss) * use_f
        w_3d = robust_weight(r_3d.norm(dim=1), cfg.robust_loss) * depth_f
        weight = torch.cat([w_px[:, None].expand(n, 2), w_3d[:, None].expand(n, 3)], 1).flatten()
        jac_w = jac.flatten(0, 1) * weight[:, None]  # (5N, 6)
        # solve_ex: no error check, which would read the device every iteration
        delta = -torch.linalg.solve_ex(jac_w.T @ jac.flatten(0, 1) + damping, jac_w.T @ residual.flatten())[0]
        dr = so3_exp(delta[:3])
        rot_cw, t_cw = dr @ rot_cw, torch.addmv(delta[3:], dr, t_cw)
    return rot_cw, t_cw


def refine_pose(rot_cw: np.ndarray, t_cw: np.ndarray, points_w: np.ndarray, pixels: np.ndarray,
                points_c: np.ndarray, has_depth: np.ndarray, k: np.ndarray, cfg: VoCfg) -> tuple[np.ndarray, np.ndarray]:
    """``refine_pose_torch`` on numpy arrays (all correspondences used): ``(rot_cw (3, 3), t_cw (3,))``."""
    def t64(a):
        return torch.as_tensor(np.asarray(a, np.float64))

    rot, t = refine_pose_torch(t64(rot_cw), t64(t_cw), t64(points_w), t64(pixels), t64(points_c),
                               torch.as_tensor(np.asarray(has_depth, bool)), torch.ones(len(points_w), dtype=torch.bool),
                               t64(k), cfg)
    return rot.numpy(), t.numpy()


__all__ = ["refine_pose", "refine_pose_torch", "robust_weight", "skew", "so3_exp"]
