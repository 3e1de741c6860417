"""One acceptance scenario: the bridge in this process, the oracle (``oracle.py``) in a child process.

Run by ``test_acceptance.py`` inside a loopback-only network namespace:
``python scenario.py jetbot|humanoid|humanoid_walk|lidar3d|foxglove OUT_DIR``. Writes ``OUT_DIR/truth.json`` (what the simulator
had) and ``OUT_DIR/oracle.json`` (what the oracle received and saw in the graph).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
PEERS: list[Peer] = []  # closed when the scenario ends, however it ends


class Peer:
    """The oracle process: JSON lines in and out."""

    def __init__(self, expect: list[str]):
        self.proc = subprocess.Popen([sys.executable, str(HERE / "oracle.py"), json.dumps(expect)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        PEERS.append(self)

    def close(self, timeout_s: float = 15.0) -> None:
        """End the oracle: it exits after ``dump``; killed if it has not within ``timeout_s``, so it
        never outlives the scenario holding the test's output pipes."""
        if self.proc.poll() is None:
            try:
                self.proc.stdin.close()
                self.proc.wait(timeout=timeout_s)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()

    def send(self, **cmd) -> None:
        self.proc.stdin.write(json.dumps(cmd) + "\n")
        self.proc.stdin.flush()

    def wait(self, event: str, world=None, timeout_s: float = 30.0) -> dict:
        """Read lines until ``event``; the World keeps stepping meanwhile if given (so topics flow)."""
        import selectors

        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if sel.select(timeout=0.0 if world is not None else 0.1):
                line = self.proc.stdout.readline()
                if not line:
                    raise RuntimeError(f"the oracle exited (status {self.proc.wait()})")
                msg = json.loads(line)
                if msg.get("event") == event:
                    return msg
            elif world is not None:
                world.step(render=False)
                time.sleep(0.002)
        raise TimeoutError(f"the oracle did not report {event!r} in {timeout_s} s")


def wait_matched(world, bridge, topics: list[str], timeout_s: float = 60.0) -> None:
    """Step until the bridge's writer on each topic has matched the oracle's reader. The oracle's
    "ready" says it sees the topics in the graph, not that DDS has paired its readers with our
    writers: a volatile writer drops what it publishes before then, so on a busy machine the
    oracle could miss a whole window the test later looks at."""
    step_until(world, lambda: all(bridge.subscribers.get(t, (0, 0.0))[0] > 0 for t in topics), timeout_s)


