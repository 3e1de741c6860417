"""The apartment's plan, drawn in numbers before any MuJoCo: rooms, a corridor, walls with door
gaps, furniture and clutter, each solid a box or a cylinder with its height.

The plan (seeded by one ``numpy.random.Generator``)::

    y ^   +-------+--------+----------+        north rooms (0..3), one depth
      |   | room  | room   |  room    |
      |   +--- ---+---- ---+---  -----+        doors 0.8-1.0 m into the corridor
      |   |            corridor       |        1.1-1.6 m wide, kept clear
      |   +----  -----+------  -------+
      |   |   room    |    room       |        south rooms, one depth; a shared wall may
      |   +-----------+---------------+        hold a door between two rooms
      +---------------------------------> x

Walls are boxes ``wall_thickness_m`` thick centred on the plan's lines, split at their doors.
Furniture stands flush against a room's wall (cabinets, shelves, sofas, beds, desks) or free in
the room (tables on four legs, round tables on a pedestal, plant pots, floor lamps, low clutter:
boxes of shoes or books 6-15 cm high), at random yaw when free. Rugs are visual only (1 cm).

What keeps every room reachable: no solid within ``door_keepout_m`` of a door's either side; the
corridor holds nothing; any two solids are either ``passage_m`` (the robot's diameter plus a
margin) apart or, for a flush piece near a room corner, pushed into that corner; and a flush
piece leaves ``passage_m`` to the opposite wall. The navigator's reachability is still checked
on the real geometry (``apartment_paths``): the sampler draws from one connected region.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .apartment_geometry import Footprints, point_clearance_m, rect_distances_m


@dataclass(frozen=True)
class Solid:
    """A static solid: a box (half extents x, y, z) or a vertical cylinder (radius, -, half height)."""

    name: str
    """Its prim path (the MuJoCo body and geom are named after it)."""
    shape: str
    """``"box"`` or ``"cylinder"``."""
    center_m: tuple[float, float, float]
    half_m: tuple[float, float, float]
    """Box: half extents along its own x, y, z. Cylinder: (radius, radius, half height)."""
    yaw_rad: float = 0.0
    look: str = "furniture"
    """Which material family renders it: ``wall``, ``furniture``, ``wood``, ``fabric``, ``metal``,
    ``plant``, ``rug``."""
    collides: bool = True
    """False for decals (rugs): rendered, never touched. Such a solid must stay below the step height."""

    @property
    def bottom_m(self) -> float:
        return self.center_m[2] - self.half_m[2]

    @property
    def top_m(self) -> float:
        return self.center_m[2] + self.half_m[2]


@dataclass(frozen=True)
class Room:
    name: str
    min_xy_m: tuple[float, float]
    """Lower-left corner of the room's inner rectangle (the wall centre lines), m."""
    max_xy_m: tuple[float, float]
    is_corridor: bool = False


@dataclass(frozen=True)
class Door:
    """An opening in a wall: its centre on the wall line, its width and the wall's direction."""

    center_xy_m: tuple[float, float]
    width_m: float
    along_x: bool
    """True: the wall runs along x (the door is crossed along y)."""
    rooms: tuple[str, str]


@dataclass
class Layout:
    rooms: list[Room]
    doors: list[Door]
    solids: list[Solid]
    extent_xy_m: tuple[float, float, float, float]
    """(x_min, y_min, x_max, y_max) of the wall centre lines' rectangle, m."""
    wall_thickness_m: float
    lights_xyz_m: list[tuple[float, float, float]] = field(default_factory=list)


def footprints(solids: list[Solid], step_height_m: float, head_height_m: float) -> Footprints:
    """The footprints of the solids that block the body band: top above ``step_height_m`` and
    bottom below ``head_height_m`` (see ``ApartmentCfg``)."""
    rects = [s for s in solids if s.shape == "box" and s.top_m > step_height_m and s.bottom_m < head_height_m]
    discs = [s for s in solids if s.shape == "cylinder" and s.top_m > step_height_m and s.bottom_m < head_height_m]
    return Footprints(np.array([s.center_m[:2] for s in rects], float).reshape(-1, 2),
                      np.array([s.half_m[:2] for s in rects], float).reshape(-1, 2),
                      np.array([s.yaw_rad for s in rects], float),
                      np.array([s.center_m[:2] for s in discs], float).reshape(-1, 2),
                      np.array([s.half_m[0] for s in discs], float))


