import pytest

from ambulo.sim import World


@pytest.fixture(autouse=True)
def _fresh_world_singleton():
    # World.instance() is the "current stage"; keep tests from seeing each other's
    yield
    World._instance = None


class _TickClock:
    """A clock that advances ``tick_s`` at every reading: a planner's wall-time budget becomes a
    fixed number of expansions (the planner reads the clock once per expansion), the same on a
    quiet machine and on one whose cores are busy with other work."""

    def __init__(self, tick_s: float):
        self.tick_s, self.now_s = tick_s, 0.0

    def perf_counter(self) -> float:
        self.now_s += self.tick_s
        return self.now_s


@pytest.fixture(autouse=True, scope="session")
def _planner_clock():
    # The footstep planner's budget is a count of expansions; a wall-time limit applies only where a
    # caller asks for one (FootstepPlannerCfg.time_budget_s, e.g. the tests that pass one). Such a
    # test reading the real clock would pass or fail with the machine's load: 1 ms a reading is
    # about one expansion on a quiet 2-core machine. Session scope: module fixtures that plan run
    # before any function-scoped one.
    import types

    from ambulo.nav import footsteps

    real = footsteps.time
    footsteps.time = types.SimpleNamespace(perf_counter=_TickClock(1e-3).perf_counter)
    yield
    footsteps.time = real
