"""Stepping stones as boxes (``TerrainCfg.box_kinds`` with ``stepping_stones``): the boxes reproduce
the stone tiles' height samples and stay solid down to the pit, a sphere resting on a stone gets
exactly one contact on MuJoCo C (the hfield gives some two or more), and the height samples and
scans, the one truth for observations, are the same bytes with the option on and off."""

import dataclasses

import mujoco
import numpy as np
import pytest
import torch

from ambulo.scenes.terrain import HeightScan, HeightScanCfg, TerrainCfg, TerrainHeights, add_terrain, generate
from ambulo.scenes.terrain.boxes import box_mask, terrain_boxes

# 4 m tiles, 1 m platforms, 3 levels: stones 0.8 -> 0.4 m, gaps 0.05 -> 0.20 m, pits 0.5 m deep
OFF = TerrainCfg(num_levels=3, tile_size_m=4.0, platform_size_m=1.0, border_m=1.0,
                 kinds=("flat", "stepping_stones", "rough"))
ON = dataclasses.replace(OFF, box_kinds=(*OFF.box_kinds, "stepping_stones"))
RADIUS_M = 0.02  # the sole spheres'
DEPTH_M = 0.0005  # how far each sphere sits in the ground


def stone_samples(grid) -> np.ndarray:
    """(nx, ny) bool: samples of the stepping-stone tiles."""
    out = np.zeros(grid.heights_m.shape, dtype=bool)
    for i in range(grid.cfg.num_levels):
        out[grid.cfg.tile_slices(i, grid.cfg.kinds.index("stepping_stones"))] = True
    return out


