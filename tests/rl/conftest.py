"""Shared set-up of the RL tests: torch's intra-op pool at one thread in this process.

The tests train small MLPs (PPO on cartpole, the time-to-criterion and stop-on-engine runs) whose
ops are too small to split: with torch's default two threads on a 2-core machine that another job
keeps busy, each op waits for a descheduled worker. Measured on the 2-core VM at load ~3:
tests/rl 231 s -> 119 s (the cartpole fixture 74 -> 9 s); the same runs, the same checks (the
trainers' own thread settings, e.g. the off-policy runner's ``cpu_threads``, still apply inside)."""

import pytest
import torch


@pytest.fixture(autouse=True, scope="package")
def _one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
