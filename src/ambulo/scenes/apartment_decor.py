"""What a home has on its walls, as visual-only geoms: skirting boards, door casings, light
switches, and framed pictures, placed from an apartment's plan (``apartment_layout.Layout``) by a seed.

Each is a finite MuJoCo **plane** 1-3 mm in front of a wall face, facing into the room, with
``contype = conaffinity = 0``. Why planes: they collide with nothing (so the robot's contacts and
the ground truth are unchanged: ``scenes.apartment`` rasterizes the plan's solids only, and
``navigation.ground_truth`` skips planes and visual-only geoms), and a ray meets a plane from its
front only, so a ray cast straight down, as the occupancy check casts them, passes by: the body band
holds exactly the solids it held before. The head camera sees them as marks on the wall
(within 3 mm of its face), which is what the odometry needs: edges and corners on walls that were
plain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..utils.rotations import mat_to_quat
from .apartment_layout import Layout, Room, Solid

DECOR_PRIM = "/World/apartment/decor"
SKIRTING_HEIGHT_RANGE_M = (0.06, 0.12)
"""Skirting boards of European and American homes: 6-12 cm high."""
CASING_WIDTH_RANGE_M = (0.05, 0.09)
"""Door casing (architrave) width either side of an opening."""
SWITCH_HEIGHT_M = 1.1
"""Light-switch centre height (UK Approved Document M: 0.45-1.2 m; 1.1-1.2 m is common)."""
SWITCH_PLATE_M = (0.08, 0.12)
"""Switch plate width, height."""


@dataclass(frozen=True)
class WallFace:
    """One face of a wall piece that looks into the apartment."""

    line: float
    """The face's coordinate across the wall (y for a wall along x), m."""
    lo_m: float
    hi_m: float
    """The face's extent along the wall, m."""
    along_x: bool
    normal_sign: float
    """+1: the face looks towards +y (+x for a wall along y)."""


def wall_faces(layout: Layout) -> list[WallFace]:
    """The faces of the wall pieces that look into the apartment (not out of its outer walls)."""
    x0, y0, x1, y1 = layout.extent_xy_m
    out = []
    for s in layout.solids:
        if s.look != "wall":
            continue
        (cx, cy, _), (hx, hy, _) = s.center_m, s.half_m
        along_x = hx >= hy
        for sign in (-1.0, 1.0):
            line = (cy + sign * hy) if along_x else (cx + sign * hx)
            probe = line + sign * 0.05
            inside = (y0 < probe < y1) if along_x else (x0 < probe < x1)
            if inside:
                lo, hi = (cx - hx, cx + hx) if along_x else (cy - hy, cy + hy)
                out.append(WallFace(line, lo, hi, along_x, sign))
    return out