def step_until(world, condition, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > end:
            raise TimeoutError("condition not met while stepping")
        world.step(render=False)
        time.sleep(0.002)


def jetbot(out: Path) -> None:
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, jetbot_world

    world = jetbot_world()
    robot = world.scene.get_object("jetbot")
    truth = {"joints": {}, "root": {}, "rejected": []}

    def record(_dt):
        ns = int(round(world.current_time * 1e9))
        truth["joints"][ns] = robot.entity.data.joint_pos[0].tolist()
        truth["root"][ns] = robot.entity.data.root_pos_w[0].tolist() + robot.entity.data.root_quat_w[0].tolist()

    # A reliable writer keeps only its history's depth of unacknowledged samples: with the default 10,
    # an oracle starved of CPU (a busy machine) loses messages the bridge did publish. The test is of
    # what the bridge sends, so the history holds the whole run.
    bridge = Ros2Bridge(world, BridgeCfg(record=str(out / "bag"), camera_rate_hz=20.0, data_qos_depth=10_000))
    world.add_physics_callback("truth", record)  # after the bridge's: the state it published
    peer = Peer(["/joint_states", "/imu/data", "/tf", "/tf_static", "/camera/depth", "/clock"])
    ready = peer.wait("ready", world)
    truth["graph_at_ready"] = ready["graph"]
    wait_matched(world, bridge, ["/joint_states", "/imu/data", "/tf", "/camera/depth", "/clock"])
    for _ in range(60):  # at rest: IMU, images
        world.step(render=False)
    truth["rest_end_ns"] = int(round(world.current_time * 1e9))
    camera = bridge.cameras[0]
    truth["depth_at_rest"] = camera.capture(0, annotators=("depth",))["depth"].astype(np.float32).tobytes().hex()
    start = robot.entity.data.root_pos_w[0].clone()
    peer.send(do="publish", topic="/cmd_vel", type="twist", data=[0.3, 0, 0, 0, 0, 0])
    step_until(world, lambda: bridge.cmd_vel is not None)
    start = robot.entity.data.root_pos_w[0].clone()
    steps = int(round(2.0 / world.get_physics_dt()))
    for _ in range(steps):
        world.step(render=False)
    truth["drive_m"] = float(np.linalg.norm((robot.entity.data.root_pos_w[0] - start)[:2].numpy()))
    truth["drive_s"] = steps * world.get_physics_dt()
    bad = [([float("nan"), 0, 0, 0, 0, 0], "twist"), ([0.3, 0.2, 0, 0, 0, 0], "twist"),
           ([5.0, 0, 0, 0, 0, 0], "twist"), ([float("inf"), 0, 0, 0, 0, 0], "twist")]
    for data, kind in bad:
        peer.send(do="publish", topic="/cmd_vel", type=kind, data=data)
    peer.send(do="publish", topic="/joint_group_position_controller/command", type="array", data=[0.1])
    peer.send(do="publish", topic="/joint_command", type="joint_state",
              data={"name": ["no_such_joint"], "position": [0.0]})
    step_until(world, lambda: len(bridge.rejected) >= 6)
    before = world.current_time
    for _ in range(10):
        world.step(render=False)
    truth["still_running"] = world.current_time > before
    truth["rejected"] = list(bridge.rejected)
    truth["cmd_vel_after_rejects"] = list(bridge.cmd_vel)
    truth["end_time_ns"] = int(round(world.current_time * 1e9))
    costmap = sample_costmap()  # every Nav2 cost class, on an odd-sized grid with a negative origin
    bridge.publish_costmap(costmap)
    truth["costmap"] = {"stamp_ns": int(round(world.current_time * 1e9)), "data": costmap.occupancy_grid_data().tolist(),
                        "info": costmap.occupancy_grid_info()}
    wait_matched(world, bridge, ["/costmap"], timeout_s=30.0)
    end = time.monotonic() + 0.5  # and got the transient-local grid
    step_until(world, lambda: time.monotonic() > end)
    peer.send(do="dump", path=str(out / "oracle.json"), until_clock_ns=truth["end_time_ns"])
    peer.wait("dumped", world, timeout_s=120.0)
    bridge.close()
    truth["published"] = dict(bridge.published)
    (out / "truth.json").write_text(json.dumps(truth))


def sample_costmap():
    import torch

    from ambulo.perception.costmap import Costmap

    cost = torch.tensor([[0, 1, 100, 252], [253, 254, 255, 0], [7, 0, 0, 254]], dtype=torch.uint8)
    # origin_xy_m: the lower-left corner of cell [0, 0] (maps.Grid2D; its centre is (-1.025, 2.475))
    return Costmap(cost=cost, origin_xy_m=(-1.05, 2.45), resolution_m=0.05)


def humanoid(out: Path) -> None:
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, humanoid_world

    world = humanoid_world()
    robot = world.scene.get_object("humanoid")
    bridge = Ros2Bridge(world, BridgeCfg(camera_rate_hz=2.0))
    peer = Peer(["/joint_states", "/imu/data"])
    peer.wait("ready", world)
    wait_matched(world, bridge, ["/joint_states", "/imu/data"])
    names = list(robot.entity.joint_names)
    targets = np.zeros(len(names))
    for joint, value in (("left_shoulder_roll", 0.5), ("right_shoulder_roll", -0.5), ("left_elbow", 0.8),
                         ("right_elbow", 0.8), ("torso_yaw", 0.2)):
        targets[names.index(joint)] = value
    walking_before = bridge.walking  # the walking policy runs from attaching until the joint command
    peer.send(do="publish", topic="/joint_group_position_controller/command", type="array", data=targets.tolist())
    step_until(world, lambda: robot.get_applied_action().joint_positions is not None
               and np.abs(np.asarray(robot.get_applied_action().joint_positions) - targets).max() < 1e-12)
    for _ in range(int(round(1.5 / world.get_physics_dt()))):
        world.step(render=False)
    # each joint's equation of motion, solved for the PD error: the drive's kp (q* - q) - kd qd
    # equals M qacc + bias - constraint - passive forces. The robot, paused mid-gait, may still sway
    # slowly after 1.5 s, so the damping and inertia terms are kept (a static check alone left
    # residuals up to 0.017 rad on some runs).
    engine, dofs = world.engine, robot.entity._dof_adr
    model, data = world.model, mujoco.MjData(world.model)
    data.qpos[:], data.qvel[:], data.qacc[:] = (engine.field(n)[0].numpy() for n in ("qpos", "qvel", "qacc"))
    mujoco.mj_forward(model, data)
    data.qacc[:] = engine.field("qacc")[0].numpy()
    inertial = np.zeros(model.nv)
    mujoco.mj_mulM(model, data, inertial, data.qacc)
    load = sum(sign * engine.field(name)[0, dofs] for sign, name in (
        (1, "qfrc_bias"), (-1, "qfrc_constraint"), (-1, "qfrc_passive"))).numpy() + inertial[dofs]
    entity_data = robot.entity.data
    load += entity_data.joint_damping[0].numpy() * entity_data.joint_vel[0].numpy()
    pd_error = (load / entity_data.joint_stiffness[0].numpy()).tolist()
    ctrl_held = engine.ctrl[0].clone()  # the drives' targets (the humanoid's are the only drives)
    truth = {"names": names, "targets": targets.tolist(), "joint_pos": robot.entity.data.joint_pos[0].tolist(),
             "pd_steady_state_error": pd_error, "physics_dt": world.get_physics_dt(),
             "walking_before_joint_command": walking_before, "walking_after_joint_command": bridge.walking,
             "base_height": float(robot.entity.data.root_pos_w[0, 2])}
    # a Twist hands the joints back to the walking policy: it sets the drives' targets again
    peer.send(do="publish", topic="/cmd_vel", type="twist", data=[0.3, 0, 0, 0, 0, 0])
    step_until(world, lambda: bridge.walking)
    for _ in range(8):  # two control periods of the policy (0.02 s)
        world.step(render=False)
    truth["walking_after_twist"] = bridge.walking
    truth["drive_targets_changed"] = float((engine.ctrl[0] - ctrl_held).abs().max())
    truth["rejected"] = list(bridge.rejected)
    peer.send(do="dump", path=str(out / "oracle.json"))
    peer.wait("dumped", world)
    bridge.close()
    (out / "truth.json").write_text(json.dumps(truth))


def humanoid_walk(out: Path) -> None:
    """/cmd_vel to the humanoid, through the shipped walking policy: forward, turn, refusals."""
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, humanoid_world

    world = humanoid_world(SceneCfg(camera=False))
    robot = world.scene.get_object("humanoid")
    data = robot.entity.data
    bridge = Ros2Bridge(world, BridgeCfg())
    truth = {"physics_dt": world.get_physics_dt(), "handler": type(bridge.commands.handler).__name__, "root": {},
             "min_pelvis_m": float(data.root_pos_w[0, 2]), "yaw": 0.0}
    heading = [float(data.heading_w[0])]

    def record(_dt):  # after the bridge's callback: the state it published this step
        pos = data.root_pos_w[0]
        truth["root"][int(round(world.current_time * 1e9))] = pos[:2].tolist()
        truth["min_pelvis_m"] = min(truth["min_pelvis_m"], float(pos[2]))
        now = float(data.heading_w[0])  # unwrapped yaw: sum of per-step changes
        truth["yaw"] += (now - heading[0] + np.pi) % (2 * np.pi) - np.pi
        heading[0] = now

    world.add_physics_callback("truth", record)
    peer = Peer(["/joint_states", "/odom"])
    peer.wait("ready", world)
    wait_matched(world, bridge, ["/joint_states", "/odom"])
    for _ in range(int(round(0.5 / world.get_physics_dt()))):  # walking in place before any Twist
        world.step(render=False)
    truth["walking_before_twist"] = bridge.walking

    def follow(command: list[float], seconds: float) -> dict:
        peer.send(do="publish", topic="/cmd_vel", type="twist", data=command)
        step_until(world, lambda: bridge.cmd_vel == (command[0], command[1], command[5]))
        start, yaw, t0 = data.root_pos_w[0, :2].clone().numpy(), truth["yaw"], world.current_time
        h0 = float(data.heading_w[0])
        for _ in range(int(round(seconds / world.get_physics_dt()))):
            world.step(render=False)
        moved = data.root_pos_w[0, :2].numpy() - start
        return {"s": world.current_time - t0, "forward_m": float(moved @ [np.cos(h0), np.sin(h0)]),
                "left_m": float(moved @ [-np.sin(h0), np.cos(h0)]), "yaw_rad": truth["yaw"] - yaw}

    truth["forward"] = follow([0.4, 0, 0, 0, 0, 0], 3.0)
    truth["turn_left"] = follow([0, 0, 0, 0, 0, 0.8], 2.0)
    truth["turn_right"] = follow([0, 0, 0, 0, 0, -0.8], 2.0)
    for bad in ([1.5, 0, 0, 0, 0, 0], [0, 0.7, 0, 0, 0, 0], [0, 0, 0, 0, 0, -2.0], [float("nan"), 0, 0, 0, 0, 0],
                  [0, 0, 0, 0, 0, float("inf")]):
        peer.send(do="publish", topic="/cmd_vel", type="twist", data=bad)
    step_until(world, lambda: len(bridge.rejected) >= 5)
    for _ in range(10):
        world.step(render=False)
    truth["rejected"] = list(bridge.rejected)
    truth["cmd_vel_after_rejects"] = list(bridge.cmd_vel)
    peer.send(do="dump", path=str(out / "oracle.json"))
    peer.wait("dumped", world)
    bridge.close()
    (out / "truth.json").write_text(json.dumps(truth))


def lidar3d(out: Path) -> None:
    """A 16-channel lidar on the Jetbot: /points recorded; the truth is the sensor's own points."""
    from ambulo import assets
    from ambulo.ros2 import BridgeCfg, Ros2Bridge
    from ambulo.sensors import Lidar, lidar_vlp16
    from ambulo.sim import DynamicCuboid, WheeledRobot, World

    world = World(physics_dt=0.01)
    world.scene.add_default_ground_plane()
    world.scene.add(WheeledRobot(prim_path="/World/Jetbot", name="jetbot", create_robot=True,
                                 usd_path=assets.path("jetbot"), wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    world.scene.add(DynamicCuboid(prim_path="/World/Box", position=[1.0, 0.0, 0.25], size=0.5))
    lidar = world.scene.add(Lidar(lidar_vlp16("/World/Jetbot/chassis/lidar", horizontal_resolution_deg=2.0,
                                              range_noise_std_m=0.0, offset_pos=(0.0, 0.0, 0.12))))
    world.reset()
    bridge = Ros2Bridge(world, BridgeCfg(record=str(out / "bag"), lidar_rate_hz=10.0))
    truth = {}

    def record(_dt):
        ns = int(round(world.current_time * 1e9))
        if bridge.publishing.last.get("lidar0") == world.current_time:  # published this step
            data = lidar.get_current_frame()
            truth[ns] = data.points_s[0][data.hit[0].reshape(-1)].tolist()

    world.add_physics_callback("truth", record)
    for _ in range(35):
        world.step(render=False)
    bridge.close()
    (out / "truth.json").write_text(json.dumps(truth))


def foxglove(out: Path) -> None:
    """``--foxglove``: a plain WebSocket client (Foxglove's protocol) subscribes /joint_states and
    decodes the CDR with mcap_ros2 from the schema the server advertised."""
    import socket
    import struct
    import threading

    from mcap_ros2._dynamic import generate_dynamic
    from websockets.sync.client import connect

    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, jetbot_world

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    world = jetbot_world(SceneCfg(camera=False))
    robot = world.scene.get_object("jetbot")
    bridge = Ros2Bridge(world, BridgeCfg(foxglove_port=port))
    truth, got, advertised = {}, [], {}

    def record(_dt):
        truth[int(round(world.current_time * 1e9))] = robot.entity.data.joint_pos[0].tolist()

    def client():
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
            decode = None
            while len(got) < 30:
                frame = ws.recv(timeout=20)
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    for channel in msg.get("channels", []) if msg.get("op") == "advertise" else []:
                        advertised[channel["topic"]] = {k: channel[k] for k in ("encoding", "schemaName",
                                                                                "schemaEncoding")}
                        if channel["topic"] == "/joint_states" and decode is None:
                            decode = generate_dynamic(channel["schemaName"], channel["schema"])[channel["schemaName"]]
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel["id"]}]}))
                elif frame[0] == 1:  # MessageData: op, subscription id, log time, payload
                    _, sub, log_time = struct.unpack_from("<BIQ", frame)
                    m = decode(frame[13:])
                    got.append([sub, log_time, m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, list(m.position)])

    world.add_physics_callback("truth", record)
    thread = threading.Thread(target=client, daemon=True)
    thread.start()
    end = time.monotonic() + 60
    while thread.is_alive() and time.monotonic() < end:
        world.step(render=False)
        time.sleep(0.002)
    bridge.close()
    (out / "truth.json").write_text(json.dumps({"truth": truth, "got": got, "advertised": advertised}))


if __name__ == "__main__":
    target = Path(sys.argv[2])
    target.mkdir(parents=True, exist_ok=True)
    try:
        {"jetbot": jetbot, "humanoid": humanoid, "humanoid_walk": humanoid_walk, "lidar3d": lidar3d,
         "foxglove": foxglove}[sys.argv[1]](target)
    finally:
        for peer in PEERS:
            peer.close()
