"""RANSAC for the camera pose in torch, batched over hypotheses, on any device.

Every hypothesis is drawn from three RGB-D correspondences (a map point in the world, the matched
keypoint back-projected with this frame's depth) and solved in closed form by the SVD of their
cross-covariance (Arun, Huang & Blostein 1987, "Least-squares fitting of two 3-D point sets",
with Umeyama's 1991 reflection fix). All ``ransac_iterations`` hypotheses are solved in one batched
SVD and scored together: each one projects every map point and counts the keypoints within
``ransac_reprojection_px``, so the inlier test is the same reprojection test as OpenCV's
``solvePnPRansac``. The best hypothesis and its inlier mask stay on the device.

Why three 3-D points and not ``kornia.geometry.solve_pnp_dlt`` on six 2-D-3-D pairs: a sample is
clean with probability w^3 instead of w^6 (at half the matches right, 12 % of the hypotheses
instead of 1.6 %), a 3-point sample on a wall is fine where the DLT's rank check raises for a
coplanar sample (and it raises for the whole batch), and the RGB-D pairs are there anyway. Samples
only come from keypoints with valid depth; scoring uses every match.
"""

from __future__ import annotations

import numpy as np
import torch


def fit_rigid_batch(points_a: torch.Tensor, points_b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Least-squares rigid transforms ``b = R a + t`` of (B, n, 3) point sets: ``R`` (B, 3, 3), ``t`` (B, 3).

    Degenerate samples (coincident or collinear points) give some rotation; RANSAC's inlier count
    discards them."""
    mean_a, mean_b = points_a.mean(1, keepdim=True), points_b.mean(1, keepdim=True)
    cov = (points_b - mean_b).transpose(1, 2) @ (points_a - mean_a)  # (B, 3, 3) sum of b a^T
    u, _, vh = torch.linalg.svd(cov)
    d = torch.linalg.det(u @ vh).sign()
    d = torch.where(d == 0, 1.0, d)
    diag = torch.ones_like(mean_a[:, 0]).clone()
    diag[:, 2] = d
    rot = u @ (diag[:, :, None] * vh)
    return rot, mean_b[:, 0] - (rot @ mean_a.transpose(1, 2))[..., 0]


def reprojection_error_px(rot_cw: torch.Tensor, t_cw: torch.Tensor, points_w: torch.Tensor,
                          pixels: torch.Tensor, k: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixel errors (..., N) and camera depths (..., N), m, of ``points_w`` (N, 3) under poses ``rot_cw``
    (..., 3, 3), ``t_cw`` (..., 3) against ``pixels`` (N, 2); ``k`` (3, 3)."""
    pc = points_w @ rot_cw.transpose(-1, -2) + t_cw[..., None, :]
    z = pc[..., 2]
    uv = pc[..., :2] / z.clamp_min(1e-6)[..., None] * k.diagonal()[:2] + k[:2, 2]
    return (uv - pixels).norm(dim=-1), z


def ransac_pose_rgbd(points_w: torch.Tensor, pixels: torch.Tensor, points_c: torch.Tensor, has_depth: torch.Tensor,
                     k: torch.Tensor, iterations: int, threshold_px: float, rng: np.random.Generator
                     ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None:
    """The best of ``iterations`` 3-point hypotheses: ``(rot_cw (3, 3), t_cw (3,), inliers (N,) bool)``,
    or None when fewer than three correspondences have depth.

    ``points_w`` (N, 3) float64 map points (world, m); ``pixels`` (N, 2) float64 keypoints (px);
    ``points_c`` (N, 3) float64 keypoints back-projected with depth (camera, m) where ``has_depth``
    (N,) bool. ``rng`` draws the samples on the host (a few hundred integers), so a CPU and a CUDA
    run of the same frames draw the same samples.
    """
    candidates = torch.nonzero(has_depth)[:, 0]
    if len(candidates) < 3:
        return None
    draw = torch.from_numpy(rng.integers(0, len(candidates), (iterations, 3))).to(points_w.device)
    sample = candidates[draw]  # (iterations, 3)
    rot, t = fit_rigid_batch(points_w[sample], points_c[sample])
    err, z = reprojection_error_px(rot, t, points_w, pixels, k)
    inliers = (err < threshold_px) & (z > 1e-6)
    best = inliers.sum(1).argmax()
    return rot[best], t[best], inliers[best]


__all__ = ["fit_rigid_batch", "ransac_pose_rgbd", "reprojection_error_px"]
