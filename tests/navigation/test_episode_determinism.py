"""Issue 24: an episode is a function of its seeds, not of the machine's speed. Under the footstep
planner's former wall-time budget (0.3 s a query) a benchmark episode replayed on another host
took other decisions (apartment 71: stuck on the 16-core host, arrived on a 2-core VM)."""

import time
import types

import numpy as np
import pytest

from ambulo.nav import footsteps
from ambulo.navigation import EpisodeCfg, run_episode

pytest.importorskip("onnxruntime")


class _SlowClock:
    """A clock that advances ``tick_s`` at every reading: a machine so loaded that every timed
    piece of work seems to take that long."""

    def __init__(self, tick_s: float):
        self.tick_s, self.now_s = tick_s, 0.0

    def perf_counter(self) -> float:
        self.now_s += self.tick_s
        return self.now_s


def _episode(monkeypatch, clock=None):
    """Apartment 1002, episode 0, oracle mode (3-4 m): three of its footstep queries search the
    lattice (the walk along the body path alone does not reach their subgoals)."""
    expansions = []
    plan = footsteps.FootstepPlanner.plan

    def counted(self, *args, **kwargs):
        out = plan(self, *args, **kwargs)
        expansions.append(out.expansions)
        return out

    with monkeypatch.context() as patch:
        patch.setattr(footsteps.FootstepPlanner, "plan", counted)
        if clock is not None:  # every module's time.perf_counter, the planner's too (tests/conftest.py swaps it)
            patch.setattr(time, "perf_counter", clock.perf_counter)
            patch.setattr(footsteps, "time", types.SimpleNamespace(perf_counter=clock.perf_counter))
        result = run_episode(1002, 0, EpisodeCfg(min_geodesic_m=3.0, max_geodesic_m=4.0))
    return result, expansions


def test_an_episode_takes_the_same_decisions_on_a_slow_clock(monkeypatch):
    quick, quick_expansions = _episode(monkeypatch)
    slow, slow_expansions = _episode(monkeypatch, _SlowClock(1.0))
    assert quick.status == "arrived", quick.to_json()
    assert any(n > 0 for n in quick_expansions)  # the planner's budget is reached for at all
    assert slow_expansions == quick_expansions
    assert slow.extras["replan_reasons"] == quick.extras["replan_reasons"]
    assert slow.extras["footstep_statuses"] == quick.extras["footstep_statuses"]
    assert slow.status == quick.status and slow.time_s == quick.time_s
    assert slow.path_length_m == quick.path_length_m and np.isclose(slow.spl, quick.spl, rtol=0, atol=0)
    assert min(slow.replan_wall_s) >= 1.0  # the slow clock did reach the loop's timings
