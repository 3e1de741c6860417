"""benchmarks/command_tracking.py: the forward speed a policy reaches at a commanded speed, and who stood."""

import sys

import pytest
import torch

import ambulo.envs as envs
from script_loader import ROOT, load_script

bench = load_script(ROOT / "benchmarks" / "command_tracking.py")
FIXED = bench.FORWARD_ONLY


def test_the_shipped_walker_reaches_the_command_and_a_still_policy_stands():
    from ambulo.policies.shipped import load_policy

    walker = load_policy("humanoid-walk")
    env = envs.make("humanoid-walk", num_envs=4, device="cpu", seed=3, play=True, **FIXED)
    steps, settle = round(4.0 / env.step_dt_s), round(2.0 / env.step_dt_s)
    walked = bench.track(env, lambda obs: walker(obs["policy"]), 0.6, steps, settle)
    assert walked["speed_m_s"] == pytest.approx(0.6, abs=0.1) and walked["stood"] == 0.0 and walked["falls"] == 0
    still = bench.track(env, lambda obs: torch.zeros(4, env.num_actions), 0.6, steps, settle)
    assert abs(still["speed_m_s"]) < 0.05 and still["stood"] == 1.0
    env.close()


@pytest.mark.parametrize("argv, said", [(["--speeds", "fast"], "is not a comma-separated list"),
                                        (["--settle-s", "9"], "must lie in"),
                                        (["--kinds", "flat,lava"], "unknown tile kinds ['lava']")])
def test_bad_input_is_one_line(monkeypatch, argv, said):
    task = ["--shipped", "humanoid-walk"] if "--kinds" not in argv else ["--run", "x"]
    if "--kinds" in argv:  # a terrain task's kinds are checked before any policy runs
        monkeypatch.setattr(bench, "policy_maker", lambda args: (
            "humanoid-rough", lambda n, seed, **o: envs.make("humanoid-rough", num_envs=n, device="cpu", **o), None))
    monkeypatch.setattr(sys, "argv", ["command_tracking.py", *task, *argv])
    with pytest.raises(SystemExit) as stop:
        bench.main()
    assert said in str(stop.value) and "\n" not in str(stop.value)
