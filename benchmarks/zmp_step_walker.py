"""``ZmpStepWalker`` walking random short footstep plans online inside an apartment scene.

    python benchmarks/zmp_step_walker.py [--seed 3] [--episodes 10] [--min-m 2] [--max-m 4]
        [--replan-after 4] [--replan-every 0]

Per episode: ``scenes.apartment(seed)`` samples a start pose and a goal ``--min-m``..``--max-m``
m of geodesic apart (the robot's clearance); the scene is built with the humanoid at the start
and started on ``core.Simulation`` (``PhysicsCfg(timestep_s=0.005)``); the walker resets there
(home keyframe, standing) and the footstep planner plans on the apartment's ground-truth
occupancy from the walker's feet to the goal (heading: start to goal). After ``--replan-after``
steps the planner plans again from the walker's ``next_stance_feet_xyyaw_w`` and ``stance_side``
(the same goal) and the walker takes the new plan at the next touchdown (0: no replanning);
``--replan-every`` N > 0 replans again every N steps after that, until the goal.

Starts the planner finds no plan from are sampled again (counted as ``unplanned_samples``).
Success: the walker reports ``done`` (standing, the plan walked) without ``fell``, and the
midpoint of its soles ends within 0.10 m of the midpoint of the plan's last two footsteps.
Reported: success rate, mean speed (straight-line distance of the soles' midpoint over the time
from the first plan to ``done``), wall and CPU (process) time per simulated second (the walker and the physics),
steps, and the failures' reasons. One ``RESULT {json}`` line at the end.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from ambulo import scenes
from ambulo.core import Entity, PhysicsCfg, Simulation
from ambulo.locomotion import ZmpStepWalker
from ambulo.nav import FootstepPlanner, GridMap, PlanStatus, humanoid_footstep_cfg
from ambulo.robots import humanoid


def episode(ap, planner: FootstepPlanner, rng: np.random.Generator, args) -> dict:
    sg = ap.sample_start_goal(rng, args.min_m, args.max_m)
    start, goal_xy = np.asarray(sg.start_pose), np.asarray(sg.goal_xy_m)
    heading = math.atan2(goal_xy[1] - start[1], goal_xy[0] - start[0])
    sim = Simulation(ap.build(robot_pose=tuple(start)), PhysicsCfg(timestep_s=0.005))
    engine = sim.start()
    walker = ZmpStepWalker().bind(sim, Entity(engine, humanoid.PRIM_PATH))
    walker.reset()
    feet = walker.feet_xyyaw_w()
    goal = (goal_xy[0], goal_xy[1], heading)
    plan = planner.plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet, time_budget_s=2.0)
    out = {"start": [round(float(v), 3) for v in start], "goal": [round(float(v), 3) for v in goal],
           "geodesic_m": round(float(sg.geodesic_m), 3), "plan_steps": plan.num_steps}
    if plan.status != PlanStatus.SUCCESS:
        return {**out, "result": "no plan", "detail": plan.detail}
    refused = walker.set_plan(plan)
    if refused:
        return {**out, "result": "refused", "detail": refused}
    start_mid = feet[:, :2].mean(0)
    dt = 0.005
    limit_s = plan.num_steps * 0.8 + 15.0
    wall, cpu, replanned, steps = time.perf_counter(), time.process_time(), args.replan_after <= 0, 0
    next_replan = args.replan_after
    while steps < int(limit_s / dt):
        walker.step(dt)
        sim.step()
        steps += 1
        if not replanned and walker.steps_taken >= next_replan and walker.swing_target_w is not None:
            new = planner.plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=walker.next_stance_feet_xyyaw_w(),
                               stance_side=walker.stance_side, time_budget_s=2.0)
            replanned = args.replan_every <= 0
            next_replan = walker.steps_taken + max(args.replan_every, 1)
            if new.status == PlanStatus.SUCCESS and not walker.set_plan(new):
                plan = new
            else:
                replanned = True  # no plan from here: walk the plan taken
        if walker.fell or (walker.done and walker.steps_taken > 0):
            break
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    sim_s = steps * dt
    end_mid = walker.feet_xyyaw_w()[:, :2].mean(0)
    target_mid = plan.footsteps_xyyaw_w[-2:, :2].mean(0)
    error = float(np.hypot(*(end_mid - target_mid)))
    ok = walker.done and not walker.fell and error <= 0.10
    reason = "" if ok else ("fell" if walker.fell else "not done in time" if not walker.done
                            else f"ended {error:.3f} m from the plan's last stance")
    return {**out, "result": "success" if ok else "failure", "detail": reason, "final_error_m": round(error, 4),
            "steps": walker.steps_taken, "plans_taken": walker.plans_taken, "sim_s": round(sim_s, 2),
            "speed_mps": round(float(np.hypot(*(end_mid - start_mid))) / sim_s, 4),
            "wall_per_sim_s": round(wall / sim_s, 3), "cpu_per_sim_s": round(cpu / sim_s, 3),
            "last_refusal": walker.last_refusal}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=3, help="apartment seed")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--min-m", type=float, default=2.0)
    parser.add_argument("--max-m", type=float, default=4.0)
    parser.add_argument("--replan-after", type=int, default=4, help="steps before the replan (0: none)")
    parser.add_argument("--replan-every", type=int, default=0, help="then again every this many steps (0: once)")
    args = parser.parse_args()
    ap = scenes.apartment(args.seed)
    grid = GridMap.from_map(ap.occupancy)
    planner = FootstepPlanner(grid, humanoid_footstep_cfg(goal_tolerance_m=0.10))
    rng = np.random.default_rng(args.seed)
    runs, unplanned = [], []
    while len(runs) < args.episodes and len(unplanned) < 3 * args.episodes:
        run = episode(ap, planner, rng, args)
        # a start whose home-pose soles the planner finds on an occupied cell (near a wall), or
        # no plan in the budget: not the walker's episode; sampled again
        (unplanned if run["result"] == "no plan" else runs).append(run)
        print(len(runs), json.dumps(run), flush=True)
    walked = [r for r in runs if "sim_s" in r]
    ok = [r for r in runs if r["result"] == "success"]
    summary = {"seed": args.seed, "episodes": len(runs), "success": len(ok),
               "success_rate": round(len(ok) / max(len(runs), 1), 3),
               "success_rate_of_planned": round(len(ok) / max(len(walked), 1), 3),
               "mean_speed_mps": round(float(np.mean([r["speed_mps"] for r in ok])), 4) if ok else None,
               "wall_per_sim_s": round(float(np.mean([r["wall_per_sim_s"] for r in walked])), 3) if walked else None,
               "cpu_per_sim_s": round(float(np.mean([r["cpu_per_sim_s"] for r in walked])), 3) if walked else None,
               "unplanned_samples": len(unplanned),
               "failures": [r["detail"] for r in runs if r["result"] != "success"]}
    print("RESULT " + json.dumps(summary))


if __name__ == "__main__":
    main()
