"""Run by test_detector_ros2.py in a loopback-only network: one node publishes detections with
``DetectionPublisher``, another takes them as any ROS 2 node would (the raw CDR of
``vision_msgs/msg/Detection2DArray``, decoded by mcap_ros2 from the .msg texts, and the typed
``sensor_msgs/Image``s: instances and semantic), then prints one JSON line of what it received and of the ROS graph."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ambulo.ros2.runtime import import_rclpy, use_fastdds_profile

use_fastdds_profile()
rclpy = import_rclpy()

from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import Image

from ambulo.detection.semantic import semantic_image
from ambulo.ros2.detections import DETECTION_ARRAY, VISION_MSGS, DetectionPublisher, detection_array_class

SHARE = Path(sys.prefix) / "share"


def decoder():
    """mcap_ros2's CDR decoder of Detection2DArray: the vision_msgs fields plus the .msg files the
    std_msgs/geometry_msgs/builtin_interfaces wheels ship."""
    from mcap_ros2._dynamic import generate_dynamic

    parts = [VISION_MSGS[DETECTION_ARRAY]]
    for name, text in VISION_MSGS.items():
        if name != DETECTION_ARRAY:
            parts.append("=" * 80 + f"\nMSG: {name.replace('/msg/', '/')}\n{text}")
    for name in ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/PoseWithCovariance",
                 "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion"):
        package, msg = name.split("/")
        parts.append("=" * 80 + f"\nMSG: {name}\n{(SHARE / package / 'msg' / f'{msg}.msg').read_text()}")
    return generate_dynamic(DETECTION_ARRAY, "\n".join(parts))[DETECTION_ARRAY]


def main() -> None:
    rclpy.init()
    talker, listener = rclpy.create_node("ambulo_detector"), rclpy.create_node("detections_listener")
    got: dict = {}
    listener.create_subscription(detection_array_class(), "detections",
                                 lambda raw: got.setdefault("array", raw), 10, raw=True)
    listener.create_subscription(Image, "detections/segmentation", lambda msg: got.setdefault("image", msg), 10)
    listener.create_subscription(Image, "detections/semantic", lambda msg: got.setdefault("semantic", msg), 10)
    publisher = DetectionPublisher(talker, frame_id="head_camera")
    masks = np.zeros((2, 6, 8), bool)
    masks[0, 1:4, 1:5] = True
    masks[1, 2:6, 3:8] = True  # overlaps detection 0, which scores higher
    found = SimpleNamespace(boxes_px=np.array([[1.0, 1.0, 5.0, 4.0], [3.0, 2.0, 8.0, 6.0]], np.float32),
                            labels=["box", "cone"], category_ids=np.array([2, 4]),
                            scores=np.array([0.9, 0.6], np.float32), masks=masks)
    found.semantic_image = lambda: semantic_image(found, masks.shape[1:])  # as ambulo.detection.Detections
    executor = SingleThreadedExecutor()
    executor.add_node(talker)
    executor.add_node(listener)
    deadline = time.monotonic() + 30.0
    while len(got) < 3 and time.monotonic() < deadline:
        publisher.publish(12.25, found)
        executor.spin_once(timeout_sec=0.05)
    graph = {name: types for name, types in listener.get_topic_names_and_types()}
    array = decoder()(got["array"]) if "array" in got else None
    out = {"graph": graph}
    if array is not None:
        out["array"] = {"stamp": [array.header.stamp.sec, array.header.stamp.nanosec],
                        "frame_id": array.header.frame_id,
                        "detections": [{"class_id": d.results[0].hypothesis.class_id,
                                        "score": d.results[0].hypothesis.score, "id": d.id,
                                        "centre": [d.bbox.center.position.x, d.bbox.center.position.y],
                                        "size": [d.bbox.size_x, d.bbox.size_y]} for d in array.detections]}
    if "image" in got:
        image = got["image"]
        out["image"] = {"encoding": image.encoding, "shape": [image.height, image.width],
                        "pixels": np.frombuffer(bytes(image.data), "<u2").reshape(image.height, image.width).tolist()}
    if "semantic" in got:
        semantic = got["semantic"]
        out["semantic"] = {"encoding": semantic.encoding, "shape": [semantic.height, semantic.width],
                           "step": semantic.step, "frame_id": semantic.header.frame_id,
                           "pixels": np.frombuffer(bytes(semantic.data), np.uint8)
                           .reshape(semantic.height, semantic.width).tolist()}
    print(json.dumps(out))
    rclpy.shutdown()


if __name__ == "__main__":
    main()
