"""``ambulo bridge`` end to end (loopback only): runs, records a rosbag2 both readers decode, and a
``kill -9`` during recording leaves a bag that ``--recover`` rebuilds up to the last whole chunk."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from ambulo.cli import main

from .conftest import needs_rclpy, run_loopback


def _decode_all(bag) -> dict[str, int]:
    """Messages per topic, each decoded by mcap_ros2 and by rosbags (two independent CDR readers)."""
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.highlevel import AnyReader

    counts: dict[str, int] = {}
    for item in read_ros2_messages(str(next(bag.glob("*.mcap")))):
        assert item.ros_msg is not None
        counts[item.channel.topic] = counts.get(item.channel.topic, 0) + 1
    with AnyReader([bag]) as reader:
        assert sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype)) == sum(counts.values())
    return counts


def test_bridge_serves_an_rl_tasks_robot(tmp_path):
    needs_rclpy()
    from rosbags.highlevel import AnyReader

    run_loopback(["-m", "ambulo.cli", "bridge", "cartpole", "--seconds", "0.05", "--record", str(tmp_path / "cp")])
    with AnyReader([tmp_path / "cp"]) as reader:
        states = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == "/joint_states"]
    assert len(states) == 5 and len(states[0].name) == 2  # the cart's slider and the pole's hinge


def test_bridge_command_runs_a_scene_and_records_it(tmp_path):
    needs_rclpy()
    proc = run_loopback(["-m", "ambulo.cli", "bridge", "jetbot", "--seconds", "1", "--no-camera", "--lidar",
                         "--record", str(tmp_path / "run.mcap")])
    assert "publishing /clock, /imu/data, /joint_states, /odom, /robot_description, /scan, /tf, /tf_static" in proc.stdout
    assert "simulated 1.00 s" in proc.stdout
    counts = _decode_all(tmp_path / "run")
    assert counts["/joint_states"] == counts["/clock"] == 100  # 1 s at the default 100 Hz
    assert counts["/scan"] == 10 and counts["/tf_static"] == counts["/robot_description"] == 1


def test_bridge_humanoid_steps_at_the_walking_policys_rate():
    needs_rclpy()
    proc = run_loopback(["-m", "ambulo.cli", "bridge", "humanoid", "--seconds", "0.05", "--no-camera"])
    assert "/clock 10," in proc.stdout  # 0.05 s at 200 Hz: physics_dt 0.005 s, as the walking policy needs
    assert "is refused" not in proc.stdout  # /cmd_vel goes to the walking policy


def test_a_3d_lidar_publishes_its_points_as_point_cloud2(tmp_path):
    needs_rclpy()
    import json

    import numpy as np
    from rosbags.highlevel import AnyReader

    from .conftest import HERE

    run_loopback([str(HERE / "scenario.py"), "lidar3d", str(tmp_path)])
    truth = json.loads((tmp_path / "truth.json").read_text())
    with AnyReader([tmp_path / "bag"]) as reader:
        clouds = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == "/points"]
    assert len(clouds) == len(truth) == 4  # 10 Hz for 0.35 s
    for cloud in clouds:
        stamp = cloud.header.stamp.sec * 10**9 + cloud.header.stamp.nanosec
        assert cloud.header.frame_id == "lidar" and [f.name for f in cloud.fields] == ["x", "y", "z"]
        points = np.frombuffer(cloud.data.tobytes(), "<f4").reshape(-1, 3)
        expected = np.array(truth[str(stamp)])
        assert len(points) == cloud.width == len(expected) > 100  # the floor and the box
        np.testing.assert_allclose(points, expected, atol=1e-5)  # float32 metres in the sensor frame


def test_foxglove_websocket_serves_the_same_messages(tmp_path):
    needs_rclpy()
    pytest.importorskip("foxglove")
    pytest.importorskip("websockets")
    import json

    from .conftest import HERE

    run_loopback([str(HERE / "scenario.py"), "foxglove", str(tmp_path)])
    result = json.loads((tmp_path / "truth.json").read_text())
    assert result["advertised"]["/joint_states"] == {"encoding": "cdr", "schemaName": "sensor_msgs/msg/JointState",
                                                     "schemaEncoding": "ros2msg"}
    assert {"/tf", "/odom", "/imu/data", "/clock"} <= set(result["advertised"])
    assert len(result["got"]) == 30
    for subscription, log_time, stamp, positions in result["got"]:
        assert subscription == 7 and log_time == stamp  # logged at simulated time
        assert positions == result["truth"][str(stamp)]


def test_namespace_and_frame_prefix(tmp_path):
    needs_rclpy()
    from rosbags.highlevel import AnyReader

    proc = run_loopback(["-m", "ambulo.cli", "bridge", "jetbot", "--seconds", "0.05", "--namespace", "robot1",
                         "--frame-prefix", "robot1/", "--record", str(tmp_path / "ns")])
    assert "node /robot1/ambulo_bridge" in proc.stdout
    assert "/robot1/joint_states, /robot1/odom" in proc.stdout and " /tf, /tf_static" in proc.stdout
    with AnyReader([tmp_path / "ns"]) as reader:
        (static,) = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == "/tf_static"]
        odom = next(reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == "/robot1/odom")
    assert {(t.header.frame_id, t.child_frame_id) for t in static.transforms} == {
        ("robot1/base_link", "robot1/imu"), ("robot1/base_link", "robot1/camera_optical")}
    assert (odom.header.frame_id, odom.child_frame_id) == ("robot1/odom", "robot1/base_link")


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid``."""
    children = []
    for stat in os.listdir("/proc"):
        if stat.isdigit():
            try:
                with open(f"/proc/{stat}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                children.append(int(stat))
    return children


def test_kill_9_while_recording_leaves_a_bag_recover_rebuilds(tmp_path):
    needs_rclpy()
    from ambulo.ros2.loopback import clean_dead_fastdds_segments, isolated, loopback_env

    bag = tmp_path / "crash"
    proc = subprocess.Popen(isolated([sys.executable, "-m", "ambulo.cli", "bridge", "jetbot", "--no-camera",
                                      "--record", str(bag)]),
                            env=loopback_env(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    mcap = bag / "crash.mcap"
    try:
        assert proc.stdout.readline().startswith("ambulo bridge: node")
        end = time.monotonic() + 60
        while (not mcap.exists() or mcap.stat().st_size < 50_000) and time.monotonic() < end:
            time.sleep(0.1)  # chunks reach the file at least once a second
        time.sleep(0.3)  # kill it mid-chunk
    finally:
        publishers = _children(proc.pid)  # the bridge's publisher process follows it (PR_SET_PDEATHSIG)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        end = time.monotonic() + 10.0
        while any(os.path.exists(f"/proc/{pid}") for pid in publishers) and time.monotonic() < end:
            time.sleep(0.05)
        clean_dead_fastdds_segments()  # what the killed processes left in /dev/shm
    assert not (bag / "metadata.yaml").exists()
    assert main(["bridge", "--recover", str(bag)]) == 0
    counts = _decode_all(bag)
    assert counts["/joint_states"] > 10 and counts["/tf_static"] == 1
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:  # a whole prefix survived: the clock from 0 without gaps
        clock = [reader.deserialize(raw, c.msgtype).clock for c, _, raw in reader.messages()
                 if c.topic == "/clock"]
    steps = [round((c.sec + c.nanosec * 1e-9) * 100) for c in clock]
    assert steps == list(range(len(steps)))
    assert not (tmp_path / "crash.partial").exists()


def test_sigterm_ends_the_bridge_like_ctrl_c_with_a_complete_bag(tmp_path):
    needs_rclpy()
    from ambulo.ros2.loopback import isolated, loopback_env

    proc = subprocess.Popen(isolated([sys.executable, "-m", "ambulo.cli", "bridge", "jetbot", "--no-camera",
                                      "--real-time", "--record", str(tmp_path / "term")]),
                            env=loopback_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().startswith("ambulo bridge: node")
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "ambulo bridge: interrupted" in err
    assert "published /clock" in out
    counts = _decode_all(tmp_path / "term")  # metadata.yaml and the MCAP summary were written
    assert counts["/clock"] > 10


def test_recover_keeps_every_whole_chunk_of_a_cut_file(tmp_path):
    """A file cut inside the third chunk keeps exactly the first two chunks' messages; cut after it,
    all three."""
    from ambulo.ros2.bag import BagRecorder, bag_qos, recover
    from ambulo.ros2.cdr import clock

    qos = bag_qos(reliable=True, transient_local=False, depth=10)
    recorder = BagRecorder(tmp_path / "full", flush_period_s=1e9)
    mcap = tmp_path / "full" / "full.mcap"
    sizes = []
    for i in range(300):
        recorder.write("/clock", "rosgraph_msgs/msg/Clock", qos, clock(i * 10**7), i * 10**7)
        if i % 100 == 99:
            recorder.flush()
            sizes.append(mcap.stat().st_size)
    recorder.close()
    for cut, kept in ((sizes[1] + 1, 200), (sizes[1] + 2000, 200), (sizes[2], 300)):  # a chunk is ~4.3 kB
        bag = tmp_path / f"cut{cut}"
        bag.mkdir()
        (bag / f"cut{cut}.mcap").write_bytes(mcap.read_bytes()[:cut])
        assert recover(bag) == kept
        assert _decode_all(bag) == {"/clock": kept}


def test_recover_leaves_a_complete_bag_alone(tmp_path):
    from ambulo.ros2.bag import BagRecorder, bag_qos, recover

    recorder = BagRecorder(tmp_path / "ok")
    recorder.write("/clock", "rosgraph_msgs/msg/Clock", bag_qos(reliable=True, transient_local=False, depth=10),
                   b"\x00\x01\x00\x00" + bytes(8), 5)
    recorder.close()
    assert recover(tmp_path / "ok") == -1
    assert _decode_all(tmp_path / "ok") == {"/clock": 1}


@pytest.mark.parametrize("argv, parts", [
    (["bridge", "jetbto"], ("no scene or robot file named 'jetbto'", "did you mean 'jetbot'?")),
    (["bridge"], ("no scene given", "ambulo bridge jetbot")),
    (["bridge", "humanoid-wlak"], ("did you mean 'humanoid-walk'",)),
    (["bridge", "jetbot", "--rate", "0"], ("--rate 0.0 is not a positive rate",)),
    (["bridge", "jetbot", "--seconds", "-1"], ("--seconds -1.0",)),
])
def test_bad_input_is_one_line(capsys, argv, parts):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("ambulo bridge: error:")
    for part in parts:
        assert part in err


def test_record_into_an_existing_bag_is_refused(capsys, tmp_path):
    (tmp_path / "old").mkdir()
    assert main(["bridge", "jetbot", "--record", str(tmp_path / "old.mcap")]) == 2
    assert "exists already" in capsys.readouterr().err
