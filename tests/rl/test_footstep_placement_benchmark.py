"""benchmarks/footstep_placement.py's touchdown log: only first episodes, only planned steps; the landings
that are not touchdowns (after a flight) counted apart."""

from types import SimpleNamespace

import pytest
import torch

from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "footstep_placement.py")


def fake_env(n):
    return SimpleNamespace(num_envs=n, device=torch.device("cpu"), episode_length_buf=torch.zeros(n, dtype=torch.long),
                           touchdown=torch.zeros(n, dtype=torch.bool), touchdown_error_m=torch.zeros(n),
                           touchdown_yaw_error_rad=torch.zeros(n), steps_taken=torch.zeros(n, dtype=torch.long),
                           flight_landing=torch.zeros(n, dtype=torch.bool))


class FakePlans:
    """Plans of 1 and 2 steps (no poses or heights: the fake env ignores them); the observations after
    ``follow_plans``."""

    vec_env = SimpleNamespace(get_observations=lambda: "planned obs")

    def __call__(self, env):
        return None, None, torch.tensor([1, 2]), None  # poses, sides, steps, heights


def step(env, touchdown, error_m, reset=(), flight=None):
    env.flight_landing = torch.tensor(flight or [False] * env.num_envs)
    env.episode_length_buf += 1
    env.episode_length_buf[list(reset)] = 0
    env.touchdown = torch.tensor(touchdown)
    env.touchdown_error_m = torch.tensor(error_m) * env.touchdown
    env.steps_taken += env.touchdown


def test_log_keeps_first_episodes_and_planned_steps():
    env = fake_env(3)
    log = bench.TouchdownLog(env, lambda obs: "action")
    assert log(None) == "action"
    step(env, [True, True, False], [0.01, 0.02, 0.0])
    log(None)
    step(env, [False, True, True], [0.0, 0.03, 0.04], reset=[1], flight=[True, True, False])  # world 1 fell:
    log(None)  # its later touchdowns and flight landings are out
    step(env, [True, True, False], [0.05, 0.06, 0.0], flight=[False, False, True])
    log(None)
    assert torch.cat(log.errors_m).tolist() == pytest.approx([0.01, 0.02, 0.04, 0.05])
    assert int(log.flight_landings) == 2  # world 0's and world 2's; not scored
    assert log.num_steps is None
    # with planner plans, a world's touchdowns past its plan's steps are out
    env = fake_env(2)
    plans = FakePlans()
    followed = []
    env.follow_plans = lambda *args: followed.append(args)
    log = bench.TouchdownLog(env, lambda obs: obs, plans)
    assert log(None) == "planned obs" and followed and log.num_steps.tolist() == [1, 2]
    for errors in ([0.01, 0.02], [0.03, 0.04], [0.05, 0.06]):
        step(env, [True, True], errors)
        log(None)
    assert torch.cat(log.errors_m).tolist() == pytest.approx([0.01, 0.02, 0.04])
    summary = bench.summary(torch.tensor([0.01, 0.02, 0.04]))
    assert summary["median"] == pytest.approx(0.02) and bench.summary(torch.zeros(0))["median"] is None
