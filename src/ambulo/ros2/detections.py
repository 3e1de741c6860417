"""Detections on ROS 2: ``vision_msgs/msg/Detection2DArray`` and an instance-segmentation image.

vision_msgs has no PyPI wheel, so the type is declared here from the ``.msg`` definitions of
vision_msgs 4.1 (the ROS 2 Humble-to-Rolling release) and published as serialized CDR through
``raw_types.raw_message_class``, as /tf is: a ROS 2 node with vision_msgs installed (rviz2, Isaac
ROS, Nav2) sees an ordinary ``vision_msgs/msg/Detection2DArray`` publisher (same DDS name, same
RIHS01 hash). The segmentation image is a ``sensor_msgs/Image`` (``mono16``): 0 is background,
k + 1 is the pixel's detection, detection k of the array (higher scores drawn over lower ones). The
semantic image is a ``sensor_msgs/Image`` (``mono8``): 0 is background, else the pixel's COCO category id
(the dataset's semantic PNG's ids), from the detections' own ``semantic_image()``
(``ambulo.detection.Detections``: one painter, ``ambulo.detection.semantic``).

This module takes detections duck-typed (``boxes_px`` (N, 4) x0 y0 x1 y1, ``labels``, ``scores``,
``masks`` (N, H, W) bool or None, ``semantic_image()``: ``ambulo.detection.Detections``) and imports nothing of
``ambulo.detection``: the two are peers (pyproject's layers).

    publisher = DetectionPublisher(node, frame_id="head_camera")
    publisher.publish(time_s, detector(rgb))       # detections; with masks detections/segmentation, /semantic
"""

from __future__ import annotations

import numpy as np

from .raw_types import typestore

DETECTION_ARRAY = "vision_msgs/msg/Detection2DArray"
VISION_MSGS = {
    "vision_msgs/msg/Point2D": "float64 x\nfloat64 y\n",
    "vision_msgs/msg/Pose2D": "vision_msgs/Point2D position\nfloat64 theta\n",
    "vision_msgs/msg/BoundingBox2D": "vision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n",
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": ("vision_msgs/ObjectHypothesis hypothesis\n"
                                                 "geometry_msgs/PoseWithCovariance pose\n"),
    "vision_msgs/msg/Detection2D": ("std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
                                    "vision_msgs/BoundingBox2D bbox\nstring id\n"),
    DETECTION_ARRAY: "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n",
}
"""The fields of vision_msgs 4.1.1's messages (comments left out: they are not part of the type)."""


def register_vision_msgs():
    """The project's typestore with the vision_msgs types added (once); returns the store."""
    from rosbags.typesys import get_types_from_msg

    store = typestore()
    if DETECTION_ARRAY not in store.fielddefs:
        types = {}
        for name, text in VISION_MSGS.items():
            types.update(get_types_from_msg(text, name))
        store.register(types)
    return store


def detection_array_class() -> type:
    """rclpy's message class of ``vision_msgs/msg/Detection2DArray`` (serialized messages only): for
    ``create_publisher`` and ``create_subscription(..., raw=True)``."""
    from .raw_types import clear_rcutils_error, raw_message_class

    register_vision_msgs()
    cls = raw_message_class(DETECTION_ARRAY)
    clear_rcutils_error()
    return cls


def detection_array_cdr(time_s: float, frame_id: str, boxes_px, labels: list[str], scores) -> bytes:
    """CDR bytes of a ``vision_msgs/msg/Detection2DArray``: per detection one hypothesis (its label
    and score), the box as centre and size in pixels (``theta`` 0), ``id`` its index in the array."""
    store = register_vision_msgs()
    t = store.types
    ns = int(round(time_s * 1e9))
    stamp = t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    header = t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)
    no_pose = t["geometry_msgs/msg/PoseWithCovariance"](
        pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                         orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
        covariance=np.zeros(36, np.float64))
    boxes = np.asarray(boxes_px, np.float64).reshape(-1, 4)
    detections = []
    for k, ((x0, y0, x1, y1), label, score) in enumerate(zip(boxes.tolist(), labels, np.asarray(scores).tolist())):
        hypothesis = t["vision_msgs/msg/ObjectHypothesisWithPose"](
            hypothesis=t["vision_msgs/msg/ObjectHypothesis"](class_id=str(label), score=float(score)), pose=no_pose)
        centre = t["vision_msgs/msg/Pose2D"](position=t["vision_msgs/msg/Point2D"](x=(x0 + x1) / 2, y=(y0 + y1) / 2),
                                             theta=0.0)
        bbox = t["vision_msgs/msg/BoundingBox2D"](center=centre, size_x=x1 - x0, size_y=y1 - y0)
        detections.append(t["vision_msgs/msg/Detection2D"](header=header, results=[hypothesis], bbox=bbox, id=str(k)))
    return bytes(store.serialize_cdr(t[DETECTION_ARRAY](header=header, detections=detections), DETECTION_ARRAY))


