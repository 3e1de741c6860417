"""``Ros2Bridge(..., detector=)`` and ``ambulo bridge --detector``: the bridge runs a trained detector on
each published camera frame; a second rclpy node in a loopback-only network receives the image and the
vision_msgs/msg/Detection2DArray (decoded by mcap_ros2, not by the project's serializer) and checks that
the array is the detector's output on that very image: same stamp, the camera's frame id, the same boxes.

The detector runs on a thread of its own by default (``BridgeCfg.detector_thread``): with fake detectors,
``--worker`` checks that the simulation goes on while it works, that its detections carry the stamp of
their frame, that frames arriving meanwhile are dropped but the newest, the inline mode (every frame, on
the physics thread) and that a detector's exception is one clear error.

Run as a script (by the test, in the isolated network): ``python test_detector_bridge.py CHECKPOINT``
(or ``--worker threaded|inline|failing``) prints one JSON line of what the listener received."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve()


def _scenario(checkpoint: str) -> None:
    """The bridge (the Jetbot, its camera at 64x48, the shapes detector) and a listener node here."""
    from ambulo.ros2.runtime import import_rclpy, use_fastdds_profile

    use_fastdds_profile()
    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image

    sys.path.insert(0, str(HERE.parent))
    from ros2_detections_scenario import decoder

    from ambulo.detection import Detector
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, jetbot_world
    from ambulo.ros2.detections import detection_array_class

    world = jetbot_world(SceneCfg(camera_width=64, camera_height=48))
    detector = Detector(checkpoint, score_threshold=0.05)  # low: frames of a warehouse floor, not of discs
    bridge = Ros2Bridge(world, BridgeCfg(camera_rate_hz=50.0, publish_depth=False), detector=detector)
    rclpy.init()
    listener = rclpy.create_node("detections_listener")
    arrays, images, segmentations, semantics = {}, {}, {}, {}

    def stamp(msg) -> int:
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    decode = decoder()

    def on_array(raw: bytes) -> None:
        array = decode(raw)
        arrays[stamp(array)] = array

    listener.create_subscription(detection_array_class(), "detections", on_array, 10, raw=True)
    listener.create_subscription(Image, "camera/image_raw", lambda msg: images.setdefault(stamp(msg), msg), 10)
    listener.create_subscription(Image, "detections/segmentation",
                                 lambda msg: segmentations.setdefault(stamp(msg), msg), 10)
    listener.create_subscription(Image, "detections/semantic", lambda msg: semantics.setdefault(stamp(msg), msg), 10)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    has_masks = detector(np.zeros((48, 64, 3), np.uint8)).masks is not None
    deadline = time.monotonic() + 60.0
    both: list[int] = []
    while time.monotonic() < deadline:
        world.step(render=False)
        executor.spin_once(timeout_sec=0.005)
        both = sorted(set(arrays) & set(images))
        if len(both) >= 2 and (not has_masks or set(segmentations) & set(semantics) & set(both)):
            break
    graph = dict(listener.get_topic_names_and_types())
    out: dict = {"graph": graph, "frames": []}
    for ns in both:
        image, array = images[ns], arrays[ns]
        rgb = np.frombuffer(bytes(image.data), np.uint8).reshape(image.height, image.width, 3)
        again = detector(rgb)  # the detector on the frame the listener got
        seg, sem = segmentations.get(ns), semantics.get(ns)
        expected_semantic = again.semantic_image()
        out["frames"].append({
            "stamp_ns": ns, "image_frame_id": image.header.frame_id, "array_frame_id": array.header.frame_id,
            "shape": [image.height, image.width],
            "boxes": [[d.bbox.center.position.x - d.bbox.size_x / 2, d.bbox.center.position.y - d.bbox.size_y / 2,
                       d.bbox.center.position.x + d.bbox.size_x / 2, d.bbox.center.position.y + d.bbox.size_y / 2]
                      for d in array.detections],
            "labels": [d.results[0].hypothesis.class_id for d in array.detections],
            "stamps": [stamp(d) for d in array.detections],
            "expected_boxes": again.boxes_px.tolist(), "expected_labels": again.labels,
            "has_masks": again.masks is not None,
            "segmentation": None if seg is None else {
                "encoding": seg.encoding, "shape": [seg.height, seg.width], "frame_id": seg.header.frame_id,
                "max": int(np.frombuffer(bytes(seg.data), "<u2").max(initial=0))},
            "semantic": None if sem is None else {
                "encoding": sem.encoding, "shape": [sem.height, sem.width], "frame_id": sem.header.frame_id,
                "pixels": np.frombuffer(bytes(sem.data), np.uint8).reshape(sem.height, sem.width).tolist()},
            "expected_semantic": None if expected_semantic is None else expected_semantic.tolist()})
    bridge.close()
    out["published"] = dict(bridge.published)
    print(json.dumps(out))
    listener.destroy_node()
    rclpy.shutdown()


def test_bridge_publishes_the_detectors_output_on_each_frame(trained_shapes):
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    pytest.importorskip("mcap_ros2")
    from ambulo.ros2.loopback import run_isolated

    _, checkpoint = trained_shapes
    done = run_isolated([str(HERE), str(checkpoint)], timeout_s=180)
    assert done.returncode == 0, done.stderr[-4000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["graph"]["/detections"] == ["vision_msgs/msg/Detection2DArray"]
    assert out["frames"], f"no frame with both its image and its detections arrived: {out['published']}"
    for frame in out["frames"]:
        h, w = frame["shape"]
        assert (h, w) == (48, 64)
        assert frame["array_frame_id"] == frame["image_frame_id"] != ""
        assert frame["stamps"] == [frame["stamp_ns"]] * len(frame["boxes"])  # each Detection2D's header too
        assert frame["boxes"], "the detector (threshold 0.05) found nothing: the check below would be empty"
        boxes = np.array(frame["boxes"])
        assert (boxes[:, 0] >= 0).all() and (boxes[:, 2] <= w).all() and (boxes[:, 1] >= 0).all()
        assert (boxes[:, 3] <= h).all() and (boxes[:, 2] >= boxes[:, 0]).all() and (boxes[:, 3] >= boxes[:, 1]).all()
        # the detections are of this very image (not the previous frame's, nor another camera's)
        np.testing.assert_allclose(boxes, np.array(frame["expected_boxes"]), atol=1e-3)
        assert frame["labels"] == frame["expected_labels"]
        if frame["has_masks"] and frame["segmentation"] is not None:
            seg = frame["segmentation"]
            assert seg["encoding"] == "mono16" and seg["shape"] == [h, w]
            assert seg["frame_id"] == frame["image_frame_id"] and seg["max"] <= len(boxes)
        if frame["has_masks"] and frame["semantic"] is not None:  # the detector's own semantic image of this frame
            sem = frame["semantic"]
            assert sem["encoding"] == "mono8" and sem["shape"] == [h, w] and sem["frame_id"] == frame["image_frame_id"]
            assert sem["pixels"] == frame["expected_semantic"]
    assert any(f["segmentation"] for f in out["frames"]) == any(f["has_masks"] for f in out["frames"])
    assert any(f["semantic"] for f in out["frames"]) == any(f["has_masks"] for f in out["frames"])


def _bridge_cli(*args: str) -> subprocess.CompletedProcess:
    from ambulo.ros2.loopback import isolated, loopback_env

    return subprocess.run(isolated([sys.executable, "-m", "ambulo", "bridge", *args]), env=loopback_env(),
                          capture_output=True, text=True, timeout=180)


def test_bridge_cli_refuses_a_missing_detector(tmp_path):
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    done = _bridge_cli("jetbot", "--seconds", "0.1", "--detector", str(tmp_path / "nope.onnx"))
    assert done.returncode != 0
    assert len(done.stderr.strip().splitlines()) == 1 and "nope.onnx" in done.stderr and "no such file" in done.stderr, done.stderr
    assert "train-detector" in done.stderr and "Traceback" not in done.stderr
    empty = tmp_path / "run"
    empty.mkdir()
    done = _bridge_cli("jetbot", "--seconds", "0.1", "--detector", str(empty))
    assert done.returncode != 0 and "neither model.onnx nor checkpoint.pt" in done.stderr, done.stderr


def test_bridge_cli_refuses_a_camera_larger_than_the_detectors_canvas(trained_shapes):
    """The Jetbot's camera is 320x240; the shapes detector was trained on 64x64 frames."""
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    _, checkpoint = trained_shapes
    done = _bridge_cli("jetbot", "--seconds", "0.1", "--detector", str(checkpoint.parent))
    assert done.returncode != 0 and "Traceback" not in done.stderr, done.stderr
    assert "320x240" in done.stderr and "64x64" in done.stderr and "train the detector on 320x240" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr


