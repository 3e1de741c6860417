"""engine.warp_hfield: MuJoCo Warp's heightfield contacts limited to a depth.

A 2 cm sphere sunk past its radius into humanoid-rough's terrain gets contacts metres deep with
sideways normals from MuJoCo Warp 4.0 (MuJoCo's CPU collision: the true 2-4 cm); with the limit
every terrain contact is at most the limit deep and the deep ones point up, from the sphere
(misfired contact points lay 0.2-3 m off it)."""

import mujoco
import numpy as np
import pytest

from ambulo.scenes.terrain import TerrainCfg, generate
from terrain_ball import ball_over_terrain

mjw = pytest.importorskip("mujoco_warp")
wp = pytest.importorskip("warp")

RADIUS_M = 0.02
LIMIT_M = 0.02


def sunk_spheres(n: int) -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
    """A free 2 cm sphere over humanoid-rough's terrain; (n, 7) poses at random spots with it
    2.5-4 cm deep (its centre under the surface: where Warp misfires), and each pose's depth, m."""
    grid = generate(TerrainCfg(box_tiles=False))  # all hfield: box tiles' contacts are analytic and unlimited
    model = ball_over_terrain(grid, RADIUS_M)
    rng = np.random.default_rng(0)
    low = grid.origin_xy_m + 0.5
    high = grid.origin_xy_m + (np.array(grid.heights_m.shape) - 1) * grid.spacing_m - 0.5
    xy = rng.uniform(low, high, (n, 2))
    # the highest ground under the sphere's footprint, so it is at least this deep everywhere
    ground = np.max([grid.height_at(xy[:, 0] + dx, xy[:, 1] + dy)
                     for dx in (-RADIUS_M, 0, RADIUS_M) for dy in (-RADIUS_M, 0, RADIUS_M)], axis=0)
    depth = rng.uniform(0.025, 0.04, n)
    qpos = np.zeros((n, 7))
    qpos[:, :2], qpos[:, 2], qpos[:, 3] = xy, ground + RADIUS_M - depth, 1.0
    return model, qpos, depth


def warp_contacts(model, qpos) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each contact's depth (dist, m), normal z and distance from its sphere's centre (m) after
    MuJoCo Warp's forward pass on its CPU device."""
    wp.init()
    with wp.ScopedDevice("cpu"):
        m = mjw.put_model(model)
        d = mjw.put_data(model, mujoco.MjData(model), nworld=len(qpos), nconmax=64, njmax=256)
        d.qpos = wp.array(qpos.astype(np.float32), dtype=float)
        mjw.forward(m, d)
        count = int(d.nacon.numpy()[0])
        world, pos = d.contact.worldid.numpy()[:count], d.contact.pos.numpy()[:count]
        off_centre = np.linalg.norm(pos - qpos[world, :3], axis=1)
        return d.contact.dist.numpy()[:count], d.contact.frame.numpy()[:count].reshape(count, -1)[:, 2], off_centre


@pytest.fixture
def depth_limit():
    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    limit_hfield_contact_depth(LIMIT_M)
    yield
    limit_hfield_contact_depth(None)


def test_warp_misfires_on_spheres_sunk_past_their_radius():
    """What the limit is for (fails once MuJoCo Warp gets this right: then drop the limit)."""
    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    limit_hfield_contact_depth(None)
    model, qpos, _ = sunk_spheres(300)
    dist, _, off_centre = warp_contacts(model, qpos)
    assert dist.min() < -0.2  # metres deep, for a sphere 4 cm deep at most
    assert off_centre.max() > 0.2  # and far from the sphere


def test_limited_contacts_are_at_most_the_limit_deep_and_the_deep_ones_point_up(depth_limit):
    model, qpos, _ = sunk_spheres(300)
    dist, normal_z, off_centre = warp_contacts(model, qpos)
    assert len(dist) >= 300  # every sphere touches
    assert dist.min() >= -LIMIT_M - 1e-6
    deep = dist <= -LIMIT_M + 1e-6
    assert deep.sum() > 50  # the limit was used (the spheres sit 2.5-4 cm deep) ...
    np.testing.assert_allclose(normal_z[deep], 1.0, atol=1e-5)  # ... pushing them up out of the ground
    assert off_centre.max() <= RADIUS_M + 0.01  # every contact at its sphere (the limited ones at its centre)


def test_the_limit_takes_a_positive_depth_or_none():
    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    with pytest.raises(ValueError, match="depth > 0"):
        limit_hfield_contact_depth(0.0)
