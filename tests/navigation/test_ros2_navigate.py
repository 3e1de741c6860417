"""Issue 24's ROS 2 acceptance: a real rclpy node in another process sends a goal on /goal_pose, the
navigator (``navigation.ros2_node.NavigateNode``) walks the humanoid there, and what the peer
received (/plan, /footsteps, /map, /costmap, /odom, /tf, /navigate/status) is checked against
the simulator's truth. On a loopback-only network, as ``tests/ros2`` runs its scenarios.

This file is also the two processes: ``python test_ros2_navigate.py scenario OUT`` (the navigator
and its node; starts the peer) and ``python test_ros2_navigate.py peer OUT GOAL_X GOAL_Y GOAL_YAW``
(the independent rclpy node: rclpy, the message wheels and ``mcap_ros2``'s CDR decoder only).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve()
APARTMENT_SEED = 1000
EPISODE_SEED = 0
"""Apartment 1000, episode 0: a start and a goal 2.9 m apart along the robot's clearance (2.8 m straight)."""
SIM_LIMIT_S = 60.0
"""Simulated seconds the robot gets from the goal (the oracle navigator arrives in ~12 s)."""
TERMINAL = ("arrived", "fell", "stuck", "timeout", "lost_timeout")


# -- the test -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def navigate_run(tmp_path_factory):
    from ros2.conftest import needs_rclpy, run_loopback

    needs_rclpy()
    out = tmp_path_factory.mktemp("navigate")
    t0 = time.perf_counter()
    run_loopback([str(HERE), "scenario", str(out)], timeout_s=300.0)
    wall_s = time.perf_counter() - t0
    print(f"navigate scenario: {wall_s:.1f} s wall")
    return json.loads((out / "peer.json").read_text()), json.loads((out / "truth.json").read_text())


def test_a_goal_on_goal_pose_is_walked_to_and_arrival_is_reported(navigate_run):
    peer, truth = navigate_run
    goal = np.array(truth["goal_xy_m"])
    statuses = [s for _, s in peer["status"]]
    assert "walking" in statuses, statuses
    assert statuses[-1] == "arrived", statuses
    assert truth["status"] == "arrived" and truth["goals_taken"] == 2  # the first goal, then the real one
    # at arrival: the simulator's pelvis, and the peer's own view of it (/ground_truth/odom; /odom in oracle mode)
    arrived_ns = round(truth["arrived_s"] * 1e9)
    assert np.linalg.norm(np.array(truth["arrived_xy_m"]) - goal) < 0.3
    for topic in ("truth", "odom"):
        at = min(peer[topic], key=lambda o: abs(o[0] - arrived_ns))
        assert abs(at[0] - arrived_ns) < 0.11e9 and np.linalg.norm(np.array(at[1:3]) - goal) < 0.3
        assert abs(math.remainder(at[3] - truth["goal_yaw_rad"], math.tau)) < 0.4  # facing the goal pose's way
    # it walked there: it stood at the start, 2.8 m away, before the goal
    assert np.linalg.norm(np.array(peer["truth"][0][1:3]) - np.array(truth["start_pose"][:2])) < 0.1
    assert not truth["fell"]


def test_a_goal_in_another_frame_is_refused_saying_why(navigate_run):
    peer, truth = navigate_run
    rejected = [s for _, s in peer["status"] if s.startswith("rejected: ")]
    assert len(rejected) == 1 and "'base_link'" in rejected[0] and "'map'" in rejected[0]
    assert truth["rejected"] == [rejected[0].removeprefix("rejected: ")]


