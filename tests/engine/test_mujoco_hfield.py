"""engine.mujoco_hfield: MuJoCo C's heightfield contacts reduced to MuJoCo Warp's.

2 cm spheres rest 0.5-15 mm deep (centre above the ground) at random spots of humanoid-rough's
hfield tiles (rough, slopes, stepping stones): MuJoCo C keeps a contact per prism a sphere
overlaps, Warp at most 4 of them; reduced, MuJoCo C's contacts are Warp's (count, depth, point).
A sphere sunk past its centre gets Warp's depth limit: no contact deeper, the deep ones up."""

import mujoco
import numpy as np
import pytest

from ambulo.engine.mujoco_hfield import MAX_CONTACTS, reduce_hfield_contacts
from ambulo.scenes.terrain import TerrainCfg, generate
from hfield_contacts import mujoco_contacts, warp_contacts
from terrain_ball import ball_over_terrain

RADIUS_M = 0.02
LIMIT_M = 0.02


@pytest.fixture(autouse=True)
def mujoco_own_contacts():
    """The reduction is process-wide: every test starts and ends with MuJoCo's own."""
    reduce_hfield_contacts(None, enabled=False)
    yield
    reduce_hfield_contacts(None, enabled=False)


def spheres(n: int, depth_range_m: tuple[float, float], seed: int = 0,
            kinds: tuple[str, ...] = ("rough", "slope_up", "slope_down", "stepping_stones")):
    """A free 2 cm sphere over hfield tiles; (n, 7) poses at random spots, its lowest point this
    deep under the ground below its centre."""
    grid = generate(TerrainCfg(kinds=kinds, num_levels=2, box_tiles=False))
    model = ball_over_terrain(grid, RADIUS_M)
    rng = np.random.default_rng(seed)
    low = grid.origin_xy_m + grid.cfg.border_m
    high = low + np.array([grid.num_levels, grid.num_kinds]) * grid.cfg.tile_size_m
    xy = rng.uniform(low, high, (n, 2))
    qpos = np.zeros((n, 7))
    qpos[:, :2], qpos[:, 2], qpos[:, 3] = xy, ground_m(model, xy) + RADIUS_M - rng.uniform(*depth_range_m, n), 1.0
    return model, qpos


def ground_m(model, xy: np.ndarray) -> np.ndarray:
    """The hfield's height under (n, 2) points, m, by MuJoCo's ray (its triangles, which the
    grid's bilinear lookup matches only where a cell is planar)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    hit = np.zeros(1, np.int32)
    return np.array([10.0 - mujoco.mj_ray(model, data, np.array([x, y, 10.0]), np.array([0.0, 0.0, -1.0]),
                                          None, 1, -1, hit) for x, y in xy])


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """One pose's contacts agree: count, depth within 20 um, point within 0.1 mm (Warp: float32)."""
    return a.shape == b.shape and np.allclose(a[:, 0], b[:, 0], atol=2e-5) and np.allclose(a[:, 1:], b[:, 1:], atol=1e-4)


@pytest.mark.parametrize("compiled", [True, False], ids=["numba", "python"])
def test_reduced_contacts_of_resting_spheres_are_warps(compiled):
    if compiled:
        pytest.importorskip("numba")
    # not stepping stones: against a stone's steep edge Warp's EPA misfires already 1.5 cm deep
    # (its contacts there are limited), which no reduction of MuJoCo C's true contacts reproduces
    model, qpos = spheres(300, (0.0005, 0.015), kinds=("rough", "slope_up", "slope_down"))
    warp = warp_contacts(model, qpos, LIMIT_M)
    own = mujoco_contacts(model, qpos)
    reduce_hfield_contacts(LIMIT_M, compiled=compiled)
    reduced = mujoco_contacts(model, qpos)
    assert all(len(w) >= 1 for w in warp)  # every sphere touches
    agree_own = np.mean([same(a, b) for a, b in zip(own, warp, strict=True)])
    agree = np.mean([same(a, b) for a, b in zip(reduced, warp, strict=True)])
    # MuJoCo's own: more contacts than Warp wherever a sphere overlaps more than 4 prisms or
    # overlaps prisms at one point (Warp keeps one of those)
    assert max(len(a) for a in own) > MAX_CONTACTS and agree_own < 0.8, agree_own
    assert agree >= 0.97, agree
    assert max(len(a) for a in reduced) <= MAX_CONTACTS


@pytest.mark.parametrize("compiled", [True, False], ids=["numba", "python"])
def test_spheres_sunk_past_their_centre_get_warps_depth_limit_pointing_up(compiled):
    if compiled:
        pytest.importorskip("numba")
    model, qpos = spheres(100, (0.025, 0.04), seed=1)
    reduce_hfield_contacts(LIMIT_M, compiled=compiled)
    data = mujoco.MjData(model)
    deep = 0
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        contacts = data.contact[:data.ncon]
        assert 1 <= len(contacts) <= MAX_CONTACTS
        for c in contacts:
            assert c.dist >= -LIMIT_M - 1e-12
            if c.dist <= -LIMIT_M + 1e-12:
                deep += 1
                np.testing.assert_allclose(c.frame[:3], [0.0, 0.0, 1.0], atol=1e-12)
                np.testing.assert_allclose(c.pos, q[:3], atol=1e-12)  # at the sphere's centre
    assert deep >= 50  # the limit was used


def test_off_gives_mujocos_own_contacts_back():
    model, qpos = spheres(50, (0.0005, 0.015), seed=2)
    own = mujoco_contacts(model, qpos)
    reduce_hfield_contacts(LIMIT_M)
    reduce_hfield_contacts(None, enabled=False)
    again = mujoco_contacts(model, qpos)
    assert all(np.array_equal(a, b) for a, b in zip(own, again, strict=True))


def test_the_limit_takes_a_positive_depth_or_none():
    with pytest.raises(ValueError, match="depth > 0"):
        reduce_hfield_contacts(-0.01)
