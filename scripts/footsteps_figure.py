"""Draw the shipped footstep policy walking a footstep planner's plan: planned soles vs where its feet landed.

    python scripts/footsteps_figure.py [--goal 2.4 0.9 60] [--seconds 14] [--out docs/images/footsteps_policy.png]
    python scripts/footsteps_figure.py --task humanoid-footsteps-stairs   # out of a pit of 0.10 m steps

With ``--task humanoid-footsteps-stairs`` the robot starts in a stairs-up tile's pit (the task's play level, 0.10 m
risers), the planner plans on the terrain's heights (``nav.grid_map.terrain_grid_map``) and the figure's backdrop is
the ground height; the default goal is 2.6 m straight ahead, up and out of the pit
(``docs/images/footsteps_stairs_policy.png``).

One humanoid-footsteps world on the CPU engine: the footstep planner (``nav.footsteps``, an empty map) plans from
the feet where the robot stands to ``--goal`` (x m, y m ahead/left of the stance centre, yaw deg); the shipped policy
(``assets/data/policies/humanoid_footsteps``) follows it (``env.follow_plans``). Drawn top down: the planned soles
(outlines, left blue, right orange, numbered), every touchdown of the swing foot on a planned step (filled: where
the sole landed; one counted a miss, > ``advance_radius_m`` from its target, in red), the landings that are not
touchdowns (grey outlines: ``env.flight_landing``, the swing foot landing from a take-off before the plan's last
advance, as the stance foot does after a flight phase; ``envs.footstep_gait.swing_touchdown`` decides, for the env,
the placement benchmark and this figure), and the pelvis path. The title gives the median and largest touchdown
error and the number of flight landings. ``tests/policies/test_footsteps_policy.py`` runs it; the committed PNG is
its default output.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import torch

import ambulo.envs as envs
from ambulo.nav.footsteps import FootstepPlanner
from ambulo.nav.grid_map import GridMap, terrain_grid_map
from ambulo.policies.shipped import load_policy
from ambulo.robots.humanoid import SOLE_LENGTH_M, SOLE_WIDTH_M

ROOT = Path(__file__).resolve().parents[1]
TASK = "humanoid-footsteps"
STAIRS_TASK = "humanoid-footsteps-stairs"
SIDE_COLOURS = {1.0: "tab:blue", -1.0: "tab:orange"}
DEFAULTS = {TASK: ((2.4, 0.9, 60.0), "footsteps_policy.png"), STAIRS_TASK: ((2.6, 0.0, 0.0), "footsteps_stairs_policy.png")}
"""Per task: the default goal (x m, y m, yaw deg) and figure name."""


def walk(goal_rel: tuple[float, float, float], seconds: float, seed: int = 0, task: str = TASK) -> dict:
    """Plan to ``goal_rel`` (x m, y m, yaw rad in the stance centre's frame) and follow the plan; returns the plan's
    soles (K, 3) and sides (K,), the touchdowns' landed soles (T, 3), their errors (T,) and step indices (T,), the
    pelvis path (S, 2), whether the robot fell and, on the stairs task, the planner's map (its ground heights)."""
    stairs = task == STAIRS_TASK
    tiles = {"terrain.kinds": ("stairs_up",)} if stairs else {}  # the pit: the robot climbs out of it
    env = envs.make(task, num_envs=1, seed=seed, num_threads=1, play=True, **tiles)
    env.reset()
    feet = env.soles_xyyaw_w().double().numpy()[0]
    centre, yaw = feet.mean(axis=0), float(np.angle(np.exp(1j * feet[:, 2]).sum()))
    c, s = math.cos(yaw), math.sin(yaw)
    goal = (centre[0] + c * goal_rel[0] - s * goal_rel[1], centre[1] + s * goal_rel[0] + c * goal_rel[1],
            yaw + goal_rel[2])
    if stairs:
        grid = terrain_grid_map(env.terrain, centre[:2], 8.0)
    else:
        grid = GridMap.from_array(np.zeros((200, 200), dtype=bool), origin_xy_m=(-5.0, -5.0), resolution_m=0.05)
    plan = FootstepPlanner(grid).plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet, time_budget_s=5.0)
    if plan.status.name != "SUCCESS":
        raise SystemExit(f"the planner gave {plan.status.name} ({plan.detail}) for goal {goal_rel}")
    soles, sides = np.asarray(plan.footsteps_xyyaw_w), np.asarray(plan.foot_sides, float)
    foot_z = (torch.from_numpy(np.asarray(plan.foot_z_m, dtype=np.float64))[None],) if stairs else ()
    obs = env.follow_plans(torch.from_numpy(soles)[None], torch.from_numpy(sides)[None],
                           torch.tensor([plan.num_steps]), *foot_z)
    policy = load_policy(task)
    landed, errors, steps, path, fell, flights = [], [], [], [], False, []
    for _ in range(int(seconds / env.step_dt_s)):
        step = int(env.steps_taken[0]) + 1  # the planned step the swing foot is aiming at
        swing = int(env._swing_index()[0])  # a touchdown in this step is this foot's (the plan advances after)
        obs, _, done, _ = env.step(policy(obs))
        fell |= bool(done[0])
        path.append(env.robot.data.root_pos_w[0, :2].double().numpy().copy())
        if bool(env.touchdown[0]) and step <= plan.num_steps:
            landed.append(env.soles_xyyaw_w()[0, swing].double().numpy().copy())
            errors.append(float(env.touchdown_error_m[0]))
            steps.append(step)
        if bool(env.flight_landing[0]) and step <= plan.num_steps:  # not a touchdown: the plan stays
            flights.append(env.soles_xyyaw_w()[0, swing].double().numpy().copy())
        if int(env.steps_taken[0]) >= plan.num_steps or fell:
            break
    return {"soles": soles, "sides": sides, "landed": np.array(landed).reshape(-1, 3), "errors": np.array(errors),
            "steps": np.array(steps, int), "path": np.array(path), "fell": fell,
            "flight_landings": np.array(flights).reshape(-1, 3),
            "advance_radius_m": env.cfg.advance_radius_m, "task": task, "grid": grid if stairs else None,
            "climbed_m": float(np.ptp(plan.foot_z_m)) if stairs else 0.0}


