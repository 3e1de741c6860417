"""Box tiles (``scenes.terrain.boxes``): the boxes reproduce the height samples, the hfield sinks
under them, and a sphere resting on a flat or stairs tile gets exactly one contact, as deep as it
sits, in MuJoCo C and on MuJoCo Warp alike (MuJoCo C gave one per hfield prism it overlapped)."""

import dataclasses

import mujoco
import numpy as np
import pytest

from ambulo.scenes.terrain import TerrainCfg, add_terrain, generate, terrain_boxes
from ambulo.scenes.terrain.boxes import SUNK_M, box_mask, hfield_heights, rectangles

# 4 m tiles, 1 m platforms: 5 treads of 0.30 m a side; risers 0.05, 0.10, 0.15 m by level
CFG = TerrainCfg(num_levels=3, tile_size_m=4.0, platform_size_m=1.0, border_m=1.0,
                 kinds=("flat", "stairs_up", "stairs_down", "slope_down"))
RADIUS_M = 0.02  # the sole spheres'
DEPTH_M = 0.0005  # how far each sphere sits in the ground


@pytest.fixture(scope="module")
def grid():
    return generate(CFG)


def highest_top(boxes, x, y) -> np.ndarray:
    """(P,) the highest box top over each of the (P,) world points, m (-inf where none)."""
    lo, hi = boxes.center_w[:, :2] - boxes.half_size_m[:, :2], boxes.center_w[:, :2] + boxes.half_size_m[:, :2]
    inside = ((x[:, None] > lo[:, 0]) & (x[:, None] < hi[:, 0]) & (y[:, None] > lo[:, 1]) & (y[:, None] < hi[:, 1]))
    return np.where(inside, boxes.top_m, -np.inf).max(axis=1)


def test_rectangles_cover_a_frame_with_four():
    mask = np.ones((10, 12), dtype=bool)
    mask[3:7, 2:9] = False
    rects = rectangles(mask)
    assert len(rects) == 4
    cover = np.zeros(mask.shape, dtype=int)
    for ix, iy, lx, ly in rects:
        cover[ix:ix + lx, iy:iy + ly] += 1
    np.testing.assert_array_equal(cover, mask.astype(int))  # every cell once, none outside


def test_box_tops_are_the_height_samples(grid):
    """At every sample of a box tile or the border (tread centres, platforms, the samples next to
    each riser) the highest box over it tops at the sample's height; the slope tiles have none."""
    boxes = terrain_boxes(grid)
    h = grid.spacing_m
    nx, ny = grid.heights_m.shape
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    mask = box_mask(grid)
    # points near opposite corners of the square each sample owns (a riser half-way between samples)
    for off in ((0.45, -0.45), (-0.45, 0.45)):
        x = grid.origin_xy_m[0] + (ix.ravel() + off[0]) * h
        y = grid.origin_xy_m[1] + (iy.ravel() + off[1]) * h
        top = highest_top(boxes, x, y).reshape(nx, ny)
        np.testing.assert_allclose(top[mask], grid.heights_m[mask], atol=1e-9)
        assert np.isneginf(top[~mask]).all()
    slope = CFG.kinds.index("slope_down")
    assert not mask[tuple(np.round((grid.tile_centers_w[:, slope, :2] - grid.origin_xy_m) / h).astype(int).T)].any()
    # a summit's 5 steps are 5 stacked squares, a pit's 5 frames of 4; the height-0 slab a few
    assert len(boxes.top_m) <= CFG.num_levels * (5 + 5 * 4) + 30


def test_the_hfield_sinks_under_the_boxes_only(grid):
    mask = box_mask(grid)
    physics = hfield_heights(grid, mask)
    sunk = physics < grid.heights_m.min() - SUNK_M + 1e-9
    assert sunk.sum() > 0.9 * mask.sum()
    assert not (sunk & ~mask).any()
    np.testing.assert_array_equal(physics[~sunk], grid.heights_m[~sunk])  # slopes and seams as they were


