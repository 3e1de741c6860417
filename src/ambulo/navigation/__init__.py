"""The autonomous humanoid navigator (issue 24): a humanoid in a scene it has never seen walks to a
goal from its own sensors.

- ``world``: ``NavWorld``, the simulation (an apartment or a user's MJCF/USD/``MjSpec`` world, the
  humanoid, its head RGB-D camera and gyro, ground truth, fall and collision monitors);
- ``localization``: ``OracleLocalizer`` (ground truth), ``VoLocalizer`` (RGB-D odometry + gyro,
  with a tracked flag per frame);
- ``mapping``: ``OracleMapper`` (ground-truth occupancy), ``OnlineMapper`` (TSDF -> body-band slice);
- ``planning``: route (unknown optimistic) -> subgoal -> footsteps (unknown blocked);
- ``walkers``: the ``Walker`` interface and ``PolicyWalker`` (the shipped walking policy);
- ``navigator``: ``Navigator``, the closed loop, modes ``oracle`` / ``mapping`` / ``full``;
- ``metrics``: ``EpisodeResult`` (success, SPL, collisions, ...) and ``run_episode``.

    from ambulo.navigation import EpisodeCfg, NavigatorCfg, run_episode
    result = run_episode(3, 0, EpisodeCfg(navigator=NavigatorCfg(mode="full")))
    print(result.to_json())
"""

from .localization import OracleLocalizer, PoseEstimate, VoLocalizer, VoLocalizerCfg
from .mapping import OnlineMapper, OnlineMapperCfg, OracleMapper, costmap_of
from .metrics import EpisodeCfg, EpisodeResult, result_of, run_episode
from .navigator import MODES, Navigator, NavigatorCfg, NavSnapshot
from .planning import PlanningCfg, ReplanRecord, Route
from .randomization import RandomizationCfg
from .tracker import PathTracker, TrackerCfg
from .walkers import BalanceReport, PolicyWalker, PolicyWalkerCfg, Walker, body_path
from .world import NavWorld, NavWorldCfg

__all__ = [
    "MODES", "BalanceReport", "EpisodeCfg", "EpisodeResult", "NavSnapshot", "NavWorld", "NavWorldCfg", "Navigator",
    "NavigatorCfg", "OnlineMapper", "OnlineMapperCfg", "OracleLocalizer", "OracleMapper", "PathTracker",
    "PlanningCfg", "PolicyWalker", "PolicyWalkerCfg", "PoseEstimate", "RandomizationCfg", "ReplanRecord", "Route",
    "TrackerCfg", "VoLocalizer", "VoLocalizerCfg", "Walker", "body_path", "costmap_of", "result_of", "run_episode",
]
