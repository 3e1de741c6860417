"""``ambulo bridge``: a scene as a real ROS 2 node (``ambulo.ros2``), optionally recorded to a rosbag2."""

from __future__ import annotations

import argparse
import difflib
import os
import signal
import time
from pathlib import Path

from .errors import CliError, check_seconds
from .viewer_args import add_viewer_args, web_watch

_KINDS = (".xml", ".urdf", ".usd", ".usda", ".usdc", ".usdz")


def _bag_folder(record: str) -> Path:
    """``out.mcap`` or ``out`` -> the rosbag2 folder ``out/`` (holding ``out.mcap`` and metadata.yaml)."""
    path = Path(record).expanduser()
    folder = path.with_suffix("") if path.suffix == ".mcap" else path
    if folder.exists():
        raise CliError(f"--record {record!r}: {str(folder)!r} exists already",
                       "choose a new name (a rosbag2 is a new folder), or remove the old one")
    if not os.access(folder.parent if str(folder.parent) else ".", os.W_OK):
        raise CliError(f"--record {record!r}: cannot write in {str(folder.parent)!r}", "choose a folder you may write to")
    return folder


def _world(target: str, args: argparse.Namespace):
    from ambulo.core.scene import resolve_file
    from ambulo.ros2 import SCENES, SceneCfg, file_world

    cfg = SceneCfg(physics_dt_s=None if args.rate is None else 1.0 / args.rate, camera=not args.no_camera,
                   lidar=args.lidar)
    task_robot = _task_robot(target)
    if task_robot is not None:  # an RL task: its robot, with our sensors when it is a bundled scene
        target = task_robot if task_robot in SCENES else resolve_file(task_robot)
    return SCENES[target](cfg) if target in SCENES else file_world(target, cfg)


def _task_robot(target: str) -> str | None:
    """The robot file (or bundled name) of the RL task named ``target``, else None."""
    if os.path.exists(target) or os.sep in target:
        return None
    from ambulo import envs

    return str(envs.make_cfg(target).robot.file) if target in envs.names() else None


def _check_target(target: str) -> None:
    """A bundled scene or a robot file, else ``CliError`` (before anything slow is imported)."""
    from ambulo.ros2.scenes import SCENES

    if target in SCENES or (os.path.isfile(target) and os.path.splitext(target)[1].lower() in _KINDS):
        return
    if _task_robot(target) is not None:
        return
    if os.path.exists(target):
        raise CliError(f"{target!r} is not a robot file", f"give an MJCF, URDF or USD file ({', '.join(_KINDS)})")
    from ambulo import envs

    close = difflib.get_close_matches(target, list(SCENES) + envs.names(), n=2)
    fix = f"did you mean {' or '.join(map(repr, close))}?" if close else (
        f"give a bundled scene ({', '.join(SCENES)}), an RL task ({', '.join(envs.names())}) or a robot file "
        f"({', '.join(_KINDS)})")
    raise CliError(f"no scene or robot file named {target!r}", fix)