def _u(rng: np.random.Generator, bounds) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def generate_layout(cfg, rng: np.random.Generator) -> Layout:
    """The seeded plan of ``cfg`` (an ``ApartmentCfg``): see the module docstring."""
    num_rooms = int(rng.integers(cfg.num_rooms_range[0], cfg.num_rooms_range[1] + 1))
    num_south = max((num_rooms + int(rng.integers(0, 2))) // 2, 1)  # the larger half either side
    sides = {"south": num_south, "north": num_rooms - num_south}
    widths = {side: [_u(rng, cfg.room_width_range_m) for _ in range(n)] for side, n in sides.items()}
    length_m = max(sum(w) for w in widths.values())
    for w in widths.values():  # the shorter side's last room takes up the slack
        if w:
            w[-1] += length_m - sum(w)
    corridor_w = _u(rng, cfg.corridor_width_range_m)
    depth = {side: _u(rng, cfg.room_depth_range_m) if n else 0.0 for side, n in sides.items()}
    y_corr0 = depth["south"]
    y_corr1 = y_corr0 + corridor_w
    y_top = y_corr1 + depth["north"]
    t = _u(rng, cfg.wall_thickness_range_m)

    rooms = [Room("corridor", (0.0, y_corr0), (length_m, y_corr1), is_corridor=True)]
    doors: list[Door] = []
    for side in ("south", "north"):
        x = 0.0
        y0, y1 = (0.0, y_corr0) if side == "south" else (y_corr1, y_top)
        for k, w in enumerate(widths[side]):
            room = Room(f"{side}_{k}", (x, y0), (x + w, y1))
            rooms.append(room)
            width = _u(rng, cfg.door_width_range_m)
            margin = t / 2 + 0.15 + width / 2
            doors.append(Door((x + _u(rng, (margin, w - margin)), y_corr0 if side == "south" else y_corr1),
                              width, True, (room.name, "corridor")))
            if k > 0 and rng.random() < cfg.connecting_door_probability:
                width = _u(rng, cfg.door_width_range_m)
                margin = t / 2 + 0.15 + width / 2
                doors.append(Door((x, _u(rng, (y0 + margin, y1 - margin))), width, False,
                                  (f"{side}_{k - 1}", room.name)))
            x += w
    solids = _walls(rooms, doors, length_m, y_top, y_corr0, y_corr1, sides, cfg.wall_height_m, t)
    lights = []
    for room in rooms:
        if not room.is_corridor:
            solids += _furnish(room, doors, solids, cfg, rng, t)
        cx, cy = (room.min_xy_m[0] + room.max_xy_m[0]) / 2, (room.min_xy_m[1] + room.max_xy_m[1]) / 2
        lights.append((cx, cy, cfg.wall_height_m - 0.15))
    layout = Layout(rooms, doors, solids, (0.0, 0.0, length_m, y_top), t, lights)
    return _transposed(layout) if rng.random() < 0.5 else layout  # half the corridors run along y


def _transposed(layout: Layout) -> Layout:
    """``layout`` mirrored about the line x = y: a box of yaw a becomes one of yaw pi/2 - a (its
    half extents kept); an axis-aligned box (yaw 0) keeps yaw 0 with its half extents swapped."""
    def solid(s: Solid) -> Solid:
        (x, y, z), (hx, hy, hz) = s.center_m, s.half_m
        if s.yaw_rad == 0.0:
            return Solid(s.name, s.shape, (y, x, z), (hy, hx, hz), 0.0, s.look, s.collides)
        return Solid(s.name, s.shape, (y, x, z), s.half_m, math.pi / 2 - s.yaw_rad, s.look, s.collides)

    x0, y0, x1, y1 = layout.extent_xy_m
    return Layout([Room(r.name, r.min_xy_m[::-1], r.max_xy_m[::-1], r.is_corridor) for r in layout.rooms],
                  [Door(d.center_xy_m[::-1], d.width_m, not d.along_x, d.rooms) for d in layout.doors],
                  [solid(s) for s in layout.solids], (y0, x0, y1, x1), layout.wall_thickness_m,
                  [(y, x, z) for x, y, z in layout.lights_xyz_m])


def _walls(rooms, doors, length_m, y_top, y_corr0, y_corr1, sides, height_m, t) -> list[Solid]:
    """Wall boxes on every plan line, split at the doors on it; each is extended by t/2 past its
    ends so corners and T junctions close."""
    lines = [((0.0, 0.0), (length_m, 0.0)), ((0.0, y_top), (length_m, y_top)),
             ((0.0, 0.0), (0.0, y_top)), ((length_m, 0.0), (length_m, y_top))]
    if sides["south"]:
        lines.append(((0.0, y_corr0), (length_m, y_corr0)))
    if sides["north"]:
        lines.append(((0.0, y_corr1), (length_m, y_corr1)))
    for room in rooms:
        if not room.is_corridor and room.min_xy_m[0] > 0.0:
            lines.append(((room.min_xy_m[0], room.min_xy_m[1]), (room.min_xy_m[0], room.max_xy_m[1])))
    solids = []
    for (x0, y0), (x1, y1) in lines:
        along_x = y0 == y1
        lo, hi = (x0, x1) if along_x else (y0, y1)
        gaps = sorted((d.center_xy_m[0] if along_x else d.center_xy_m[1], d.width_m) for d in doors
                      if d.along_x == along_x and (d.center_xy_m[1] == y0 if along_x else d.center_xy_m[0] == x0)
                      and lo < (d.center_xy_m[0] if along_x else d.center_xy_m[1]) < hi)
        pieces, start = [], lo - t / 2
        for centre, width in gaps:
            pieces.append((start, centre - width / 2))
            start = centre + width / 2
        pieces.append((start, hi + t / 2))
        for a, b in pieces:
            if b - a <= 1e-9:
                continue
            mid, half = (a + b) / 2, (b - a) / 2
            center = (mid, y0, height_m / 2) if along_x else (x0, mid, height_m / 2)
            half_m = (half, t / 2, height_m / 2) if along_x else (t / 2, half, height_m / 2)
            solids.append(Solid(f"/World/apartment/walls/wall_{len(solids)}", "box", center, half_m, look="wall"))
    return solids


# kind: (half x range, half y range, height range, look); x runs along the wall for flush pieces
_FLUSH = {"cabinet": ((0.3, 0.6), (0.2, 0.3), (0.75, 1.0), "wood"),
          "shelf": ((0.3, 0.5), (0.15, 0.22), (1.5, 2.1), "wood"),
          "sofa": ((0.7, 1.0), (0.4, 0.48), (0.7, 0.9), "fabric"),
          "bed": ((0.7, 1.0), (0.95, 1.05), (0.45, 0.6), "fabric"),
          "desk": ((0.5, 0.7), (0.3, 0.38), (0.72, 0.78), "wood")}
_FREE = ("table", "round_table", "pot", "lamp", "low_box", "low_pile", "armchair")


def _furnish(room: Room, doors: list[Door], walls: list[Solid], cfg, rng, t: float) -> list[Solid]:
    """Flush and free furniture for ``room`` (see the module docstring); rejection-sampled."""
    base = f"/World/apartment/{room.name}"
    (x0, y0), (x1, y1) = room.min_xy_m, room.max_xy_m
    ix0, iy0, ix1, iy1 = x0 + t / 2, y0 + t / 2, x1 - t / 2, y1 - t / 2  # inner faces
    keepout = [d for d in doors if room.name in d.rooms]
    placed: list[tuple[tuple, tuple, float]] = []  # footprint rectangles (centre, half, yaw) so far
    out: list[Solid] = []

    def fits(center, half, yaw, flush_walls=()) -> bool:
        cx, cy = center
        hx, hy = abs(half[0] * math.cos(yaw)) + abs(half[1] * math.sin(yaw)), \
            abs(half[0] * math.sin(yaw)) + abs(half[1] * math.cos(yaw))
        if cx - hx < ix0 - 1e-9 or cx + hx > ix1 + 1e-9 or cy - hy < iy0 - 1e-9 or cy + hy > iy1 + 1e-9:
            return False
        gaps = {"w": cx - hx - ix0, "e": ix1 - cx - hx, "s": cy - hy - iy0, "n": iy1 - cy - hy}
        for side, gap in gaps.items():  # touching a wall (flush) or a passage away from it
            if side not in flush_walls and 0.03 < gap < cfg.passage_m:
                return False
        if keepout:
            rect = Footprints(np.array([center], float), np.array([half], float), np.array([yaw], float),
                              np.zeros((0, 2)), np.zeros(0))
            reach = point_clearance_m(rect, np.array([d.center_xy_m for d in keepout], float))
            if (reach < cfg.door_keepout_m + np.array([d.width_m for d in keepout]) / 2).any():
                return False
        if not placed:
            return True
        centers, halves, yaws = (np.array(v, float) for v in zip(*placed))
        # only pieces whose circumcircles come within a passage need the exact distance
        near = (np.hypot(*(centers - center).T) - np.hypot(*halves.T) - math.hypot(*half)) < cfg.passage_m
        if not near.any():
            return True
        return bool((rect_distances_m(center, half, yaw, centers[near], halves[near], yaws[near])
                     >= cfg.passage_m).all())

    def add(kind: str, center, half, yaw, height, look):
        placed.append((center, half, yaw))
        name = f"{base}/{kind}_{len(out)}"
        out.extend(_pieces(name, kind, center, half, yaw, height, look))

    for _ in range(int(rng.integers(cfg.furniture_per_room_range[0], cfg.furniture_per_room_range[1] + 1))):
        kind = str(rng.choice(list(_FLUSH)))
        hx_r, hy_r, h_r, look = _FLUSH[kind]
        for _try in range(20):
            half = (_u(rng, hx_r), _u(rng, hy_r))
            wall = str(rng.choice(["s", "n", "w", "e"]))
            vertical = wall in ("w", "e")
            half_w = (half[1], half[0]) if vertical else half  # world half extents
            if vertical:
                cx = ix0 + half_w[0] if wall == "w" else ix1 - half_w[0]
                cy = _u(rng, (iy0 + half_w[1], max(iy0 + half_w[1], iy1 - half_w[1])))
            else:
                cy = iy0 + half_w[1] if wall == "s" else iy1 - half_w[1]
                cx = _u(rng, (ix0 + half_w[0], max(ix0 + half_w[0], ix1 - half_w[0])))
            flush = {wall}
            # a piece that nearly meets a side wall goes into that corner
            if vertical:
                if cy - half_w[1] - iy0 < cfg.passage_m:
                    cy, flush = iy0 + half_w[1], flush | {"s"}
                elif iy1 - cy - half_w[1] < cfg.passage_m:
                    cy, flush = iy1 - half_w[1], flush | {"n"}
            else:
                if cx - half_w[0] - ix0 < cfg.passage_m:
                    cx, flush = ix0 + half_w[0], flush | {"w"}
                elif ix1 - cx - half_w[0] < cfg.passage_m:
                    cx, flush = ix1 - half_w[0], flush | {"e"}
            if fits((cx, cy), half_w, 0.0, flush):
                add(kind, (cx, cy), half_w, 0.0, _u(rng, h_r), look)
                break
    for _ in range(int(rng.integers(cfg.clutter_per_room_range[0], cfg.clutter_per_room_range[1] + 1))):
        kind = str(rng.choice(_FREE))
        for _try in range(20):
            half, height, look = _free_size(kind, rng)
            yaw = _u(rng, (-math.pi, math.pi)) if kind not in ("pot", "lamp") else 0.0
            center = (_u(rng, (ix0, ix1)), _u(rng, (iy0, iy1)))
            if fits(center, half, yaw):
                add(kind, center, half, yaw, height, look)
                break
    if rng.random() < cfg.rug_probability:  # a decal: 1 cm, below any step height
        half = (_u(rng, (0.6, 1.1)), _u(rng, (0.4, 0.8)), 0.005)
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        out.append(Solid(f"{base}/rug", "box", (cx, cy, half[2]), half, _u(rng, (-0.3, 0.3)), "rug", False))
    return out


def _free_size(kind: str, rng) -> tuple[tuple[float, float], float, str]:
    """Footprint half extents (a disc's radius twice), height and look of a free piece."""
    if kind == "table":
        return (_u(rng, (0.45, 0.8)), _u(rng, (0.35, 0.5))), _u(rng, (0.72, 0.78)), "wood"
    if kind == "round_table":
        r = _u(rng, (0.35, 0.55))
        return (r, r), _u(rng, (0.7, 0.76)), "wood"
    if kind == "pot":
        r = _u(rng, (0.12, 0.25))
        return (r, r), _u(rng, (0.3, 1.2)), "plant"
    if kind == "lamp":
        return (0.18, 0.18), _u(rng, (1.4, 1.8)), "metal"
    if kind == "low_box":
        return (_u(rng, (0.15, 0.3)), _u(rng, (0.1, 0.2))), _u(rng, (0.06, 0.15)), "furniture"
    if kind == "low_pile":
        return (_u(rng, (0.12, 0.2)), _u(rng, (0.1, 0.15))), _u(rng, (0.05, 0.12)), "furniture"
    return (_u(rng, (0.35, 0.45)), _u(rng, (0.35, 0.45))), _u(rng, (0.8, 1.0)), "fabric"  # armchair


def _pieces(name, kind, center, half, yaw, height, look) -> list[Solid]:
    """The solids of one piece of furniture (a table is its top and four legs; a lamp a pole on a
    2 cm base the feet may step on; a round table a top on a pedestal)."""
    cx, cy = center
    if kind == "table":
        top = 0.03
        solids = [Solid(name + "/top", "box", (cx, cy, height - top / 2), (half[0], half[1], top / 2), yaw, look)]
        leg = 0.025
        c, s = math.cos(yaw), math.sin(yaw)
        for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
            lx, ly = sx * (half[0] - leg - 0.03), sy * (half[1] - leg - 0.03)
            solids.append(Solid(f"{name}/leg_{k}", "box", (cx + lx * c - ly * s, cy + lx * s + ly * c,
                                                          (height - top) / 2), (leg, leg, (height - top) / 2), yaw,
                                "metal"))
        return solids
    if kind == "round_table":
        top = 0.03
        return [Solid(name + "/top", "cylinder", (cx, cy, height - top / 2), (half[0], half[0], top / 2), 0.0, look),
                Solid(name + "/pedestal", "cylinder", (cx, cy, (height - top) / 2), (0.05, 0.05, (height - top) / 2),
                      0.0, "metal")]
    if kind == "lamp":
        base = 0.02
        return [Solid(name + "/base", "cylinder", (cx, cy, base / 2), (half[0], half[0], base / 2), 0.0, "metal"),
                Solid(name + "/pole", "cylinder", (cx, cy, height / 2), (0.02, 0.02, height / 2), 0.0, "metal")]
    if kind == "pot":
        return [Solid(name, "cylinder", (cx, cy, height / 2), (half[0], half[0], height / 2), 0.0, look)]
    return [Solid(name, "box", (cx, cy, height / 2), (half[0], half[1], height / 2), yaw, look)]


__all__ = ["Door", "Layout", "Room", "Solid", "footprints", "generate_layout"]
