"""``ambulo navigate apartment --seed S --object chair``: an object goal (``navigation.object_search``):
the robot looks around and explores until the shipped apartment-objects detector (or ``--detector``)
has seen the object from several views, then walks to within 1 m of it and stops facing it.

Writes ``<out>/episode.json`` (``navigation.object_episode``'s metrics), ``<out>/map.png`` and, with
``--video``, the MP4; the exit status is 0 on success (within 1 m, facing it, standing), 1 otherwise.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .errors import CliError, check_output_file, check_seconds


def run_object(args: argparse.Namespace, *, parse_start, check_point) -> int:
    """One object-goal episode; ``parse_start`` and ``check_point`` are ``navigate``'s (--start as there)."""
    from ..navigation.benchmark import pinned_threads

    with pinned_threads():
        return _run_object(args, parse_start, check_point)


def _run_object(args: argparse.Namespace, parse_start, check_point) -> int:
    if args.world not in (None, "apartment"):
        raise CliError(f"--object searches a seeded apartment (its objects' ground truth scores it), not {args.world!r}",
                       "drop the world argument")
    for flag, value in (("--goal", args.goal), ("--episodes", args.episodes)):
        if value is not None:
            raise CliError(f"{flag} does not go with --object (the object is the goal; one episode)", f"drop {flag}")
    if args.walker != "policy":
        raise CliError("--object looks around by turning on the spot, which only the policy walker does",
                       "drop --walker zmp")
    if args.time_limit is not None:
        check_seconds(args.time_limit, "--time-limit")
    from ..scenes.apartment_labels import canonical_label

    try:
        label = canonical_label(args.object)
    except ValueError as err:
        raise CliError(str(err), "give one of those names to --object") from None
    out = Path(args.out).expanduser()
    check_output_file(out / "episode.json", "--out")
    if args.video is not None:
        check_output_file(args.video, "--video")

    from ..detection import Detector
    from ..navigation.benchmark import EpisodeSpec, episode_cfg, with_perception_device
    from ..navigation.object_episode import DETECTOR_PATH, ObjectEpisodeCfg, goal_instances, run_object_episode
    from ..navigation.video import EpisodeVideo
    from ..scenes.apartment import apartment
    from ..utils.atomic import atomic_write_json

    path = Path(args.detector).expanduser() if args.detector else DETECTOR_PATH
    if not path.is_file():
        raise CliError(f"no detector at {path}", "give --detector MODEL.onnx (from `ambulo export-detector`)")
    base = ObjectEpisodeCfg()
    detector = Detector(path, score_threshold=base.search.score_threshold)
    if label not in detector.categories:
        raise CliError(f"the detector {path} knows {', '.join(detector.categories)}, not {label}",
                       "give a detector trained on apartment objects (--detector)")
    mode = args.mode
    spec = EpisodeSpec(args.seed, args.episode_seed, mode, "policy", args.randomize)
    nav_cfg = episode_cfg(spec, with_perception_device(args.perception_device))
    cfg = ObjectEpisodeCfg(navigator=type(nav_cfg.navigator)(**{**nav_cfg.navigator.__dict__, "time_limit_s": 60.0}),
                           world=nav_cfg.world, time_limit_s=args.time_limit or base.time_limit_s)
    apt = apartment(args.seed)
    try:
        goal_instances(apt, label)
    except ValueError as err:
        raise CliError(str(err), "give one of those to --object, or another --seed") from None
    video = EpisodeVideo(args.video, map_png=out / "map.png", title=f"apartment {args.seed}  {mode}  {label}",
                         view_xy_m=apt.occupancy.extent_xy_m())
    start = None
    if args.start is not None:
        from ..robots import humanoid

        start = parse_start(args.start)
        check_point(apt.occupancy, start, "--start", humanoid.BODY_RADIUS_M)
    print(f"navigate: apartment {args.seed}, mode {mode}, object {label} (detector {path.name}), "
          f"time limit {cfg.time_limit_s:.0f} s")
    try:
        result = run_object_episode(args.seed, args.episode_seed, label, cfg, detector=detector, observer=video,
                                    start_pose=start)
    except BaseException:
        video.abort()
        raise
    files = video.close(final_pose_xyyaw=result["final_pose"])
    atomic_write_json(out / "episode.json", result, indent=1)
    where = "no object localized" if result["object_xy_m"] is None else \
        f"object at {result['object_xy_m'][0]:.2f},{result['object_xy_m'][1]:.2f} ({result['object_views']} views, " \
        f"{result['localization_error_m']:.2f} m from the true {label})"
    print(f"{result['status']}{' (success)' if result['success'] else ''}: {where}; stopped "
          f"{result['distance_to_object_m']:.2f} m from the nearest {label}, facing it: {result['facing']}; walked "
          f"{result['path_length_m']:.2f} m, SPL {result['spl']:.2f}, {result['time_s']:.1f} s simulated in "
          f"{result['wall_s']:.1f} s")
    for file in [*files, out / "episode.json"]:
        print(f"wrote {file}")
    return 0 if result["success"] else 1
