"""``ambulo navigate``: the autonomous humanoid navigator (``ambulo.navigation``) on one episode or
on a benchmark of many.

    ambulo navigate apartment --seed 3 --goal 4.0,2.5 --mode full --video out/nav.mp4
    ambulo navigate my_world.xml --start 0,0,0 --goal 3,1
    ambulo navigate --episodes 100 --workers 2 --mode oracle,full --out out/nav_bench

One episode writes ``<out>/episode.json`` (``EpisodeResult``), ``<out>/map.png`` (the final map
with the walked path) and, with ``--video``, the MP4; the exit status is 0 on success, 1 when the
robot did not arrive. A benchmark (``--episodes``) runs ``navigation.benchmark``: one JSON per
episode under ``<out>/episodes`` (a rerun skips those that exist), a table and ``summary.json``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from .errors import CliError, check_output_file, check_seconds
from .viewer_args import add_viewer_args, viewer_kind

_WORLD_SUFFIXES = (".xml", ".mjcf", ".usd", ".usda", ".usdc", ".usdz")


def _numbers(text: str, flag: str, sizes: tuple[int, ...], example: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in sizes or not all(math.isfinite(v) for v in values):
        what = " or ".join(("x,y", "x,y,yaw")[n - 2] for n in sizes)
        raise CliError(f"{flag} {text!r} is not {what}", f"give numbers in m (yaw in degrees), e.g. {flag} {example}")
    return values


def parse_goal(text: str) -> tuple[float, float]:
    x, y = _numbers(text, "--goal", (2,), "4.0,2.5")
    return x, y


def parse_start(text: str) -> tuple[float, float, float]:
    """``x,y[,yaw]`` (m, m, degrees) -> (x m, y m, yaw rad)."""
    x, y, yaw_deg = ([*_numbers(text, "--start", (2, 3), "1.0,2.0,90"), 0.0])[:3]
    return x, y, math.radians(yaw_deg)


def check_point(grid, xy, flag: str, clearance_m: float) -> None:
    """``CliError`` when ``xy`` is outside ``grid`` (a ``maps.Grid2D``), in an obstacle or closer
    than ``clearance_m`` to one; the fix names the nearest point that would do."""
    import numpy as np
    from scipy import ndimage

    x0, y0, x1, y1 = grid.extent_xy_m()
    x, y = float(xy[0]), float(xy[1])
    text = f"{flag} {x:g},{y:g}"
    if not (x0 <= x < x1 and y0 <= y < y1):
        raise CliError(f"{text} is outside the map (x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m)",
                       "give a point inside it")
    occupied = grid.occupied()
    # distance from a cell centre to the nearest occupied cell's edge
    clearance = ndimage.distance_transform_edt(~occupied) * grid.resolution_m - grid.resolution_m / 2
    clearance[occupied] = 0.0
    iy, ix = grid.cell_of((x, y))
    here = float(clearance[iy, ix])
    if here >= clearance_m:
        return
    good = np.argwhere((clearance >= clearance_m + grid.resolution_m) & ~grid.unknown())
    fix = "choose a point in free space"
    if len(good):
        xs, ys = grid.cell_center_xy_m(good[:, 0], good[:, 1])
        k = int(np.argmin((xs - x) ** 2 + (ys - y) ** 2))
        fix = f"the nearest point with room for the robot is {flag} {xs[k]:.2f},{ys[k]:.2f}"
    if occupied[iy, ix]:
        raise CliError(f"{text} is inside an obstacle", fix)
    raise CliError(f"{text} is {max(here, 0.0):.2f} m from an obstacle; the robot needs {clearance_m:.2f} m", fix)


def _world_kind(world: str | None) -> str:
    if world is None or world == "apartment":
        return "apartment"
    path = Path(world).expanduser()
    if not path.is_file():
        raise CliError(f"world {world!r} is neither 'apartment' nor a file",
                       "give 'apartment' or the path of an MJCF (.xml) or USD world")
    if path.suffix.lower() not in _WORLD_SUFFIXES:
        raise CliError(f"world {world!r} has the unknown format {path.suffix!r}",
                       "give an MJCF (.xml) or USD (.usd/.usda/.usdc) world")
    return "file"


def _modes(text: str, many: bool) -> list[str]:
    from ..navigation import MODES

    modes = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in modes if m not in MODES]
    if bad or not modes:
        raise CliError(f"--mode {text!r} is not a mode", f"use one of {', '.join(MODES)}"
                       + (" (comma-separated for a benchmark)" if many else ""))
    if len(modes) > 1 and not many:
        raise CliError(f"--mode {text!r} names several modes for one episode", "give one, or add --episodes N")
    return modes


def run_one(args: argparse.Namespace) -> int:
    """One episode (module docstring), with torch and OpenCV on one thread as in the benchmark's
    workers, so that an episode of ``--episodes N`` replays alike on its own."""
    from ..navigation.benchmark import pinned_threads

    with pinned_threads():
        return _run_one(args)


def _run_one(args: argparse.Namespace) -> int:
    watch = viewer_kind(args)
    kind = _world_kind(args.world)
    mode = _modes(args.mode, many=False)[0]
    goal = None if args.goal is None else parse_goal(args.goal)
    start = None if args.start is None else parse_start(args.start)
    if kind == "file" and (goal is None or start is None):
        raise CliError(f"a world file needs --start and --goal (missing {'--start' if start is None else '--goal'})",
                       "give e.g. --start 0,0,0 --goal 3,1")
    if args.time_limit is not None:
        check_seconds(args.time_limit, "--time-limit")
    out = Path(args.out).expanduser()
    check_output_file(out / "episode.json", "--out")
    if args.video is not None:
        check_output_file(args.video, "--video")

    from ..navigation import Navigator, NavigatorCfg, NavWorld, result_of  # heavy imports only when run
    from ..navigation.benchmark import EpisodeSpec, episode_cfg, make_walker, with_perception_device
    from ..navigation.metrics import episode_world_cfg
    from ..navigation.planning import PlanningCfg, RoutePlanner
    from ..navigation.video import EpisodeVideo
    from ..robots import humanoid
    from ..scenes.apartment import apartment
    from ..utils.atomic import atomic_write_json

    spec = EpisodeSpec(args.seed, args.episode_seed, mode, args.walker, args.randomize)
    walker = make_walker(args.walker)
    cfg = episode_cfg(spec, with_perception_device(args.perception_device))
    world_cfg = episode_world_cfg(cfg.world, mode)
    radius = humanoid.BODY_RADIUS_M
    if kind == "apartment":
        apt = apartment(args.seed)
        if goal is None or start is None:
            ep = apt.sample_start_goal(args.episode_seed, cfg.min_geodesic_m, cfg.max_geodesic_m, radius)
            start = start or tuple(ep.start_pose)
            goal = goal or tuple(ep.goal_xy_m)
        check_point(apt.occupancy, start, "--start", radius)
        check_point(apt.occupancy, goal, "--goal", radius)
        geodesic_m = apt.geodesic_m(start[:2], goal, radius)
        if not math.isfinite(geodesic_m):
            raise CliError(f"no path with room for the robot joins --start and --goal in apartment {args.seed}",
                           "choose a goal in a room the start can reach")
        world = NavWorld.from_apartment(apt, start, world_cfg)
        name = f"apartment {args.seed}"
    else:
        world = NavWorld.from_file(args.world, start, world_cfg, cover_xy_m=[goal])  # the map reaches the goal
        try:
            check_point(world.occupancy, start, "--start", radius)
            check_point(world.occupancy, goal, "--goal", radius)
        except CliError:
            world.close()
            raise
        textured, visible = world.textured_geoms()
        if mode == "full" and textured == 0:
            print(f"warning: none of the {visible} surfaces of {Path(args.world).name} has a texture: full mode's "
                  "visual odometry tracks image features and will lose its pose on plain colours; give the walls "
                  "and floor textured materials, or use --mode mapping (true pose)", file=sys.stderr)
        # no exact geodesic for a user's world: the navigator's route on its true map (cell path)
        route = RoutePlanner(PlanningCfg(inflation_gain=0.0)).route(world.occupancy, 0, start[:2], goal)
        geodesic_m = route.length_m if route.found else math.inf
        name = Path(args.world).name
    limit_s = args.time_limit or cfg.time_limit_base_s + cfg.time_limit_per_m_s * (
        geodesic_m if math.isfinite(geodesic_m) else 2 * math.dist(start[:2], goal))
    nav_cfg = NavigatorCfg(**{**cfg.navigator.__dict__, "time_limit_s": limit_s})
    print(f"navigate: {name}, mode {mode}, walker {args.walker}{', randomized' if args.randomize else ''}: "
          f"start {start[0]:.2f},{start[1]:.2f},{math.degrees(start[2]):.0f} deg -> goal {goal[0]:.2f},{goal[1]:.2f} "
          f"(geodesic {geodesic_m:.2f} m, time limit {limit_s:.0f} s)")
    t0 = time.perf_counter()
    viewer = None
    try:
        if watch is not None:
            from ..viewer import serve

            viewer = serve(world, port=args.viewer_port)
        nav = Navigator(world, nav_cfg, walker=walker)
        video = EpisodeVideo(args.video, map_png=out / "map.png", title=f"{name}  {mode}",
                             goal_tolerance_m=nav_cfg.goal_tolerance_m,
                             view_xy_m=world.occupancy.extent_xy_m())  # an online map covers far more
        nav.add_observer(video, images=args.video is not None)
        if viewer is not None:  # the page's map, plan, footsteps and walked path
            nav.add_observer(viewer.navigator_observer, images=False)
        nav.set_goal(goal)
        try:
            nav.run()
        except BaseException:
            video.abort()
            raise
        final_pose = world.true_pose()
    finally:
        if viewer is not None:
            viewer.close()
        world.close()
    result = result_of(nav, geodesic_m=geodesic_m, wall_s=time.perf_counter() - t0,
                       apartment_seed=args.seed if kind == "apartment" else None,
                       episode_seed=args.episode_seed if kind == "apartment" else None)
    if kind == "file":
        result.extras["geodesic"] = "route on the true map (cell path), not exact"
    files = video.close(final_pose_xyyaw=final_pose)
    atomic_write_json(out / "episode.json", {**result.__dict__, "world": str(args.world or "apartment")}, indent=1)
    print(f"{result.status}{' (success)' if result.success else ''}: {result.distance_to_goal_m:.2f} m from the goal, "
          f"walked {result.path_length_m:.2f} m, SPL {result.spl:.2f}, {result.collisions} collisions, "
          f"{result.num_replans} replans (p95 {1e3 * result.replan_p95_s:.0f} ms), "
          f"{result.time_s:.1f} s simulated in {result.wall_s:.1f} s")
    for file in [*files, out / "episode.json"]:
        print(f"wrote {file}")
    return 0 if result.success else 1


def run_many(args: argparse.Namespace) -> int:
    """A benchmark (module docstring)."""
    if args.world not in (None, "apartment"):
        raise CliError(f"--episodes runs on apartments, not on {args.world!r}", "drop the world argument or --episodes")
    for flag, value in (("--goal", args.goal), ("--start", args.start), ("--video", args.video),
                        ("--time-limit", args.time_limit)):
        if value is not None:
            raise CliError(f"{flag} applies to one episode, not to --episodes",
                           f"drop {flag} (benchmark episodes draw their own start, goal and time limit)")
    if args.episodes < 1:
        raise CliError(f"--episodes {args.episodes} is not a positive count", "give e.g. --episodes 100")
    if args.workers < 1:
        raise CliError(f"--workers {args.workers} is not a positive count", "give e.g. --workers 2")
    modes = _modes(args.mode, many=True)
    out = Path(args.out).expanduser()
    check_output_file(out / "summary.json", "--out")

    from ..navigation.benchmark import EpisodeSpec, format_table, run_benchmark, with_perception_device

    specs = [EpisodeSpec(args.seed + i, args.episode_seed, mode, args.walker, args.randomize)
             for mode in modes for i in range(args.episodes)]
    run = run_benchmark(specs, out, workers=args.workers, base=with_perception_device(args.perception_device))
    print(format_table(run.summary))
    print(f"wrote {out / 'summary.json'} and {len(specs)} episodes under {out / 'episodes'}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.object is not None:  # an object goal ("walk to the chair"): navigate_object
        from .navigate_object import run_object

        return run_object(args, parse_start=parse_start, check_point=check_point)
    if args.episodes is not None and getattr(args, "viewer", "none") != "none":
        raise CliError("--viewer web watches one episode; --episodes runs many in worker processes",
                       "leave out --episodes (or --viewer)")
    return run_many(args) if args.episodes is not None else run_one(args)


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navigate`` to the ``ambulo`` parser."""
    p = subparsers.add_parser(
        "navigate", help="the humanoid walks to a goal from its own sensors (one episode, or --episodes N)",
        description="The autonomous navigator: the bundled humanoid walks to a goal in a seeded apartment or in "
                    "your own MJCF/USD world, localizing and mapping as it goes (--mode). One episode writes "
                    "episode.json and map.png under --out (and --video); exit status 1 when it does not arrive. "
                    "--episodes N runs a resumable benchmark on apartments --seed .. --seed+N-1.")
    p.add_argument("world", nargs="?", default=None,
                   help="'apartment' (default) or an MJCF (.xml) / USD world file (needs --start and --goal)")
    p.add_argument("--seed", type=int, default=0, help="apartment seed (the first one with --episodes; default 0)")
    p.add_argument("--episode-seed", type=int, default=0,
                   help="seed drawing the start and goal when they are not given (default 0)")
    p.add_argument("--goal", help="goal x,y in m (default: drawn in the apartment with --episode-seed)")
    p.add_argument("--start", help="start x,y[,yaw]: m, m, degrees (default: drawn with --episode-seed)")
    p.add_argument("--mode", default="oracle",
                   help="oracle (true pose and map), mapping (true pose, online map) or full (visual odometry "
                        "and online map); comma-separated with --episodes (default oracle)")
    p.add_argument("--walker", default="policy", choices=("policy", "zmp", "footsteps"),
                   help="policy: the shipped walking policy (default); zmp: the ZMP preview-control walker "
                        "stepping on the planned footholds (use it in oracle mode); footsteps: the shipped "
                        "footstep-following policy stepping on the planned footholds")
    p.add_argument("--randomize", action="store_true", help="domain randomization (friction, mass, lights, "
                   "colours, pushes, sensor noise)")
    p.add_argument("--video", metavar="OUT.mp4", help="film the episode: head camera beside the top-down map")
    p.add_argument("--perception-device", default="cpu",
                   help="torch device of full mode's TSDF and odometry map/refinement, e.g. cuda (ORB stays on the "
                        "host; default cpu)")
    add_viewer_args(p)
    p.add_argument("--out", default="out/navigate", help="folder for episode.json and map.png, or for a "
                   "benchmark's episodes/ and summary.json (default out/navigate)")
    p.add_argument("--time-limit", type=float, metavar="S",
                   help="simulated seconds before the episode ends (default 30 + 6 per metre of geodesic)")
    p.add_argument("--object", metavar="NAME", help="an object goal instead of --goal: search the apartment for "
                   "it with the detector and stop within 1 m facing it (chair, bed, sofa, table, desk, shelf, "
                   "cabinet, plant)")
    p.add_argument("--detector", metavar="MODEL.onnx", help="the detector for --object (default: the shipped "
                   "apartment-objects detector)")
    p.add_argument("--episodes", type=int, metavar="N", help="run a benchmark of N apartments per mode")
    p.add_argument("--workers", type=int, default=1, help="processes for --episodes (default 1)")
    p.set_defaults(func=run)
