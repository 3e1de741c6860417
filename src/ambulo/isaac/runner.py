"""``run_script``: run an Isaac Sim script, unchanged, on ambulo (what ``ambulo run`` calls)."""

from __future__ import annotations

import contextlib
import os
import runpy
import sys
from dataclasses import dataclass
from pathlib import Path

from ambulo.sim.current import current_world_or_none
from ambulo.sim.usd_stage import forget_stages
from ambulo.sim.viewers import viewer_for_new_worlds

from .app import run_budget
from .gym import GymBudgetSpent, gym_session, simulated
from .gym.viewer import web_viewers
from .hook import isaac_names
from .kit_commands import clear_stack


class ScriptPathError(FileNotFoundError):
    """The script to run is missing or is a folder (not an error raised inside the script)."""


@dataclass(frozen=True)
class RunResult:
    """What a script run did: simulated seconds and steps of the last World it used."""

    script: str
    ran_sample: str | None
    """The ``BaseSample`` subclass run as LOAD then PLAY, or None for a standalone script."""
    sim_time_s: float
    physics_steps: int
    """For an Isaac Gym script: the ``simulate`` calls of its sims (each ``substeps`` MuJoCo steps)."""
    budget_spent: bool = False
    """An Isaac Gym script was stopped at a ``simulate`` call because ``seconds`` were simulated."""


def run_script(path: str | os.PathLike, argv: list[str] | tuple[str, ...] = (), seconds: float = 10.0,
               viewer: str | None = None, viewer_port: int = 8080) -> RunResult:
    """Run the Isaac script ``path`` with ``sys.argv = [path, *argv]`` and Isaac's module names.

    A script with a ``__main__`` flow (``SimulationApp``, then a World it steps) runs as is;
    ``while simulation_app.is_running()`` loops stop after ``seconds`` of simulated time. A
    script that only defines a ``BaseSample`` subclass (an extension-workflow example) is then
    loaded and played for ``seconds``, as the Examples browser's LOAD and PLAY would. An Isaac
    Gym script (``from isaacgym import gymapi``) stops at the ``simulate`` call that would pass
    ``seconds`` of simulated time (``ambulo.isaac.gym.session``).

    ``viewer="web"`` (``ambulo run --viewer web``) watches the script in a browser from
    ``viewer_port``: each World it creates opens a web viewer (``sim.viewers.viewer_for_new_worlds``),
    and so does each Isaac Gym viewer (``gym.create_viewer``; ``gym.viewer.web_viewers``), shown
    at every ``draw_viewer``. They close when the run ends, Ctrl-C included.
    """
    script = Path(path)
    if script.is_dir():
        raise ScriptPathError(f"{script} is a folder; give the Isaac script (.py) to run")
    if not script.is_file():
        raise ScriptPathError(f"no script {str(script)!r}; check the path")
    from .sample import BaseSample, run_sample  # imports the World

    saved_argv, saved_path = sys.argv, list(sys.path)
    forget_stages()  # no World and an empty stage, as Kit starts a script (nothing left from a previous run)
    clear_stack()  # no undo history either
    budget_spent = False
    try:
        with isaac_names(), run_budget(seconds), gym_session(seconds), _watched(viewer, viewer_port):
            sys.argv = [str(script), *argv]
            sys.path.insert(0, str(script.resolve().parent))  # as `python script.py` would
            try:
                namespace = runpy.run_path(str(script), run_name="__main__")
                _finish_replicator()
            except GymBudgetSpent:
                namespace, budget_spent = {}, True
            samples = [v for v in namespace.values() if isinstance(v, type) and issubclass(v, BaseSample)
                       and v is not BaseSample and v.__module__ == "__main__"]
            ran_sample = None
            if samples and current_world_or_none() is None:
                ran_sample = samples[-1].__name__
                run_sample(samples[-1], seconds)
    finally:
        sys.argv, sys.path[:] = saved_argv, saved_path
    gym_time_s, gym_calls = simulated()
    if gym_calls:
        return RunResult(script=str(script), ran_sample=None, sim_time_s=gym_time_s, physics_steps=gym_calls,
                         budget_spent=budget_spent)
    world = current_world_or_none()
    return RunResult(script=str(script), ran_sample=ran_sample,
                     sim_time_s=0.0 if world is None else world.current_time,
                     physics_steps=0 if world is None else world.current_time_step_index)


def _finish_replicator() -> None:
    """A Replicator script that ended after ``rep.orchestrator.preview()`` gets what Kit's Run
    button would do (``replicator.orchestrator.finish_script``)."""
    if "omni.replicator.core" in sys.modules:
        from .replicator.orchestrator import finish_script

        finish_script()


@contextlib.contextmanager
def _watched(viewer: str | None, port: int):
    """The run's Worlds and Isaac Gym viewers open ``viewer`` inside the block (nothing for None)."""
    if viewer is None:
        yield
        return
    import ambulo.viewer  # noqa: F401  (registers viewer="web" for the Worlds)

    with viewer_for_new_worlds(viewer, port) as worlds, web_viewers(port) as gym_views:
        yield
    if not worlds and not any(view.viewer is not None for view in gym_views):
        print(f"ambulo run: --viewer {viewer} showed nothing: the script created no World and drew no Isaac Gym "
              "viewer (gym.create_viewer, then gym.draw_viewer in its loop)", file=sys.stderr)


__all__ = ["RunResult", "ScriptPathError", "run_script"]
