"""Trajectories in TUM RGB-D format and their scores from ``evo`` (Grupp, *evo: Python package
for the evaluation of odometry and SLAM*, 2017): ATE (absolute trajectory error, after an SE(3)
alignment) and RPE (relative pose error over 1 m of travel, as a percentage of that metre).

The same numbers come from evo's command line on the written files::

    evo_ape tum groundtruth.tum estimate.tum --align
    evo_rpe tum groundtruth.tum estimate.tum --align --delta 1 --delta_unit m --all_pairs
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


@dataclass
class TrajectoryScore:
    ate_rmse_m: float
    """evo APE (translation part) RMSE after SE(3) alignment, m."""
    rpe_percent: float
    """evo RPE (translation part) RMSE over all pose pairs 1 m of travel apart, as % of 1 m (nan for a
    path shorter than that)."""
    rpe_deg_per_m: float
    """evo RPE (rotation angle) RMSE over the same pairs, deg per m."""
    path_length_m: float
    num_poses: int

    def as_dict(self) -> dict:
        return {k: round(v, 6) if isinstance(v, float) else v for k, v in self.__dict__.items()}


def score_tum(groundtruth: str | Path, estimate: str | Path, rpe_delta_m: float = 1.0) -> TrajectoryScore:
    """Score ``estimate`` against ``groundtruth`` (TUM files) with evo's own metrics."""
    from evo.core import filters, metrics, sync  # noqa: PLC0415 - perception extra
    from evo.core.units import Unit  # noqa: PLC0415
    from evo.tools import file_interface  # noqa: PLC0415

    ref = file_interface.read_tum_trajectory_file(str(groundtruth))
    est = file_interface.read_tum_trajectory_file(str(estimate))
    ref, est = sync.associate_trajectories(ref, est)
    est.align(ref, correct_scale=False)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    stat = metrics.StatisticsType.rmse
    rpe_values = []
    for relation in (metrics.PoseRelation.translation_part, metrics.PoseRelation.rotation_angle_deg):
        rpe = metrics.RPE(relation, delta=rpe_delta_m, delta_unit=Unit.meters, all_pairs=True)
        try:
            rpe.process_data((ref, est))
            rpe_values.append(float(rpe.get_statistic(stat)) / rpe_delta_m)
        except filters.FilterException:  # the path is shorter than the RPE's delta
            rpe_values.append(float("nan"))
    return TrajectoryScore(ate_rmse_m=float(ape.get_statistic(stat)),
                           rpe_percent=rpe_values[0] * 100.0, rpe_deg_per_m=rpe_values[1],
                           path_length_m=float(ref.path_length), num_poses=int(ref.num_poses))


__all__ = ["TrajectoryScore", "score_tum", "write_tum"]
