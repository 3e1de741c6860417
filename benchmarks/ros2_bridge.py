"""The ROS 2 bridge against its targets, measured to a separate rclpy subscriber on loopback.

    python benchmarks/ros2_bridge.py [--seconds 3] [--image-seconds 2] [--realtime-seconds 8] [--steps 1000]

1. state: the Jetbot at 1 kHz physics, paced to real time; /joint_states every step (1 kHz) and
   /imu/data at 400 Hz. Delivery = messages received / published after the match (both the
   subscriber's reader and the bridge's writer report ``matched``; the discovery window before it is
   reported apart); latency = receive wall time minus the wall time at which the physics thread took
   the snapshot (``on_publish``; one host clock), so it includes the hop through the publisher
   process; p50/p99.
2. images: a 640x480 camera, rgb8 at 60 Hz paced to real time (depth off), same measures.
3. slow-down, the issue's scenario: the humanoid at 1 kHz physics in real time with the issue's rates
   and the subscriber listening; the time ``world.step`` takes with the bridge's callback over without
   it, in alternating blocks (``realtime_slowdown``).
4. slow-down flat out: the Jetbot and the humanoid at 1 kHz physics stepped as fast as they go, with the
   bridge over without it, (with / without) - 1, with nobody subscribed and with the subscriber
   listening (which then gets far more than 1 kHz and shares the 2 cores): at the issue's rates
   (joint states every step, IMU 400 Hz) and with every state topic at 100 Hz. The physics thread
   only snapshots the state into shared memory; a publisher process builds and sends the messages.
   Flat out, the simulation outruns that process: measured with ``drop_when_behind=True`` (skipped
   snapshots counted) and with the lossless default (it waits for the publisher, so it measures the
   publisher's throughput).

Runs itself in a loopback-only network namespace (``ambulo.ros2.loopback``). Targets (issue 12):
>= 99 % delivery, p99 < 1 ms for JointState, p99 < 10 ms for images, <= 10 % slow-down.
Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

TOPICS = {"/joint_states": "JointState", "/imu/data": "Imu", "/camera/image_raw": "Image"}
BRIDGE = {}
"""BridgeCfg fields every bridge here gets (``--publisher-cpus``)."""


def subscriber() -> int:
    """The measuring node (its own process): records (stamp ns, receive wall time) per topic."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, Imu, JointState

    rclpy.init()
    node = rclpy.create_node("bench_subscriber")
    from rclpy.event_handler import SubscriptionEventCallbacks

    got = {topic: [] for topic in TOPICS}
    matched = {}
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    for topic, kind in TOPICS.items():
        msg_type = {"JointState": JointState, "Imu": Imu, "Image": Image}[kind]

        def record(msg, topic=topic):
            got[topic].append((msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec, time.time()))

        def on_matched(info, topic=topic):
            if info.current_count > 0 and topic not in matched:
                matched[topic] = time.time()
        node.create_subscription(msg_type, topic, record, qos,
                                 event_callbacks=SubscriptionEventCallbacks(matched=on_matched))
    print("ready", flush=True)
    import threading

    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
    while not stop.is_set():  # blocks in DDS until a message comes: no busy loop competing for the CPU
        rclpy.spin_once(node, timeout_sec=0.05)
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
    got["matched"] = matched
    print(json.dumps(got), flush=True)
    return 0