def _plane(spec: mujoco.MjSpec, name: str, face: WallFace, along_m: float, z_m: float, half_w_m: float,
           half_h_m: float, offset_m: float, *, rgba=None, material: str | None = None) -> None:
    """A visual-only plane of half extents (along the wall, up) centred at ``along_m``, ``z_m`` on
    ``face``, ``offset_m`` in front of it, its front towards the room."""
    n = np.array([0.0, face.normal_sign, 0.0]) if face.along_x else np.array([face.normal_sign, 0.0, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    rot = np.stack([np.cross(up, n), up, n], axis=1)  # local x along the wall, y up, z (the front) out
    across = face.line + face.normal_sign * offset_m
    pos = [along_m, across, z_m] if face.along_x else [across, along_m, z_m]
    geom = spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_PLANE, pos=pos, quat=mat_to_quat(rot).tolist(),
                                   size=[half_w_m, half_h_m, max(half_w_m, half_h_m)], contype=0, conaffinity=0)
    if material is not None:
        geom.material = material
    if rgba is not None:
        geom.rgba = list(rgba)


def _near_solid(solids: list[Solid], face: WallFace, lo_m: float, hi_m: float, bottom_m: float) -> bool:
    """Whether a solid reaching above ``bottom_m`` stands within 0.1 m in front of ``face`` over
    [lo, hi] (a shelf or a wardrobe would hide a picture there)."""
    for s in solids:
        if s.look == "wall" or s.top_m <= bottom_m:
            continue
        c, h = abs(math.cos(s.yaw_rad)), abs(math.sin(s.yaw_rad))
        ex, ey = s.half_m[0] * c + s.half_m[1] * h, s.half_m[0] * h + s.half_m[1] * c
        along, half_along = (s.center_m[0], ex) if face.along_x else (s.center_m[1], ey)
        across, half_across = (s.center_m[1], ey) if face.along_x else (s.center_m[0], ex)
        if along + half_along < lo_m or along - half_along > hi_m:
            continue
        if abs(across - face.line) - half_across < 0.1:
            return True
    return False


def _room_faces(faces: list[WallFace], room: Room, t: float) -> list[tuple[WallFace, float, float]]:
    """The faces looking into ``room``, each clipped to the room's inner span less 0.4 m a side
    (corners, and the casings and switches at doors, which are on the piece's ends)."""
    out = []
    (rx0, ry0), (rx1, ry1) = room.min_xy_m, room.max_xy_m
    for f in faces:
        probe = f.line + f.normal_sign * 0.05
        inside, (a, b) = ((ry0 < probe < ry1), (rx0, rx1)) if f.along_x else ((rx0 < probe < rx1), (ry0, ry1))
        if not inside:
            continue
        lo, hi = max(f.lo_m, a + t / 2) + 0.4, min(f.hi_m, b - t / 2) - 0.4
        if hi - lo > 0.3:
            out.append((f, lo, hi))
    return out


def add_decor(spec: mujoco.MjSpec, layout: Layout, rng: np.random.Generator, *, wall_height_m: float,
              poster_materials: list[str], trim_rgba, frame_rgbas: list) -> int:
    """Skirting on every inner wall face, casings and a switch at both faces of every door, and 0-3
    framed pictures a room (module docstring); returns how many geoms were added."""
    t = layout.wall_thickness_m
    faces = wall_faces(layout)
    count = 0
    skirting = float(rng.uniform(*SKIRTING_HEIGHT_RANGE_M))
    for k, f in enumerate(faces):
        _plane(spec, f"{DECOR_PRIM}/skirting_{k}", f, (f.lo_m + f.hi_m) / 2, skirting / 2, (f.hi_m - f.lo_m) / 2,
               skirting / 2, 0.001, rgba=trim_rgba)
        count += 1
    casing = float(rng.uniform(*CASING_WIDTH_RANGE_M))
    for k, door in enumerate(layout.doors):
        cx, cy = door.center_xy_m
        along, line = (cx, cy) if door.along_x else (cy, cx)
        for sign in (-1.0, 1.0):
            face = WallFace(line + sign * t / 2, along - 1.0, along + 1.0, door.along_x, sign)
            for side in (-1.0, 1.0):  # a casing either side of the opening
                _plane(spec, f"{DECOR_PRIM}/door_{k}/casing_{int(sign > 0)}{int(side > 0)}", face,
                       along + side * (door.width_m / 2 + casing / 2), wall_height_m / 2, casing / 2,
                       wall_height_m / 2, 0.002, rgba=trim_rgba)
            side = float(rng.choice([-1.0, 1.0]))  # the switch on the side the door opens to, drawn
            u = along + side * (door.width_m / 2 + casing + 0.06 + SWITCH_PLATE_M[0] / 2)
            plate = np.clip(np.asarray(trim_rgba[:3]) * rng.uniform(0.9, 1.05), 0, 1).tolist() + [1.0]
            _plane(spec, f"{DECOR_PRIM}/door_{k}/switch_{int(sign > 0)}", face, u, SWITCH_HEIGHT_M,
                   SWITCH_PLATE_M[0] / 2, SWITCH_PLATE_M[1] / 2, 0.002, rgba=plate)
            _plane(spec, f"{DECOR_PRIM}/door_{k}/switch_{int(sign > 0)}/rocker", face, u, SWITCH_HEIGHT_M, 0.015,
                   0.025, 0.003, rgba=[0.55, 0.55, 0.55, 1.0] if rng.random() < 0.5 else [0.95, 0.95, 0.93, 1.0])
            count += 4
    pictures, hung = 0, []  # (face, lo, hi) of the pictures so far
    for room in layout.rooms:
        candidates = _room_faces(faces, room, t)
        for _ in range(int(rng.integers(2, 6)) if candidates else 0):  # tries; some do not fit
            f, lo, hi = candidates[int(rng.integers(len(candidates)))]
            half_w, half_h = float(rng.uniform(0.15, 0.45)), float(rng.uniform(0.15, 0.4))
            if hi - lo < 2 * half_w:
                continue
            u = float(rng.uniform(lo + half_w, hi - half_w))
            z = float(rng.uniform(1.3, 1.65))
            if _near_solid(layout.solids, f, u - half_w, u + half_w, z - half_h) or \
                    any(g == f and a < u + half_w + 0.1 and u - half_w - 0.1 < b for g, a, b in hung):
                continue
            hung.append((f, u - half_w, u + half_w))
            border = float(rng.uniform(0.015, 0.04))
            name = f"{DECOR_PRIM}/{room.name}/picture_{pictures}"
            _plane(spec, name + "/frame", f, u, z, half_w + border, half_h + border, 0.001,
                   rgba=frame_rgbas[int(rng.integers(len(frame_rgbas)))])
            _plane(spec, name, f, u, z, half_w, half_h, 0.002,
                   material=poster_materials[int(rng.integers(len(poster_materials)))])
            pictures += 1
            count += 2
    return count


__all__ = ["DECOR_PRIM", "WallFace", "add_decor", "wall_faces"]
