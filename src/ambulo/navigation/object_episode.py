"""One object-goal episode in a seeded apartment, scored as ObjectNav scores it (Batra et al. 2020,
*ObjectNav Revisited*, arXiv:2006.13171), and the shipped apartment-objects detector.

- **success**: the search ended "found", the robot standing (not fallen) within the time limit,
  its base within ``success_distance_m`` (1 m) of an instance of the class (its footprint, from the
  scene's ground truth) and facing it: the heading's ray meets that footprint within
  ``facing_ray_m``, or the footprint's nearest point is within ``facing_tolerance_deg`` (30 deg) of
  the heading;
- **SPL**: success x the shortest path (8-connected grid path with the robot's clearance) from the
  start to any place within ``success_distance_m`` of an instance, over max(walked, that);
- **distance_to_object_m**: the robot's final distance to the nearest instance's footprint;
- **localization_error_m**: from the point the robot went to (the fused detections) to the
  nearest instance's footprint (0 on it); **track_precision**: the share of confirmed tracks of
  the class whose point lies within ``correct_within_m`` of an instance.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import assets
from ..robots import humanoid
from ..scenes.apartment import Apartment, apartment
from ..scenes.apartment_labels import ObjectInstance, object_instances
from ..scenes.apartment_paths import path_length_m
from ..utils.validate import Checked
from .metrics import episode_world_cfg, spl
from .navigator import Navigator, NavigatorCfg
from .object_search import ObjectSearch, ObjectSearchCfg
from .world import NavWorld, NavWorldCfg

DETECTOR_PATH = Path(assets.get_assets_root_path()) / "detectors" / "apartment_objects" / "model.onnx"
"""The shipped apartment-objects detector (its training command and scores: ``TRAINING.md`` beside it)."""


@dataclass(kw_only=True)
class ObjectEpisodeCfg(Checked):
    navigator: NavigatorCfg = field(default_factory=lambda: NavigatorCfg(time_limit_s=60.0))
    """The navigator; its time limit bounds one walk (the search's legs are shorter)."""
    world: NavWorldCfg = field(default_factory=NavWorldCfg)
    search: ObjectSearchCfg = field(default_factory=ObjectSearchCfg)
    time_limit_s: float = 150.0
    success_distance_m: float = 1.0
    facing_tolerance_deg: float = 30.0
    facing_ray_m: float = 2.0
    correct_within_m: float = 0.5
    min_start_distance_m: float = 2.0
    """A drawn class has no instance nearer the start than this (the robot must search), m."""


def draw_label(apt: Apartment, start_xy_m, rng: np.random.Generator, min_distance_m: float) -> str:
    """A class present in ``apt`` with no instance within ``min_distance_m`` of the start."""
    by_label: dict[str, list[ObjectInstance]] = {}
    for inst in object_instances(apt):
        by_label.setdefault(inst.label, []).append(inst)
    ok = sorted(lab for lab, insts in by_label.items()
                if min(float(i.distance_m(start_xy_m)) for i in insts) >= min_distance_m)
    if not ok:
        raise RuntimeError(f"apartment {apt.seed}: no class farther than {min_distance_m} m from the start")
    return ok[int(rng.integers(len(ok)))]


def goal_instances(apt: Apartment, label: str) -> list[ObjectInstance]:
    """The instances of ``label`` in ``apt``: an object goal's targets. ValueError, in one line naming the
    classes ``apt`` has, when it has none (``run_object_episode`` and ``ambulo navigate --object`` both ask here)."""
    instances = object_instances(apt, label)
    if not instances:
        raise ValueError(f"apartment {apt.seed} has no {label}; it has "
                         f"{', '.join(sorted({i.label for i in object_instances(apt)}))}")
    return instances


def facing(pose_xyyaw, inst: ObjectInstance, tolerance_rad: float, ray_m: float) -> bool:
    """Whether a robot at ``pose_xyyaw`` faces ``inst`` (module docstring)."""
    x, y, yaw = (float(v) for v in pose_xyyaw)
    steps = np.linspace(0.0, ray_m, int(ray_m / 0.02) + 1)
    ray = np.stack([x + steps * math.cos(yaw), y + steps * math.sin(yaw)], -1)
    if (inst.distance_m(ray) <= 1e-9).any():
        return True
    px, py = nearest_point(inst, (x, y))
    return abs((math.atan2(py - y, px - x) - yaw + math.pi) % (2 * math.pi) - math.pi) <= tolerance_rad


def nearest_point(inst: ObjectInstance, xy_m) -> tuple[float, float]:
    """The point of ``inst``'s footprint nearest to ``xy_m``."""
    fp, p = inst.footprint, np.asarray(xy_m, float)
    if len(fp.rect_yaw_rad):
        c, s = math.cos(fp.rect_yaw_rad[0]), math.sin(fp.rect_yaw_rad[0])
        d = p - fp.rect_center_xy_m[0]
        local = np.clip([d[0] * c + d[1] * s, -d[0] * s + d[1] * c], -fp.rect_half_xy_m[0], fp.rect_half_xy_m[0])
        return (float(fp.rect_center_xy_m[0, 0] + local[0] * c - local[1] * s),
                float(fp.rect_center_xy_m[0, 1] + local[0] * s + local[1] * c))
    d = p - fp.disc_center_xy_m[0]
    n = float(np.hypot(*d))
    r = min(float(fp.disc_radius_m[0]), n)
    return tuple(float(v) for v in fp.disc_center_xy_m[0] + (d / n * r if n > 0 else 0.0))


def success_geodesic_m(apt: Apartment, start_xy_m, instances: list[ObjectInstance], within_m: float) -> float:
    """Shortest grid path with the robot's clearance from the start to within ``within_m`` of any instance, m."""
    paths = apt.paths
    cell = paths._cell(start_xy_m)
    if cell is None:
        return math.inf
    dist, _ = paths.grid_distances(cell, humanoid.BODY_RADIUS_M)
    near = np.zeros(paths.shape, bool)
    for inst in instances:
        near |= inst.distance_m(paths.centers_xy_m) <= within_m
    reach = dist[near & np.isfinite(dist)]
    return float(reach.min()) if reach.size else math.inf


class KnownObjects:
    """A stand-in detector that never fires, for the ceiling: the search is told the object's place."""

    canvas_hw = (1 << 16, 1 << 16)

    def __init__(self, categories):
        self.categories = list(categories)

    def __call__(self, rgb):
        from ..detection.detector import Detections

        return Detections(np.zeros((0, 4), np.float32), [], np.zeros(0, np.int64), np.zeros(0, np.float32))


def run_object_episode(apartment_seed: int, episode_seed: int, label: str | None = None,
                       cfg: ObjectEpisodeCfg | None = None, *, detector=None, walker=None, observer=None,
                       start_pose=None, known_object: bool = False) -> dict:
    """Search ``apartment(apartment_seed)`` for ``label`` (None: a class drawn with ``episode_seed``)
    from the start ``sample_start_goal(episode_seed)`` draws (or ``start_pose``); returns the
    episode's metrics (module docstring) as a JSON-ready dict. ``known_object``: the ceiling, no
    detector and no search: the search starts with the true nearest instance's nearest footprint
    point confirmed (the same approach and facing)."""
    cfg = cfg or ObjectEpisodeCfg()
    if known_object:
        from ..scenes.apartment_labels import object_labels

        detector = KnownObjects(object_labels())
    if detector is None:
        from ..detection import Detector

        detector = Detector(DETECTOR_PATH, score_threshold=cfg.search.score_threshold)
    apt = apartment(apartment_seed)
    if start_pose is None:
        start_pose = apt.sample_start_goal(episode_seed, 3.0, 8.0, humanoid.BODY_RADIUS_M).start_pose
    if label is None:
        label = draw_label(apt, start_pose[:2], np.random.default_rng([episode_seed, apartment_seed, 7]),
                           cfg.min_start_distance_m)
    instances = goal_instances(apt, label)
    t0 = time.perf_counter()
    world = NavWorld.from_apartment(apt, start_pose, episode_world_cfg(cfg.world, cfg.navigator.mode))
    nav = Navigator(world, cfg.navigator, walker=walker)
    search = ObjectSearch(nav, detector, label, cfg.search)
    if known_object:
        geo = [success_geodesic_m(apt, start_pose[:2], [i], 0.3) for i in instances]
        nearest = instances[int(np.argmin(geo))]
        point = np.array([*nearest_point(nearest, start_pose[:2]), 0.3])
        for _ in range(cfg.search.objects.min_views):
            search.objects.add(label, point, 1.0)
    if observer is not None:
        nav.add_observer(observer)
    try:
        res = search.run(cfg.time_limit_s)
    finally:
        world.close()
    wall_s = time.perf_counter() - t0
    final = world.true_pose()
    dists = [float(i.distance_m(final[:2])) for i in instances]
    nearest = instances[int(np.argmin(dists))]
    faces = facing(final, nearest, math.radians(cfg.facing_tolerance_deg), cfg.facing_ray_m)
    ok = bool(res.status == "found" and not world.fell and min(dists) <= cfg.success_distance_m and faces)
    walked = path_length_m(np.array(nav.walked_path_xy_m + [final[:2]]).reshape(-1, 2))
    geodesic = success_geodesic_m(apt, start_pose[:2], instances, cfg.success_distance_m)
    loc_err = None if res.object_xy_m is None else float(min(i.distance_m(res.object_xy_m) for i in instances))
    confirmed = [t for t in res.tracks if t["views"] >= cfg.search.objects.min_views]
    correct = [min(float(i.distance_m(t["point_w"][:2])) for i in instances) <= cfg.correct_within_m for t in confirmed]
    return {
        "apartment_seed": apartment_seed, "episode_seed": episode_seed, "mode": cfg.navigator.mode, "label": label,
        "start_pose": [float(v) for v in start_pose], "status": res.status, "success": ok,
        "spl": spl(ok, geodesic, walked),
        "geodesic_m": geodesic, "path_length_m": walked, "distance_to_object_m": min(dists), "facing": faces,
        "fell": bool(world.fell), "collisions": len(world.collisions), "time_s": res.time_s, "wall_s": wall_s,
        "object_xy_m": None if res.object_xy_m is None else [float(v) for v in res.object_xy_m],
        "object_views": res.views, "localization_error_m": loc_err,
        "localized_correct": None if loc_err is None else loc_err <= cfg.correct_within_m,
        "confirmed_tracks": len(confirmed), "correct_tracks": int(sum(correct)),
        "detections": res.detections, "legs": res.legs, "final_pose": [float(v) for v in final],
        "known_object": known_object,
        "ate_m": float(np.sqrt(np.mean(np.square(nav.frame_errors_m)))) if nav.frame_errors_m else 0.0,
    }


__all__ = ["DETECTOR_PATH", "KnownObjects", "ObjectEpisodeCfg", "draw_label", "facing", "goal_instances", "nearest_point",
           "run_object_episode", "success_geodesic_m"]