def _sole(ax, pose, **style) -> None:
    """A sole rectangle (SOLE_LENGTH_M x SOLE_WIDTH_M) at (x, y, yaw)."""
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import Affine2D

    x, y, yaw = pose
    rect = Rectangle((-SOLE_LENGTH_M / 2, -SOLE_WIDTH_M / 2), SOLE_LENGTH_M, SOLE_WIDTH_M, **style)
    rect.set_transform(Affine2D().rotate(yaw).translate(x, y) + ax.transData)
    ax.add_patch(rect)


def draw(result: dict, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 6), dpi=110)
    grid = result.get("grid")
    if grid is not None:  # the ground heights under the plan (the stairs tile's pit)
        ny, nx = grid.height_m.shape
        x0, y0 = grid.origin_xy_m
        extent = (x0, x0 + nx * grid.resolution_m, y0, y0 + ny * grid.resolution_m)
        image = ax.imshow(grid.height_m, origin="lower", extent=extent, cmap="Greys_r", alpha=0.45,
                          interpolation="nearest")  # darker is lower: the pit
        fig.colorbar(image, ax=ax, shrink=0.7, label="ground height (m)")
    for k, (pose, side) in enumerate(zip(result["soles"], result["sides"])):
        _sole(ax, pose, fill=False, lw=1.6, ec=SIDE_COLOURS[side], ls="--" if k < 2 else "-")
        if k >= 2:
            ax.annotate(str(k - 1), pose[:2], ha="center", va="center", fontsize=7, color=SIDE_COLOURS[side])
    for pose, error, step in zip(result["landed"], result["errors"], result["steps"]):
        side = result["sides"][step + 1]
        miss = error > result["advance_radius_m"]
        _sole(ax, pose, fill=True, alpha=0.35, lw=0, fc="tab:red" if miss else SIDE_COLOURS[side])
    for pose in result["flight_landings"]:
        _sole(ax, pose, fill=False, lw=1.0, ec="0.55", ls=":")
    if len(result["path"]):
        ax.plot(*result["path"].T, color="0.3", lw=1.0, label="pelvis")
    errors = result["errors"]
    climbed = f", {100 * result['climbed_m']:.0f} cm up" if result.get("climbed_m") else ""
    title = (f"shipped {result.get('task', TASK)} policy on a footstep planner's plan "
             f"({len(result['soles']) - 2} steps{climbed})\n"
             f"touchdowns {len(errors)}: median error {100 * np.median(errors):.1f} cm, "
             f"largest {100 * errors.max():.1f} cm; {len(result['flight_landings'])} landings after a flight, not counted"
             f"{'; FELL' if result['fell'] else ''}" if len(errors) else "no touchdowns")
    ax.set_title(title, fontsize=9 if grid is None else 7.5)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.15)
    if grid is not None:  # the plan, not the whole 8 m map
        xy = np.concatenate([result["soles"][:, :2], result["path"].reshape(-1, 2)])
        ax.set_xlim(xy[:, 0].min() - 0.5, xy[:, 0].max() + 0.5)
        ax.set_ylim(xy[:, 1].min() - 0.5, xy[:, 1].max() + 0.5)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(handles=[plt.Line2D([], [], color="tab:blue", label="planned, left (outline) / landed (filled)"),
                       plt.Line2D([], [], color="tab:orange", label="planned, right / landed"),
                       plt.Line2D([], [], color="tab:red", label="a miss (> advance radius from its target)"),
                       plt.Line2D([], [], color="0.55", ls=":", label="landed after a flight (not a touchdown)"),
                       plt.Line2D([], [], color="0.3", label="pelvis path")], fontsize=7 if grid is None else 6,
              loc="best")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=tuple(DEFAULTS), default=TASK)
    parser.add_argument("--goal", type=float, nargs=3, metavar=("X_M", "Y_M", "YAW_DEG"),
                        help="default: 2.4 0.9 60 (flat), 2.6 0 0 (stairs: out of the pit)")
    parser.add_argument("--seconds", type=float, default=14.0)
    parser.add_argument("--out", type=Path, help="default: docs/images/footsteps_policy.png or footsteps_stairs_policy.png")
    args = parser.parse_args(argv)
    goal = args.goal or DEFAULTS[args.task][0]
    out = args.out or ROOT / "docs" / "images" / DEFAULTS[args.task][1]
    result = walk((goal[0], goal[1], math.radians(goal[2])), args.seconds, task=args.task)
    out = draw(result, out)
    print(f"{out}: {len(result['errors'])} touchdowns on planned steps, median error "
          f"{100 * np.median(result['errors']):.1f} cm" if len(result["errors"]) else f"{out}: no touchdowns")
    return out


if __name__ == "__main__":
    main()
