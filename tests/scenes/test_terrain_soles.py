"""sphere_soles: feet resting on the terrain's heightfield get upward contacts on MuJoCo Warp.

MuJoCo Warp 4.0's box-heightfield collision gives a flat sole resting on flat ground contacts
that point down with ~the box's height as depth (humanoid-rough's robots fell on the GPU);
through the corner spheres every contact points up and is as deep as the foot sits."""

import mujoco
import numpy as np
import pytest

from ambulo import assets
from ambulo.robots import humanoid
from ambulo.scenes.terrain import TerrainCfg, add_terrain, generate, sphere_soles

FOOT = "foot"
HALF = (0.11, 0.045, 0.025)  # the humanoid's foot box, m
DEPTH_M = 0.0005  # how far each sole sits in the ground


def foot_on_terrain(spheres: bool) -> tuple[mujoco.MjModel, np.ndarray]:
    """A free humanoid foot box over a terrain of flat and stairs tiles (so the hfield's elevation
    and base are humanoid-rough's kind, not a degenerate all-zero field); the flat tile's centre."""
    grid = generate(TerrainCfg(kinds=("flat", "stairs_down"), num_levels=1, tile_size_m=4.0, border_m=0.5,
                               box_tiles=False))  # the hfield: box tiles are in test_terrain_boxes.py
    spec = mujoco.MjSpec()
    add_terrain(spec, grid)
    body = spec.worldbody.add_body(name="foot_body")
    body.add_freejoint()
    body.add_geom(name=FOOT, type=mujoco.mjtGeom.mjGEOM_BOX, size=list(HALF), pos=[0.03, 0.0, -0.045], mass=0.9,
                  contype=2, conaffinity=1)
    if spheres:
        sphere_soles(spec, (FOOT,), radius_m=0.02)
    return spec.compile(), grid.tile_centers_w[0, 0]


def test_spheres_keep_the_sole_plane_outline_and_mass():
    box, _ = foot_on_terrain(spheres=False)
    model, _ = foot_on_terrain(spheres=True)
    body = model.body("foot_body").id
    assert model.body_mass[body] == pytest.approx(box.body_mass[body])
    np.testing.assert_allclose(model.body_inertia[body], box.body_inertia[body])
    ids = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE]
    assert len(ids) == 4
    centres, radius = model.geom_pos[ids], model.geom_size[ids, 0]
    # lowest points on the sole (box bottom z = -0.045 - 0.025), outline at the box's corners
    np.testing.assert_allclose(centres[:, 2] - radius, -0.07, atol=1e-12)
    np.testing.assert_allclose(np.abs(centres[:, 0] - 0.03) + radius, HALF[0], atol=1e-12)
    np.testing.assert_allclose(np.abs(centres[:, 1]) + radius, HALF[1], atol=1e-12)
    foot = model.geom(FOOT).id
    assert model.geom_contype[foot] == 0 and model.geom_conaffinity[foot] == 0
    assert (model.geom_contype[ids] == 0).all() and (model.geom_conaffinity[ids] == 1).all()


def test_timeconst_sets_the_spheres_solref_only():
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_freejoint()
    box = body.add_geom(name=FOOT, type=mujoco.mjtGeom.mjGEOM_BOX, size=list(HALF), solref=[0.02, 1.0])
    names = sphere_soles(spec, (FOOT,), timeconst_s=0.01)
    model = spec.compile()
    np.testing.assert_allclose(model.geom_solref[[model.geom(n).id for n in names]], [[0.01, 1.0]] * 4)
    np.testing.assert_allclose(model.geom_solref[model.geom(FOOT).id], [0.02, 1.0])
    assert box.name == FOOT


def test_bad_geoms_are_refused():
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0])
    with pytest.raises(ValueError, match="not a box"):
        sphere_soles(spec, ("ball",))
    with pytest.raises(ValueError, match="not a box"):
        sphere_soles(spec, ("missing",))


def resting_feet(model: mujoco.MjModel, centre: np.ndarray, n: int) -> np.ndarray:
    """(n, 7) free-joint poses: the foot at random yaws and xy within 1.5 m of the flat tile's
    centre, its sole ``DEPTH_M`` into the ground (z = 0 on a flat tile)."""
    rng = np.random.default_rng(0)
    yaw = rng.uniform(-np.pi, np.pi, n)
    qpos = np.zeros((n, 7))
    qpos[:, :2] = centre[:2] + rng.uniform(-1.5, 1.5, (n, 2))
    qpos[:, 2] = 0.07 - DEPTH_M  # the body origin is 0.07 m above its sole
    qpos[:, 3], qpos[:, 6] = np.cos(yaw / 2), np.sin(yaw / 2)
    return qpos


def test_resting_feet_get_upward_contacts_on_the_cpu_engine():
    model, centre = foot_on_terrain(spheres=True)
    data = mujoco.MjData(model)
    for q in resting_feet(model, centre, 50):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        normals = data.contact.frame[:data.ncon, :3]
        assert data.ncon >= 4 and (normals[:, 2] > 0.9).all()
        dist = data.contact.dist[:data.ncon]  # a sphere over a prism's edge touches it less deep
        assert dist.min() == pytest.approx(-DEPTH_M, abs=1e-4) and (dist >= -DEPTH_M - 1e-4).all()


@pytest.mark.slow  # MuJoCo Warp on its CPU device: ~25 s of kernel compilation the first time
def test_resting_feet_get_upward_contacts_on_mujoco_warp():
    """200 resting feet: on the boxes MuJoCo Warp gave ~1 in 4 a downward contact ~5 cm deep."""
    mjw = pytest.importorskip("mujoco_warp")
    wp = pytest.importorskip("warp")
    model, centre = foot_on_terrain(spheres=True)
    n = 200
    qpos = resting_feet(model, centre, n)
    wp.init()
    with wp.ScopedDevice("cpu"):
        m = mjw.put_model(model)
        d = mjw.put_data(model, mujoco.MjData(model), nworld=n, nconmax=32, njmax=128)
        d.qpos = wp.array(qpos.astype(np.float32), dtype=float)
        mjw.kinematics(m, d)
        mjw.collision(m, d)
        count = int(d.nacon.numpy()[0])
        world = d.contact.worldid.numpy()[:count]
        normals = d.contact.frame.numpy()[:count].reshape(count, -1)[:, :3]
        dist = d.contact.dist.numpy()[:count]
    assert set(world.tolist()) == set(range(n))  # every foot touches
    assert (normals[:, 2] > 0.9).all(), f"{int((normals[:, 2] <= 0.9).sum())} contacts do not point up"
    assert (dist >= -DEPTH_M - 2e-4).all(), f"deepest contact {dist.min():.4f} m; the soles sit {DEPTH_M} m deep"


def test_humanoid_foot_box_matches_this_test():
    """The box above is the bundled humanoid's foot (so the test covers what the robot has)."""
    model = mujoco.MjModel.from_xml_path(assets.path(humanoid.ASSET))
    foot = model.geom("left_foot").id
    np.testing.assert_allclose(model.geom_size[foot], HALF)
    np.testing.assert_allclose(model.geom_pos[foot], [0.03, 0.0, -0.045])