def test_the_plan_runs_from_the_robot_to_the_goal_and_a_new_goal_replaces_the_old(navigate_run):
    peer, truth = navigate_run
    goal, decoy = np.array(truth["goal_xy_m"]), np.array(truth["decoy_xy_m"])
    assert peer["plan"], "no /plan received"
    ends = np.array([p[2][-1] for p in peer["plan"]])
    to_decoy = np.linalg.norm(ends - decoy, axis=1) < 0.15
    to_goal = np.linalg.norm(ends - goal, axis=1) < 0.15  # the goal's cell centre
    assert to_decoy.any() and to_goal[-1]
    assert to_goal[np.argmax(to_decoy):].any() and not to_decoy[np.argmax(to_goal):].any()  # decoy, then goal
    for stamp, frame, path in peer["plan"]:
        path = np.array(path)
        assert frame == "map" and len(path) >= 2
        robot = min(peer["truth"], key=lambda o: abs(o[0] - stamp))  # where the robot was then (+- 50 ms)
        assert np.linalg.norm(path[0] - np.array(robot[1:3])) < 0.1  # the robot's cell centre
    stamp, frame, path = peer["plan"][-1][0], peer["plan"][-1][1], np.array(peer["plan"][-1][2])
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() < 0.15  # neighbouring 5 cm cells: a path, not a jump
    # the route keeps the robot's clearance: no point of it on an occupied cell of the true map
    occ = np.array(peer["map"][-1]["data"], np.int8).reshape(peer["map"][-1]["height"], peer["map"][-1]["width"])
    ox, oy, res = peer["map"][-1]["origin"][0], peer["map"][-1]["origin"][1], peer["map"][-1]["resolution"]
    ix, iy = ((path[:, 0] - ox) / res).astype(int), ((path[:, 1] - oy) / res).astype(int)
    assert (occ[iy, ix] < 100).all()


def test_footsteps_are_cubes_alternating_left_and_right_ending_at_the_goal(navigate_run):
    peer, truth = navigate_run
    assert peer["footsteps"], "no /footsteps received"
    for markers in peer["footsteps"]:
        assert markers[0]["action"] == 3  # DELETEALL first: the last plan's markers go
    final = peer["footsteps"][-1]
    cubes = [m for m in final[1:] if m["action"] == 0]
    assert len(cubes) > 2 and all(m["type"] == 1 and m["frame_id"] == "map" for m in cubes)
    green, red = (m["color"][1] > m["color"][0] for m in cubes), (m["color"][0] > m["color"][1] for m in cubes)
    sides = [1 if g else -1 if r else 0 for g, r in zip(green, red)]
    assert all(s != 0 for s in sides) and all(a == -b for a, b in zip(sides[2:], sides[3:]))  # steps alternate
    assert all(m["scale"][0] > m["scale"][1] > m["scale"][2] > 0 for m in cubes)  # a sole: long, narrow, thin
    last_two = np.array([m["xyz"][:2] for m in cubes[-2:]])
    assert np.linalg.norm(last_two.mean(axis=0) - np.array(truth["goal_xy_m"])) < 0.3
    assert len({m["id"] for m in cubes}) == len(cubes)


def test_map_is_the_apartment_occupancy_and_the_costmap_matches_it(navigate_run):
    peer, truth = navigate_run
    assert peer["map"] and peer["costmap"]
    m, c, occ = peer["map"][-1], peer["costmap"][-1], truth["occupancy"]
    assert (m["height"], m["width"]) == tuple(occ["shape"]) == (c["height"], c["width"])
    assert m["resolution"] == pytest.approx(occ["resolution_m"]) == c["resolution"]
    assert m["origin"] == pytest.approx(occ["origin_xy_m"]) == c["origin"]
    assert m["frame_id"] == c["frame_id"] == "map"
    truth_data = np.array(occ["data"], np.int8)
    assert np.array_equal(np.array(m["data"], np.int8), truth_data)  # oracle mode: the true map, cell for cell
    cost = np.array(c["data"], np.int8)
    assert (cost[truth_data == 100] == 100).all()  # occupied cells are lethal (Nav2's 100)
    assert (cost[truth_data == 0] < 100).any() and cost.max() <= 100 and cost.min() >= -1


