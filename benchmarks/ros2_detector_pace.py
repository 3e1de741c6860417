"""The simulation's pace with a bridge detector on its own thread vs inline (issue 27 item 4).

    python benchmarks/ros2_detector_pace.py [--ms 20] [--seconds 3]

The Jetbot (320x240 camera at 10 Hz of simulated time, physics 100 Hz, no depth topic), stepped flat out for
``--seconds`` of simulated time, with no detector and then two fake box-only detectors of ``--ms`` ms a frame:
``sleep`` (a GPU inference: the GIL is free while it waits) and ``numpy`` (a CPU inference: matrix products in
BLAS). Each with ``BridgeCfg(detector_thread=True)`` and ``False`` (inline). Prints one line a case: wall time,
steps/s, detections and images published, frames the detector skipped (``Ros2Bridge.dropped_detections``),
then ``RESULT {json}``: each case's median wall time and ``ratio``, the no-detector run's wall time (the
ceiling, measured in the same run) over the case's: the share of the bridge's own pace a detector leaves.
Needs rclpy; nothing subscribes (a ROS domain id of its own).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import numpy as np

CANVAS_HW = (240, 320)


class _Found:
    boxes_px, labels, scores, masks = np.zeros((0, 4)), [], np.zeros(0), None


class SleepDetector:
    canvas_hw = CANVAS_HW

    def __init__(self, ms: float):
        self.ms = ms

    def __call__(self, rgb):
        time.sleep(self.ms / 1e3)
        return _Found()


class NumpyDetector(SleepDetector):
    _a = np.random.default_rng(0).random((256, 256))

    def __call__(self, rgb):
        end = time.perf_counter() + self.ms / 1e3
        while time.perf_counter() < end:
            self._a @ self._a
        return _Found()


def run(detector, threaded: bool, seconds: float) -> tuple[str, float]:
    from ambulo.ros2 import BridgeCfg, Ros2Bridge, SceneCfg, jetbot_world

    world = jetbot_world(SceneCfg())
    bridge = Ros2Bridge(world, BridgeCfg(publish_depth=False, detector_thread=threaded), detector=detector)
    steps = int(round(seconds / world.get_physics_dt()))
    start = time.perf_counter()
    for _ in range(steps):
        world.step(render=False)
    wall = time.perf_counter() - start
    bridge.close()
    name = "none" if detector is None else type(detector).__name__.removesuffix("Detector").lower()
    return (f"{name:6s} {'thread' if threaded else 'inline'}: {seconds:g} s simulated in {wall:.2f} s wall "
            f"({steps / wall:.0f} steps/s); detections {bridge.published.get('/detections', 0)}, images "
            f"{bridge.published.get('/camera/image_raw', 0)}, skipped {bridge.dropped_detections}"), wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ms", type=float, default=20.0, help="the fake detectors' ms a frame (default 20)")
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated seconds a case (default 3)")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 100))
    run(None, True, args.seconds)  # warm-up: the first World pays for imports and compilation
    walls: dict[str, list[float]] = {}
    for _ in range(args.repeats):
        cases = [("none", None, True)] + [(f"{name}_{'thread' if threaded else 'inline'}", detector, threaded)
                                          for name, detector in (("sleep", SleepDetector(args.ms)),
                                                                 ("numpy", NumpyDetector(args.ms)))
                                          for threaded in (False, True)]
        for key, detector, threaded in cases:
            line, wall = run(detector, threaded, args.seconds)
            print(line, flush=True)
            walls.setdefault(key, []).append(wall)
    median = {key: statistics.median(w) for key, w in walls.items()}
    print("RESULT " + json.dumps({
        "benchmark": "ros2_detector_pace", "detector_ms": args.ms, "simulated_s": args.seconds,
        "wall_s": {key: round(w, 3) for key, w in median.items()},
        "ratio": {key: round(median["none"] / w, 3) for key, w in median.items() if key != "none"}}))


if __name__ == "__main__":
    main()
