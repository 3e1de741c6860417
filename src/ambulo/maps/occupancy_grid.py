"""``nav_msgs/OccupancyGrid`` (ROS 2, Nav2): a ``Grid2D`` to and from the message, as a plain dict
with the message's field names or, when the ``ros2`` extra's ``nav_msgs`` is installed, as the
message class itself.

The dict form::

    {"header": {"frame_id": "map"},
     "info": {"resolution": r, "width": W, "height": H,          # MapMetaData
              "origin": {"position": {"x": ox, "y": oy, "z": 0.0},  # lower-left corner of cell (0, 0)
                         "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}},
     "data": (H * W,) int8}   # row-major from the origin: data[iy * W + ix] = cell [iy, ix]

``info.resolution`` is a float32 in the message: a value read back from one is rounded to the
shortest decimal that float32 holds (0.05000000074505806 -> 0.05), so a map survives the trip.
"""

from __future__ import annotations

import array
import math
from collections.abc import Mapping

import numpy as np

from ..utils.checks import Described, InvalidValueError
from .grid import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION, Grid2D, check_yaw_zero


def grid_info(origin_xy_m, resolution_m: float, shape) -> dict:
    """``nav_msgs/MapMetaData`` fields of a grid of ``shape`` (num_y, num_x), as a dict."""
    return {"resolution": float(resolution_m), "width": int(shape[1]), "height": int(shape[0]),
            "origin": {"position": {"x": float(origin_xy_m[0]), "y": float(origin_xy_m[1]), "z": 0.0},
                       "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}


def cost_to_occupancy(cost: np.ndarray) -> np.ndarray:
    """int8 ``OccupancyGrid.data`` values of uint8 Nav2 costs, by Nav2's translation table
    (``Costmap2DPublisher``): 0 -> 0, 253 -> 99, 254 -> 100, 255 -> -1, else 1 + 97 (c - 1) / 251."""
    c = np.asarray(cost).astype(np.int64)
    out = 1 + (97 * (c - 1)) // 251
    out = np.where(c == 0, 0, out)
    out = np.where(c == INSCRIBED_INFLATED_OBSTACLE, 99, out)
    out = np.where(c == LETHAL_OBSTACLE, 100, out)
    out = np.where(c == NO_INFORMATION, -1, out)
    return out.astype(np.int8)


def to_occupancy_grid(grid: Grid2D, *, layer: str = "occupancy", frame_id: str = "map") -> dict:
    """The dict form of ``grid``: its occupancy, or with ``layer="cost"`` its Nav2 costs translated
    as Nav2 publishes a costmap."""
    if layer == "occupancy":
        values = grid.occupancy
    elif layer == "cost" and grid.cost is not None:
        values = cost_to_occupancy(grid.cost)
    else:
        raise InvalidValueError("layer", layer, "expected 'occupancy', or 'cost' on a map with a cost layer",
                                "pass layer='occupancy'")
    return {"header": {"frame_id": frame_id}, "info": grid_info(grid.origin_xy_m, grid.resolution_m, grid.shape),
            "data": np.ascontiguousarray(values, np.int8).reshape(-1)}


def from_occupancy_grid(message) -> Grid2D:
    """The ``Grid2D`` of an OccupancyGrid: the dict form or a ``nav_msgs.msg.OccupancyGrid``."""
    info = _get(message, "info")
    width, height = int(_get(info, "width")), int(_get(info, "height"))
    resolution = float(_get(info, "resolution"))
    if float(np.float32(resolution)) == resolution:  # the message's float32: back to its decimal
        resolution = float(str(np.float32(resolution)))
    pose = _get(info, "origin")
    position, q = _get(pose, "position"), _get(pose, "orientation")
    qx, qy, qz, qw = (float(_get(q, k)) for k in "xyzw")
    if math.hypot(qx, qy) > 1e-9:
        raise InvalidValueError("OccupancyGrid origin orientation", (qx, qy, qz, qw), "the map is tilted",
                                "publish the map with a rotation about z only")
    check_yaw_zero("OccupancyGrid origin yaw", 2.0 * math.atan2(qz, qw) if qw >= 0 else 2.0 * math.atan2(-qz, -qw))
    data = _get(message, "data")
    data = np.frombuffer(data, np.int8) if isinstance(data, (array.array, bytes)) else np.asarray(data)
    if data.size != width * height:
        raise InvalidValueError("OccupancyGrid data", Described(f"of {data.size} cells"),
                                f"info says {width} x {height} = {width * height}",
                                "send one int8 per cell, row-major from the origin")
    if data.dtype.kind not in "iu":
        raise InvalidValueError("OccupancyGrid data", Described(f"of dtype {data.dtype}"), "expected int8 values",
                                "send -1 (unknown) or 0..100")
    return Grid2D(occupancy=data.astype(np.int8).reshape(height, width),
                  origin_xy_m=(float(_get(position, "x")), float(_get(position, "y"))), resolution_m=resolution)


def to_msg(occupancy_grid: dict, *, stamp=None):
    """A ``nav_msgs.msg.OccupancyGrid`` of the dict form (needs ``pip install 'ambulo[ros2]'``);
    ``stamp`` (``builtin_interfaces/Time``) goes into the header and ``info.map_load_time``."""
    from geometry_msgs.msg import Point, Pose, Quaternion  # the ros2 extra, only when asked
    from nav_msgs.msg import MapMetaData, OccupancyGrid
    from std_msgs.msg import Header

    info = occupancy_grid["info"]
    p, q = info["origin"]["position"], info["origin"]["orientation"]
    meta = MapMetaData(resolution=float(info["resolution"]), width=int(info["width"]), height=int(info["height"]),
                       origin=Pose(position=Point(x=float(p["x"]), y=float(p["y"]), z=float(p["z"])),
                                   orientation=Quaternion(x=float(q["x"]), y=float(q["y"]), z=float(q["z"]),
                                                          w=float(q["w"]))))
    header = Header(frame_id=str(occupancy_grid.get("header", {}).get("frame_id", "map")))
    if stamp is not None:
        meta.map_load_time, header.stamp = stamp, stamp
    data = np.ascontiguousarray(occupancy_grid["data"], np.int8).reshape(-1)
    return OccupancyGrid(header=header, info=meta, data=array.array("b", data.tobytes()))


def _get(obj, name: str):
    try:
        return obj[name] if isinstance(obj, Mapping) else getattr(obj, name)
    except (KeyError, AttributeError):
        raise InvalidValueError(f"OccupancyGrid field {name!r}", Described("missing"),
                                "expected nav_msgs/OccupancyGrid's fields (info.resolution, info.origin, data)",
                                "pass the message or its dict form (to_occupancy_grid)") from None


__all__ = ["cost_to_occupancy", "from_occupancy_grid", "grid_info", "to_msg", "to_occupancy_grid"]
