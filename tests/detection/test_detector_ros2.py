"""``ambulo.ros2.detections``: a real rclpy node publishes vision_msgs/msg/Detection2DArray and a
segmentation image and a semantic one; another node in a loopback-only network receives them."""

import json
from pathlib import Path

import numpy as np
import pytest

SCENARIO = Path(__file__).resolve().parent / "ros2_detections_scenario.py"


def test_detections_reach_another_node():
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    pytest.importorskip("mcap_ros2")
    from ambulo.ros2.loopback import run_isolated

    done = run_isolated([str(SCENARIO)], timeout_s=120)
    assert done.returncode == 0, done.stderr[-4000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["graph"]["/detections"] == ["vision_msgs/msg/Detection2DArray"]
    assert out["graph"]["/detections/segmentation"] == ["sensor_msgs/msg/Image"]
    assert out["graph"]["/detections/semantic"] == ["sensor_msgs/msg/Image"]
    array = out["array"]
    assert array["stamp"] == [12, 250_000_000] and array["frame_id"] == "head_camera"
    assert [(d["class_id"], d["id"]) for d in array["detections"]] == [("box", "0"), ("cone", "1")]
    assert array["detections"][0]["centre"] == [3.0, 2.5] and array["detections"][0]["size"] == [4.0, 3.0]
    assert array["detections"][1]["score"] == pytest.approx(0.6)
    image = out["image"]
    assert image["encoding"] == "mono16" and image["shape"] == [6, 8]
    pixels = np.array(image["pixels"])
    expected = np.zeros((6, 8), int)
    expected[2:6, 3:8] = 2
    expected[1:4, 1:5] = 1  # the higher score is drawn over the overlap
    assert (pixels == expected).all(), pixels
    semantic = out["semantic"]  # mono8 category ids: box is 2, cone 4; the box scores higher
    assert semantic["encoding"] == "mono8" and semantic["shape"] == [6, 8] and semantic["step"] == 8
    assert semantic["frame_id"] == "head_camera"
    assert (np.array(semantic["pixels"]) == np.array([0, 2, 4])[expected]).all(), semantic["pixels"]


def test_instance_image_draws_higher_scores_over_lower():
    from ambulo.ros2.detections import instance_image

    masks = np.zeros((3, 2, 3), bool)
    masks[0, :, :2] = True
    masks[1, :, 1:] = True
    image = instance_image(masks, [0.2, 0.7, 0.1])
    assert image.dtype == np.uint16 and image.tolist() == [[1, 2, 2], [1, 2, 2]]
    assert instance_image(np.zeros((0, 2, 3), bool), []).tolist() == [[0, 0, 0], [0, 0, 0]]


RIHS01_DETECTION2D_ARRAY = "RIHS01_214274120007f4a683866481336b70310268cfa107aebe9d594a6acf75bda968"
"""What rosidl_generator_type_description (the wheels' own, 4.9.5) computes from vision_msgs 4.1.1's
msg/*.msg files (ros-perception/vision_msgs, branch ros2, tag 4.1.1): the hash a ROS 2 node with
vision_msgs installed matches our publisher on."""


def test_detection_array_hash_is_vision_msgs_own():
    pytest.importorskip("rclpy", reason="needs rclpy: pip install 'ambulo[ros2]'")
    from ambulo.ros2.detections import DETECTION_ARRAY, register_vision_msgs
    from ambulo.ros2.raw_types import hash_of

    register_vision_msgs()
    assert hash_of(DETECTION_ARRAY) == RIHS01_DETECTION2D_ARRAY