class _FakeDetections:
    """What a box-only detector returns: one box whose label is the frame's index (``_number_frames``)."""

    def __init__(self, index: int):
        self.boxes_px = np.array([[1.0, 2.0, 10.0, 12.0]])
        self.labels, self.scores, self.masks = [str(index)], np.array([0.9]), None


def _frame_index(rgb: np.ndarray) -> int:
    """The index ``_number_frames`` wrote into pixel (0, 0)."""
    return int(rgb[0, 0, 0]) + 256 * int(rgb[0, 0, 1])


def _number_frames(camera, world) -> list:
    """Make ``camera.capture`` write a running frame index into pixel (0, 0) (red + 256 green), so that the
    detector and the listener each read which frame they got; returns the simulated time (ns) of each frame
    captured, by index."""
    captured: list[int] = []
    capture = camera.capture

    def numbered(*args, **kwargs):
        out = capture(*args, **kwargs)
        k = len(captured)
        out["rgb"][0, 0, :2] = (k % 256, k // 256)
        captured.append(round(world.current_time * 1e9))
        return out

    camera.capture = numbered
    return captured


class _Detector:
    """A fake detector of 48x64 frames: records the frame index and thread of each call; ``hold`` (an Event)
    keeps its first call waiting until set; ``fail`` makes it raise instead."""

    canvas_hw = (48, 64)

    def __init__(self, hold: threading.Event | None = None, fail: bool = False):
        self.hold, self.fail, self.started = hold, fail, threading.Event()
        self.calls: list[tuple[int, str]] = []

    def __call__(self, rgb):
        index = _frame_index(rgb)
        self.calls.append((index, threading.current_thread().name))
        self.started.set()
        if self.fail:
            raise ValueError(f"no weights for frame {index}")
        if self.hold is not None and len(self.calls) == 1:
            self.hold.wait(60.0)
        return _FakeDetections(index)


def _worker_scenario(part: str) -> None:
    """``part`` of three: bridges on the Jetbot (camera 64x48 at 50 Hz) with fake detectors; prints one JSON line.

    threaded: the detector holds its first frame until the bridge has stepped on and the listener has images
    stamped later; then it is released and the bridge closed. inline: ``detector_thread=False``. failing: a
    detector that raises, threaded (raised by a step) and inline, and threaded raised by ``close``."""
    from ambulo.ros2.runtime import import_rclpy, use_fastdds_profile

    use_fastdds_profile()
    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image

    sys.path.insert(0, str(HERE.parent))
    from ros2_detections_scenario import decoder

    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, jetbot_world
    from ambulo.ros2.bridge_detection import DetectorFailed
    from ambulo.ros2.detections import detection_array_class

    def bridge_with(detector, **cfg):
        world = jetbot_world(SceneCfg(camera_width=64, camera_height=48))
        bridge = Ros2Bridge(world, BridgeCfg(camera_rate_hz=50.0, publish_depth=False, **cfg), detector=detector)
        return world, bridge, _number_frames(bridge.cameras[0], world)

    out: dict = {}
    rclpy.init()
    if part == "threaded":
        # -- threaded: the simulation goes on while the detector holds its first frame
        hold = threading.Event()
        detector = _Detector(hold)
        world, bridge, captured = bridge_with(detector)
        listener = rclpy.create_node("detections_listener")
        decode = decoder()
        arrays: dict[int, list] = {}
        images: dict[int, int] = {}

        def stamp(msg) -> int:
            return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

        def on_array(raw: bytes) -> None:
            array = decode(raw)
            arrays[stamp(array)] = [d.results[0].hypothesis.class_id for d in array.detections]

        def on_image(msg) -> None:
            images[stamp(msg)] = _frame_index(np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.width, 3))

        listener.create_subscription(detection_array_class(), "detections", on_array, 10, raw=True)
        listener.create_subscription(Image, "camera/image_raw", on_image, 50)
        executor = SingleThreadedExecutor()
        executor.add_node(listener)
        deadline = time.monotonic() + 60.0
        topics = [bridge.publishing._topic[key] for key in ("rgb0", "det0")]
        while time.monotonic() < deadline and not all(bridge.subscribers.get(t, (0,))[0] for t in topics):
            executor.spin_once(timeout_sec=0.01)  # matched before frame 0: its image and detections reach us
        held_at_s = None
        while time.monotonic() < deadline:
            world.step(render=False)
            executor.spin_once(timeout_sec=0.002)
            if held_at_s is None and captured:  # the worker has frame 0 (not a later one) before frame 1 comes
                assert detector.started.wait(30.0), "the detector never got frame 0"
                held_at_s = world.current_time
            if held_at_s is not None and sum(k >= 1 for k in images.values()) >= 5:
                break
        out["threaded"] = {"held_at_s": held_at_s, "stepped_to_s": world.current_time,
                           "indices_received_while_held": sorted(images.values()),
                           "arrays_while_held": len(arrays), "calls_while_held": len(detector.calls)}
        frames = len(captured)
        hold.set()
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and len(arrays) < 2:
            executor.spin_once(timeout_sec=0.01)
        bridge.close()
        out["threaded"].update(frames=frames, calls=detector.calls, frame_stamps=captured, dropped=bridge.dropped_detections,
                               arrays={str(ns): labels for ns, labels in arrays.items()},
                               images={str(ns): k for ns, k in images.items()})
        listener.destroy_node()
    if part == "inline":
        # -- inline: every frame, on the physics thread
        detector = _Detector()
        world, bridge, captured = bridge_with(detector, detector_thread=False)
        for _ in range(30):
            world.step(render=False)
        bridge.close()
        out["inline"] = {"frames": len(captured), "calls": detector.calls, "dropped": bridge.dropped_detections,
                         "published": dict(bridge.published), "main": threading.current_thread().name}
    if part == "failing":
        # -- failing: one clear error, raised once
        out["failing"] = {}
        for mode, cfg in (("threaded", {}), ("inline", {"detector_thread": False}), ("at_close", {})):
            world, bridge, captured = bridge_with(_Detector(fail=True), **cfg)
            raised, deadline = [], time.monotonic() + 30.0
            try:
                if mode == "at_close":  # one camera frame handed over, no step after it: close must say it
                    bridge.publish_now()
                while time.monotonic() < deadline and mode != "at_close":
                    world.step(render=False)
            except DetectorFailed as err:
                raised.append(["step", str(err)])
            try:
                bridge.close()
            except DetectorFailed as err:
                raised.append(["close", str(err)])
            out["failing"][mode] = raised
    print(json.dumps(out))
    rclpy.shutdown()