def test_tf_is_map_odom_base_link_with_odom_equal_to_the_odometry(navigate_run):
    peer, _ = navigate_run
    assert peer["tf"]
    by_stamp = {o[0]: o for o in peer["odom"]}
    checked = 0
    for stamp, transforms in peer["tf"]:
        pairs = {(p, ch): (xyz, q) for p, ch, xyz, q in transforms}
        xyz, q = pairs[("map", "odom")]
        assert xyz == [0.0, 0.0, 0.0] and q == [0.0, 0.0, 0.0, 1.0]  # identity (ros2_node docstring)
        xyz, q = pairs[("odom", "base_link")]
        if stamp in by_stamp:
            _, x, y, yaw = by_stamp[stamp]
            assert xyz[:2] == pytest.approx([x, y]) and 2 * math.atan2(q[2], q[3]) == pytest.approx(yaw, abs=1e-9)
            checked += 1
    assert checked > 10
    stamps = [s for s, _ in peer["tf"]]
    assert stamps == sorted(stamps) and peer["clock"] == sorted(peer["clock"]) and len(set(peer["clock"])) > 100


# -- the messages, by hand ------------------------------------------------------------------------------
def test_footstep_markers_decode_as_a_deleteall_then_one_cube_per_foot():
    from ros2.conftest import needs_rclpy

    needs_rclpy()
    from ambulo.nav import FootstepPlan, PlanStatus
    from ambulo.navigation.ros2_messages import footstep_markers_cdr
    from ambulo.ros2.raw_types import typestore

    feet = np.array([[0.0, 0.1, 0.0], [0.0, -0.1, 0.0], [0.3, 0.1, 0.0], [0.6, -0.1, math.pi / 2]])
    plan = FootstepPlan(PlanStatus.SUCCESS, feet, np.array([1, -1, 1, -1], np.int8), np.array([0.0, 0.0, 0.0, 0.05]),
                        4.0, 10, 0.01)
    raw = footstep_markers_cdr(2.5, "map", plan, (0.22, 0.10))
    markers = _decoder("visualization_msgs/msg/MarkerArray", typestore())(raw).markers  # mcap_ros2's decoder
    assert [m.action for m in markers] == [3, 0, 0, 0, 0] and [m.id for m in markers[1:]] == [0, 1, 2, 3]
    cubes = markers[1:]
    assert all(m.type == 1 and m.header.frame_id == "map" for m in cubes)
    assert cubes[0].header.stamp.sec == 2 and cubes[0].header.stamp.nanosec == 500_000_000
    assert [(m.pose.position.x, m.pose.position.y) for m in cubes] == [tuple(f[:2]) for f in feet]
    assert cubes[3].pose.position.z == pytest.approx(0.05 + 0.01)  # on its terrain, half the 2 cm thickness up
    q = cubes[3].pose.orientation  # 90 deg about z
    assert (q.x, q.y, q.z, q.w) == pytest.approx((0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))
    assert (cubes[0].scale.x, cubes[0].scale.y, cubes[0].scale.z) == pytest.approx((0.22, 0.10, 0.02))
    left, right = cubes[2].color, cubes[3].color
    assert left.g > left.r and right.r > right.g  # left green, right red
    assert cubes[0].color.a < cubes[2].color.a  # the start feet are faint
    empty = _decoder("visualization_msgs/msg/MarkerArray", typestore())(footstep_markers_cdr(0.0, "map", None))
    assert [m.action for m in empty.markers] == [3]  # no plan: only the DELETEALL


def test_path_poses_face_the_next_point():
    from ros2.conftest import needs_rclpy

    needs_rclpy()
    from ambulo.navigation.ros2_messages import path_msg

    msg = path_msg(1.0, "map", np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    yaws = [2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w) for p in msg.poses]
    assert yaws == pytest.approx([0.0, math.pi / 2, math.pi, math.pi])  # the last keeps the previous heading
    assert [(p.pose.position.x, p.pose.position.y) for p in msg.poses] == [(0, 0), (1, 0), (1, 1), (0, 1)]
    assert msg.header.frame_id == "map" and msg.header.stamp.sec == 1


