"""``--viewer web`` on train, play, eval, generate and run: each command, run for a moment with the
flag, serves the viewer's page over HTTP while it runs, finishes as it would without it, and
leaves the port free. (The page itself is checked in a browser by test_viewer_browser.py.)"""

from __future__ import annotations

import signal
import socket
import textwrap
import threading
import time
import urllib.request

import pytest

pytest.importorskip("viser")
pytest.importorskip("rsl_rl")
import ambulo.viewer
from ambulo.cli import main
from ambulo.sim import World
from ports import free_port


class PageProbe:
    """Fetches http://127.0.0.1:port/ from a thread until it gets the page or is stopped."""

    def __init__(self, port: int):
        self.url, self.page = f"http://127.0.0.1:{port}/", None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()

    def _poll(self) -> None:
        while not self._stop.is_set() and self.page is None:
            try:
                with urllib.request.urlopen(self.url, timeout=2) as reply:
                    self.page = reply.read().decode(errors="replace")
            except OSError:
                time.sleep(0.02)

    def stop(self) -> str | None:
        self._stop.set()
        self._thread.join(timeout=5)
        return self.page


def run_served(argv: list[str]) -> tuple[int, str | None]:
    """``ambulo ARGV --viewer web --viewer-port P`` (the run's flags before a script for ``run``):
    (exit status, the page fetched while it ran); checks that the port is free afterwards."""
    port = free_port()
    flags = ["--viewer", "web", "--viewer-port", str(port)]
    argv = [argv[0], *flags, *argv[1:]]
    probe = PageProbe(port)
    try:
        status = main(argv)
    finally:
        page = probe.stop()
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0, "the viewer still holds its port"
    return status, page


def served_the_viewer(page: str | None) -> bool:
    return page is not None and "<html" in page.lower()


def recording_viewers(mp: pytest.MonkeyPatch) -> list:
    """The web viewers opened while ``mp`` is active, in order."""
    opened = []
    original = ambulo.viewer.WebViewer.__init__

    def record(viewer, target, **kwargs):
        original(viewer, target, **kwargs)
        opened.append(viewer)

    mp.setattr(ambulo.viewer.WebViewer, "__init__", record)
    return opened


@pytest.fixture(scope="module")
def watched_training(tmp_path_factory):
    """``ambulo train cartpole --viewer web`` for 2 iterations, the scalars it sent recorded."""
    root = tmp_path_factory.mktemp("runs")
    sent: list[tuple[int, dict]] = []
    original = ambulo.viewer.WebViewer.add_scalars

    def record(viewer, step, scalars):
        sent.append((step, dict(scalars)))
        original(viewer, step, scalars)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ambulo.viewer.WebViewer, "add_scalars", record)
        status, page = run_served(["train", "cartpole", "--num-envs", "4", "--max-iterations", "2",
                                   "--log-root", str(root)])
    runs = list((root / "cartpole").iterdir())
    return status, page, sent, runs


@pytest.mark.timeout(300)
def test_train_serves_the_page_and_plots_every_iteration(watched_training):
    status, page, sent, runs = watched_training
    assert status == 0 and served_the_viewer(page)
    assert [step for step, _ in sent] == [0, 1]
    assert all(scalars["env steps/s"] > 0 for _, scalars in sent)
    assert len(runs) == 1 and (runs[0] / "model_1.pt").is_file()  # the run finished and saved


@pytest.mark.timeout(300)
def test_play_shows_the_rollout_instead_of_filming_it(watched_training, capsys):
    run = watched_training[3][0]
    with pytest.MonkeyPatch.context() as mp:
        opened = recording_viewers(mp)
        status, page = run_served(["play", str(run), "--seconds", "0.3"])
    assert status == 0 and served_the_viewer(page)
    assert "played 15 steps" in capsys.readouterr().out  # 0.3 s of cartpole's 0.02 s steps
    assert not (run / "videos").exists()
    assert len(opened) == 1 and opened[0].controls.speed == 1.0  # at real time, not the env's max


@pytest.mark.timeout(300)
def test_eval_serves_the_page_and_writes_its_result(watched_training):
    run = watched_training[3][0]
    status, page = run_served(["eval", str(run), "--episodes", "2", "--episode-length-s", "0.2"])
    assert status == 0 and served_the_viewer(page)
    assert (run / "eval.json").is_file()


@pytest.mark.timeout(300)
def test_generate_serves_the_page_and_writes_the_dataset(tmp_path):
    status, page = run_served(["generate", "--frames", "2", "--out", str(tmp_path / "data"), "--width", "64",
                               "--height", "48", "--quiet"])
    assert status == 0 and served_the_viewer(page)
    assert (tmp_path / "data" / "annotations.json").is_file()


def test_training_curves_include_each_evaluation_and_its_criteria(tmp_path):
    """What --eval-every adds to the curves, without running 100 evaluation episodes."""
    from types import SimpleNamespace

    from ambulo.rl.interrupt import StopRequest
    from ambulo.rl.progress import TrainingProgress

    evaluation = {"fall_rate": 0.25, "mean_return": 3.0, "mean_abs_lin_vel_error": 0.3, "criteria": ["walks"],
                  "walks": False}
    periodic = type("Periodic", (), {"due": lambda self, it: it == 1, "started_s": time.monotonic(), "reached": None,
                                     "__call__": lambda self, runner, it: evaluation, "poll": lambda self: []})()
    sent = []
    (tmp_path / "task" / "run").mkdir(parents=True)
    progress = TrainingProgress(SimpleNamespace(device="cpu"), tmp_path / "task" / "run", start=0, total=2,
                                episodes=SimpleNamespace(means=lambda: (2.0, 50)), verbose=True, step_dt_s=0.02,
                                steps_per_iteration=96, stop=StopRequest(), periodic=periodic,
                                on_scalars=lambda step, scalars: sent.append((step, scalars)))
    progress.iteration_done(0, 0.5, 0.5, 1.0)
    progress.iteration_done(1, 0.5, 0.5, 1.0)
    progress.close()
    assert sent[0] == (0, {"env steps/s": 96.0, "mean reward": 2.0, "episode length (s)": 1.0})
    assert [step for step, _ in sent] == [0, 1, 1]  # iteration 1's numbers, then its evaluation's
    assert sent[2][1] == {"eval fall rate": 0.25, "eval abs_lin_vel_error": 0.3, "criterion walks": 0.0}


