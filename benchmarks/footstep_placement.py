"""Foot placement of a humanoid-footsteps policy: the median error of the touchdowns themselves.

``ambulo eval`` judges ``places_feet`` on each world's latest touchdown error held over the steps
(``envs.humanoid_footsteps``); the issue's bar is the median foot placement error (<= 5 cm). This
runs the same evaluation (``rl.run_episodes``: one episode per env of the play variant,
deterministic actions) and also records every touchdown of every world's first episode: the
sole-centre-to-target distance and the yaw error, from which it reports the median, mean and 90th
percentile, the touchdowns per second and the fall (or lost-plan) rate. A touchdown is the env's
(``envs.footstep_gait.swing_touchdown``, through ``env.touchdown``): a swing-foot landing from a
take-off after the plan's last advance; ``flight_landings`` counts the landings it leaves out (the
stance foot landing after a flight phase, which the env scored as a touchdown before 2026-11-29
session 9).

``--plans planner`` gives every world a plan of the footstep planner (``nav.footsteps``, on an
empty 10 m map) from the feet where the robot stands to a goal 1.5-3 m away in a random direction
within +-90 degrees of its heading, facing within +-90 degrees of it (``env.follow_plans``); only
the touchdowns on planned steps count. Default ``sampler``: the task's own drawn plans.

On a task with terrain (``humanoid-footsteps-stairs``) the planner's map around each robot is
8 m x 8 m on the terrain's 5 cm sample cells with its heights (``GridMap.height_m``, from the
samples the physics hfield is built from; ``terrain_map``), so its plans put the soles on treads, and the env follows them
with their heights (``follow_plans(..., foot_z_m)``); a goal the planner cannot reach is drawn
again (up to 8 times, then its best partial plan of >= 2 steps). ``--terrain flat`` or
``stairs`` puts every robot of such a task on its flat or its stairs tiles (default: the
task's mix).

    python benchmarks/footstep_placement.py --run runs/humanoid-footsteps/<run> --num-episodes 64
    python benchmarks/footstep_placement.py --run <run> --device cuda --num-episodes 1000 --plans planner
    python benchmarks/footstep_placement.py --run runs/humanoid-footsteps-stairs/<run> --plans planner --terrain stairs

Ends with one ``RESULT {json}``; ``ratio`` = 5 cm / the median error (>= 1 meets the bar).
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import torch

from ambulo import envs
from ambulo.envs.humanoid_footsteps import PLACEMENT_BAR_M
from ambulo.nav.footsteps import FootstepPlanner
from ambulo.nav.grid_map import GridMap, terrain_grid_map
from ambulo.rl import runs
from ambulo.rl.evaluate import eval_episode_length_s, run_episodes


class TouchdownLog:
    """Wraps a policy: before each action it records the touchdowns of the step just taken, in
    worlds still in their first episode (a world whose step counter went back was reset)."""

    def __init__(self, env, policy, plans=None):
        self.env, self.policy, self.plans = env, policy, plans
        self.num_steps = None
        """(N,) steps of each world's planner plan (``--plans planner``), None for drawn plans."""
        self.first_episode = torch.ones(env.num_envs, dtype=torch.bool, device=env.device)
        self._last_length = env.episode_length_buf.clone()
        self.errors_m: list[torch.Tensor] = []
        self.yaw_errors_rad: list[torch.Tensor] = []
        self.flight_landings = torch.zeros((), dtype=torch.long, device=env.device)
        """Landings of the swing foot that are not touchdowns: from a take-off before the plan's last advance."""

    def __call__(self, obs):
        env = self.env
        if self.plans is not None and self.num_steps is None:  # after the first reset: where the feet stand
            with torch.inference_mode(False):  # the env's plan state is updated in place, outside the policy's mode
                footsteps, sides, self.num_steps, foot_z = self.plans(env)
                env.follow_plans(footsteps, sides, self.num_steps, foot_z)
            obs = self.plans.vec_env.get_observations()
        self.first_episode &= env.episode_length_buf >= self._last_length
        self._last_length = env.episode_length_buf.clone()
        counted = self.first_episode.clone()
        if self.num_steps is not None:
            counted &= env.steps_taken <= self.num_steps
        keep = env.touchdown & counted
        self.flight_landings += (env.flight_landing & counted).sum()
        self.errors_m.append(env.touchdown_error_m[keep])
        self.yaw_errors_rad.append(env.touchdown_yaw_error_rad[keep])
        return self.policy(obs)


MAP_SIZE_M = 8.0
"""Edge of the planner's map around each robot on a terrain task, m (goals lie within 3 m)."""


def terrain_map(terrain, center_xy_m) -> GridMap:
    """The planner's map of ``MAP_SIZE_M`` around ``center_xy_m`` on the terrain's sample cells
    (``nav.grid_map.terrain_grid_map``)."""
    return terrain_grid_map(terrain, center_xy_m, MAP_SIZE_M)