def sample_points(grid, off: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """World (x, y) of every sample shifted by ``off`` spacings: near a corner of its square."""
    nx, ny = grid.heights_m.shape
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    return (grid.origin_xy_m[0] + (ix.ravel() + off[0]) * grid.spacing_m,
            grid.origin_xy_m[1] + (iy.ravel() + off[1]) * grid.spacing_m)


def over(boxes, x, y) -> np.ndarray:
    """(P, B) bool: which boxes lie over each world point."""
    lo, hi = boxes.center_w[:, :2] - boxes.half_size_m[:, :2], boxes.center_w[:, :2] + boxes.half_size_m[:, :2]
    return (x[:, None] > lo[:, 0]) & (x[:, None] < hi[:, 0]) & (y[:, None] > lo[:, 1]) & (y[:, None] < hi[:, 1])


def solid_down_to(boxes, inside: np.ndarray) -> np.ndarray:
    """(P,) how far down the boxes over each point are solid without a gap from the highest top, m."""
    bottom = boxes.center_w[:, 2] - boxes.half_size_m[:, 2]
    z = np.where(inside, boxes.top_m, -np.inf).max(axis=1)
    while True:  # step down through every box whose top reaches the solid part so far
        reach = inside & (boxes.top_m[None] >= z[:, None] - 1e-9)
        lower = np.where(reach, bottom, np.inf).min(axis=1)
        if (lower >= z).all():
            return z
        z = np.minimum(z, lower)


def test_stone_box_tops_are_the_height_samples():
    grid = generate(ON)
    boxes, mask = terrain_boxes(grid), box_mask(grid)
    stones = stone_samples(grid)
    assert mask[stones].all() and not box_mask(generate(OFF))[stones].any()
    for off in ((0.45, -0.45), (-0.45, 0.45)):  # opposite corners of each sample's square: a stone's
        inside = over(boxes, *sample_points(grid, off))  # side is half-way between two samples
        top = np.where(inside, boxes.top_m, -np.inf).max(axis=1).reshape(grid.heights_m.shape)
        np.testing.assert_allclose(top[mask], grid.heights_m[mask], atol=1e-9)
    assert set(np.unique(grid.heights_m[stones])) == {0.0, -ON.stone_pit_depth_m}  # stones and pits both met


@pytest.mark.parametrize("pit_m", [0.5, 1.2])
def test_stones_are_solid_down_to_the_pit(pit_m):
    """Under every stone sample the boxes reach the pit's floor without a gap (a pit deeper than
    the 0.5 m slab left the stones hanging over a hollow a foot could slide into)."""
    grid = generate(dataclasses.replace(ON, stone_pit_depth_m=pit_m))
    boxes = terrain_boxes(grid)
    on_stone = (stone_samples(grid) & (grid.heights_m == 0.0)).ravel()
    x, y = sample_points(grid, (0.3, 0.3))
    inside = over(boxes, x[on_stone], y[on_stone])
    assert (solid_down_to(boxes, inside) <= -pit_m - 0.4).all()


def resting_spheres(grid, n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) centres of spheres resting ``DEPTH_M`` deep on stones (off the tiles' centre
    platforms): random points of stone samples whose 8 neighbours are stone too, kept where the
    sphere's footprint lies inside one box's top (off the slab's seams)."""
    heights, h = grid.heights_m, grid.spacing_m
    flat = stone_samples(grid) & (heights == 0.0)
    for i in range(grid.cfg.num_levels):  # not the platforms: those are flat ground, boxes already
        xs, ys = grid.cfg.tile_slices(i, grid.cfg.kinds.index("stepping_stones"))
        c, r = (xs.start + xs.stop) // 2, int(round(grid.cfg.platform_size_m / (2 * h))) + 2
        flat[c - r:c + r + 1, (ys.start + ys.stop) // 2 - r:(ys.start + ys.stop) // 2 + r + 1] = False
    interior = flat.copy()
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            interior[1:-1, 1:-1] &= flat[1 + dx:flat.shape[0] - 1 + dx, 1 + dy:flat.shape[1] - 1 + dy]
    rng = np.random.default_rng(seed)
    cells = np.argwhere(interior)
    pick = cells[rng.choice(len(cells), 4 * n)]
    xy = grid.origin_xy_m + (pick + rng.uniform(-0.5, 0.5, size=pick.shape)) * h
    boxes = terrain_boxes(grid)
    lo = boxes.center_w[:, :2] - boxes.half_size_m[:, :2] + RADIUS_M
    hi = boxes.center_w[:, :2] + boxes.half_size_m[:, :2] - RADIUS_M
    keep = np.flatnonzero((((xy[:, None] > lo) & (xy[:, None] < hi)).all(-1) & (boxes.top_m == 0.0)).any(1))[:n]
    assert keep.size == n
    return np.column_stack([xy[keep], np.full(n, RADIUS_M - DEPTH_M)])


def contacts_per_sphere(cfg: TerrainCfg, centres: np.ndarray) -> np.ndarray:
    """(n,) MuJoCo C's contacts on each sphere of ``centres`` (n, 3) over ``cfg``'s terrain."""
    spec = mujoco.MjSpec()
    add_terrain(spec, generate(cfg))
    for i in range(len(centres)):
        body = spec.worldbody.add_body(name=f"ball{i}")
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[RADIUS_M, 0, 0], mass=0.1, contype=0, conaffinity=1)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos.reshape(-1, 7)[:, :3] = centres
    mujoco.mj_forward(model, data)
    balls = np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_SPHERE)
    con = data.contact
    return np.bincount(np.maximum(con.geom1, con.geom2), minlength=model.ngeom)[balls]


def test_a_sphere_resting_on_a_stone_gets_one_contact_on_the_cpu_engine():
    centres = resting_spheres(generate(ON), 200)  # on the stones the option builds as boxes
    on, off = contacts_per_sphere(ON, centres), contacts_per_sphere(OFF, centres)
    assert (on == 1).all(), f"stones as boxes, contacts per sphere: {np.bincount(on).tolist()} (0, 1, 2, ...)"
    assert (off >= 1).all() and (off > 1).sum() > 20  # the hfield: one per prism overlapped


def test_heights_and_scans_are_the_same_bytes_with_stones_as_boxes():
    """The samples (scans, spawns, planners read them) do not depend on how physics builds the
    stones, not even after ``add_terrain`` has built the boxes and the sunk hfield."""
    grids = {}
    for name, cfg in (("off", OFF), ("on", ON)):
        grid = generate(cfg)
        add_terrain(mujoco.MjSpec(), grid)
        grids[name] = grid
    assert grids["on"].heights_m.tobytes() == grids["off"].heights_m.tobytes()
    assert grids["on"].tile_centers_w.tobytes() == grids["off"].tile_centers_w.tobytes()
    # bases over every stone tile at random yaws, 0.9 m up: each scan's 187 points
    gen = torch.Generator().manual_seed(0)
    centres = torch.as_tensor(grids["on"].tile_centers_w[:, OFF.kinds.index("stepping_stones")], dtype=torch.float32)
    root = centres.repeat(8, 1) + torch.cat([torch.rand(8 * OFF.num_levels, 2, generator=gen) * 3 - 1.5,
                                             torch.full((8 * OFF.num_levels, 1), 0.9)], dim=-1)
    yaw = torch.rand(root.shape[0], generator=gen) * 6.28
    scans = {k: HeightScan(HeightScanCfg(), TerrainHeights(g, "cpu")).scan(root, yaw) for k, g in grids.items()}
    assert scans["on"].numpy().tobytes() == scans["off"].numpy().tobytes()
    assert scans["on"].max() > 0.3  # the scans see pits (the ground 0.5 m lower)


def test_box_tiles_off_is_all_hfield_whatever_box_kinds():
    """``terrain.box_tiles=false`` (older runs' setting) still builds the one hfield alone."""
    spec = mujoco.MjSpec()
    add_terrain(spec, generate(dataclasses.replace(ON, box_tiles=False)))
    assert spec.compile().ngeom == 1
