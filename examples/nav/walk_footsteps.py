"""The bundled humanoid walks a planned footstep path in MuJoCo: footstep planner -> ZMP preview
control -> whole-body controller (IK + inverse-dynamics feed-forward + capture-point stabilizer)
on the simulated robot, with the measured ZMP (centre of pressure) checked against the support
polygon.

    python examples/nav/walk_footsteps.py [--distance 3] [--turn-deg 90] [--seed 0]
        [--png out/walk_footsteps.png] [--video out/walk_footsteps.mp4]

Prints the walk's balance statistics and writes a picture of the plan, the CoM/ZMP paths and the
measured ZMP margin (and an MP4 with --video).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ambulo.locomotion.walk_plot import plot_walk
from ambulo.locomotion.walk_sim import acceptance_walk, straight_and_turn_goal
from ambulo.nav import GridMap


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--distance", type=float, default=3.0, help="m straight ahead")
    parser.add_argument("--turn-deg", type=float, default=90.0, help="then turn on the spot, degrees")
    parser.add_argument("--seed", type=int, default=0, help="initial-state perturbation; -1 for none")
    parser.add_argument("--png", default="out/walk_footsteps.png")
    parser.add_argument("--video", default=None, help="MP4 of the walk (slow: software rendering)")
    args = parser.parse_args(argv)

    plan, sim = acceptance_walk(args.distance, math.radians(args.turn_deg))
    result = sim.run(None if args.seed < 0 else args.seed, video=args.video)
    summary = result.summary()
    start, goal = straight_and_turn_goal(args.distance, math.radians(args.turn_deg))
    size = args.distance + 3.0
    grid = GridMap.empty((size, size), resolution_m=0.05, origin_xy_m=(-1.5, -size / 2))
    Path(args.png).parent.mkdir(parents=True, exist_ok=True)
    plot_walk(grid, plan, args.png, pattern=sim.pattern, result=result, goal_xyyaw_w=goal,
              title=f"{plan.num_steps} steps: {args.distance:g} m and a {args.turn_deg:g} deg turn, simulated")
    margin = summary["zmp_margin_single_support_mm"]
    print(f"{plan.num_steps} steps planned in {plan.planning_time_s * 1e3:.0f} ms; walk "
          f"{'FELL: ' + summary['fall_reason'] if summary['fell'] else 'without a fall'}: "
          f"{summary['distance_m']:.2f} m, turned {summary['turn_deg']:.1f} deg")
    print(f"measured ZMP inside the support polygon in {100 * summary['zmp_inside_single_support']:.1f} % of "
          f"{summary['single_support_samples']} single-support samples (margin min {margin['min']:.1f} mm, "
          f"p5 {margin['p5']:.1f} mm, median {margin['median']:.1f} mm)")
    print(f"capture point inside the support polygon at {int((result.capture_margin_m >= 0).sum())}/"
          f"{summary['touchdowns']} touchdowns (margin min {summary['capture_margin_min_mm']:.1f} mm); wrote {args.png}"
          + (f" and {args.video}" if args.video else ""))
    return {"summary": summary, "png": args.png, "video": args.video, "plan": plan, "result": result}


if __name__ == "__main__":
    main()
