"""What ``ambulo run`` sets up around an Isaac Gym script, and takes down after it.

- a budget of simulated seconds: Isaac Gym scripts loop ``for iteration in range(1000)`` or train
  for thousands of epochs, with no ``is_running()`` to end them headless; once the sims of the run
  have simulated ``--seconds``, the next ``simulate`` ends the script (``GymBudgetSpent``, which the
  runner reports as the run's end, not as an error);
- on a host where torch sees no CUDA, once the script imports ``isaacgym``, its ``"cuda:0"``
  tensors and ``.cuda()`` models live on the CPU (``device.cuda_on_cpu``): Isaac Gym scripts
  hard-code CUDA;
- rl_games' vecenv types ``RLGPU`` and ``ISAACGYM`` (``rl_games_env``), registered only for the run.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator

import torch

from .device import cuda_on_cpu

log = logging.getLogger(__name__)


class GymBudgetSpent(BaseException):
    """The run's simulated-time budget is spent: unwinds the script (a BaseException, so a script's
    ``except Exception`` does not swallow it) back to ``ambulo run``."""


class _Budget:
    seconds: float | None = None
    simulated_s: float = 0.0
    simulate_calls: int = 0
    stack: contextlib.ExitStack | None = None
    """The running session's contexts (None outside ``gym_session``)."""
    on_cpu: bool = False


def charge(dt_s: float) -> None:
    """Count one ``simulate`` of ``dt_s``; raise ``GymBudgetSpent`` before one that would pass the budget."""
    if _Budget.seconds is not None and _Budget.simulated_s + dt_s > _Budget.seconds + 1e-9:
        raise GymBudgetSpent(f"isaacgym: the run's budget of {_Budget.seconds:g} simulated seconds is spent "
                             f"after {_Budget.simulate_calls} simulate calls")
    _Budget.simulated_s += dt_s
    _Budget.simulate_calls += 1


def simulated() -> tuple[float, int]:
    """(simulated seconds, simulate calls) of the Isaac Gym sims of this run so far."""
    return _Budget.simulated_s, _Budget.simulate_calls


@contextlib.contextmanager
def gym_session(seconds: float | None) -> Iterator[None]:
    """Inside the block, Isaac Gym scripts run as described in this module's docstring."""
    previous = (_Budget.seconds, _Budget.simulated_s, _Budget.simulate_calls)
    _Budget.seconds, _Budget.simulated_s, _Budget.simulate_calls = seconds, 0.0, 0
    with contextlib.ExitStack() as stack:
        from .rl_games_env import registered_vecenvs

        stack.enter_context(registered_vecenvs())
        _Budget.stack, _Budget.on_cpu = stack, False
        try:
            yield
        finally:
            _Budget.seconds = previous[0]  # the counts stay readable (``simulated``) after the run
            _Budget.stack = None


def on_isaacgym_import() -> None:
    """Called by the import hook when a script imports ``isaacgym``: on a host without CUDA, the
    rest of the run maps the script's CUDA devices to the CPU (only Isaac Gym scripts pay the
    torch function mode's per-call cost)."""
    if _Budget.stack is not None and not _Budget.on_cpu and not torch.cuda.is_available():
        _Budget.stack.enter_context(cuda_on_cpu())
        _Budget.on_cpu = True


__all__ = ["GymBudgetSpent", "charge", "gym_session", "on_isaacgym_import", "simulated"]