@pytest.mark.timeout(300)
def test_ctrl_c_during_training_frees_the_port(tmp_path):
    def interrupt(viewer, step, scalars):  # Ctrl-C arrives during the first iteration's bookkeeping
        signal.raise_signal(signal.SIGINT)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ambulo.viewer.WebViewer, "add_scalars", interrupt)
        status, page = run_served(["train", "cartpole", "--num-envs", "4", "--max-iterations", "5",
                                   "--log-root", str(tmp_path)])
    assert status == 128 + signal.SIGINT and served_the_viewer(page)  # run_served checked the port


@pytest.mark.timeout(300)
def test_ctrl_c_during_play_frees_the_port(watched_training):
    updates = []
    original = ambulo.viewer.WebViewer.update

    def interrupt_after_half_a_second(viewer, dt_s):
        updates.append(dt_s)
        if len(updates) == 25:
            raise KeyboardInterrupt
        original(viewer, dt_s)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ambulo.viewer.WebViewer, "update", interrupt_after_half_a_second)
        status, page = run_served(["play", str(watched_training[3][0]), "--seconds", "5"])
    assert status == 130 and served_the_viewer(page) and len(updates) == 25


WORLD_SCRIPT = """
from isaacsim import SimulationApp
simulation_app = SimulationApp({"headless": True})
import numpy as np
from isaacsim.core.api import World
from isaacsim.core.api.objects import DynamicCuboid
world = World()
world.scene.add_default_ground_plane()
world.scene.add(DynamicCuboid(prim_path="/World/cube", name="cube", position=np.array([0.0, 0.0, 1.0])))
world.reset()
while simulation_app.is_running():
    world.step(render=False)
simulation_app.close()
"""

GYM_SCRIPT = """
from isaacgym import gymapi
gym = gymapi.acquire_gym()
params = gymapi.SimParams()
params.up_axis, params.gravity = gymapi.UP_AXIS_Z, gymapi.Vec3(0.0, 0.0, -9.81)
sim = gym.create_sim(0, 0, gymapi.SIM_PHYSX, params)
gym.add_ground(sim, gymapi.PlaneParams())
viewer = gym.create_viewer(sim, gymapi.CameraProperties())  # before the envs, as many scripts do
asset = gym.load_asset(sim, "assets", "humanoid.urdf", gymapi.AssetOptions())
for i in range(2):
    env = gym.create_env(sim, gymapi.Vec3(-1.0, -1.0, 0.0), gymapi.Vec3(1.0, 1.0, 1.0), 2)
    gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(0.0, 0.0, 1.0)), "humanoid", i, 0)
gym.prepare_sim(sim)
while not gym.query_viewer_has_closed(viewer):
    gym.simulate(sim)
    gym.fetch_results(sim, True)
    gym.step_graphics(sim)
    gym.draw_viewer(viewer, sim, True)
    gym.sync_frame_time(sim)
"""


@pytest.mark.timeout(300)
@pytest.mark.parametrize("script", [WORLD_SCRIPT, GYM_SCRIPT], ids=["isaac-sim-world", "isaac-gym-viewer"])
def test_run_serves_the_scripts_simulation(tmp_path, capsys, script):
    path = tmp_path / "script.py"
    path.write_text(textwrap.dedent(script))
    World.clear_instance()
    with pytest.MonkeyPatch.context() as mp:
        opened = recording_viewers(mp)
        status, page = run_served(["run", "--seconds", "0.3", str(path)])
    World.clear_instance()
    assert status == 0 and served_the_viewer(page)
    printed = capsys.readouterr()
    assert "0.30 s simulated" in printed.out and "showed nothing" not in printed.err
    assert len(opened) == 1 and opened[0].frames_sent > 1  # frames after the first: its steps were streamed


def test_run_says_when_a_script_showed_nothing(tmp_path, capsys):
    path = tmp_path / "headless.py"
    path.write_text("print('no World, no viewer')\n")
    status, _ = run_served(["run", str(path)])
    assert status == 0 and "showed nothing" in capsys.readouterr().err


@pytest.mark.parametrize("argv, problem", [
    (["generate", "--out", "x", "--workers", "2", "--viewer", "web"], "--viewer web watches the frames rendered"),
    (["play", "cartpole", "--out", "x.mp4", "--viewer", "web"], "--viewer web shows the rollout live"),
    (["train", "cartpole", "--viewer", "web", "--viewer-port", "0"], "--viewer-port 0 is not a TCP port"),
    (["bridge", "apartment", "--navigate", "--viewer", "web"], "the navigator's node (--navigate) is not watched"),
    (["bridge", "jetbot", "--viewer", "web", "--viewer-port", "0"], "--viewer-port 0 is not a TCP port"),
])
def test_viewer_flags_that_cannot_apply_are_one_line_errors(capsys, argv, problem, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and problem in err[0], err
