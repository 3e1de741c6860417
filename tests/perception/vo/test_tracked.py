"""A consumer can tell a measured pose from a coasted one: ``VoResult.tracked`` is False exactly
while tracking is lost, and ``run_mapping`` never fuses or scores an untracked pose."""

import json

import numpy as np
import pytest

from ambulo.perception.vo.config import TrackState
from ambulo.perception.vo.eval import run_walk_vo
from ambulo.perception.vo.odometry import VoResult

pytest.importorskip("cv2", reason="the perception extra is not installed")
pytest.importorskip("evo", reason="the perception extra is not installed")


def test_tracked_is_false_exactly_while_the_lens_is_covered(tmp_path, rendered_walk):
    run = run_walk_vo(rendered_walk(320, 240), 75, blackout=(30, 45))  # 0.5 s of black frames without depth
    measured = {TrackState.TRACKING, TrackState.RECOVERED}
    assert run.tracked[0] and run.states[0] == TrackState.INITIALIZED  # the first keyframe: the given pose
    assert all(run.tracked[i] == (run.states[i] in measured) for i in range(1, len(run.states)))
    assert not run.tracked[30:45].any() and run.tracked[:30].all()
    # the coasted poses drift (what must not be acted on); the tracked ones after recovery do not
    error = run.position_error_m()
    assert error[30:45].max() > 0.02
    back = np.flatnonzero(run.tracked[45:])[0] + 45
    assert error[back:].max() < 0.05 and run.untracked_frames == back - 30
    # the score is over the tracked poses only
    score = run.score(tmp_path)
    assert score.num_poses == 75 - run.untracked_frames
    assert len((tmp_path / "estimate_all.tum").read_text().splitlines()) == 76


class _LostMidway:
    """An odometry that returns the true pose, except for frames [10, 15): a pose 1 m off, untracked."""

    def __init__(self, true_pose: dict):
        self.i, self.true_pose = -1, true_pose

    def track(self, rgb, depth, gyro=None):
        self.i += 1
        pose = self.true_pose["wc"].copy()
        lost = 10 <= self.i < 15
        if lost:
            pose[:3, 3] += (1.0, 0.0, 0.0)
        return VoResult(pose, TrackState.LOST if lost else TrackState.TRACKING, 0 if lost else 100, 1,
                        tracked=not lost)


def test_run_mapping_never_fuses_or_scores_an_untracked_pose(tmp_path, monkeypatch):
    from ambulo.perception import pipeline

    true_pose = {}
    real_make_walk = pipeline.make_walk

    def make_walk(*args, **kwargs):  # hand each frame's true pose to the stub odometry
        walk = real_make_walk(*args, **kwargs)
        frame = walk.frame

        def spy(i):
            f = frame(i)
            true_pose["wc"] = f.pose_wc.numpy().astype(np.float64)
            return f
        walk.frame = spy
        return walk

    def make_vo(*args, **kwargs):
        return _LostMidway(true_pose)

    fused = []
    real_integrate = pipeline.TsdfMap.integrate

    def integrate(self, frame):
        fused.append(frame.pose_wc.numpy().copy())
        return real_integrate(self, frame)

    monkeypatch.setattr(pipeline, "make_walk", make_walk)
    monkeypatch.setattr(pipeline, "RgbdOdometry", make_vo)
    monkeypatch.setattr(pipeline.TsdfMap, "integrate", integrate)
    cfg = pipeline.MapRunCfg(num_frames=25, width=160, height=120, vo_gyro=False)
    summary = pipeline.run_mapping(cfg, tmp_path)
    assert summary["untracked_frames"] == 5 and summary["fused_frames"] == 20 and len(fused) == 20
    truth = np.loadtxt(tmp_path / "groundtruth.tum")[:, 1:4]
    fused_xyz = np.array([p[:3, 3] for p in fused])
    # every fused pose is a true one (none of the 1 m-off coasted poses)
    assert np.abs(fused_xyz - np.delete(truth, range(10, 15), axis=0)).max() < 1e-4
    # the score covers the 20 tracked poses only (the 1 m errors would dominate an ATE over all 25)
    t = summary["trajectory"]
    assert t["num_poses"] == 20 and t["ate_rmse_m"] < 1e-3
    assert summary["trajectory_scored"] == "tracked poses only (20 of 25)"
    assert summary["untracked_max_position_error_m"] == pytest.approx(1.0, abs=1e-4)
    assert json.loads((tmp_path / "summary.json").read_text())["untracked_frames"] == 5
    assert len(np.loadtxt(tmp_path / "estimate_all.tum")) == 25
