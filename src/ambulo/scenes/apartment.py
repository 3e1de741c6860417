"""Seeded procedural apartments: ``apartment(seed)`` is a furnished, lit, textured 2-5 room flat
with the exact ground-truth occupancy of the humanoid's body band and a start/goal sampler.

    apt = apartment(3)                            # the same seed, the same flat
    spec = apt.build(robot_pose=(x, y, yaw))      # an MjSpec for core.Simulation / sim.World
    apt.occupancy                                 # maps.Grid2D, origin = lower-left corner of cell [0, 0]
    ep = apt.sample_start_goal(7)                 # start pose, goal, geodesic with the robot's clearance

The plan (rooms, corridor, doors, furniture) is ``apartment_layout``; its MuJoCo scene is
``apartment_build``; exact footprint geometry is ``apartment_geometry``; geodesics and the sampler
are ``apartment_paths``.

**What is an obstacle (the body band rule).** A solid blocks the map where its footprint is iff
its top is above ``step_height_m`` and its bottom below ``head_height_m``. The body band proper
runs from the swinging foot's clearance to the top of the head; a solid lower than the foot's
clearance but higher than a step (a box of shoes, a pile of books, 5-15 cm) is still an
obstacle for the feet, so the two make one interval (``step_height_m``, ``head_height_m``). A 1 cm
rug is below it and walkable; a table's top (0.7 m) is in it, so the whole table top's footprint
is blocked, not only its legs; a floor lamp's 2 cm base is walkable, its pole is not.

**The occupancy** (``ApartmentCfg.resolution_m`` cells): a cell is OCCUPIED iff its square (less
1 micrometre a side, so a face on a cell border occupies one cell, not two) meets a blocking
footprint, rectangles and discs tested exactly; every other cell is FREE, outside the walls too.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..maps import Grid2D
from ..robots import humanoid
from ..utils.checks import InvalidValueError
from ..utils.validate import Checked, rule
from .apartment_build import build_spec
from .apartment_geometry import Footprints, rasterize
from .apartment_layout import Door, Layout, Room, Solid, footprints, generate_layout
from .apartment_paths import PathFinder, StartGoal


@dataclass(kw_only=True)
class ApartmentCfg(Checked):
    """How apartments are drawn; the seed is ``apartment``'s argument."""

    num_rooms_range: tuple[int, int] = (2, 5)
    """Rooms besides the corridor, drawn uniformly (1..6 supported)."""
    room_width_range_m: tuple[float, float] = (2.8, 4.5)
    """Room extent along the corridor (wall centre to wall centre), m."""
    room_depth_range_m: tuple[float, float] = (3.0, 4.2)
    """Room extent across the corridor, m; one depth per side."""
    corridor_width_range_m: tuple[float, float] = (1.1, 1.6)
    door_width_range_m: tuple[float, float] = (0.8, 1.0)
    """Clear opening of a door, m."""
    wall_thickness_range_m: tuple[float, float] = (0.1, 0.15)
    wall_height_m: float = 2.5
    connecting_door_probability: float = 0.35
    """Chance of a door between two neighbouring rooms on one side of the corridor."""
    furniture_per_room_range: tuple[int, int] = (2, 5)
    """Pieces flush against the walls: cabinets, shelves, sofas, beds, desks (tried; some may not fit)."""
    clutter_per_room_range: tuple[int, int] = (2, 6)
    """Free pieces: tables, round tables, pots, lamps, armchairs, low boxes and piles."""
    rug_probability: float = 0.5
    passage_m: float = 0.65
    """Least gap between two pieces, or between a piece and a wall it does not touch, m: the robot's
    diameter (2 x 0.265 m) and a margin, so furniture never closes a room."""
    door_keepout_m: float = 0.7
    """Nothing stands within this of a door's opening, m (beyond half its width from its centre)."""
    step_height_m: float = field(default=0.03, metadata=rule(minimum=0.0))
    """Solids whose top is at or below this are walked over (module docstring), m."""
    head_height_m: float = humanoid.HEAD_HEIGHT_M
    """Solids whose bottom is at or above this pass over the robot, m."""
    resolution_m: float = field(default=0.05, metadata=rule(minimum=0.005))
    """Occupancy cell side, m."""
    map_margin_m: float = 0.5
    """Free border around the outer walls in the occupancy map, m."""
    texture_px: int = field(default=256, metadata=rule(minimum=16))
    """Side of each procedural texture image, px (``apartment_textures``): 256 px over a 1.2 m wall
    tile is 4.7 mm a texel, the head camera's pixel at 1.2 m."""

    def __post_init__(self) -> None:
        super().__post_init__()
        low, high = self.num_rooms_range
        if not 1 <= low <= high <= 6:
            raise InvalidValueError("ApartmentCfg.num_rooms_range", self.num_rooms_range,
                                    "rooms must be 1 <= low <= high <= 6", "pass e.g. num_rooms_range=(2, 5)")
        if self.door_width_range_m[0] <= 0.0:
            raise InvalidValueError("ApartmentCfg.door_width_range_m", self.door_width_range_m,
                                    "a door must be wider than 0", "pass e.g. door_width_range_m=(0.8, 1.0)")
        if self.head_height_m <= self.step_height_m:
            raise InvalidValueError("ApartmentCfg.head_height_m", self.head_height_m,
                                    f"the body band is empty: head height <= step height {self.step_height_m}",
                                    "pass the robot's head height in m, e.g. 1.62")
        if self.room_width_range_m[0] < self.door_width_range_m[1] + 1.0 or \
                self.room_depth_range_m[0] < self.door_width_range_m[1] + 1.0:
            raise InvalidValueError("ApartmentCfg.room_width_range_m", self.room_width_range_m,
                                    "a room must be at least its door plus 1 m wide and deep",
                                    "pass e.g. room_width_range_m=(2.8, 4.5), room_depth_range_m=(3.0, 4.2)")