class PlannerPlans:
    """``(env) -> (footsteps (N, K, 3), sides (N, K), num_steps (N,), foot_z_m (N, K))``: one plan
    of the footstep planner per world from its feet (module docstring), padded to K rows with
    alternating sides."""

    def __init__(self, vec_env, seed: int, tries: int = 8):
        self.vec_env, self.rng, self.tries = vec_env, np.random.default_rng(seed), tries

    def _goal(self, feet):
        body = feet.mean(axis=0)
        heading = float(np.angle(np.exp(1j * feet[:, 2]).sum()))
        distance, bearing = self.rng.uniform(1.5, 3.0), heading + self.rng.uniform(-np.pi / 2, np.pi / 2)
        return (body[0] + distance * np.cos(bearing), body[1] + distance * np.sin(bearing),
                heading + self.rng.uniform(-np.pi / 2, np.pi / 2))

    def _plan(self, i, planner, feet):
        best = None
        for _ in range(self.tries if planner.grid.height_m is not None else 1):
            plan = planner.plan(goal_xyyaw_w=self._goal(feet), start_feet_xyyaw_w=feet, time_budget_s=5.0)
            if plan.status.name == "SUCCESS" and plan.num_steps >= 2:
                return plan
            if plan.num_steps >= 2 and (best is None or plan.num_steps > best.num_steps):
                best = plan
        if best is None:
            raise RuntimeError(f"world {i}: the planner gave {plan.status.name} ({plan.detail})")
        return best

    def __call__(self, env):
        terrain = getattr(env, "terrain", None)
        flat = GridMap.from_array(np.zeros((200, 200), dtype=bool), origin_xy_m=(-5.0, -5.0), resolution_m=0.05)
        feet = env.soles_xyyaw_w().double().cpu().numpy()
        plans = []
        for i in range(env.num_envs):
            grid = flat if terrain is None else terrain_map(terrain, feet[i, :, :2].mean(axis=0))
            plans.append(self._plan(i, FootstepPlanner(grid), feet[i]))
        rows = max(len(p.footsteps_xyyaw_w) for p in plans)
        footsteps = np.zeros((env.num_envs, rows, 3))
        sides = np.zeros((env.num_envs, rows))
        foot_z = np.zeros((env.num_envs, rows))
        for i, p in enumerate(plans):
            k = len(p.footsteps_xyyaw_w)
            footsteps[i, :k], footsteps[i, k:] = p.footsteps_xyyaw_w, p.footsteps_xyyaw_w[-1]
            foot_z[i, :k], foot_z[i, k:] = p.foot_z_m, p.foot_z_m[-1]
            sides[i] = p.foot_sides[0] * (-1.0) ** np.arange(rows)  # alternating, the padding too
            assert np.array_equal(sides[i, :k], p.foot_sides)
        steps = torch.tensor([p.num_steps for p in plans], device=env.device)
        self.statuses = [p.status.name for p in plans]
        return torch.from_numpy(footsteps), torch.from_numpy(sides), steps, torch.from_numpy(foot_z)


def summary(values: torch.Tensor) -> dict[str, float]:
    if values.numel() == 0:
        return {"median": None, "mean": None, "p90": None}
    v = values.double()
    return {"median": float(v.median()), "mean": float(v.mean()), "p90": float(torch.quantile(v, 0.9))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, help="a humanoid-footsteps run folder or checkpoint")
    parser.add_argument("--log-root", default="runs")
    parser.add_argument("--device", default=None, help="default: the run's")
    parser.add_argument("--num-episodes", type=int, default=64)
    parser.add_argument("--episode-length-s", type=float, default=None)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--plans", choices=("sampler", "planner"), default="sampler",
                        help="the task's drawn plans, or the footstep planner's (module docstring)")
    parser.add_argument("--terrain", choices=("task", "flat", "stairs"), default="task",
                        help="on a terrain task: every robot on its flat or its stairs tiles (default: the task's mix)")
    parser.add_argument("--num-threads", type=int, default=None,
                        help="CPU engine threads (default: the env's, every CPU); a shared machine wants fewer")
    args = parser.parse_args()
    run_dir, ckpt = runs.resolve_policy(args.run, None, args.log_root)
    info = runs.read_run_info(run_dir)
    spec = envs.spec(info["task"])
    tiles = {}
    if args.terrain != "task":
        if "terrain" not in spec.cfg_fn().__dataclass_fields__:
            raise SystemExit(f"--terrain {args.terrain}: task {info['task']} has no terrain; leave --terrain out")
        tiles["terrain.kinds"] = ("flat",) if args.terrain == "flat" else ("stairs_up", "stairs_down")
    env = runs.make_env_for_run(info, num_envs=args.num_episodes, seed=args.seed, play=True, device=args.device,
                                episode_length_s=eval_episode_length_s(spec, args.episode_length_s),
                                num_threads=args.num_threads, **tiles)
    runner = runs.load_runner(run_dir, env, ckpt)
    plans = PlannerPlans(runner.env, args.seed) if args.plans == "planner" else None
    log = TouchdownLog(env, runner.get_inference_policy(device=str(env.device)), plans)
    measured = run_episodes(env, runner.env, log, spec, desc="footsteps", quiet=True)
    errors, yaw = torch.cat(log.errors_m), torch.cat(log.yaw_errors_rad)
    position = summary(errors)
    result = {
        "task": info["task"], "run": str(run_dir), "checkpoint": ckpt.name, "device": str(env.device),
        "episodes": args.num_episodes, "episode_length_s": measured["episode_length_s"], "plans": args.plans,
        "terrain": args.terrain, "plan_statuses": None if plans is None else
        {s: plans.statuses.count(s) for s in sorted(set(plans.statuses))},
        "planned_steps": None if log.num_steps is None else int(log.num_steps.sum()),
        "touchdowns": int(errors.numel()), "flight_landings": int(log.flight_landings),
        "placement_error_m": position, "yaw_error_rad": summary(yaw),
        "median_within_5cm": position["median"] is not None and position["median"] <= PLACEMENT_BAR_M,
        "eval": {k: v for k, v in measured.items() if k not in ("task", "episodes", "episode_length_s")},
        "ratio": round(PLACEMENT_BAR_M / position["median"], 3) if position["median"] else None,
    }
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
