"""``ambulo plan``: footsteps for the bundled humanoid on a map, drawn to a PNG with the walking
pattern's CoM and ZMP paths; with ``--simulate`` the humanoid walks the plan in MuJoCo (an MP4,
and the measured ZMP and capture point on the picture and in the printout)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .errors import CliError, check_output_file

MAPS = ("empty", "boxes")
"""Built-in maps: ``empty`` floor (8 m x 8 m around the origin) and ``boxes`` (the same with two
boxes between the default start and goal)."""


def _pose(text: str, flag: str) -> tuple[float, float, float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise CliError(f"{flag} {text!r} is not a pose", f"give x,y or x,y,yaw in m and degrees, e.g. {flag} 3,0,90")
    x, y, yaw_deg = (values + [0.0])[:3]
    return x, y, math.radians(yaw_deg)


def load_map(name: str, resolution_m: float, origin: tuple[float, float] | None):
    """A ``GridMap`` with unknown cells blocked: a built-in name (``MAPS``); a map file that says
    where it lies (``ambulo map``'s ``.npz``, a ROS map_server ``.yaml``); or a bare ``.npy``
    (2-D array, non-zero = occupied, row i at y = origin_y + i * resolution) or image (read as
    map_server reads one: dark occupied, light free, grey unknown; the top row is the far y), placed
    by ``resolution_m`` and ``origin`` (lower-left corner, m)."""
    import numpy as np

    from ..maps import load_map_image, load_map_yaml, load_npz
    from ..nav import GridMap

    if not resolution_m > 0 or not math.isfinite(resolution_m):
        raise CliError(f"--resolution {resolution_m} is not a positive cell size", "give metres, e.g. --resolution 0.05")
    if name in MAPS:
        grid = GridMap.empty((8.0, 8.0), resolution_m=resolution_m, origin_xy_m=origin or (-2.0, -4.0))
        if name == "boxes":
            grid.add_box((1.5, 0.15), (0.5, 0.7))
            grid.add_box((2.5, -1.0), (0.6, 0.6))
        return grid
    path = Path(name)
    if not path.is_file():
        raise CliError(f"--map {name!r} is neither a file nor a built-in map",
                       f"give a .npz, map_server .yaml, .npy or image map, or one of {', '.join(MAPS)}")
    suffix = path.suffix.lower()
    if suffix in (".npz", ".yaml", ".yml"):
        if origin is not None:
            raise CliError(f"--origin is set, but {path.name} carries its own origin",
                           "drop --origin (it places .npy and image maps)")
        return GridMap.from_map(load_npz(path) if suffix == ".npz" else load_map_yaml(path))
    if suffix != ".npy":
        return GridMap.from_map(load_map_image(path, resolution_m=resolution_m, origin_xy_m=origin or (0.0, 0.0)))
    try:
        occupied = np.load(path, allow_pickle=False)
    except ValueError as err:
        raise CliError(f"--map {name!r} is not a readable .npy array ({err})", "save it with numpy.save") from None
    if occupied.ndim != 2:
        raise CliError(f"--map {name!r} has shape {occupied.shape}", "give a 2-D occupancy grid")
    return GridMap.from_array(occupied != 0, resolution_m=resolution_m, origin_xy_m=origin or (0.0, 0.0))


def run(args: argparse.Namespace) -> int:
    start = _pose(args.start, "--start")
    goal = _pose(args.goal, "--goal")
    origin = None
    if args.origin is not None:
        origin = _pose(args.origin, "--origin")[:2]
    png = check_output_file(args.png, "--png")
    if args.simulate:
        check_output_file(args.video, "--video")
    if not args.budget_ms > 0:
        raise CliError(f"--budget-ms {args.budget_ms} is not positive", "give milliseconds, e.g. --budget-ms 500")
    grid = load_map(args.map, args.resolution, origin)

    from ..locomotion.walk_plot import plot_walk  # heavy imports only when run
    from ..locomotion.walk_sim import WalkSimulation, plan_walk, walk_pattern

    plan = plan_walk(grid, start, goal, time_budget_s=args.budget_ms / 1e3)
    print(f"plan: {plan.status.value}, {plan.num_steps} steps, {plan.planning_time_s * 1e3:.0f} ms"
          + (f" ({plan.detail})" if plan.detail else ""))
    pattern = walk_pattern(plan) if plan.num_steps > 0 else None
    result = None
    ok = plan.status.value == "success"
    if args.simulate and ok:
        sim = WalkSimulation(pattern, grid=grid)
        result = sim.run(args.seed, video=args.video)
        s = result.summary()
        fall = f"FELL at {s['fall_time_s']:.2f} s ({s['fall_reason']})" if s['fell'] else "no fall"
        print(f"walk: {fall}; "
              f"{s['distance_m']:.2f} m, turned {s['turn_deg']:.0f} deg; measured ZMP inside the support polygon "
              f"in {100 * s['zmp_inside_single_support']:.1f} % of single-support samples "
              f"(margin min {s['zmp_margin_single_support_mm']['min']:.1f} mm); capture point inside the support "
              f"polygon at {int(sum(result.capture_margin_m >= 0))}/{s['touchdowns']} touchdowns")
        print(f"wrote {args.video} ({result.frames} frames)")
        ok = not result.fell
    elif args.simulate:
        print("walk: not simulated (the plan did not reach the goal)")
    plot_walk(grid, plan, png, pattern=pattern, result=result, goal_xyyaw_w=goal)
    print(f"wrote {png}")
    return 0 if ok else 1


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``plan`` to the ``ambulo`` parser."""
    p = subparsers.add_parser(
        "plan", help="footstep plan for the humanoid on a map (PNG); --simulate walks it (MP4)",
        description="Plan footsteps for the bundled humanoid, turn them into a ZMP preview-control walking "
                    "pattern and draw the map, footsteps and CoM/ZMP paths to a PNG. With --simulate the "
                    "humanoid walks the plan in MuJoCo and an MP4 is written. Exit status 1 when the plan "
                    "does not reach the goal or the humanoid falls.")
    p.add_argument("--map", default="empty",
                   help=f"built-in map ({', '.join(MAPS)}) or a map file: costmap.npz from 'ambulo map', a ROS "
                        "map_server .yaml, a .npy (non-zero = occupied) or an image (dark = occupied, grey = unknown); "
                        "unknown cells are blocked; default empty")
    p.add_argument("--resolution", type=float, default=0.05,
                   help="cell size of a built-in, .npy or image map, m (default 0.05)")
    p.add_argument("--origin", help="x,y of a .npy or image map's lower-left corner, m (default 0,0)")
    p.add_argument("--start", default="0.03,0,0", help="start body pose x,y[,yaw]: m, m, degrees (default 0.03,0,0)")
    p.add_argument("--goal", default="3.03,0,90", help="goal body pose x,y[,yaw] (default 3.03,0,90)")
    p.add_argument("--budget-ms", type=float, default=1000.0, help="planning time budget, ms (default 1000)")
    p.add_argument("--png", default="out/plan.png", help="picture to write (default out/plan.png)")
    p.add_argument("--simulate", action="store_true", help="walk the plan in MuJoCo and write --video")
    p.add_argument("--video", default="out/plan_walk.mp4", help="MP4 of the walk (default out/plan_walk.mp4)")
    p.add_argument("--seed", type=int, default=None,
                   help="perturb the initial state with this seed (default: start exactly on the pattern)")
    p.set_defaults(func=run)
