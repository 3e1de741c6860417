"""``isaacgym.terrain_utils`` under ``ambulo run``: height-field terrain generators and their mesh.

legged_gym builds its rough terrain with these (``SubTerrain`` tiles filled by the generators,
then ``convert_heightfield_to_trimesh``) and hands the result to ``Gym.add_heightfield`` or
``Gym.add_triangle_mesh``. Heights are int16 multiples of ``vertical_scale`` (m) on a grid of
``horizontal_scale`` (m) cells, indexed ``[x, y]``, as in Isaac Gym; every generator adds to
``height_field_raw`` in place and returns the tile. Randomness draws from numpy's global
generator, so a script's ``np.random.seed`` makes the terrain repeatable.
"""

from __future__ import annotations

import numpy as np
from scipy import interpolate


class SubTerrain:
    """One tile: ``height_field_raw`` (width, length) int16, in units of ``vertical_scale``."""

    def __init__(self, terrain_name: str = "terrain", width: int = 256, length: int = 256,
                 vertical_scale: float = 1.0, horizontal_scale: float = 1.0):
        self.terrain_name = terrain_name
        self.vertical_scale = vertical_scale
        self.horizontal_scale = horizontal_scale
        self.width = width
        self.length = length
        self.height_field_raw = np.zeros((width, length), dtype=np.int16)


def _units(terrain: SubTerrain, height_m: float) -> int:
    return int(height_m / terrain.vertical_scale)


def _cells(terrain: SubTerrain, size_m: float) -> int:
    return int(size_m / terrain.horizontal_scale)


def random_uniform_terrain(terrain: SubTerrain, min_height: float, max_height: float, step: float = 1,
                           downsampled_scale: float | None = None) -> SubTerrain:
    """Random heights in [min_height, max_height] m, quantized to ``step`` m, drawn on a grid of
    ``downsampled_scale`` m cells and interpolated bilinearly onto the tile."""
    scale = downsampled_scale if downsampled_scale is not None else terrain.horizontal_scale
    levels = np.arange(_units(terrain, min_height), _units(terrain, max_height) + _units(terrain, step),
                       max(_units(terrain, step), 1))
    nx = max(int(terrain.width * terrain.horizontal_scale / scale), 2)
    ny = max(int(terrain.length * terrain.horizontal_scale / scale), 2)
    coarse = np.random.choice(levels, (nx, ny))
    xs, ys = np.linspace(0, terrain.width * terrain.horizontal_scale, nx), \
        np.linspace(0, terrain.length * terrain.horizontal_scale, ny)
    fine = interpolate.RegularGridInterpolator((xs, ys), coarse.astype(float))
    gx, gy = np.meshgrid(np.linspace(0, xs[-1], terrain.width), np.linspace(0, ys[-1], terrain.length), indexing="ij")
    terrain.height_field_raw += np.rint(fine(np.stack([gx, gy], -1))).astype(np.int16)
    return terrain


def sloped_terrain(terrain: SubTerrain, slope: float = 1) -> SubTerrain:
    """A plane rising along x with ``slope`` (m per m)."""
    x = np.arange(terrain.width)[:, None]
    rise = slope * terrain.horizontal_scale / terrain.vertical_scale
    terrain.height_field_raw += np.broadcast_to(rise * x, terrain.height_field_raw.shape).astype(np.int16)
    return terrain


def _pyramid_weight(n: int) -> np.ndarray:
    """0 at both edges, 1 at the centre, linear in between."""
    c = n // 2
    return (c - np.abs(c - np.arange(n))) / max(c, 1)


