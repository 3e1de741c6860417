"""The shipped rough-terrain walkers (humanoid-rough and g1-rough, both trained on MuJoCo Warp) on the CPU engine, at the
hardest level of the terrain on the tiles both engines build as boxes (flat, 0.15 m stairs up out of a pit and down off
a pyramid), so what is checked is the walker and not the engines' heightfield gap (``docs/terrain.md``). The G1's cases
need the ``robots`` extra (its URDF) and skip without it.

Each row holds one forward command for every robot (``benchmarks/command_tracking.py``'s ``track``: no lateral, yaw,
standing or heading commands; mean forward speed after 2 s). The bars are the task's and hold with margin for both
shipped walkers (seeds 1-4, 8 robots). humanoid-rough: flat 0.48 m/s at 0.5 and 0.91-0.92 at 1 m/s, no falls; stairs
0.67-0.84 m/s at 1 m/s, at most 1 fall of 8. g1-rough: flat 0.545-0.546 m/s at 0.5 and 1.039-1.045 at 1 m/s, no falls;
stairs up 0.61-0.78 m/s with 0-1 falls, down 0.76-0.83 with none. Broken on purpose they fail. humanoid-rough: actions
scaled by 0.3 (flat: no progress at 0.5 m/s, 13 falls at 1 m/s; stairs 0.15-0.25 m/s), the height scan zeroed (16
and 7 falls on the stairs; flat still passes). g1-rough (seed 3): actions scaled by 0.3 (every row 32 falls: it cannot
stand), the height scan zeroed (24 falls on stairs up, 6 down; flat still passes)."""

import dataclasses
import importlib.util

import pytest

from ambulo import envs
from ambulo.envs.humanoid_rough import WALKS_ROUGH
from ambulo.policies.shipped import load_policy, read_contract
from script_loader import ROOT, load_script

ROBOTS_EXTRA = pytest.mark.skipif(importlib.util.find_spec("cmeel") is None,
                                  reason="the robots extra (example-robot-data) brings the G1 URDF")
TASKS = ["humanoid-rough", pytest.param("g1-rough", marks=ROBOTS_EXTRA)]
WORLDS = 8
SECONDS, SETTLE_S = 6.0, 2.0
MAX_ERROR_M_S = WALKS_ROUGH.max_values["mean_abs_vel_error_m_s"]


@pytest.fixture(scope="module", params=TASKS)
def task(request) -> str:
    """Each rough-terrain task with a shipped walker (g1-rough's walking criterion is humanoid-rough's)."""
    return request.param


@pytest.fixture(scope="module")
def walk(task):
    """``walk(kind, speed_m_s)``: ``track``'s row for ``WORLDS`` robots of ``task``'s shipped walker on ``kind`` tiles."""
    tracking = load_script(ROOT / "benchmarks" / "command_tracking.py")
    shipped = load_policy(task)

    def run(kind: str, speed_m_s: float) -> dict:
        env = envs.make(task, num_envs=WORLDS, device="cpu", seed=3, play=True,
                        **tracking.FORWARD_ONLY, **{"terrain.kinds": (kind,)})
        try:
            steps, settle = round(SECONDS / env.step_dt_s), round(SETTLE_S / env.step_dt_s)
            return tracking.track(env, lambda obs: shipped(obs["policy"]), speed_m_s, steps, settle)
        finally:
            env.close()
    return run


@pytest.mark.parametrize("speed_m_s", [0.5, 1.0])
def test_walks_flat_tiles_at_its_command_without_falling(walk, speed_m_s):
    row = walk("flat", speed_m_s)
    assert row["falls"] == 0, row
    assert abs(row["speed_m_s"] - speed_m_s) <= MAX_ERROR_M_S, row


@pytest.mark.parametrize("kind", ["stairs_up", "stairs_down"])
def test_walks_up_and_down_the_hardest_stairs(walk, kind):
    """0.15 m risers at a 1 m/s command: it keeps going (no standing at the foot of the stairs) and at most a
    quarter of the robots fall in 6 s (the CPU engine's 140-episode tables have 15 % and 10 % of 20 s episodes for
    humanoid-rough, 5 % and 0 % for g1-rough)."""
    row = walk(kind, 1.0)
    assert row["speed_m_s"] >= 0.5, row
    assert row["falls"] <= WORLDS // 4, row


def test_its_contract_matches_the_task(task):
    """The shipped network reads the task's observation as it is today: its terms and sizes and the height scan's
    grid (a changed ``HeightScanCfg`` default would feed it other points without an error)."""
    contract = read_contract(task)
    env = envs.make(task, num_envs=1, device="cpu", play=True)
    try:
        env.reset()
        terms = {name: int(t.shape[1]) for name, t in env._policy_terms().items()}
        assert [(t["name"], t["size"]) for t in contract["observation_terms"]] == list(terms.items())
        assert contract["num_obs"] == env.num_obs
        assert contract["height_scan"] == dataclasses.asdict(env.cfg.height_scan)
        assert contract["export"]["onnx_max_abs_diff"] < 1e-4 and contract["export"]["torchscript_max_abs_diff"] < 1e-4
    finally:
        env.close()
