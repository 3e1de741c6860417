"""Terrain: heights equal the hand-computed shapes, in the generator, on the device and in MuJoCo's
hfield; a body dropped on a stair rests on its tread; the height scan reads the right points."""

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo.scenes.terrain import HeightScan, HeightScanCfg, TerrainCfg, TerrainHeights, add_terrain, generate

# 4 m tiles, 1 m platforms, 0.30 m treads at 5 cm: (2.0 - 0.5) / 0.30 = 5 whole steps per side
CFG = TerrainCfg(num_levels=3, tile_size_m=4.0, platform_size_m=1.0, border_m=1.0,
                 kinds=("flat", "stairs_up", "stairs_down", "slope_down"))
RISERS_M = (0.05, 0.10, 0.15)  # levels 0, 1, 2 of stair_riser_range_m (0.05, 0.15)


@pytest.fixture(scope="module")
def grid():
    return generate(CFG)


def stair_points(grid, level, kind):
    """(x, y, expected height) on the treads of one stairs tile, walking out along +x from the
    centre: tread k from the edge spans [k, k+1) * 0.30 m from the edge; the platform is tread 5."""
    cx, cy, _ = grid.tile_centers_w[level, kind]
    sign = 1.0 if CFG.kinds[kind] == "stairs_down" else -1.0
    points = [(cx, cy, 5 * RISERS_M[level] * sign)]
    for k in range(5):
        from_edge = (k + 0.5) * 0.30  # the middle of tread k
        points.append((cx + 2.0 - from_edge, cy + 0.1, k * RISERS_M[level] * sign))
    return points


@pytest.mark.parametrize("level", [0, 2])
@pytest.mark.parametrize("kind", [1, 2])
def test_stair_heights_are_the_hand_computed_steps(grid, level, kind):
    points = stair_points(grid, level, kind)
    xy = np.array([(x, y) for x, y, _ in points])
    expected = np.array([z for _, _, z in points])
    np.testing.assert_allclose(grid.height_at(xy[:, 0], xy[:, 1]), expected, atol=1e-9)
    on_device = TerrainHeights(grid, "cpu").height_at(torch.as_tensor(xy))
    np.testing.assert_allclose(on_device.numpy(), expected, atol=1e-5)
    # MuJoCo's hfield (what the physics collides with): a ray straight down
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom = np.zeros(1, np.int32)
    for (x, y), z in zip(xy, expected):
        dist = mujoco.mj_ray(model, data, np.array([x, y, 5.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)
        assert 5.0 - dist == pytest.approx(z, abs=1e-5)


def test_device_heights_match_the_generator_everywhere():
    """Bilinear on the device equals the host's bilinear at random points over rough tiles
    (heights vary along x and y there) and beyond the grid (the border's edge)."""
    grid = generate(TerrainCfg(num_levels=2, tile_size_m=2.0, platform_size_m=0.4, border_m=0.5,
                               kinds=("rough", "slope_up")))
    rng = np.random.default_rng(0)
    xy = rng.uniform(-4.0, 4.0, size=(2000, 2))
    device = TerrainHeights(grid, "cpu").height_at(torch.as_tensor(xy)).numpy()
    np.testing.assert_allclose(device, grid.height_at(xy[:, 0], xy[:, 1]), atol=1e-5)
    assert np.ptp(device) > 0.05


def test_the_hardest_stairs_have_the_issues_risers(grid):
    heights = [z for _, _, z in stair_points(grid, 2, 2)]
    assert np.diff(sorted(heights)) == pytest.approx([0.15] * 5)


def test_tiles_meet_at_height_zero_and_centres_sit_on_platforms(grid):
    for level in range(CFG.num_levels):
        for kind in range(len(CFG.kinds)):
            cx, cy, cz = grid.tile_centers_w[level, kind]
            assert grid.height_at(cx, cy) == pytest.approx(cz)
            assert grid.height_at(cx - 2.0, cy) == pytest.approx(0.0, abs=1e-9)  # the tile's edge
            # the platform is flat: 0.4 m off the centre reads the centre's height
            assert grid.height_at(cx + 0.4, cy - 0.4) == pytest.approx(cz)


def test_a_box_dropped_on_a_stair_rests_on_its_tread(grid):
    """Physics: a 0.2 m box released 0.3 m above tread 2 of the hardest stairs-down tile settles
    with its bottom on the tread (0.30 m up), not on the tread below or the summit."""
    x, y, tread_z = stair_points(grid, 2, 2)[3]
    assert tread_z == pytest.approx(0.30)
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.002
    add_terrain(spec, grid)
    body = spec.worldbody.add_body(name="box", pos=[x, y, tread_z + 0.1 + 0.3])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1], mass=2.0)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=1000)  # 2 s
    assert data.qpos[2] - 0.1 == pytest.approx(tread_z, abs=3e-3)
    assert np.abs(data.qvel).max() < 1e-2


def test_height_scan_reads_the_slope_under_rotated_points(grid):
    """On a pyramid slope, heights are linear in the distance from the edge: a point 0.8 m ahead
    of a base facing +y at the tile centre lies 0.8 m along +y, on the platform's edge or the slope."""
    heights = TerrainHeights(grid, "cpu")
    scan = HeightScan(HeightScanCfg(length_m=1.6, width_m=0.0, resolution_m=0.8), heights)
    cx, cy, cz = grid.tile_centers_w[2, 3]
    root = torch.tensor([[cx, cy, cz + 0.5]])  # readings under the 1 m clip
    readings = scan.scan(root, torch.tensor([math.pi / 2]))
    points = scan.points_w(root, torch.tensor([math.pi / 2]))[0]
    np.testing.assert_allclose(points.numpy(), [[cx, cy - 0.8], [cx, cy], [cx, cy + 0.8]], atol=1e-5)
    expected = root[0, 2] - torch.as_tensor(grid.height_at(points[:, 0].numpy(), points[:, 1].numpy()))
    np.testing.assert_allclose(readings[0].numpy(), expected.numpy(), atol=1e-5)
    # 0.8 m off the centre is 1.2 m from the edge, below the 1.5 m platform edge: grade 0.3
    assert readings[0, 2].item() == pytest.approx(0.5 + 0.3 * (1.5 - 1.2), abs=1e-5)


def test_unknown_kinds_are_named():
    with pytest.raises(ValueError, match="unknown \\['stairs'\\]"):
        TerrainCfg(kinds=("stairs",))