@dataclass(eq=False)
class Apartment:
    """One seeded apartment: its plan, ground-truth occupancy, MuJoCo scene and geodesics."""

    seed: int
    cfg: ApartmentCfg
    layout: Layout
    footprints: Footprints
    """The footprints that block the body band (module docstring)."""
    occupancy: Grid2D
    """Exact ground-truth occupancy of the body band (module docstring)."""

    @property
    def rooms(self) -> list[Room]:
        """The rooms, the corridor first (``is_corridor``)."""
        return self.layout.rooms

    @property
    def doors(self) -> list[Door]:
        return self.layout.doors

    @property
    def solids(self) -> list[Solid]:
        return self.layout.solids

    @functools.cached_property
    def paths(self) -> PathFinder:
        """Clearance field and shortest paths over this apartment's cells."""
        x0, y0, x1, y1 = self.layout.extent_xy_m
        return PathFinder(self.footprints, self.occupancy.origin_xy_m, self.occupancy.resolution_m,
                          self.occupancy.shape, (x0, y0, x1, y1))

    def build(self, spec: mujoco.MjSpec | None = None,
              robot_pose: tuple[float, float, float] | None = None) -> mujoco.MjSpec:
        """The scene as an ``MjSpec`` (into ``spec``, e.g. a ``sim.World``'s stage, if given), with
        the bundled humanoid at ``robot_pose`` (x m, y m, yaw rad) unless None. The same seed
        builds the same MJCF."""
        rng = np.random.default_rng([self.seed, 1])
        return build_spec(self.layout, rng, texture_px=self.cfg.texture_px, spec=spec, robot_pose=robot_pose)

    def sample_start_goal(self, rng: np.random.Generator | int, min_geodesic_m: float = 3.0,
                          max_geodesic_m: float = 15.0, clearance_m: float = humanoid.BODY_RADIUS_M) -> StartGoal:
        """A start pose (x, y, yaw) and a goal (x, y), cell centres where a disc of ``clearance_m``
        touches nothing, joined by a path with that clearance whose length (the geodesic,
        ``apartment_paths``) is in [``min_geodesic_m``, ``max_geodesic_m``]. ``rng``: a Generator
        or a seed; RuntimeError if none is found."""
        if not 0.0 <= min_geodesic_m <= max_geodesic_m or not math.isfinite(max_geodesic_m):
            raise InvalidValueError("min_geodesic_m, max_geodesic_m", (min_geodesic_m, max_geodesic_m),
                                    "expected 0 <= min <= max < inf", "pass e.g. 3.0, 15.0")
        if not clearance_m >= 0.0:
            raise InvalidValueError("clearance_m", clearance_m, "a radius must be >= 0", "pass e.g. 0.265")
        rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        return self.paths.sample_start_goal(rng, min_geodesic_m, max_geodesic_m, clearance_m)

    def geodesic_m(self, start_xy_m, goal_xy_m, clearance_m: float = humanoid.BODY_RADIUS_M) -> float:
        """Length of the shortest path with ``clearance_m`` between two points, m (inf if there is
        none): the denominator of SPL."""
        return self.paths.shortest_path(start_xy_m, goal_xy_m, clearance_m)[0]


def apartment(seed: int, cfg: ApartmentCfg | None = None) -> Apartment:
    """The apartment of ``seed`` (module docstring): plan, footprints and occupancy, no MuJoCo yet
    (``Apartment.build`` makes the scene)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidValueError("seed", seed, "expected a whole number >= 0", "pass e.g. apartment(3)")
    cfg = ApartmentCfg() if cfg is None else cfg
    if not isinstance(cfg, ApartmentCfg):
        raise InvalidValueError("cfg", type(cfg).__name__, "expected an ApartmentCfg", "pass ApartmentCfg(...)")
    layout = generate_layout(cfg, np.random.default_rng([int(seed), 0]))
    fp = footprints(layout.solids, cfg.step_height_m, cfg.head_height_m)
    x0, y0, x1, y1 = layout.extent_xy_m
    r, margin = cfg.resolution_m, cfg.map_margin_m
    origin = (x0 - margin, y0 - margin)
    shape = (int(math.ceil((y1 - y0 + 2 * margin) / r)), int(math.ceil((x1 - x0 + 2 * margin) / r)))
    occupied = rasterize(fp, origin, r, shape)
    grid = Grid2D.from_masks(occupied, origin_xy_m=origin, resolution_m=r)
    return Apartment(int(seed), cfg, layout, fp, grid)


__all__ = ["Apartment", "ApartmentCfg", "StartGoal", "apartment"]