def test_odometry_bytes_decode_with_rclpy_to_the_pose_and_body_velocity():
    from ros2.conftest import needs_rclpy

    needs_rclpy()
    import rclpy  # noqa: F401 - the message packages need its libraries
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    from ambulo.navigation.ros2_messages import OdometryCdr

    raw = OdometryCdr("odom", "base_link")(3.25, (1.0, -2.0, -math.pi / 2), (0.4, -0.1, 0.3))
    msg = deserialize_message(raw, Odometry)  # rclpy's own typesupport
    assert (msg.header.frame_id, msg.child_frame_id) == ("odom", "base_link")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (3, 250_000_000)
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    assert (p.x, p.y, p.z) == (1.0, -2.0, 0.0)
    assert (q.x, q.y, q.z, q.w) == pytest.approx((0.0, 0.0, -math.sqrt(0.5), math.sqrt(0.5)))  # -90 deg about z
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    assert (v.x, v.y, v.z, w.x, w.y, w.z) == (0.4, -0.1, 0.0, 0.0, 0.0, 0.3)
    assert not any(msg.pose.covariance) and not any(msg.twist.covariance)


def test_status_says_no_route_while_the_latest_replan_for_the_goal_found_none():
    from ambulo.navigation.planning import ReplanRecord
    from ambulo.navigation.ros2_node import goal_status

    found = ReplanRecord(1.0, 0.01, "new goal", True, "success", 12, True)
    none = ReplanRecord(2.0, 0.01, "period", False, "no_route", 0, False)
    assert goal_status("walking", None) == "walking"  # no replan for this goal yet
    assert goal_status("walking", found) == "walking"
    assert goal_status("walking", none) == "no_route"
    assert goal_status("arrived", none) == "arrived"  # an ending stands
    assert goal_status("lost", none) == "lost"


# -- the command ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, parts", [
    (["bridge", "apartment", "--navigate", "--record", "x.mcap"], ["--record does not go with --navigate"]),
    (["bridge", "apartment", "--navigate", "--start", "1,2"], ["--start '1,2' is not 3 finite numbers", "e.g."]),
    (["bridge", "apartment", "--navigate", "--goal", "1,nan"], ["--goal '1,nan' is not 2 or 3 finite numbers"]),
    (["bridge", "jetbot", "--navigate"], ["--navigate needs 'apartment' or a world file, not 'jetbot'"]),
    (["bridge", str(HERE), "--navigate"], ["--navigate needs 'apartment' or a world file"]),
])
def test_navigate_bad_input_is_one_line(capsys, argv, parts):
    from ambulo.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("ambulo bridge: error: ")
    assert all(part in err for part in parts), err


def test_navigate_a_world_file_needs_a_start(capsys, tmp_path):
    from ambulo.cli import main

    world = tmp_path / "room.xml"
    world.write_text("<mujoco><worldbody><geom type='box' size='1 1 1' pos='3 0 1'/></worldbody></mujoco>")
    assert main(["bridge", str(world), "--navigate"]) == 2
    assert "--start is missing" in capsys.readouterr().err


@pytest.mark.slow  # ~40-70 s on a loaded machine: the apartment, the navigator and rclpy start in a process
def test_bridge_navigate_walks_to_the_goal_given_on_the_command_line():
    from ambulo.robots import humanoid
    from ambulo.scenes.apartment import apartment
    from ros2.conftest import needs_rclpy, run_loopback

    needs_rclpy()
    ep = apartment(APARTMENT_SEED).sample_start_goal(EPISODE_SEED, 2.5, 3.5, humanoid.BODY_RADIUS_M)
    proc = run_loopback(["-m", "ambulo.cli", "bridge", "apartment", "--seed", str(APARTMENT_SEED), "--navigate",
                         "--start", ",".join(map(str, ep.start_pose)), "--goal", ",".join(map(str, ep.goal_xy_m)),
                         "--seconds", "25"])
    assert "publishing /clock, /costmap, /footsteps, /ground_truth/odom, /map, /navigate/status, /odom, /plan, /tf" \
        in proc.stdout
    assert "simulated 25.00 s" in proc.stdout and "status arrived" in proc.stdout


