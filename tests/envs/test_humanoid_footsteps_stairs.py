"""humanoid-footsteps-stairs: drawn targets land on treads at the treads' heights, a robot on a
tread (0.9 m down a pit) is not fallen, the command carries the targets' heights, PPO trains it
and the placement benchmark runs on planner plans over the stairs."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.humanoid_footsteps_stairs import STAIR_RISER_M
from script_loader import ROOT, load_script

STAIRS = {"terrain.kinds": ("stairs_up", "stairs_down"), "terrain.num_levels": 2, "terrain.border_m": 2.0}
"""Only stairs tiles (the play variant: 0.10 m risers), a small grid."""


def make(num_envs, **overrides):
    return envs.make("humanoid-footsteps-stairs", num_envs=num_envs, seed=0, num_threads=1, play=True,
                     **{**STAIRS, **overrides})


def draw_plan(env, num_steps):
    """(N, num_steps, 3) footsteps the env draws after its first targets, and (N, num_steps) heights."""
    stance, side, segments = env.targets_xyyaw_w[:, 0].clone(), env.target_sides[:, 0].clone(), env._segments.clone()
    poses, heights = [], []
    for _ in range(num_steps):
        stance, z, segments = env._next_footstep(stance, side, segments)
        side = -side
        poses.append(stance)
        heights.append(z)
    return torch.stack(poses, dim=1), torch.stack(heights, dim=1)


def test_drawn_targets_land_flat_on_treads_at_their_height():
    """Plans from the platform down and up 0.10 m stairs: every sole lies flat on one
    tread (its widened sole reads one height), and its height is that tread's, a whole number of
    risers. Without the tread snap, most soles past the platform straddle an edge."""
    env = make(16)
    poses, z = draw_plan(env, 30)
    spread = env.treads.spread_m(poses)
    flat = spread <= env.cfg.treads.max_spread_m
    on_stairs = (poses[..., :2] - env.tiles.origins_w[:, None, :2]).abs().amax(dim=-1) > 1.0  # off the platform
    assert on_stairs.sum() > 100, int(on_stairs.sum())  # the plans go onto the stairs
    assert flat[on_stairs].all(), float(flat[on_stairs].float().mean())
    risers = z / STAIR_RISER_M
    np.testing.assert_allclose(risers[flat], risers[flat].round(), atol=1e-4)
    torch.testing.assert_close(z, env.ground_height_m(poses[..., :2]))
    # the same plans without the snap straddle edges
    raw_env = make(16)
    raw_env.treads.snap = lambda stance, step: (step, raw_env.ground_height_m(step[:, :2]))
    raw_poses, _ = draw_plan(raw_env, 30)
    raw_on = (raw_poses[..., :2] - raw_env.tiles.origins_w[:, None, :2]).abs().amax(dim=-1) > 1.0
    assert (raw_env.treads.spread_m(raw_poses)[raw_on] <= 1e-3).float().mean() < 0.8


@pytest.mark.parametrize("engine", ["mujoco", pytest.param("warp", marks=pytest.mark.slow)])
def test_a_robot_standing_in_the_stairs_pit_is_not_fallen(engine):
    """On the stairs-up tile the robot starts 1.0 m below z = 0 (ten 0.10 m risers): its base is
    under humanoid-walk's 0.5 m fall height, yet over the ground under it it stands. On MuJoCo
    Warp (its CPU device here) the terrain holds it too."""
    env = make(2, engine=engine)
    assert env.tiles.origins_w[:, 2].tolist() == pytest.approx([-1.0, 1.0])
    for _ in range(10):
        _, _, dones, _ = env.step(torch.zeros(2, env.num_actions))
        assert not dones.any()
    assert env.robot.data.root_pos_w[0, 2].item() < 0.0
    assert env.base_height_over_ground_m().min().item() > 0.8


def test_command_carries_the_targets_heights_over_the_ground_under_the_base():
    env = make(2)
    cmd = env.footstep_command()
    assert cmd.shape == (2, 12) and env.num_obs == 79 + 2 + 187  # humanoid-footsteps: 79, + 2 heights, + the scan
    ground = env.ground_height_m(env.robot.data.root_pos_w[:, :2])
    env.targets_z_m.copy_(torch.tensor([[0.1, 0.2], [-0.3, 0.0]]))
    cmd = env.footstep_command()
    torch.testing.assert_close(cmd[:, [2, 8]], env.targets_z_m - ground[:, None])
    # a planner plan's heights become the targets', then advance with them
    k = 6
    plan = env.soles_xyyaw_w()[:, [1, 0]].repeat(1, 3, 1)  # any poses: only the heights matter here
    sides = torch.tensor([[-1.0, 1.0] * 3] * 2) * env.target_sides[:, :1] * -1
    heights = torch.arange(2 * k, dtype=torch.float32).view(2, k) / 10
    env.follow_plans(plan, sides, torch.tensor([4, 4]), foot_z_m=heights)
    torch.testing.assert_close(env.targets_z_m, heights[:, 2:4])
    env._advance(torch.tensor([0]))
    torch.testing.assert_close(env.targets_z_m[0], heights[0, 3:5])


def test_planner_plans_over_the_terrain_keep_every_sole_on_a_tread():
    """The placement benchmark's planner map (``terrain_map``) on the terrain's sample cells:
    every planned sole of 4 plans over 0.10 m stairs lies flat on a tread, its ``foot_z_m`` the
    tread's height (with the map's cells at another offset, a fifth of the soles reach a ramp)."""
    bench = load_script(ROOT / "benchmarks" / "footstep_placement.py")
    env = make(4)
    footsteps, _, steps, foot_z = bench.PlannerPlans(None, seed=0)(env)
    planned = torch.arange(footsteps.shape[1])[None] < steps[:, None] + 2
    soles = footsteps.float()[planned]
    assert len(soles) > 40 and (env.treads.spread_m(soles) <= 1e-3).all()
    torch.testing.assert_close(foot_z.float()[planned], env.ground_height_m(soles[:, :2]))
    climbed = foot_z.max(dim=1).values - foot_z.min(dim=1).values
    assert (climbed >= 2 * STAIR_RISER_M - 1e-6).all()  # every plan crosses two risers or more


@pytest.mark.slow  # ~60 s on a shared 2-core machine: 2 PPO iterations, then the benchmark on planner plans
def test_trains_and_the_placement_benchmark_runs_on_stairs(tmp_path):
    from ambulo.rl import train

    small = {"terrain.num_levels": 2, "terrain.border_m": 2.0}
    run = train("humanoid-footsteps-stairs", num_envs=6, max_iterations=2, seed=0, log_root=tmp_path,
                env_overrides=small, ppo_overrides={"num_steps_per_env": 8})
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    assert [int(r["iteration"]) for r in rows] == [0, 1]
    bench = Path(__file__).resolve().parents[2] / "benchmarks" / "footstep_placement.py"
    out = subprocess.run([sys.executable, str(bench), "--run", str(run), "--num-episodes", "2", "--episode-length-s",
                          "1", "--plans", "planner", "--terrain", "stairs", "--num-threads", "1"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.split("RESULT ", 1)[1])
    assert result["terrain"] == "stairs" and result["planned_steps"] >= 4
    assert sum(result["plan_statuses"].values()) == 2
