"""2-D grid maps: one type (``Grid2D``, origin = lower-left corner of cell [0, 0], as ROS), its cell
arithmetic (``CellGeometry``) and its files: ambulo's ``.npz`` (``npz``), ROS map_server YAML +
PGM/PNG (``map_server``) and ``nav_msgs/OccupancyGrid`` (``occupancy_grid``).

Content, not an app: this package imports numpy, torch and ``ambulo.utils`` only, so perception
(which writes maps), the footstep planner (which reads them) and the ROS 2 bridge share it."""

from .grid import (
    FREE,
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    OCCUPIED,
    UNKNOWN,
    CellGeometry,
    Grid2D,
)
from .map_server import load_map_image, load_map_yaml, save_map_yaml
from .npz import load_npz, save_npz
from .occupancy_grid import cost_to_occupancy, from_occupancy_grid, grid_info, to_msg, to_occupancy_grid

__all__ = [
    "FREE", "FREE_SPACE", "INSCRIBED_INFLATED_OBSTACLE", "LETHAL_OBSTACLE", "NO_INFORMATION", "OCCUPIED", "UNKNOWN",
    "CellGeometry", "Grid2D", "cost_to_occupancy", "from_occupancy_grid", "grid_info", "load_map_image",
    "load_map_yaml", "load_npz", "save_map_yaml", "save_npz", "to_msg", "to_occupancy_grid",
]