# -- the scenario process: the navigator and its node ------------------------------------------------
def scenario(out: Path) -> int:
    t0 = time.monotonic()

    def phase(name: str) -> None:  # where the wall time goes (shown when the test fails)
        print(f"scenario: {name} at {time.monotonic() - t0:.1f} s wall", flush=True)

    from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg
    from ambulo.navigation.ros2_node import NavigateNode, NavigateNodeCfg
    from ambulo.robots import humanoid
    from ambulo.scenes.apartment import apartment

    apt = apartment(APARTMENT_SEED)
    ep = apt.sample_start_goal(EPISODE_SEED, 2.5, 3.5, humanoid.BODY_RADIUS_M)
    world = NavWorld.from_apartment(apt, ep.start_pose, NavWorldCfg(record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="oracle", time_limit_s=SIM_LIMIT_S))
    # a reliable writer keeps only its history of unacknowledged samples: the test is of what the node
    # sends, so a peer starved of CPU must lose nothing
    node = NavigateNode(nav, NavigateNodeCfg(qos_depth=10_000))
    phase("imported, world and node built")
    goal = np.array(ep.goal_xy_m, float)
    d = goal - np.array(ep.start_pose[:2])
    yaw = math.atan2(d[1], d[0])  # arrive facing the way it came
    # the first goal, replaced by the real one: another episode's goal, reachable from the start
    decoy = next(np.array(g) for g in (apt.sample_start_goal(s, 1.5, 6.0, humanoid.BODY_RADIUS_M).goal_xy_m
                                       for s in range(1, 20))
                 if math.isfinite(apt.geodesic_m(ep.start_pose[:2], g)) and math.dist(g, goal) > 1.0)
    peer = subprocess.Popen([sys.executable, str(HERE), "peer", str(out),
                             *map(str, (goal[0], goal[1], yaw, decoy[0], decoy[1]))], stdin=subprocess.PIPE)
    wall_end = time.monotonic() + 240.0
    goal_time: list[float] = []
    arrived: dict = {}

    def over(n: NavigateNode) -> bool:
        if n.goals and not goal_time:
            goal_time.append(world.time_s)
        if nav.status == "arrived" and not arrived:  # where it was when it said so
            arrived.update(arrived_s=world.time_s, arrived_xy_m=world.true_pose()[:2].tolist())
        sim_over = bool(goal_time) and world.time_s - goal_time[0] > SIM_LIMIT_S + 5.0
        # the peer's dump ends it (its DDS teardown may take seconds the robot would stand through)
        return (out / "peer.json").exists() or peer.poll() is not None or time.monotonic() > wall_end or sim_over

    try:
        # the simulation waits for the peer (its goal publisher): stepping meanwhile would only take
        # the CPU the peer needs to start, and walk the robot in place
        while node.node.count_publishers("/goal_pose") == 0 and peer.poll() is None and time.monotonic() < wall_end:
            time.sleep(0.05)
        phase("peer ready")
        node.spin(until=over)
        phase(f"over at {world.time_s:.1f} s simulated ({nav.status})")
        peer.stdin.close()  # over without arrival: the peer dumps what it has
        end = time.monotonic() + 30.0
        while peer.poll() is None and time.monotonic() < end and not (out / "peer.json").exists():
            node.spin(seconds=0.05)
        phase("peer dumped")
    finally:  # a peer that dumped has nothing left to lose: its DDS teardown is not waited for
        if peer.poll() is None:
            peer.kill()
        peer.wait()
        node.close()
    grid = apt.occupancy
    (out / "truth.json").write_text(json.dumps({
        "status": nav.status, "goals_taken": len(node.goals), "goal_xy_m": goal.tolist(),
        "start_pose": list(ep.start_pose), "goal_yaw_rad": yaw, "decoy_xy_m": decoy.tolist(),
        "rejected": node.rejected, **arrived, "fell": world.fell,
        "published": dict(node.published),
        "occupancy": {"shape": list(grid.shape), "resolution_m": grid.resolution_m,
                      "origin_xy_m": list(grid.origin_xy_m), "data": grid.occupancy.reshape(-1).tolist()}}))
    world.close()
    phase("truth written")
    return 0