def _worker_run(part: str) -> dict:
    """What ``_worker_scenario(part)`` saw (run in the isolated network)."""
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    pytest.importorskip("mcap_ros2")
    from ambulo.ros2.loopback import run_isolated

    done = run_isolated([str(HERE), "--worker", part], timeout_s=180)
    assert done.returncode == 0, done.stderr[-4000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_threaded_detector_keeps_the_simulation_going_and_stamps_its_frames():
    run = _worker_run("threaded")["threaded"]
    # while the detector held frame 0, simulated time went on and later frames' images came out, no detections
    assert run["held_at_s"] is not None and run["stepped_to_s"] > run["held_at_s"]
    assert sum(k >= 1 for k in run["indices_received_while_held"]) >= 5
    assert run["arrays_while_held"] == 0 and run["calls_while_held"] == 1
    # released: the held frame, then only the newest of those that arrived meanwhile; the others dropped
    frames = run["frames"]
    assert frames >= 6
    assert [index for index, _ in run["calls"]] == [0, frames - 1]
    assert all(thread != "MainThread" for _, thread in run["calls"])
    assert run["dropped"] == frames - 2
    # each array is stamped with the time of the very frame it was computed on (and of its image, if received)
    assert len(run["arrays"]) == 2
    index_at = {str(ns): k for k, ns in enumerate(run["frame_stamps"])}
    for ns, labels in run["arrays"].items():
        assert labels == [str(index_at.get(ns))], (ns, labels, run["frame_stamps"])
        assert run["images"].get(ns, index_at[ns]) == index_at[ns]
    assert sorted(int(labels[0]) for labels in run["arrays"].values()) == [0, frames - 1]


def test_inline_detector_detects_every_frame_on_the_physics_thread():
    run = _worker_run("inline")["inline"]
    assert run["frames"] >= 10
    assert run["calls"] == [[k, run["main"]] for k in range(run["frames"])]
    assert run["dropped"] == 0
    published = run["published"]
    assert published["/detections"] == published["/camera/image_raw"] == run["frames"]


def test_a_failing_detector_is_one_clear_error_raised_once():
    failing = _worker_run("failing")["failing"]
    for mode, where in (("threaded", "step"), ("inline", "step"), ("at_close", "close")):
        raised = failing[mode]
        assert [w for w, _ in raised] == [where], (mode, raised)
        message = raised[0][1]
        assert message == "the detector failed on camera 0's frame at t=" + message.split("t=")[1]
        assert "ValueError: no weights for frame 0" in message and "\n" not in message


def _cli_with_a_failing_detector(extra: list[str]) -> int:
    """``ambulo bridge jetbot --detector x`` with a detector (loaded in place of ``x``) that raises."""
    import ambulo.cli.bridge as cli_bridge
    from ambulo.cli import main

    cli_bridge._detector = lambda path: _Detector(fail=True)
    _Detector.canvas_hw = (240, 320)  # the Jetbot's camera
    return main(["bridge", "jetbot", "--seconds", "0.5", "--detector", "x", *extra])


@pytest.mark.parametrize("extra", [[], ["--detector-inline"]])
def test_bridge_cli_reports_a_failing_detector_in_one_line(extra):
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    from ambulo.ros2.loopback import run_isolated

    done = run_isolated([str(HERE), "--cli-failing", *extra], timeout_s=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert re.fullmatch(r"ambulo bridge: error: the detector failed on camera 0's frame at t=0\.000 s: ValueError: "
                        r"no weights for frame \d+; run the detector on such a frame in Python for the traceback, "
                        r"or leave out --detector", done.stderr.strip()), done.stderr


if __name__ == "__main__":
    if sys.argv[1] == "--worker":
        _worker_scenario(sys.argv[2])
    elif sys.argv[1] == "--cli-failing":
        sys.exit(_cli_with_a_failing_detector(sys.argv[2:]))
    else:
        _scenario(sys.argv[1])
