"""The shipped footstep-following policy (humanoid-footsteps) on the CPU engine: it puts its feet on the
footsteps of a plan it is given, without falling, and meets the task's criterion in ``ambulo eval --shipped``."""

import numpy as np
import torch

import ambulo.envs as envs
from ambulo.envs.footstep_sampler import compose_xyyaw
from ambulo.policies.shipped import load_policy
from ambulo.rl.evaluate import evaluate_shipped

TASK = "humanoid-footsteps"


def straight_plans(env, num_steps: int, length_m: float, width_m: float = 0.18) -> tuple[torch.Tensor, torch.Tensor]:
    """(N, num_steps + 2, 3) plans in the planner's layout from where each robot stands (its left foot first to
    move), ``length_m`` ahead per step, and (N, num_steps + 2) their sides."""
    feet = env.soles_xyyaw_w()
    rows, sides = [feet[:, 0], feet[:, 1]], [1.0, -1.0]
    for k in range(num_steps):  # left, right, left, ...: each step in the previous (stance) sole's frame
        side = 1.0 if k % 2 == 0 else -1.0
        step = torch.tensor([length_m, side * width_m, 0.0]).expand(env.num_envs, 3)
        rows.append(compose_xyyaw(rows[-1], step))
        sides.append(side)
    return torch.stack(rows, dim=1), torch.tensor(sides).expand(env.num_envs, -1)


def test_steps_on_a_given_straight_plan():
    policy = load_policy(TASK)
    env = envs.make(TASK, num_envs=4, seed=3, num_threads=1, play=True)
    env.reset()
    num_steps = 8
    plans, sides = straight_plans(env, num_steps, 0.15)
    obs = env.follow_plans(plans, sides, torch.full((env.num_envs,), num_steps))
    start_xy = env.robot.data.root_pos_w[:, :2].clone()
    errors, fell = [], torch.zeros(env.num_envs, dtype=torch.bool)
    for _ in range(int(6.0 / env.step_dt_s)):
        obs, _, dones, _ = env.step(policy(obs))
        fell |= dones.bool()
        planned = env.touchdown & (env.steps_taken <= num_steps)  # touchdowns on the plan's own steps
        errors += env.touchdown_error_m[planned].tolist()
    assert not fell.any()
    assert len(errors) >= 4 * env.num_envs  # it walks the plan, not stands
    assert np.median(errors) <= 0.05  # the bar: median foot placement error <= 5 cm
    # and it went where the plan goes: ~8 x 0.15 m ahead (+x of the start yaw), not sideways
    moved = env.robot.data.root_pos_w[:, :2] - start_xy
    heading = plans[:, 1, 2]
    along = moved[:, 0] * torch.cos(heading) + moved[:, 1] * torch.sin(heading)
    assert (along > 0.6).all()


def test_meets_places_feet_in_ambulo_eval_on_the_cpu_engine():
    result = evaluate_shipped(TASK, num_episodes=8, episode_length_s=6.0, device="cpu", quiet=True)
    assert result["places_feet"] and result["fall_rate"] == 0.0


def test_the_figure_script_draws_a_walk(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "footsteps_figure.py"
    spec = importlib.util.spec_from_file_location("footsteps_figure", path)
    figure = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(figure)
    out = figure.main(["--seconds", "3", "--out", str(tmp_path / "walk.png")])
    assert out.stat().st_size > 10_000
    result = figure.walk((1.0, 0.0, 0.0), 3.0)
    hits = result["errors"][result["errors"] <= result["advance_radius_m"]]
    assert not result["fell"] and len(hits) >= 3 and np.median(hits) <= 0.05