# -- the peer process: an independent rclpy node --------------------------------------------------------
def _raw_class(typename: str):
    """A serialized-only class for a type without a wheel, from ambulo's ``raw_types.py`` loaded by path
    (the declaration a stock ROS 2 node would have from its generated package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("peer_raw_types", HERE.parents[2] / "src/ambulo/ros2/raw_types.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.raw_message_class(typename), module.typestore(), module.clear_rcutils_error


def _decoder(typename: str, store):
    """``mcap_ros2``'s CDR decoder, from the type's message definition text."""
    from mcap_ros2._dynamic import generate_dynamic

    text, _ = store.generate_msgdef(typename, ros_version=2)
    return generate_dynamic(typename, text)[typename]


def peer(out: Path, goal_x: float, goal_y: float, goal_yaw: float, decoy_x: float, decoy_y: float) -> int:
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import OccupancyGrid, Odometry
    from nav_msgs.msg import Path as PathMsg
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node("navigate_peer")
    reliable = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    status_qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
    got: dict[str, list] = {k: [] for k in ("status", "plan", "footsteps", "map", "costmap", "odom", "truth", "tf",
                                            "clock")}
    lock = threading.Lock()

    def add(key, item):
        with lock:
            got[key].append(item)

    def t(stamp) -> int:
        return stamp.sec * 1_000_000_000 + stamp.nanosec

    def yaw(q) -> float:
        return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))

    def grid(m) -> dict:
        return {"frame_id": m.header.frame_id, "width": m.info.width, "height": m.info.height,
                "resolution": m.info.resolution, "origin": [m.info.origin.position.x, m.info.origin.position.y],
                "data": list(m.data)}

    def odom(m) -> list:
        p = m.pose.pose
        return [t(m.header.stamp), p.position.x, p.position.y, yaw(p.orientation)]

    (markers_type, store, clear), (tf_type, _, _) = (_raw_class("visualization_msgs/msg/MarkerArray"),
                                                      _raw_class("tf2_msgs/msg/TFMessage"))
    decode_markers, decode_tf = _decoder("visualization_msgs/msg/MarkerArray", store), _decoder(
        "tf2_msgs/msg/TFMessage", store)

    def markers(raw: bytes) -> list:
        return [{"action": m.action, "type": m.type, "id": m.id, "frame_id": m.header.frame_id,
                 "xyz": [m.pose.position.x, m.pose.position.y, m.pose.position.z],
                 "scale": [m.scale.x, m.scale.y, m.scale.z], "color": [m.color.r, m.color.g, m.color.b, m.color.a]}
                for m in decode_markers(raw).markers]

    def transforms(raw: bytes) -> list:
        msg = decode_tf(raw).transforms
        return [t(msg[0].header.stamp), [[x.header.frame_id, x.child_frame_id,
                                          [x.transform.translation.x, x.transform.translation.y,
                                           x.transform.translation.z],
                                          [x.transform.rotation.x, x.transform.rotation.y, x.transform.rotation.z,
                                           x.transform.rotation.w]] for x in msg]]

    sub = node.create_subscription
    sub(String, "/navigate/status", lambda m: add("status", [time.monotonic(), m.data]), status_qos)
    sub(PathMsg, "/plan", lambda m: add("plan", [t(m.header.stamp), m.header.frame_id,
                                                 [[p.pose.position.x, p.pose.position.y] for p in m.poses]]), reliable)
    sub(markers_type, "/footsteps", lambda raw: add("footsteps", markers(raw)), reliable, raw=True)
    clear()  # the error rmw leaves set probing a raw type's typesupports
    sub(OccupancyGrid, "/map", lambda m: add("map", grid(m)), latched)
    sub(OccupancyGrid, "/costmap", lambda m: add("costmap", grid(m)), latched)
    sub(Odometry, "/odom", lambda m: add("odom", odom(m)), reliable)
    sub(Odometry, "/ground_truth/odom", lambda m: add("truth", odom(m)), reliable)
    sub(tf_type, "/tf", lambda raw: add("tf", transforms(raw)), reliable, raw=True)
    clear()
    sub(Clock, "/clock", lambda m: add("clock", t(m.clock)), reliable)
    pub = node.create_publisher(PoseStamped, "/goal_pose", 10)
    stop = threading.Event()  # the scenario closes our stdin when it is over
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()

    end = time.monotonic() + 120.0
    while (pub.get_subscription_count() == 0 or not got["map"]) and time.monotonic() < end \
            and not stop.is_set():
        rclpy.spin_once(node, timeout_sec=0.05)  # the navigator's node is there and we have its map

    def send(x: float, y: float, yaw_rad: float, frame_id: str = "map") -> None:
        goal = PoseStamped()
        goal.header.frame_id = frame_id  # RViz's "2D Goal Pose": the fixed frame
        goal.pose.position.x, goal.pose.position.y = x, y
        goal.pose.orientation.z, goal.pose.orientation.w = math.sin(yaw_rad / 2), math.cos(yaw_rad / 2)
        pub.publish(goal)

    def wait_for(condition, timeout_s: float) -> None:
        until = time.monotonic() + timeout_s
        while time.monotonic() < until and not stop.is_set():
            rclpy.spin_once(node, timeout_sec=0.05)
            with lock:
                if condition():
                    return

    # a goal in the robot's frame is refused; a first goal is then replaced by the real one once planned
    send(1.0, 0.0, 0.0, frame_id="base_link")
    wait_for(lambda: any(s.startswith("rejected") for _, s in got["status"]), 60.0)
    send(decoy_x, decoy_y, 0.0)
    wait_for(lambda: any(math.dist(p[2][-1], (decoy_x, decoy_y)) < 0.3 for p in got["plan"]), 60.0)
    send(goal_x, goal_y, goal_yaw)
    linger_until = None
    while time.monotonic() < end + 120.0 and not stop.is_set():
        rclpy.spin_once(node, timeout_sec=0.05)
        with lock:
            done = got["status"] and got["status"][-1][1] in TERMINAL
        if done and linger_until is None:
            linger_until = time.monotonic() + 1.0  # what is still in flight (the last odometry, TF)
        if linger_until is not None and time.monotonic() > linger_until:
            break
    with lock:
        (out / "peer.json.tmp").write_text(json.dumps(got))
    (out / "peer.json.tmp").rename(out / "peer.json")  # whole, or not there
    threading.Timer(10.0, os._exit, args=(0,)).start()  # DDS teardown has hung on CI: nothing is left to lose
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    if sys.argv[1] == "scenario":
        code = scenario(Path(sys.argv[2]))
        sys.stdout.flush()
        sys.stderr.flush()
        # everything is written: the interpreter's teardown (DDS, rclpy, warp) took ~10 s on a loaded machine
        os._exit(code)
    sys.exit(peer(Path(sys.argv[2]), *map(float, sys.argv[3:8])))