def pyramid_sloped_terrain(terrain: SubTerrain, slope: float = 1, platform_size: float = 1.0) -> SubTerrain:
    """A pyramid of ``slope`` (negative: a pit) with a flat ``platform_size`` m square on top."""
    w = _pyramid_weight(terrain.width)[:, None] * _pyramid_weight(terrain.length)[None, :]
    peak = slope * terrain.horizontal_scale * terrain.width / 2 / terrain.vertical_scale
    terrain.height_field_raw += (peak * w).astype(np.int16)
    half = _cells(terrain, platform_size) // 2
    edge = terrain.height_field_raw[terrain.width // 2 - half, terrain.length // 2 - half]
    np.clip(terrain.height_field_raw, min(edge, 0), max(edge, 0), out=terrain.height_field_raw)
    return terrain


def discrete_obstacles_terrain(terrain: SubTerrain, max_height: float, min_size: float, max_size: float,
                               num_rects: int, platform_size: float = 1.0) -> SubTerrain:
    """``num_rects`` boxes of random size (``min_size``..``max_size`` m) and height (+-max_height,
    +-max_height / 2) at random places, and a flat platform in the middle."""
    h = _units(terrain, max_height)
    heights = [-h, -h // 2, h // 2, h]
    sizes = np.arange(_cells(terrain, min_size), _cells(terrain, max_size), 4)
    for _ in range(num_rects):
        sx, sy = np.random.choice(sizes), np.random.choice(sizes)
        x, y = np.random.randint(0, max(terrain.width - sx, 1)), np.random.randint(0, max(terrain.length - sy, 1))
        terrain.height_field_raw[x:x + sx, y:y + sy] = np.random.choice(heights)
    _flat_platform(terrain, platform_size)
    return terrain


def wave_terrain(terrain: SubTerrain, num_waves: int = 1, amplitude: float = 1.0) -> SubTerrain:
    """Sine waves along x and y, ``amplitude`` m."""
    if num_waves > 0:
        k = 2 * np.pi * num_waves / terrain.width
        x, y = np.arange(terrain.width)[:, None], np.arange(terrain.length)[None, :]
        a = _units(terrain, amplitude)
        terrain.height_field_raw += (a * np.cos(k * y) + a * np.sin(k * x)).astype(np.int16)
    return terrain


def stairs_terrain(terrain: SubTerrain, step_width: float, step_height: float) -> SubTerrain:
    """Steps ``step_width`` m deep rising ``step_height`` m each along x."""
    w = max(_cells(terrain, step_width), 1)
    steps = np.arange(terrain.width) // w
    terrain.height_field_raw += (steps * _units(terrain, step_height))[:, None].astype(np.int16)
    return terrain


def pyramid_stairs_terrain(terrain: SubTerrain, step_width: float, step_height: float,
                           platform_size: float = 1.0) -> SubTerrain:
    """Concentric square steps (``step_height`` m each, negative: down) up to a flat platform."""
    w, dh = max(_cells(terrain, step_width), 1), _units(terrain, step_height)
    x0, x1, y0, y1, height = 0, terrain.width, 0, terrain.length, 0
    while x1 - x0 > _cells(terrain, platform_size) and y1 - y0 > _cells(terrain, platform_size):
        x0, x1, y0, y1 = x0 + w, x1 - w, y0 + w, y1 - w
        height += dh
        terrain.height_field_raw[x0:x1, y0:y1] = height
    return terrain


def stepping_stones_terrain(terrain: SubTerrain, stone_size: float, stone_distance: float, max_height: float,
                            platform_size: float = 1.0, depth: float = -10) -> SubTerrain:
    """Square stones ``stone_size`` m wide, ``stone_distance`` m apart, random heights up to
    ``max_height`` m, over a pit ``depth`` m deep; a flat platform in the middle."""
    size, gap = max(_cells(terrain, stone_size), 1), _cells(terrain, stone_distance)
    h = _units(terrain, max_height)
    levels = np.arange(-h - 1, h, step=1)
    terrain.height_field_raw[:, :] = _units(terrain, depth)
    for x in range(0, terrain.width, size + gap):
        offset = np.random.randint(0, size)
        for y in range(-offset, terrain.length, size + gap):
            terrain.height_field_raw[x:x + size, max(y, 0):y + size] = np.random.choice(levels)
    _flat_platform(terrain, platform_size)
    return terrain


def _flat_platform(terrain: SubTerrain, platform_size: float) -> None:
    half = _cells(terrain, platform_size) // 2
    cx, cy = terrain.width // 2, terrain.length // 2
    terrain.height_field_raw[max(cx - half, 0):cx + half, max(cy - half, 0):cy + half] = 0


def convert_heightfield_to_trimesh(height_field_raw: np.ndarray, horizontal_scale: float, vertical_scale: float,
                                   slope_threshold: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The height field as a triangle mesh: vertices (rows * cols, 3) float32 m, vertex ``[i, j]``
    at ``(i * horizontal_scale, j * horizontal_scale, h[i, j] * vertical_scale)``, and triangles
    (2 (rows - 1)(cols - 1), 3) uint32, two per cell, counter-clockwise seen from above.

    With ``slope_threshold`` (rise per run), a vertex at the foot of a slope steeper than that is
    moved under the top of the slope, so steep slopes become vertical walls (stairs' risers)."""
    hf = np.asarray(height_field_raw)
    rows, cols = hf.shape
    xx, yy = np.meshgrid(np.arange(rows, dtype=float), np.arange(cols, dtype=float), indexing="ij")
    if slope_threshold is not None:
        threshold = slope_threshold * horizontal_scale / vertical_scale
        move_x, move_y = np.zeros_like(xx), np.zeros_like(yy)
        step_x = (hf[1:, :] - hf[:-1, :]).astype(float)
        step_y = (hf[:, 1:] - hf[:, :-1]).astype(float)
        move_x[:-1, :] += step_x > threshold   # the next cell is much higher: move this vertex up to it
        move_x[1:, :] -= step_x < -threshold   # the previous cell is much higher: move this vertex back to it
        move_y[:, :-1] += step_y > threshold
        move_y[:, 1:] -= step_y < -threshold
        xx, yy = xx + move_x, yy + move_y
    vertices = np.stack([xx * horizontal_scale, yy * horizontal_scale, hf * vertical_scale], -1)
    vertices = vertices.reshape(-1, 3).astype(np.float32)
    corner = (np.arange(rows - 1)[:, None] * cols + np.arange(cols - 1)[None, :]).reshape(-1)
    a, b, c, d = corner, corner + cols, corner + 1, corner + cols + 1  # [i,j], [i+1,j], [i,j+1], [i+1,j+1]
    triangles = np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)])
    return vertices, triangles.astype(np.uint32)


__all__ = ["SubTerrain", "convert_heightfield_to_trimesh", "discrete_obstacles_terrain", "pyramid_sloped_terrain",
           "pyramid_stairs_terrain", "random_uniform_terrain", "sloped_terrain", "stairs_terrain",
           "stepping_stones_terrain", "wave_terrain"]