def segmentation_of(detections) -> np.ndarray | None:
    """The instance image (``instance_image``) of duck-typed detections, or None when they carry no masks
    (a box-only model): the one rule for when ``<topic>/segmentation`` is published."""
    masks = getattr(detections, "masks", None)
    return None if masks is None else instance_image(masks, detections.scores)


def semantic_of(detections) -> np.ndarray | None:
    """The (H, W) uint8 semantic image of duck-typed detections (their ``semantic_image()``), or None when
    they carry no masks or cannot paint one: the one rule for when ``<topic>/semantic`` is published."""
    if getattr(detections, "masks", None) is None or not hasattr(detections, "semantic_image"):
        return None
    return detections.semantic_image()


def detections_fit(canvas_hw, width: int, height: int, what: str) -> str | None:
    """Why a detector trained on a ``canvas_hw`` (height, width) canvas cannot take ``what``'s
    ``width`` x ``height`` frames (smaller ones are padded, larger ones are not resized), or None."""
    ch, cw = canvas_hw
    if width <= cw and height <= ch:
        return None
    return (f"{what} is {width}x{height} px, larger than the detector's {cw}x{ch} canvas (frames are padded, "
            f"never resized); train the detector on {width}x{height} frames (`ambulo generate` at that camera size) "
            f"or give the scene a camera of at most {cw}x{ch} px")


def instance_image(masks, scores) -> np.ndarray:
    """(H, W) uint16: k + 1 where detection k's mask is, the highest-scoring one where masks overlap."""
    masks = np.asarray(masks, bool)
    out = np.zeros(masks.shape[1:], np.uint16)
    for k in np.argsort(np.asarray(scores))[::-1] if len(masks) else []:
        out[masks[k] & (out == 0)] = k + 1
    return out


class DetectionPublisher:
    """Publishes detections on ``topic`` (Detection2DArray) and, for detections with masks,
    ``topic``/segmentation (mono16 instance image) and ``topic``/semantic (mono8 category ids) from an
    rclpy ``node``."""

    def __init__(self, node, topic: str = "detections", frame_id: str = "camera", qos_depth: int = 10):
        from sensor_msgs.msg import Image

        from .raw_types import clear_rcutils_error

        self.frame_id = frame_id
        self.boxes = node.create_publisher(detection_array_class(), topic, qos_depth)
        clear_rcutils_error()
        self.segmentation = node.create_publisher(Image, f"{topic}/segmentation", qos_depth)
        self.semantic = node.create_publisher(Image, f"{topic}/semantic", qos_depth)

    def publish(self, time_s: float, detections) -> None:
        self.boxes.publish(detection_array_cdr(time_s, self.frame_id, detections.boxes_px, detections.labels,
                                               detections.scores))
        for publisher, image, encoding in ((self.segmentation, segmentation_of(detections), "mono16"),
                                           (self.semantic, semantic_of(detections), "mono8")):
            if image is None:
                continue
            from sensor_msgs.msg import Image

            from .messages import header

            data = np.ascontiguousarray(image, "<u2" if encoding == "mono16" else np.uint8)
            msg = Image(header=header(time_s, self.frame_id), height=image.shape[0], width=image.shape[1],
                        encoding=encoding, is_bigendian=0, step=data.itemsize * image.shape[1])
            msg.data = data.tobytes()
            publisher.publish(msg)


__all__ = ["DETECTION_ARRAY", "VISION_MSGS", "DetectionPublisher", "detection_array_cdr", "detection_array_class",
           "detections_fit", "instance_image", "register_vision_msgs", "segmentation_of", "semantic_of"]
