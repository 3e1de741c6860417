"""The viewer as a component of the watched simulation, without a browser: frames are copied only
when the streaming thread asks, the page's pause holds the simulation thread (Step lets exactly one
step through), an env gets the page's command and reset through its own paths, and ``close``
frees the port. Waits are on conditions with generous limits; nothing asserts a duration."""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import torch

pytest.importorskip("viser")
import ambulo.viewer
from ambulo.sim import World
from ambulo.sim.viewers import open_viewer
from ambulo.utils.checks import InvalidValueError
from ports import free_port

LIMIT_S = 120.0


def wait_until(condition, what: str) -> None:
    deadline = time.monotonic() + LIMIT_S
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


@contextlib.contextmanager
def stepping(world):
    """Step ``world`` on a thread of its own (the simulation the viewer watches) while the block runs;
    at its end the viewer is unpaused, so a step held by a pause returns and the thread ends."""
    stop = threading.Event()

    def loop():
        while not stop.is_set():
            world.step(render=False)

    runner = threading.Thread(target=loop, daemon=True)
    runner.start()
    try:
        yield
    finally:
        stop.set()
        world.viewer.controls.set_paused(False)
        runner.join(timeout=LIMIT_S)


@pytest.fixture
def world(box_world):
    w = box_world((0.0, 0.0, 1.0), physics_dt=0.01, viewer="web", viewer_port=free_port())
    w.reset()
    yield w
    w.viewer.close()
    World.clear_instance()


def test_world_viewer_by_name_and_unknown_name():
    assert isinstance(ambulo.viewer.WebViewer, type)
    with pytest.raises(InvalidValueError, match="import ambulo.viewer"):
        open_viewer(None, "vr", 8080)


def test_frames_are_copied_only_when_the_stream_asks(world):
    viewer = world.viewer
    requests, copies = [0], [0]
    request, publish = viewer.exchange.request, viewer.exchange.publish

    def counted_request():
        requests[0] += 1
        request()

    def counted_publish(frame):
        copies[0] += 1
        publish(frame)

    viewer.exchange.request, viewer.exchange.publish = counted_request, counted_publish
    viewer.controls.speed = None  # as fast as it runs
    for _ in range(300):
        world.step(render=False)
    assert world.current_time == pytest.approx(3.0)
    assert copies[0] <= requests[0] + 1 < 300


def test_pause_holds_the_simulation_and_step_lets_one_through(world):
    viewer, controls = world.viewer, world.viewer.controls
    controls.speed = None
    with stepping(world):
        controls.set_paused(True)
        sequence, frame = 0, None
        while frame is None or not frame.paused:  # a frame copied by the held simulation thread
            sequence, frame = viewer.exchange.latest(sequence, timeout_s=LIMIT_S)
        held_at = world.current_time
        for _ in range(5):  # the stream keeps asking; the held simulation answers with the same state
            sequence, frame = viewer.exchange.latest(sequence, timeout_s=LIMIT_S)
        assert world.current_time == held_at
        controls.step_once()
        wait_until(lambda: world.current_time > held_at, "the single step")
        sequence, _ = viewer.exchange.latest(sequence, timeout_s=LIMIT_S)
        sequence, _ = viewer.exchange.latest(sequence, timeout_s=LIMIT_S)
        assert world.current_time == pytest.approx(held_at + world.physics_dt)
        controls.set_paused(False)
        wait_until(lambda: world.current_time > held_at + 0.5, "the resumed simulation")


def test_close_frees_the_port_and_leaves_the_simulation(world):
    viewer = world.viewer
    port = viewer.port
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) == 0
    viewer.close()
    assert "ambulo.viewer" not in world.sim.components
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0
    world.step(render=False)  # the simulation goes on without it


KILLED_SCRIPT = """
import sys
import ambulo.viewer
from ambulo.sim import World
w = World(physics_dt=0.01)
w.scene.add_default_ground_plane()
w.reset()
v = ambulo.viewer.serve(w, port=int(sys.argv[1]), announce=False)
print(v.port, v.link.process.pid, flush=True)
while True:
    w.step(render=False)
"""


def test_a_killed_process_leaves_no_server_behind():
    """The page's server runs in its own process (``remote``): SIGKILL of the watched one (no
    ``close``, no atexit) must still free the port."""
    watched = subprocess.Popen([sys.executable, "-c", KILLED_SCRIPT, str(free_port())], stdout=subprocess.PIPE,
                               text=True)
    try:
        port, server_pid = (int(v) for v in watched.stdout.readline().split())
        assert server_pid != watched.pid
        with socket.socket() as s:
            assert s.connect_ex(("127.0.0.1", port)) == 0
    finally:
        watched.kill()
        watched.wait()

    def port_free() -> bool:
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", port)) != 0

    wait_until(port_free, "the server process to leave with the watched one")


def page_messages(port: int):
    """Each message a page gets from the viewer's websocket, decoded as viser's client does."""
    import msgspec
    import viser
    import zstandard
    from websockets.sync.client import connect

    decompress = zstandard.ZstdDecompressor()
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["viser-v" + viser.__version__], max_size=None) as ws:
        while True:
            raw = ws.recv(timeout=LIMIT_S)
            size, packed = int.from_bytes(raw[:8], "little"), int.from_bytes(raw[8:16], "little")
            yield from msgspec.msgpack.decode(decompress.decompress(raw[16:16 + packed], max_output_size=size))[
                "messages"]


def test_the_server_process_draws_what_is_shown_and_the_poses(world):
    """What crosses the pipe (``remote``): a fed layer and the frames reach the page from the server's process."""
    viewer = world.viewer
    assert viewer.link is not None and viewer.link.process.pid != threading.get_native_id()
    viewer.controls.speed = None
    viewer.show_points("probe", np.array([[1.0, 2.0, 0.5], [2.0, 1.0, 0.3]]))
    with stepping(world):
        points, pose_updates, deadline = None, 0, time.monotonic() + LIMIT_S
        for message in page_messages(viewer.port):
            assert time.monotonic() < deadline, f"the page got {pose_updates} pose updates, points: {points}"
            if message.get("type") == "PointCloudMessage" and message["name"] == "/overlay/points/probe":
                points = message
            updates = message.get("updates", {}) if message.get("type") == "SceneNodeUpdateMessage" else {}
            if message.get("name", "").startswith("/worlds/g") and "batched_positions" in updates:
                pose_updates += 1
            if points is not None and pose_updates >= 3:
                break
    assert points is not None and pose_updates >= 3


def test_env_gets_the_pages_command_and_reset():
    from ambulo import envs

    env = envs.make("humanoid-walk", num_envs=2, seed=0)
    viewer = ambulo.viewer.serve(env, port=free_port(), announce=False)
    try:
        viewer.controls.watch(1)
        viewer.controls.set_command([0.5, 0.0, 0.3])
        other = env.commands.command[0, :2].clone()  # (its yaw rate may steer to a heading)
        actions = torch.zeros(env.num_envs, env.num_actions)
        for _ in range(3):
            env.step(actions)
        np.testing.assert_allclose(env.commands.command[1].numpy(), [0.5, 0.0, 0.3], atol=1e-6)
        assert torch.equal(env.commands.command[0, :2], other)  # the other env keeps its own
        assert int(env.episode_length_buf[1]) == 3
        viewer.controls.request_reset()
        env.step(actions)
        assert int(env.episode_length_buf[1]) == 0 and int(env.episode_length_buf[0]) == 4
    finally:
        viewer.close()