def _require(module: str, package: str, flag: str) -> None:
    """``CliError`` naming what to install when ``flag`` needs ``module`` and it is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise CliError(f"{flag} needs the package {package!r}, which is not installed", "pip install 'ambulo[ros2]'")


def _interrupt(_signum, _frame) -> None:
    raise KeyboardInterrupt


def _recover(bag: str) -> int:
    from ambulo.ros2.bag import recover

    kept = recover(bag)
    print(f"{bag}: complete already, nothing to recover" if kept < 0 else f"{bag}: recovered {kept} messages")
    return 0


def _numbers(flag: str, text: str, counts: tuple[int, ...], example: str) -> list[float]:
    """``"1,2,0.5"`` -> [1.0, 2.0, 0.5] with one of ``counts`` entries, else ``CliError``."""
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not all(abs(v) < float("inf") for v in values):
        raise CliError(f"{flag} {text!r} is not {' or '.join(map(str, counts))} finite numbers", f"e.g. {flag} {example}")
    return values


_NAVIGATE_UNSUPPORTED = {"record": "--record", "foxglove": "--foxglove", "lidar": "--lidar", "rate": "--rate",
                         "no_camera": "--no-camera", "detector": "--detector"}


def _detector(path: str):
    """``--detector``: a train-detector run folder (its exported ``model.onnx``, else ``checkpoint.pt``),
    a checkpoint or an ONNX file, loaded as ``ambulo.detection.Detector``; else ``CliError``."""
    from ambulo.detection.train import CHECKPOINT

    file = Path(path).expanduser()
    if file.is_dir():
        found = [file / name for name in ("model.onnx", CHECKPOINT) if (file / name).is_file()]
        if not found:
            raise CliError(f"--detector {path!r}: the folder holds neither model.onnx nor {CHECKPOINT}",
                           "give a run folder of `ambulo train-detector`, its checkpoint.pt or an exported .onnx")
        file = found[0]
    if not file.is_file():
        raise CliError(f"--detector {path!r}: no such file",
                       "train one with `ambulo train-detector DATASET --out RUN` and give RUN (or RUN/checkpoint.pt)")
    from ambulo.detection import Detector

    try:
        return Detector(file)
    except Exception as err:  # a file that is not a detector: torch, onnxruntime or pickle say why
        raise CliError(f"--detector {path!r}: {str(file)!r} is not a detector ({type(err).__name__}: "
                       f"{str(err).splitlines()[0][:200] if str(err) else 'unreadable'})",
                       "give a checkpoint.pt of `ambulo train-detector` or the .onnx `ambulo export-detector` "
                       "wrote") from None


def _navigate(args: argparse.Namespace) -> int:
    """``ambulo bridge apartment|WORLD --navigate``: the navigator in its world as a ROS 2 node
    (``navigation.ros2_node``): goals on /goal_pose, plan, footsteps, map, odometry and TF out."""
    for name, flag in _NAVIGATE_UNSUPPORTED.items():
        if getattr(args, name) not in (None, False):
            raise CliError(f"{flag} does not go with --navigate", f"leave {flag} out (the navigator's robot has its "
                           "head RGB-D camera and runs its own physics rate)")
    world_file = args.target != "apartment"
    if world_file and not (os.path.isfile(args.target) and os.path.splitext(args.target)[1].lower() in _KINDS):
        raise CliError(f"--navigate needs 'apartment' or a world file, not {args.target!r}",
                       "e.g. `ambulo bridge apartment --seed 3 --navigate` or `ambulo bridge room.xml --navigate "
                       "--start 0,0,0`")
    if world_file and args.start is None:
        raise CliError(f"--start is missing for the world {args.target!r}",
                       "give the robot's start pose x,y,yaw in m, m, rad, e.g. --start 0,0,0")
    start = None if args.start is None else _numbers("--start", args.start, (3,), "1.0,2.0,0.0")
    goal = None if args.goal is None else _numbers("--goal", args.goal, (2, 3), "4.0,2.5")
    if args.seconds is not None:
        check_seconds(args.seconds)
    from ambulo.ros2.runtime import Ros2Unavailable, import_rclpy

    try:
        import_rclpy()
    except Ros2Unavailable as err:
        raise CliError(str(err).split("; ")[0], str(err).split("; ", 1)[-1]) from None
    from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg
    from ambulo.navigation.ros2_node import NavigateNode, NavigateNodeCfg

    world_cfg = NavWorldCfg(record_gyro=args.mode == "full")  # only the VO reads the gyro
    if world_file:
        world = NavWorld.from_file(args.target, start, world_cfg)
    else:
        from ambulo.robots import humanoid
        from ambulo.scenes.apartment import apartment

        apt = apartment(args.seed)
        if start is None:  # a free cell where the robot fits, drawn with the apartment's seed
            start = apt.sample_start_goal(args.seed, 1.0, 100.0, humanoid.BODY_RADIUS_M).start_pose
        world = NavWorld.from_apartment(apt, start, world_cfg)
    nav = Navigator(world, NavigatorCfg(mode=args.mode, camera_hz=args.camera_rate))
    signal.signal(signal.SIGTERM, _interrupt)
    node = NavigateNode(nav, NavigateNodeCfg(namespace=args.namespace, frame_prefix=args.frame_prefix))
    x, y, yaw = world.start_pose
    print(f"ambulo bridge: navigator ({args.mode}) node {node.node.get_fully_qualified_name()} on ROS_DOMAIN_ID="
          f"{os.environ.get('ROS_DOMAIN_ID', '0')}; robot at ({x:.2f}, {y:.2f}, {yaw:.2f} rad); send goals on "
          f"{node.cfg.goal_topic} (RViz: 2D Goal Pose, fixed frame map); publishing {', '.join(sorted(node.topics.values()))}",
          flush=True)
    if goal is not None:
        node.set_goal(goal[:2], goal[2] if len(goal) == 3 else None)
    start_wall = time.perf_counter()
    t0 = world.time_s
    try:
        node.spin(args.seconds, real_time=args.real_time)
    finally:
        node.close()
        world.close()
        print(f"simulated {world.time_s - t0:.2f} s in {time.perf_counter() - start_wall:.2f} s wall; "
              f"{len(node.goals)} goals, status {node.status}; published "
              + ", ".join(f"{t} {n}" for t, n in sorted(node.published.items())), flush=True)
    return 0


def run(args: argparse.Namespace) -> int:
    if args.navigate and not args.recover:
        if args.target is None:
            raise CliError("no world given", "e.g. `ambulo bridge apartment --seed 3 --navigate`")
        if getattr(args, "viewer", "none") != "none":
            raise CliError("--viewer web watches a bridged robot; the navigator's node (--navigate) is not watched",
                           "watch a navigation with `ambulo navigate ... --viewer web`, or leave out --viewer")
        return _navigate(args)
    if args.recover:
        _require("rosbags", "rosbags", "--recover")
        _require("mcap", "mcap", "--recover")
        return _recover(args.recover)
    if args.target is None:
        raise CliError("no scene given", "e.g. `ambulo bridge jetbot` or `ambulo bridge humanoid`")
    if args.rate is not None and (not args.rate > 0 or args.rate == float("inf")):
        raise CliError(f"--rate {args.rate} is not a positive rate", "give Hz of simulated time, e.g. --rate 100")
    if args.seconds is not None:
        check_seconds(args.seconds)
    _check_target(args.target)
    bag = _bag_folder(args.record) if args.record else None
    if bag:
        _require("rosbags", "rosbags", "--record")
    if args.foxglove:
        _require("foxglove", "foxglove-sdk", "--foxglove")
    if args.detector_inline and not args.detector:
        raise CliError("--detector-inline runs a detector, and none is given", "add --detector RUN")
    if args.detector and args.no_camera:
        raise CliError("--detector needs the camera that --no-camera removes", "leave out one of the two")
    watch = web_watch(args)  # bad viewer flags fail before the world is built
    from ambulo.ros2.runtime import Ros2Unavailable, import_rclpy

    try:
        import_rclpy()
    except Ros2Unavailable as err:
        raise CliError(str(err).split("; ")[0], str(err).split("; ", 1)[-1]) from None
    detector = _detector(args.detector) if args.detector else None
    from ambulo.ros2 import BridgeCfg, Ros2Bridge

    world = _world(args.target, args)
    viewer = watch(world) if watch else None
    if viewer is not None and detector is not None:  # the page shows each detected frame with its boxes
        from ambulo.viewer.detections import ShownDetector

        detector = ShownDetector(detector, viewer)
    cfg = BridgeCfg(namespace=args.namespace, frame_prefix=args.frame_prefix, camera_qos=args.camera_qos,
                    camera_rate_hz=args.camera_rate, record=str(bag) if bag else None,
                    foxglove_port=args.foxglove_port if args.foxglove else None,
                    detector_thread=not args.detector_inline)
    signal.signal(signal.SIGTERM, _interrupt)  # `kill` ends like Ctrl-C: the bag is finished
    try:
        bridge = Ros2Bridge(world, cfg, detector=detector)
    except ValueError as err:  # the detector cannot take the scene's camera (check_detector)
        if viewer is not None:
            viewer.close()
        if detector is None:
            raise
        raise CliError(f"--detector: {str(err).split('; ')[0]}", str(err).split("; ", 1)[-1]) from None
    print(f"ambulo bridge: node {bridge.node_name} on ROS_DOMAIN_ID="
          f"{os.environ.get('ROS_DOMAIN_ID', '0')}, publishing {', '.join(bridge.topics)}"
          + (f"; Foxglove: ws://127.0.0.1:{bridge.foxglove.port}" if bridge.foxglove else ""), flush=True)
    if bridge.robot is not None and bridge.cmd_vel_problem:
        print(f"ambulo bridge: {bridge.cfg.cmd_vel_topic} is refused: {bridge.cmd_vel_problem}", flush=True)
    dt, start = world.get_physics_dt(), time.perf_counter()
    steps = None if args.seconds is None else int(round(args.seconds / dt))
    done = 0
    from ambulo.ros2.bridge_detection import DetectorFailed

    try:
        try:
            while steps is None or done < steps:
                world.step(render=False)
                done += 1
                if args.real_time:
                    ahead = done * dt - (time.perf_counter() - start)
                    if ahead > 0:
                        time.sleep(ahead)
        finally:
            bridge.close()
            if viewer is not None:
                viewer.close()
            wall = time.perf_counter() - start
            print(f"simulated {done * dt:.2f} s in {wall:.2f} s wall; published "
                  + ", ".join(f"{t} {n}" for t, n in sorted(bridge.published.items()))
                  + (f"; {len(bridge.rejected)} commands rejected" if bridge.rejected else "")
                  + (f"; {bridge.dropped_detections} frames skipped by the detector"
                     if bridge.dropped_detections else "")
                  + (f"; bag: {bag}" if bag else ""), flush=True)
    except DetectorFailed as err:  # one line, not the detector's traceback
        raise CliError(str(err), "run the detector on such a frame in Python for the traceback, or leave out "
                       "--detector") from None
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``bridge`` to the ``ambulo`` parser."""
    p = subparsers.add_parser("bridge", help="run a scene as a ROS 2 node (topics, tf, commands, rosbag2)",
                              description="Serve a scene over ROS 2 with real rclpy: /clock, /joint_states, "
                              "/imu/data, /tf, /tf_static, /odom, camera and lidar topics; /cmd_vel and joint "
                              "commands in. Needs pip install 'ambulo[ros2]' or a sourced ROS 2.")
    p.add_argument("target", nargs="?", help="'jetbot', 'humanoid', an RL task's robot (e.g. cartpole, "
                   "humanoid-walk) or a robot file (MJCF, URDF, USD)")
    p.add_argument("--rate", type=float, default=None,
                   help="physics steps per simulated second; state topics publish at this rate (default 100; "
                   "200 for the humanoid, the rate its walking policy needs to follow /cmd_vel)")
    p.add_argument("--real-time", action="store_true", help="pace the simulation to the wall clock "
                   "(default: as fast as it runs)")
    p.add_argument("--seconds", type=float, help="simulated seconds to run (default: until Ctrl-C)")
    p.add_argument("--record", metavar="OUT.mcap", help="record everything published to this rosbag2 (MCAP)")
    p.add_argument("--foxglove", action="store_true", help="also serve the topics to Foxglove/Lichtblick over "
                   "WebSocket (ws://127.0.0.1:8765, needs foxglove-sdk)")
    p.add_argument("--foxglove-port", type=int, default=8765, help=argparse.SUPPRESS)
    p.add_argument("--recover", metavar="BAG", help="rebuild a bag whose recording was killed, then exit")
    p.add_argument("--namespace", default="", help="ROS namespace of the node and its topics")
    p.add_argument("--frame-prefix", default="", help="put before every frame id, e.g. robot1/")
    p.add_argument("--camera-rate", type=float, default=10.0, help="camera Hz of simulated time (default 10)")
    p.add_argument("--camera-qos", choices=("default", "sensor_data"), default="default",
                   help="QoS of camera topics: reliable (default) or best-effort sensor data")
    p.add_argument("--no-camera", action="store_true", help="no camera on the robot")
    p.add_argument("--lidar", action="store_true", help="add a planar lidar (/scan) to the Jetbot")
    p.add_argument("--detector", metavar="PATH", help="run this detector (a train-detector run folder, its "
                   "checkpoint.pt or exported .onnx) on every published camera frame: /detections "
                   "(vision_msgs/Detection2DArray) and /detections/segmentation (mono16, models with masks), "
                   "stamped like the image they were computed on. Inference runs on a thread of its own: the "
                   "simulation keeps its pace; when the detector is slower than --camera-rate it takes each "
                   "camera's newest frame and skips the others")
    p.add_argument("--detector-inline", action="store_true", help="run the detector in the camera path on the "
                   "physics thread instead: every published frame detected, deterministic, and the simulation "
                   "slowed by each inference")
    add_viewer_args(p)  # the scene live, and with --detector each detected frame with its boxes
    nav = p.add_argument_group("navigator", "`ambulo bridge apartment|WORLD --navigate`: the humanoid navigator "
                               "as a ROS 2 node: goals on /goal_pose (RViz's 2D Goal Pose); /plan, /footsteps, /map, "
                               "/costmap, /odom, /tf (map -> odom -> base_link), /navigate/status out")
    nav.add_argument("--navigate", action="store_true", help="run the navigator in 'apartment' or a world file "
                     "(MJCF/USD) instead of serving a robot")
    nav.add_argument("--seed", type=int, default=0, help="the apartment's seed (default 0)")
    nav.add_argument("--mode", choices=("oracle", "mapping", "full"), default="oracle",
                     help="oracle: true pose and map; mapping: true pose, online map; full: visual odometry and "
                     "online map (default oracle)")
    nav.add_argument("--start", metavar="X,Y,YAW", help="the robot's start pose, m, m, rad (needed for a world file; "
                     "default in an apartment: a free spot drawn with --seed)")
    nav.add_argument("--goal", metavar="X,Y[,YAW]", help="a first goal, m (more come on /goal_pose)")
    p.set_defaults(func=run)