def resting_spheres(grid, n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) centres of spheres resting ``DEPTH_M`` deep on one box top each: random points of
    box-tile samples whose 8 neighbours have the same height (treads, platforms, flat tiles: no
    riser within the radius), kept where the sphere's footprint lies inside one box's top (off the
    seams of coplanar boxes); half on the stairs tiles' treads, half anywhere."""
    heights, h = grid.heights_m, grid.spacing_m
    flat = box_mask(grid)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            flat[1:-1, 1:-1] &= heights[1 + dx:heights.shape[0] - 1 + dx, 1 + dy:heights.shape[1] - 1 + dy] \
                == heights[1:-1, 1:-1]
    flat[[0, -1], :] = flat[:, [0, -1]] = False
    rng = np.random.default_rng(seed)
    cells = np.argwhere(flat)
    stairs = cells[heights[tuple(cells.T)] != 0.0]
    pick = np.concatenate([stairs[rng.choice(len(stairs), 4 * n)], cells[rng.choice(len(cells), 4 * n)]])
    xy = grid.origin_xy_m + (pick + rng.uniform(-0.5, 0.5, size=pick.shape)) * h
    z = heights[tuple(pick.T)]
    boxes = terrain_boxes(grid)
    lo = boxes.center_w[:, :2] - boxes.half_size_m[:, :2] + RADIUS_M
    hi = boxes.center_w[:, :2] + boxes.half_size_m[:, :2] - RADIUS_M
    on_one = ((xy[:, None] > lo) & (xy[:, None] < hi)).all(-1) & (np.abs(boxes.top_m - z[:, None]) < 1e-9)
    keep = on_one.any(axis=1)
    keep_stairs, keep_any = np.flatnonzero(keep[:4 * n])[:n // 2], 4 * n + np.flatnonzero(keep[4 * n:])[:n - n // 2]
    rows = np.concatenate([keep_stairs, keep_any])
    assert rows.size == n
    return np.column_stack([xy[rows], z[rows] + RADIUS_M - DEPTH_M])


def spheres_on(grid) -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    for i in range(200):
        body = spec.worldbody.add_body(name=f"ball{i}")
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[RADIUS_M, 0, 0], mass=0.1, contype=0, conaffinity=1)
    return spec.compile()


def sphere_qpos(model, centres) -> np.ndarray:
    qpos = np.tile(model.qpos0, 1)
    qpos.reshape(-1, 7)[:, :3] = centres
    return qpos


def test_a_resting_sphere_gets_exactly_one_contact_on_the_cpu_engine(grid):
    model = spheres_on(grid)
    data = mujoco.MjData(model)
    data.qpos[:] = sphere_qpos(model, resting_spheres(grid, 200))
    mujoco.mj_forward(model, data)
    con = data.contact
    balls = np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_SPHERE)
    per_ball = np.bincount(np.maximum(con.geom1, con.geom2), minlength=model.ngeom)[balls]
    assert (per_ball == 1).all(), f"contacts per sphere: {np.bincount(per_ball).tolist()} (0, 1, 2, ...)"
    np.testing.assert_allclose(con.dist, -DEPTH_M, atol=1e-9)
    assert (np.abs(con.frame[:, 2]) > 1 - 1e-9).all()  # vertical (from the sphere or to it)
    assert all(model.geom_type[min(g1, g2)] == mujoco.mjtGeom.mjGEOM_BOX for g1, g2 in zip(con.geom1, con.geom2))
    stairs = np.abs(data.qpos.reshape(-1, 7)[:, 2] - RADIUS_M) > 0.01
    assert stairs.sum() >= 100  # half of them on treads off height 0


@pytest.mark.slow  # MuJoCo Warp on its CPU device: kernel compilation the first time
def test_mujoco_warp_gives_the_same_contacts(grid):
    mjw = pytest.importorskip("mujoco_warp")
    wp = pytest.importorskip("warp")
    model = spheres_on(grid)
    qpos = sphere_qpos(model, resting_spheres(grid, 200, seed=1))
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    wp.init()
    with wp.ScopedDevice("cpu"):
        m = mjw.put_model(model)
        d = mjw.put_data(model, mujoco.MjData(model), nworld=1, nconmax=512, njmax=2048)
        d.qpos = wp.array(qpos[None].astype(np.float32), dtype=float)
        mjw.kinematics(m, d)
        mjw.collision(m, d)
        count = int(d.nacon.numpy()[0])
        geoms = d.contact.geom.numpy()[:count]
        dist = d.contact.dist.numpy()[:count]
    assert count == data.ncon == 200
    cpu = {tuple(sorted(g)): c for g, c in zip(zip(data.contact.geom1, data.contact.geom2), data.contact.dist)}
    warp = {tuple(sorted(g)): c for g, c in zip(map(tuple, geoms), dist)}
    assert warp.keys() == cpu.keys()  # the same sphere on the same box
    np.testing.assert_allclose([warp[k] for k in cpu], list(cpu.values()), atol=2e-6)  # float32


def test_the_old_hfield_path_has_no_boxes(grid):
    old = generate(dataclasses.replace(CFG, box_tiles=False))
    spec = mujoco.MjSpec()
    add_terrain(spec, old)
    assert spec.compile().ngeom == 1
