"""The torch path of the visual odometry (``kornia_vo_cfg``: kornia corners + RootSIFT, torch
RANSAC and refinement) on the CPU: its math (rigid fit, RANSAC, masked refinement, lifting), the
head-camera walk within the acceptance's bounds, and recovery after a covered lens and a
textureless wall. CPU/CUDA agreement is vo/test_cuda.py."""

import dataclasses

import numpy as np
import pytest
import torch

from ambulo.perception.vo.config import KorniaFeaturesCfg, TrackState, VoCfg, kornia_vo_cfg
from ambulo.perception.vo.eval import run_walk_vo
from ambulo.perception.vo.features import KorniaFeatures, lift_keypoints
from ambulo.perception.vo.pnp_torch import fit_rigid_batch, ransac_pose_rgbd
from ambulo.perception.vo.refine import refine_pose_torch, so3_exp
from ambulo.utils.checks import InvalidValueError

pytest.importorskip("kornia", reason="the perception extra is not installed")
pytest.importorskip("evo", reason="the perception extra is not installed")

K = torch.tensor([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]], dtype=torch.float64)


def _scene_points(n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(n, 3) points in front of a camera at the origin, and a world-to-camera pose (R, t) to move them by."""
    gen = torch.Generator().manual_seed(seed)
    points_c = torch.rand(n, 3, generator=gen, dtype=torch.float64) * torch.tensor([3.0, 2.0, 2.5]) \
        + torch.tensor([-1.5, -1.0, 1.5])
    return points_c, so3_exp(torch.tensor([0.1, -0.25, 0.05], dtype=torch.float64))


def test_so3_exp_matches_rodrigues_and_is_exact_near_zero():
    cv2 = pytest.importorskip("cv2")
    for w in ([0.3, -1.2, 0.7], [1e-7, 0.0, -2e-7], [0.0, 0.0, 0.0]):
        expected = cv2.Rodrigues(np.array(w))[0]
        np.testing.assert_allclose(so3_exp(torch.tensor(w, dtype=torch.float64)).numpy(), expected, atol=1e-15)


def test_rigid_fit_recovers_a_transform_and_never_a_reflection():
    points_c, rot = _scene_points(3 * 50, 0)
    a = points_c.reshape(50, 3, 3)
    b = a @ rot.T + torch.tensor([0.2, -0.1, 0.4], dtype=torch.float64)
    r, t = fit_rigid_batch(a, b)
    torch.testing.assert_close(r, rot.expand(50, 3, 3), atol=1e-10, rtol=0)
    torch.testing.assert_close(t, torch.tensor([[0.2, -0.1, 0.4]], dtype=torch.float64).expand(50, 3), atol=1e-10, rtol=0)
    mirrored = b * torch.tensor([1.0, 1.0, -1.0], dtype=torch.float64)  # no rotation maps a onto a mirror image
    assert torch.allclose(torch.linalg.det(fit_rigid_batch(a, mirrored)[0]), torch.ones(50, dtype=torch.float64))


def test_ransac_finds_the_pose_with_40_percent_wrong_matches_and_the_refinement_polishes_it():
    points_w, rot = _scene_points(400, 1)
    t = torch.tensor([0.05, 0.02, -0.1], dtype=torch.float64)
    points_c = points_w @ rot.T + t
    pixels = points_c[:, :2] / points_c[:, 2:] * 525.0 + torch.tensor([319.5, 239.5], dtype=torch.float64)
    gen = torch.Generator().manual_seed(2)
    pixels = pixels + 0.3 * torch.randn(400, 2, generator=gen, dtype=torch.float64)
    points_c = points_c + 0.003 * torch.randn(400, 3, generator=gen, dtype=torch.float64)  # depth noise, 3 mm
    wrong = torch.arange(400) < 160
    pixels[wrong] = pixels[wrong].flip(0)  # 160 matches to someone else's keypoint (and 3-D point)
    points_c[wrong] = points_c[wrong].flip(0)
    has_depth = torch.arange(400) % 5 != 0
    found = ransac_pose_rgbd(points_w, pixels, points_c, has_depth, K, 200, 2.0, np.random.default_rng(0))
    assert found is not None
    r0, t0, inliers = found
    assert inliers[~wrong].float().mean() > 0.95 and inliers[wrong].float().mean() < 0.05
    r1, t1 = refine_pose_torch(r0, t0, points_w, pixels, points_c, has_depth, inliers, K, VoCfg())
    # three noisy points leave millimetres; all inliers' pixels and depths bring it well under one
    assert (t0 - t).norm() > 2e-3 and (t1 - t).norm() < 1e-3
    torch.testing.assert_close(r1, rot, atol=3e-4, rtol=0)


def test_masked_refinement_equals_refinement_on_the_selected_points():
    """The refinement selects inliers by mask (no device read); it must equal indexing them out."""
    points_w, rot = _scene_points(300, 3)
    points_c = points_w @ rot.T
    pixels = points_c[:, :2] / points_c[:, 2:] * 525.0 + torch.tensor([319.5, 239.5], dtype=torch.float64)
    pixels[:100] += 3.0  # inside the robust loss's 4.685 px: only the mask keeps them out
    use = torch.arange(300) >= 100
    has_depth = torch.ones(300, dtype=torch.bool)
    start = (so3_exp(torch.tensor([0.02, 0.0, 0.01], dtype=torch.float64)) @ rot, torch.tensor([0.03, 0, 0.02]).double())
    masked = refine_pose_torch(*start, points_w, pixels, points_c, has_depth, use, K, VoCfg())
    picked = refine_pose_torch(*start, points_w[use], pixels[use], points_c[use], has_depth[use],
                               torch.ones(200, dtype=torch.bool), K, VoCfg())
    torch.testing.assert_close(masked, picked, atol=1e-12, rtol=0)
    torch.testing.assert_close(masked[0], rot, atol=1e-9, rtol=0)


def test_lifting_rejects_depth_edges_holes_and_range():
    depth = torch.full((20, 30), 2.0)
    depth[:, 15:] = 4.0  # a depth edge at u = 14.5
    depth[3, 3] = 0.0  # a hole
    pixels = torch.tensor([[8.0, 10.0], [14.0, 10.0], [20.0, 10.0], [4.0, 4.0], [8.2, 9.6]], dtype=torch.float64)
    points_c, valid = lift_keypoints(pixels, depth, K, (0.2, 3.0))
    assert valid.tolist() == [True, False, False, False, True]  # edge, beyond 3 m, next to the hole
    torch.testing.assert_close(points_c[0], torch.tensor([(8 - 319.5) / 525 * 2, (10 - 239.5) / 525 * 2, 2.0],
                                                         dtype=torch.float64))


def test_the_kornia_front_end_fetches_and_loads_no_weights(monkeypatch):
    """kornia's learned detectors, orienters and descriptors download weights, which ambulo may not
    do at run time: building and running the front end (with the orientation step too) must neither
    open a connection nor load a file."""
    import socket

    def refuse(*args, **kwargs):
        raise AssertionError("the kornia front end tried to fetch or load weights")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(torch, "load", refuse)
    monkeypatch.setattr(torch.hub, "load_state_dict_from_url", refuse)
    cfg = dataclasses.replace(kornia_vo_cfg(), kornia=KorniaFeaturesCfg(orient=True))
    front_end = KorniaFeatures(cfg, K, torch.device("cpu"))
    blocks = torch.randint(0, 256, (30, 40, 3), generator=torch.Generator().manual_seed(0), dtype=torch.uint8)
    rgb = blocks.repeat_interleave(16, 0).repeat_interleave(16, 1)  # 480x640 of random 16 px tiles: corners
    found = front_end.detect(rgb, torch.full((480, 640), 2.0))
    assert len(found.pixels) > 100 and found.valid.any()
    assert len(front_end.match(found.descriptors, found.descriptors)) > 0


def test_kornia_config_checks_device_and_names():
    # ORB on a GPU device: detection, matching and solvePnPRansac stay in OpenCV on the host, the map
    # and the refinement go to the device (the navigator's ``--perception-device cuda``)
    assert VoCfg(device="cuda").features == "orb"
    with pytest.raises(InvalidValueError, match="features"):
        VoCfg(features="sift")
    cfg = kornia_vo_cfg("cpu")
    assert cfg.features == "kornia" and cfg.pnp == "torch"


@pytest.mark.parametrize("loss", ["covered_lens", "textureless_wall"])
def test_kornia_tracking_resumes_within_1s_after_a_loss(rendered_walk, loss):
    """1 s of black frames without depth, or of a plain grey wall at 0.5 m (depth, no corner):
    lost throughout, then relocalised against the keyframes within 1 s."""
    run = run_walk_vo(rendered_walk(320, 240), 130, kornia_vo_cfg("cpu"), blackout=(60, 90), loss=loss)
    assert all(s == TrackState.LOST for s in run.states[60:90])
    frames = run.recovery_frames(tolerance_m=0.05)
    assert frames is not None and frames <= 30
    assert run.states[90 + frames] == TrackState.RECOVERED