def subscriber_process() -> subprocess.Popen:
    """The subscriber with a stock Fast DDS set-up (not the bridge's transport profile)."""
    env = dict(os.environ)
    if env.get("FASTDDS_DEFAULT_PROFILES_FILE", "").endswith(".xml") and "ambulo-fastdds" in env[
            "FASTDDS_DEFAULT_PROFILES_FILE"]:
        del env["FASTDDS_DEFAULT_PROFILES_FILE"]
    return subprocess.Popen([sys.executable, __file__, "--subscriber"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=env)


def state_world(camera: bool = False):
    from ambulo.ros2 import SceneCfg, jetbot_world

    if camera:
        return jetbot_world(SceneCfg(physics_dt_s=1 / 60, camera=True, camera_width=640, camera_height=480))
    return jetbot_world(SceneCfg(physics_dt_s=0.001, camera=False))


def attach(world, camera: bool):
    from ambulo.ros2 import BridgeCfg, Ros2Bridge

    cfg = BridgeCfg(imu_rate_hz=400.0, tf_rate_hz=100.0, odom_rate_hz=100.0, camera_rate_hz=60.0, publish_depth=False,
                    **BRIDGE)
    bridge = Ros2Bridge(world, cfg)
    sent: dict[str, list] = {topic: [] for topic in TOPICS}

    def timed(topic: str, stamp_ns: int) -> None:
        if topic in sent:
            sent[topic].append((stamp_ns, time.time()))
    bridge.on_publish = timed
    return bridge, sent


def measure(world, bridge, sent, seconds: float, real_time: bool) -> dict:
    """Step until both ends of every topic have matched, then ``seconds`` more; per-topic stats.

    "After match" is the DDS meaning: a message published once the subscriber's reader had matched the
    bridge's writer (its ``matched`` event) and the writer had matched the reader (the bridge's
    ``subscribers``), the later of the two. Messages published in the discovery window before that may
    reach the new subscriber late (Fast DDS hands a reliable reader the writer's history when the
    handshake completes) or not at all; they are counted apart (``in_discovery_window``)."""
    proc = subscriber_process()
    assert proc.stdout.readline().strip() == "ready"
    dt = world.get_physics_dt()
    for values in sent.values():
        values.clear()
    start, steps = time.perf_counter(), 0
    total = int(round((seconds + 1.0) / dt))  # the first simulated second is for discovery
    while steps < total:
        world.step(render=False)
        steps += 1
        if real_time:
            ahead = steps * dt - (time.perf_counter() - start)
            if ahead > 0:
                time.sleep(ahead)
    wall = time.perf_counter() - start
    writer_matched = {topic: t for topic, (count, t) in bridge.subscribers.items() if count > 0}
    proc.stdin.write("dump\n")
    proc.stdin.flush()
    got = json.loads(proc.stdout.readline())
    proc.wait()
    stats = {"sim_rate_vs_real_time": round(steps * dt / wall, 3)}
    for topic, published in sent.items():
        if not published:
            continue
        received = dict((s, t) for s, t in got[topic])
        if topic not in got["matched"] or topic not in writer_matched:
            stats[topic] = {"published": len(published), "received": len(received), "matched": False}
            continue
        matched = max(got["matched"][topic], writer_matched[topic])
        after = [(s, t) for s, t in published if t >= matched]
        before = [(s, t) for s, t in published if t < matched]
        lat = np.array([received[s] - t for s, t in after if s in received]) * 1e3
        early = np.array([received[s] - t for s, t in before if s in received]) * 1e3
        settled = np.array([received[s] - t for s, t in after if s in received and t >= matched + 0.1]) * 1e3
        stats[topic] = {"published_after_match": len(after), "received": len(lat),
                        "delivery": round(len(lat) / max(len(after), 1), 4),
                        "rate_hz_wall": round(len(after) / wall, 1),
                        "latency_ms_p50": round(float(np.percentile(lat, 50)), 3),
                        "latency_ms_p99": round(float(np.percentile(lat, 99)), 3),
                        "latency_ms_max": round(float(lat.max()), 3),
                        # the join transient: the reader matched our writer after our writer matched it, and
                        # holds samples until what came in between is resent (one 10 ms heartbeat away)
                        "latency_ms_p99_from_0.1s_after_match": round(float(np.percentile(settled, 99)), 3),
                        "in_discovery_window": {"published": len(before), "received": len(early),
                                                "latency_ms_max": round(float(early.max()), 3) if len(early) else None}}
    return stats


RATES = {"issue": dict(imu_rate_hz=400.0, tf_rate_hz=100.0, odom_rate_hz=100.0),
         "state_100hz": dict(clock_rate_hz=100.0, joint_states_rate_hz=100.0, imu_rate_hz=100.0, tf_rate_hz=100.0,
                             odom_rate_hz=100.0)}
"""Publishing rates of the slow-down runs at 1 kHz physics: the issue's (joint states and /clock every
step, IMU 400 Hz, /tf and /odom 100 Hz), and every state topic at 100 Hz."""


def slowdown(steps: int, rounds: int = 7) -> dict:
    """Microseconds per physics step (1 kHz) without and with the bridge: wall time, and the CPU time of
    the physics thread (``time.thread_time``: the work the bridge adds to the step path, which the
    load of a shared machine inflates far less than the wall time).

    Flat out, the simulation outruns the publisher process; both modes are measured. ``drop``
    (``drop_when_behind=True``: a snapshot that finds the ring full is skipped, the physics loop never
    waits): ``rounds`` runs of ``steps`` steps with the bridge's physics callback, each followed, once
    the publisher process has emptied the ring, by as many steps without it (same world, same processes:
    paired under the same load); the minimum of each; slow-down = with / without - 1. ``lossless`` (the
    default: the loop waits for a free slot, so flat out it runs at the publisher's pace): the minimum
    of 3 runs with the ring in its steady state (1000 steps first), against the fastest bare runs.
    """
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, humanoid_world, jetbot_world
    from ambulo.ros2.publisher import READ, WRITTEN

    out = {}
    for name, make in (("jetbot", jetbot_world), ("humanoid", humanoid_world)):
        world = make(SceneCfg(physics_dt_s=0.001, camera=False))
        for _ in range(200):
            world.step(render=False)

        def run(n: int = steps) -> np.ndarray:
            """(wall, physics-thread CPU) us per step."""
            t0, c0 = time.perf_counter(), time.thread_time()
            for _ in range(n):
                world.step(render=False)
            return np.array([time.perf_counter() - t0, time.thread_time() - c0]) / n * 1e6

        def best(samples: list) -> np.ndarray:
            return np.min(samples, axis=0)

        bare_runs = [run() for _ in range(3)]

        def paired(bridge) -> tuple[np.ndarray, np.ndarray]:
            """(best with, best without) over ``rounds`` pairs."""
            with_bridge, without = [], []
            for _ in range(rounds):
                with_bridge.append(run())
                world.remove_physics_callback("ros2_bridge")
                header = bridge.process.ring.header
                while header[READ] < header[WRITTEN]:  # let the publisher finish: an idle machine for both
                    time.sleep(0.001)
                time.sleep(0.02)
                without.append(run())
                world.add_physics_callback("ros2_bridge", bridge._on_physics_step)
            bare_runs.extend(without)
            return best(with_bridge), best(without)

        out[name] = {}
        for label, rates in RATES.items():
            for mode, drop in (("drop", True), ("lossless", False)):
                bridge = Ros2Bridge(world, BridgeCfg(**rates, drop_when_behind=drop, **BRIDGE))
                run(1000)
                entry = {}
                for sub in ("no_subscriber", "subscriber"):
                    proc = None
                    if sub == "subscriber":
                        proc = subscriber_process()
                        proc.stdout.readline()
                        run(1000)  # until matched
                    if drop:
                        with_b, without_b = paired(bridge)
                        entry[sub] = {"step_us": round(float(with_b[0]), 1), "bare_step_us": round(float(without_b[0]), 1),
                                      "cpu_us": round(float(with_b[1]), 1), "bare_cpu_us": round(float(without_b[1]), 1),
                                      "slowdown": round(float(with_b[0] / without_b[0] - 1), 3),
                                      "slowdown_cpu": round(float(with_b[1] / without_b[1] - 1), 3)}
                    else:
                        with_b = best([run() for _ in range(3)])
                        entry[sub] = {"step_us": round(float(with_b[0]), 1), "cpu_us": round(float(with_b[1]), 1)}
                    if proc is not None:
                        proc.stdin.write("dump\n")
                        proc.stdin.flush()
                        proc.stdout.readline()
                        proc.wait()
                bridge.close()
                entry.update(snapshots_dropped=bridge.dropped, published=dict(bridge.published))
                out[name][f"{label}_{mode}"] = entry
        bare_runs += [run() for _ in range(3)]
        bare = best(bare_runs)  # the fastest bare step of all
        out[name]["step_us_without_bridge"] = round(float(bare[0]), 1)
        out[name]["cpu_us_without_bridge"] = round(float(bare[1]), 1)
        for label in RATES:  # lossless: against the fastest bare runs
            for sub, m in out[name][f"{label}_lossless"].items():
                if isinstance(m, dict) and sub != "published":
                    m["slowdown"] = round(m["step_us"] / bare[0] - 1, 3)
                    m["slowdown_cpu"] = round(m["cpu_us"] / bare[1] - 1, 3)
    return out


def realtime_slowdown(seconds: float, block_steps: int = 500) -> dict:
    """The issue's scenario: the humanoid at 1 kHz physics paced to the wall clock, /joint_states and
    /clock every step (1 kHz), Imu at 400 Hz, /tf and /odom at 100 Hz, the subscriber listening. The
    bridge's physics callback is attached and detached in alternate blocks of ``block_steps`` steps (same
    world, same processes, paired under the same load); per step, the wall and thread-CPU time spent in
    ``world.step`` (the sleep to the next tick excluded). Slow-down = mean with / mean without - 1: how
    much of the physics loop's time the bridge takes. Also the ticks that overran their 1 ms."""
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, humanoid_world

    world = humanoid_world(SceneCfg(physics_dt_s=0.001, camera=False))
    bridge = Ros2Bridge(world, BridgeCfg(**RATES["issue"], **BRIDGE))
    proc = subscriber_process()
    proc.stdout.readline()
    dt = world.get_physics_dt()
    busy = {True: [], False: []}
    attached, overruns, ticks = True, 0, 0
    start = time.perf_counter()
    pairs = max(1, int(seconds / (2 * block_steps * dt)))
    for block in range(2 * pairs + 2):  # the first pair: discovery and warm-up, not counted
        for _ in range(block_steps):
            t0, c0 = time.perf_counter(), time.thread_time()
            world.step(render=False)
            t1, c1 = time.perf_counter(), time.thread_time()
            if block >= 2:
                busy[attached].append((t1 - t0, c1 - c0))
            ticks += 1
            ahead = ticks * dt - (t1 - start)
            if ahead > 0:
                time.sleep(ahead)
            elif block >= 2 and ahead < -dt:
                overruns += 1
        if attached:
            world.remove_physics_callback("ros2_bridge")
        else:
            world.add_physics_callback("ros2_bridge", bridge._on_physics_step)
        attached = not attached
    proc.stdin.write("dump\n")
    proc.stdin.flush()
    proc.stdout.readline()
    proc.wait()
    bridge.close()
    with_b, without = np.array(busy[True]) * 1e6, np.array(busy[False]) * 1e6
    return {"steps_each": len(with_b), "step_us_mean": round(float(with_b[:, 0].mean()), 2),
            "bare_step_us_mean": round(float(without[:, 0].mean()), 2),
            "step_us_p99": round(float(np.percentile(with_b[:, 0], 99)), 2),
            "bare_step_us_p99": round(float(np.percentile(without[:, 0], 99)), 2),
            "cpu_us_mean": round(float(with_b[:, 1].mean()), 2), "bare_cpu_us_mean": round(float(without[:, 1].mean()), 2),
            "slowdown": round(float(with_b[:, 0].mean() / without[:, 0].mean() - 1), 4),
            "slowdown_cpu": round(float(with_b[:, 1].mean() / without[:, 1].mean() - 1), 4),
            "ticks_late_by_over_1ms": overruns, "sim_rate_vs_real_time": round(ticks * dt / (time.perf_counter() - start), 3),
            "published": dict(bridge.published)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="wall seconds of the 1 kHz state run")
    parser.add_argument("--image-seconds", type=float, default=2.0, help="simulated seconds of the 60 Hz image run")
    parser.add_argument("--steps", type=int, default=1000, help="steps per timing of the flat-out slow-down runs")
    parser.add_argument("--realtime-seconds", type=float, default=8.0, help="wall seconds of the real-time slow-down run")
    parser.add_argument("--publisher-cpus", choices=("auto", "none"), default="auto",
                        help="BridgeCfg.publisher_cpus: auto (the default) or none (no affinity)")
    parser.add_argument("--only", choices=("latency", "realtime", "flat-out"), action="append",
                        help="run only these parts (repeatable; default all)")
    parser.add_argument("--subscriber", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.subscriber:
        return subscriber()
    if os.environ.get("AMBULO_ROS2_BENCH_ISOLATED") != "1":
        from ambulo.ros2.loopback import isolated, loopback_env

        env = loopback_env()
        env["AMBULO_ROS2_BENCH_ISOLATED"] = "1"
        return subprocess.call(isolated([sys.executable, __file__, *sys.argv[1:]]), env=env)

    BRIDGE["publisher_cpus"] = None if args.publisher_cpus == "none" else "auto"
    parts = set(args.only or ("latency", "realtime", "flat-out"))
    state = images = realtime = {}
    slow = {"humanoid": {k: {"subscriber": {}, "no_subscriber": {}} for k in ("issue_drop", "issue_lossless",
                                                                             "state_100hz_drop")}}
    if "latency" in parts:
        world = state_world()
        bridge, sent = attach(world, camera=False)
        state = measure(world, bridge, sent, args.seconds, real_time=True)
        bridge.close()
        world = state_world(camera=True)
        bridge, sent = attach(world, camera=True)
        images = measure(world, bridge, sent, args.image_seconds, real_time=True)
        bridge.close()
    if "realtime" in parts:
        realtime = realtime_slowdown(args.realtime_seconds)
    if "flat-out" in parts:
        slow = slowdown(args.steps)
    js, imu, img = state.get("/joint_states", {}), state.get("/imu/data", {}), images.get("/camera/image_raw", {})
    ratios = {"joint_states_delivery": js.get("delivery"), "imu_delivery": imu.get("delivery"),
              "image_delivery": img.get("delivery"),
              "joint_states_p99_over_1ms": js.get("latency_ms_p99", float("nan")) / 1.0,
              "joint_states_p99_from_0.1s_after_match_over_1ms":
                  js.get("latency_ms_p99_from_0.1s_after_match", float("nan")) / 1.0,
                            "image_p99_over_10ms": img.get("latency_ms_p99", float("nan")) / 10.0,
              "humanoid_realtime_slowdown_over_10pct": realtime.get("slowdown", float("nan")) / 0.10,
              "humanoid_realtime_slowdown_cpu_over_10pct": realtime.get("slowdown_cpu", float("nan")) / 0.10,
              "humanoid_flat_out_slowdown_over_10pct": slow["humanoid"]["issue_drop"]["subscriber"].get("slowdown", float("nan")) / 0.10,
              "humanoid_flat_out_slowdown_cpu_over_10pct": slow["humanoid"]["issue_drop"]["subscriber"].get("slowdown_cpu", float("nan")) / 0.10,
              "humanoid_slowdown_no_subscriber_over_10pct":
                  slow["humanoid"]["issue_drop"]["no_subscriber"].get("slowdown", float("nan")) / 0.10,
              "humanoid_lossless_slowdown_over_10pct": slow["humanoid"]["issue_lossless"]["subscriber"].get("slowdown", float("nan")) / 0.10,
              "humanoid_state_100hz_slowdown_over_10pct":
                  slow["humanoid"]["state_100hz_drop"]["subscriber"].get("slowdown", float("nan")) / 0.10}
    for name, value in ratios.items():
        print(f"{name:44s} {value}")
    result = {"benchmark": "ros2_bridge", "ratio": ratios, "state_1khz": state, "images_640x480_60hz": images,
              "realtime_1khz": realtime, "slowdown": slow, "publisher_cpus": BRIDGE["publisher_cpus"], "domain": os.environ.get("ROS_DOMAIN_ID")}
    print("RESULT " + json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
