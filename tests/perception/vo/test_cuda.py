"""The torch visual odometry on CUDA against the same code on the CPU: the kornia front end finds
the same corners, descriptors and matches; RANSAC + refinement give the same pose; the head-camera
walk is tracked within the acceptance's bounds and within millimetres of the CPU trajectory;
recovery after a covered lens. Skipped without CUDA."""

import dataclasses

import numpy as np
import pytest
import torch

from ambulo.perception.sources.head_camera_walk import HeadCameraWalk
from ambulo.perception.vo.config import TrackState, VoCfg, kornia_vo_cfg
from ambulo.perception.vo.eval import run_walk_vo
from ambulo.perception.vo.features import KorniaFeatures
from ambulo.perception.vo.pnp_torch import ransac_pose_rgbd
from ambulo.perception.vo.refine import refine_pose_torch, so3_exp
from ambulo.scenes.indoor import build_indoor_scene

pytest.importorskip("kornia", reason="the perception extra is not installed")
pytest.importorskip("evo", reason="the perception extra is not installed")
pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

DEVICE = "cuda"


@pytest.fixture(scope="module")
def scene():
    return build_indoor_scene()


@pytest.fixture(scope="module")
def frames(scene):
    """Frames 0 and 8 of the 640x480 kinematic walk: (rgb, depth, K) numpy."""
    walk = HeadCameraWalk(scene, width=640, height=480)
    out = [(f.rgb.numpy(), f.depth_m.numpy(), f.intrinsics.numpy()) for f in (walk.frame(0), walk.frame(8))]
    walk.close()
    return out


def _front_end(device: str, k: np.ndarray) -> KorniaFeatures:
    return KorniaFeatures(kornia_vo_cfg(device), torch.as_tensor(k, dtype=torch.float64, device=device),
                          torch.device(device))


def test_front_end_finds_the_same_corners_descriptors_and_matches(frames):
    k = frames[0][2]
    cpu, gpu = _front_end("cpu", k), _front_end(DEVICE, k)
    found = {name: [fe.detect(rgb, depth) for rgb, depth, _ in frames] for name, fe in (("cpu", cpu), ("gpu", gpu))}
    for a, b in zip(found["cpu"], found["gpu"], strict=True):
        pa, pb = a.pixels.numpy(), b.pixels.cpu().numpy()
        assert len(pa) > 300 and abs(len(pa) - len(pb)) <= 0.02 * len(pa)
        # the same corner sits on the same pixel: index the CUDA corners by position
        where = {tuple(p): i for i, p in enumerate(pb)}
        common = [(i, where[tuple(p)]) for i, p in enumerate(pa) if tuple(p) in where]
        assert len(common) >= 0.98 * len(pa)
        ia, ib = np.array(common).T
        des_a, des_b = a.descriptors.numpy()[ia], b.descriptors.cpu().numpy()[ib]
        # RootSIFT entries are O(0.1) in a unit vector; its square root magnifies round-off in near-empty
        # bins (on an H100 one entry differed by 4.9e-3: a bin of ~2.4e-5 on one device, ~0 on the other),
        # so compare whole descriptors: each within 2e-2 of its CPU twin, far below a match's distance
        assert np.linalg.norm(des_a - des_b, axis=1).max() < 2e-2
        assert (a.valid.numpy()[ia] == b.valid.cpu().numpy()[ib]).all()
        np.testing.assert_allclose(a.points_c.numpy()[ia], b.points_c.cpu().numpy()[ib], atol=1e-12)
    pairs = {}
    for name, fe in (("cpu", cpu), ("gpu", gpu)):
        now, before = found[name][1], found[name][0]
        m = fe.match(now.descriptors, before.descriptors).cpu().numpy()
        pix_now, pix_before = now.pixels.cpu().numpy(), before.pixels.cpu().numpy()
        pairs[name] = {(*pix_now[q], *pix_before[t]) for q, t in m}
    assert len(pairs["cpu"]) > 200
    assert len(pairs["cpu"] & pairs["gpu"]) >= 0.95 * len(pairs["cpu"])


def test_ransac_and_refinement_give_the_same_pose():
    gen = torch.Generator().manual_seed(0)
    points_w = torch.rand(500, 3, generator=gen, dtype=torch.float64) * torch.tensor([3.0, 2.0, 2.5]) \
        + torch.tensor([-1.5, -1.0, 1.5])
    rot, t = so3_exp(torch.tensor([0.05, -0.2, 0.02], dtype=torch.float64)), torch.tensor([0.1, 0.0, -0.05]).double()
    k = torch.tensor([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]], dtype=torch.float64)
    points_c = points_w @ rot.T + t + 0.003 * torch.randn(500, 3, generator=gen, dtype=torch.float64)
    pixels = points_c[:, :2] / points_c[:, 2:] * 525.0 + torch.tensor([319.5, 239.5]) \
        + 0.3 * torch.randn(500, 2, generator=gen, dtype=torch.float64)
    pixels[:150] = pixels[:150].flip(0)
    has_depth = torch.ones(500, dtype=torch.bool)
    poses = []
    for device in ("cpu", DEVICE):
        args = [x.to(device) for x in (points_w, pixels, points_c, has_depth)]
        r0, t0, inliers = ransac_pose_rgbd(*args, k.to(device), 200, 2.0, np.random.default_rng(0))
        poses.append([x.cpu() for x in refine_pose_torch(r0, t0, *args, inliers, k.to(device), VoCfg())])
    torch.testing.assert_close(poses[0], poses[1], atol=1e-9, rtol=0)
    assert (poses[1][1] - t).norm() < 5e-3  # found the pose, not the 150 flipped matches (3 mm depth noise)


