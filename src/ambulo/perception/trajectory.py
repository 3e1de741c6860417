"""Trajectories in TUM RGB-D format and their scores from ``evo`` (Grupp, *evo: Python package
for the evaluation of odometry and SLAM*, 2017): ATE (absolute trajectory error, after an SE(3)
alignment) and RPE (relative pose error over 1 m of travel, as a percentage of that metre).

The same numbers come from evo's command line on the written files::

    evo_ape tum groundtruth.tum estimate.tum --align
    evo_rpe tum groundtruth.tum estimate.tum --align --delta 1 --delta_unit m --all_pairs

A score that cannot mean anything is not a number but ``None`` with a one-line reason
(``TrajectoryScore.ate_unavailable`` / ``rpe_unavailable``): the SE(3) alignment needs at least three
poses on each path that do not lie on one line (a camera that has not moved, or whose odometry
never started, cannot be aligned: evo's Umeyama alignment raises on it), and the RPE needs pose pairs
1 m apart along the estimated path.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ambulo.utils.rotations import mat_to_quat


def write_tum(path: str | Path, times_s, poses_wc) -> Path:
    """Write ``timestamp tx ty tz qx qy qz qw`` lines (camera-to-world poses, metres)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    poses = np.asarray(poses_wc, float).reshape(-1, 4, 4)
    quats = mat_to_quat(poses[:, :3, :3])  # (w, x, y, z)
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        for t, pose, q in zip(np.asarray(times_s, float), poses, quats):
            x, y, z = pose[:3, 3]
            f.write(f"{t:.6f} {x:.6f} {y:.6f} {z:.6f} {q[1]:.8f} {q[2]:.8f} {q[3]:.8f} {q[0]:.8f}\n")
    return path


MIN_EXTENT_M = 1e-4
"""A path whose positions spread less than this (RMS, m) across their main direction is a point or
a line to the alignment: too little to fix a rotation (TUM files keep 1e-6 m)."""


@dataclass
class TrajectoryScore:
    ate_rmse_m: float | None
    """evo APE (translation part) RMSE after SE(3) alignment, m; None when the paths cannot be aligned
    (``ate_unavailable`` says why)."""
    rpe_percent: float | None
    """evo RPE (translation part) RMSE over all pose pairs 1 m of travel apart along the estimate, as %
    of 1 m; None without such pairs (a path shorter than that; ``rpe_unavailable`` says why)."""
    rpe_deg_per_m: float | None
    """evo RPE (rotation angle) RMSE over the same pairs, deg per m (None with ``rpe_percent``)."""
    path_length_m: float
    num_poses: int
    ate_unavailable: str | None = None
    """Why there is no ATE (one line), else None."""
    rpe_unavailable: str | None = None
    """Why there is no RPE (one line), else None."""

    def as_dict(self) -> dict:
        return {k: round(v, 6) if isinstance(v, float) else v for k, v in self.__dict__.items()}


def alignment_problem(ref_xyz, est_xyz, min_extent_m: float = MIN_EXTENT_M) -> str | None:
    """Why the (N, 3) positions ``est_xyz`` cannot be SE(3)-aligned to ``ref_xyz`` (one line), or
    None: fewer than 3 poses, or either path a point (the camera did not move) or a straight line
    (the rotation about it is undetermined) to within ``min_extent_m`` RMS."""
    ref_xyz, est_xyz = np.asarray(ref_xyz, float).reshape(-1, 3), np.asarray(est_xyz, float).reshape(-1, 3)
    n = len(ref_xyz)
    if n < 3:
        return f"{n} pose{'s' * (n != 1)}: the alignment needs at least 3 poses not on one line"
    for name, xyz in (("ground-truth", ref_xyz), ("estimated", est_xyz)):
        extent = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False) / np.sqrt(n)  # RMS along each axis
        if extent[0] < min_extent_m:
            why = "; the odometry never started or lost track at once" if name == "estimated" else ""
            return (f"the {name} camera did not move over the {n} poses ({extent[0] * 1e3:.2f} mm RMS{why}): "
                    "nothing to align")
        if extent[1] < min_extent_m:
            return (f"the {name} camera moved on a straight line over the {n} poses ({extent[1] * 1e3:.2f} mm RMS "
                    "off it): the alignment's rotation about it is undetermined")
    return None


def score_tum(groundtruth: str | Path, estimate: str | Path, rpe_delta_m: float = 1.0) -> TrajectoryScore:
    """Score ``estimate`` against ``groundtruth`` (TUM files) with evo's own metrics; a metric that
    cannot be computed (``alignment_problem``, a path too short for the RPE) is None with its reason."""
    from evo.core import filters, geometry, metrics, sync  # perception extra
    from evo.core.units import Unit
    from evo.tools import file_interface

    if not (_has_poses(groundtruth) and _has_poses(estimate)):
        none = "no poses to score"
        return TrajectoryScore(None, None, None, 0.0, 0, ate_unavailable=none, rpe_unavailable=none)
    ref = file_interface.read_tum_trajectory_file(str(groundtruth))
    est = file_interface.read_tum_trajectory_file(str(estimate))
    ref, est = sync.associate_trajectories(ref, est)
    stat = metrics.StatisticsType.rmse
    ate, ate_unavailable = None, alignment_problem(ref.positions_xyz, est.positions_xyz)
    if ate_unavailable is None:
        try:
            est.align(ref, correct_scale=False)
        except geometry.GeometryException as err:  # the paths do not vary together (a degenerate covariance)
            ate_unavailable = f"evo cannot align the estimate to the ground truth: {err}"
        else:
            ape = metrics.APE(metrics.PoseRelation.translation_part)
            ape.process_data((ref, est))
            ate = float(ape.get_statistic(stat))
    rpe_values, rpe_unavailable = [], None  # relative poses: the same with or without the alignment
    for relation in (metrics.PoseRelation.translation_part, metrics.PoseRelation.rotation_angle_deg):
        rpe = metrics.RPE(relation, delta=rpe_delta_m, delta_unit=Unit.meters, all_pairs=True)
        try:
            rpe.process_data((ref, est))
        except filters.FilterException:  # no pose pairs rpe_delta_m apart: the path is shorter than that
            rpe_unavailable = (f"no pose pairs {rpe_delta_m:g} m apart along the estimated path, "
                               f"{est.path_length:.2f} m long")
            rpe_values = [None, None]
            break
        rpe_values.append(float(rpe.get_statistic(stat)) / rpe_delta_m)
    return TrajectoryScore(ate_rmse_m=ate, rpe_percent=None if rpe_values[0] is None else rpe_values[0] * 100.0,
                           rpe_deg_per_m=rpe_values[1], path_length_m=float(ref.path_length),
                           num_poses=int(ref.num_poses), ate_unavailable=ate_unavailable,
                           rpe_unavailable=rpe_unavailable)


def _has_poses(path: str | Path) -> bool:
    """Whether the TUM file has a pose line (evo cannot read one without)."""
    with open(path) as f:
        return any(line.strip() and not line.lstrip().startswith("#") for line in f)


__all__ = ["MIN_EXTENT_M", "TrajectoryScore", "alignment_problem", "score_tum", "write_tum"]
