"""Trajectory scores (evo ATE / RPE) of runs too short or too still to score: no crash in evo's
Umeyama alignment and no silent NaN, but None with a one-line reason; real runs score as before."""

import numpy as np
import pytest

pytest.importorskip("evo", reason="the perception extra is not installed")

from ambulo.perception.trajectory import alignment_problem, score_tum, write_tum
from ambulo.perception.vo.eval import VoRun, run_walk_vo


def poses(xyz) -> np.ndarray:
    """(N, 4, 4) camera-to-world poses at the (N, 3) positions, level heading."""
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    out = np.tile(np.eye(4), (len(xyz), 1, 1))
    out[:, :3, 3] = xyz
    return out


def walk_xyz(n: int, length_m: float = 2.0) -> np.ndarray:
    """A curved walk with a head bob: ``length_m`` of travel in x over ``n`` poses."""
    s = np.linspace(0.0, 1.0, n)
    return np.stack([length_m * s, 0.3 * np.sin(3 * s), 1.5 + 0.03 * np.sin(20 * s)], axis=1)


def score(tmp_path, truth_xyz, estimate_xyz):
    times = np.arange(len(truth_xyz)) / 30.0
    return score_tum(write_tum(tmp_path / "gt.tum", times, poses(truth_xyz)),
                     write_tum(tmp_path / "est.tum", times, poses(estimate_xyz)))


def test_a_real_walk_scores_as_evo_does(tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    truth = walk_xyz(90)
    estimate = truth + np.random.default_rng(0).normal(0, 0.01, truth.shape)
    s = score(tmp_path, truth, estimate)
    assert s.ate_unavailable is None and s.rpe_unavailable is None
    ref, est = sync.associate_trajectories(file_interface.read_tum_trajectory_file(str(tmp_path / "gt.tum")),
                                           file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum")))
    est.align(ref)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    assert s.ate_rmse_m == pytest.approx(ape.get_statistic(metrics.StatisticsType.rmse))
    assert 0.005 < s.ate_rmse_m < 0.02 and 0 < s.rpe_percent < 5 and s.rpe_deg_per_m == 0.0
    assert s.num_poses == 90 and s.path_length_m > 2.0


STILL = np.tile([0.1, -1.5, 1.5], (8, 1))


@pytest.mark.parametrize("truth,estimate,reason", [
    (walk_xyz(8, 0.2), STILL, "the estimated camera did not move over the 8 poses"),  # VO never started
    (STILL, walk_xyz(8, 0.2), "the ground-truth camera did not move"),  # the robot has not moved yet
    (walk_xyz(2, 0.1), walk_xyz(2, 0.1) + 0.01, "2 poses: the alignment needs at least 3"),
    (walk_xyz(1), walk_xyz(1), "1 pose: the alignment needs at least 3"),
    (np.linspace([0, 0, 1.5], [0.5, 0, 1.5], 10), walk_xyz(10, 0.5), "ground-truth camera moved on a straight line"),
    (walk_xyz(10, 0.5), np.linspace([0, 0, 1.5], [0.5, 0, 1.5], 10), "estimated camera moved on a straight line"),
])
def test_a_path_that_cannot_be_aligned_has_no_ate_and_says_why(tmp_path, truth, estimate, reason):
    s = score(tmp_path, truth, estimate)
    assert s.ate_rmse_m is None and reason in s.ate_unavailable and "\n" not in s.ate_unavailable
    assert s.num_poses == len(truth)
    assert s.rpe_percent is None and s.rpe_deg_per_m is None and "1 m apart" in s.rpe_unavailable
    d = s.as_dict()
    assert d["ate_rmse_m"] is None and d["ate_unavailable"] == s.ate_unavailable


def test_a_long_walk_the_odometry_never_followed_has_an_rpe_but_no_ate(tmp_path):
    """The RPE needs no alignment (relative poses): a 2 m walk seen as 2 m along one straight line."""
    truth = walk_xyz(60)
    estimate = np.linspace([0, 0, 1.5], [2.0, 0, 1.5], 60)
    s = score(tmp_path, truth, estimate)
    assert s.ate_rmse_m is None and "straight line" in s.ate_unavailable
    assert s.rpe_unavailable is None and s.rpe_percent > 0


def test_a_path_shorter_than_the_rpe_metre_has_an_ate_and_no_rpe(tmp_path):
    truth = walk_xyz(20, 0.3)
    estimate = truth * [1.02, 1.0, 1.0]
    s = score(tmp_path, truth, estimate)
    assert s.ate_rmse_m is not None and s.ate_rmse_m < 0.01 and s.ate_unavailable is None
    assert s.rpe_percent is None and s.rpe_deg_per_m is None and s.path_length_m < 0.9
    length = np.linalg.norm(np.diff(estimate, axis=0), axis=1).sum()
    assert s.rpe_unavailable == f"no pose pairs 1 m apart along the estimated path, {length:.2f} m long"


def test_no_poses_scores_as_not_available(tmp_path):
    s = score(tmp_path, np.zeros((0, 3)), np.zeros((0, 3)))
    assert s.num_poses == 0 and s.ate_rmse_m is None and s.rpe_percent is None
    assert s.ate_unavailable == s.rpe_unavailable == "no poses to score"


def test_alignment_problem_passes_a_real_walk():
    assert alignment_problem(walk_xyz(3, 0.1), walk_xyz(3, 0.1)) is None
    assert "0 poses" in alignment_problem(np.zeros((0, 3)), np.zeros((0, 3)))


def test_vo_run_of_an_odometry_that_never_started_scores_without_crashing(tmp_path):
    n = 5
    truth = poses(walk_xyz(n, 0.1))
    run = VoRun(np.arange(n) / 30.0, np.repeat(truth[:1], n, axis=0), truth, [], [], None)
    s = run.score(tmp_path)
    assert s.ate_rmse_m is None and "estimated camera did not move" in s.ate_unavailable
    assert (tmp_path / "estimate.tum").exists() and (tmp_path / "groundtruth.tum").exists()


@pytest.mark.parametrize("frames", [0, -3])
def test_run_walk_vo_refuses_no_frames(frames):
    with pytest.raises(ValueError, match=f"num_frames is {frames}: a run needs at least 1 frame"):
        run_walk_vo(None, frames)


def test_run_mapping_refuses_no_frames(tmp_path):
    from ambulo.perception.pipeline import MapRunCfg, run_mapping

    with pytest.raises(ValueError, match="num_frames is 0: a map needs at least 1 frame"):
        run_mapping(MapRunCfg(num_frames=0), tmp_path / "m")
    assert not (tmp_path / "m").exists()