def test_refinement_graphs_give_the_eager_pose_at_every_size():
    """The captured refinement (``vo.refine_graph``) against the eager one, on problems of 5 to 900
    correspondences in an order that reuses each padded graph with fewer rows than last time (stale
    rows must not count), with outliers and points without depth."""
    from ambulo.perception.vo.refine_graph import GraphRefiner

    cfg = kornia_vo_cfg(DEVICE)
    refiner = GraphRefiner(cfg, torch.device(DEVICE))
    gen = torch.Generator().manual_seed(1)
    k = torch.tensor([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]], dtype=torch.float64, device=DEVICE)
    for i, n in enumerate((700, 5, 64, 65, 900, 600, 33)):
        # a pose of its own per problem: rows left over from the last one would pull the result away
        truth_rot = so3_exp(torch.tensor([0.02, -0.1 + 0.003 * i, 0.01], dtype=torch.float64)).to(DEVICE)
        truth_t = torch.tensor([0.05, -0.02 + 0.004 * i, 0.03], dtype=torch.float64, device=DEVICE)
        points_w = (torch.rand(n, 3, generator=gen, dtype=torch.float64) * 2 + torch.tensor([-1.0, -1.0, 1.5])).to(DEVICE)
        points_c = points_w @ truth_rot.T + truth_t
        pixels = points_c[:, :2] / points_c[:, 2:] * 525.0 + k[:2, 2]
        pixels[: n // 5] += 30.0  # outliers: the robust loss drops them
        has_depth = (torch.rand(n, generator=gen) > 0.2).to(DEVICE)
        use = (torch.rand(n, generator=gen) > 0.1).to(DEVICE)
        start = (so3_exp(torch.tensor([0.001, 0.0, -0.001], dtype=torch.float64, device=DEVICE)) @ truth_rot,
                 truth_t + 0.002)  # RANSAC's pose is this close
        args = (*start, points_w, pixels, points_c, has_depth, use, k)
        eager = refine_pose_torch(*args, cfg)
        graph = refiner(*args, cfg)
        torch.testing.assert_close(graph, eager, atol=1e-12, rtol=0)
        if n >= 64:
            assert (graph[1] - truth_t).norm() < 1e-6
    assert sorted(refiner.graphs) == [64, 128, 1024]


def test_gyro_aid_on_cuda_keeps_the_heading_through_a_turn_too_fast_for_the_images():
    """The CUDA odometry with the walk's gyro: 180 deg in 0.4 s (the CPU test: vo/test_imu.py)."""
    import math

    from ambulo.perception.sources.head_camera_walk import WalkCfg

    walk = HeadCameraWalk(build_indoor_scene(), WalkCfg(look_away=(2.0, 0.4, math.pi)), width=320, height=240)
    run = run_walk_vo(walk, 102, kornia_vo_cfg(DEVICE), blackout=(60, 72), loss="motion", imu=True)
    walk.close()
    assert run.rotation_error_deg().max() < 2.0 and run.position_error_m().max() < 0.08
    frames = run.recovery_frames(tolerance_m=0.05)
    assert frames is not None and frames <= 30


def test_kornia_vo_on_cuda_tracks_the_walk_like_the_cpu(scene, tmp_path):
    """300 frames at 640x480 (10 s, 5.4 m) of the kinematic walk: the acceptance's ATE <= 2 cm and
    RPE <= 1 %, every frame tracked, and every pose within 5 mm of the CPU run's (the two differ only
    by float round-off in the front end; tracking either run wrongly would be centimetres)."""
    walk = HeadCameraWalk(scene, width=640, height=480)
    runs = {device: run_walk_vo(walk, 300, kornia_vo_cfg(device)) for device in (DEVICE, "cpu")}
    walk.close()
    gpu = runs[DEVICE]
    score = gpu.score(tmp_path)
    assert score.ate_rmse_m <= 0.02 and score.rpe_percent <= 1.0
    assert all(s == TrackState.TRACKING for s in gpu.states[1:])
    gap = np.linalg.norm(gpu.estimate_wc[:, :3, 3] - runs["cpu"].estimate_wc[:, :3, 3], axis=1)
    assert gap.max() < 0.005


def test_kornia_features_with_opencv_pnp_on_cuda(scene, tmp_path):
    """The split path: features and matching on the GPU, ``solvePnPRansac`` on the host."""
    pytest.importorskip("cv2", reason="OpenCV (the perception extra) is not installed")
    walk = HeadCameraWalk(scene, width=640, height=480)
    run = run_walk_vo(walk, 150, dataclasses.replace(kornia_vo_cfg(DEVICE), pnp="opencv"))
    walk.close()
    score = run.score(tmp_path)
    assert score.ate_rmse_m <= 0.02 and score.rpe_percent <= 1.0


def test_tracking_resumes_on_cuda_within_1s_after_a_covered_lens(scene):
    walk = HeadCameraWalk(scene, width=320, height=240)
    run = run_walk_vo(walk, 130, kornia_vo_cfg(DEVICE), blackout=(60, 90))
    walk.close()
    assert all(s == TrackState.LOST for s in run.states[60:90])
    frames = run.recovery_frames(tolerance_m=0.05)
    assert frames is not None and frames <= 30
