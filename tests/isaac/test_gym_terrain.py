"""Isaac Gym terrain (legged_gym's rough ground): add_heightfield and add_triangle_mesh as MuJoCo
height fields that a robot stands on at the right height."""

import mujoco
import numpy as np
import pytest

from ambulo.isaac.gym import gymapi, gymtorch, terrain_utils

BOX = """<mujoco><worldbody><body name="box"><freejoint/>
  <geom type="box" size="0.05 0.05 0.05" mass="1"/></body></worldbody></mujoco>"""
H_SCALE, V_SCALE = 0.1, 0.005


def _samples() -> np.ndarray:
    tile = terrain_utils.SubTerrain("t", width=40, length=30, vertical_scale=V_SCALE, horizontal_scale=H_SCALE)
    return terrain_utils.pyramid_stairs_terrain(tile, step_width=0.5, step_height=0.1, platform_size=1.0).height_field_raw


def _sim(tmp_path, add_terrain):
    (tmp_path / "box.xml").write_text(BOX)
    gym = gymapi.acquire_gym()
    params = gymapi.SimParams()
    params.up_axis, params.gravity, params.dt = gymapi.UP_AXIS_Z, gymapi.Vec3(0.0, 0.0, -9.81), 0.005
    sim = gym.create_sim(0, -1, gymapi.SIM_PHYSX, params)
    add_terrain(gym, sim)
    asset = gym.load_asset(sim, str(tmp_path), "box.xml", gymapi.AssetOptions())
    for xy in ((-0.5 + 0.15, -0.5 + 0.15), (-0.5 + 2.0, -0.5 + 1.5)):  # the lowest step, the top platform
        env = gym.create_env(sim, gymapi.Vec3(), gymapi.Vec3(), 2)
        gym.create_actor(env, asset, gymapi.Transform(gymapi.Vec3(xy[0], xy[1], 0.8)), "box", 0, 0, 0)
    gym.prepare_sim(sim)
    return gym, sim


def _ground_z(sim, x: float, y: float) -> float:
    model, data = sim.engine.model, sim.engine.get_data(0)
    geom = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(model, data, np.array([x, y, 5.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)
    return 5.0 - dist


def _heightfield(gym, sim):
    hf = _samples()
    params = gymapi.HeightFieldParams()
    params.column_scale = params.row_scale = H_SCALE
    params.vertical_scale = V_SCALE
    params.nbColumns, params.nbRows = hf.shape  # legged_gym: nbColumns = rows along x, nbRows = columns along y
    params.transform.p = gymapi.Vec3(-0.5, -0.5, 0.0)
    gym.add_heightfield(sim, hf.flatten(), params)


def _trimesh(gym, sim):
    vertices, triangles = terrain_utils.convert_heightfield_to_trimesh(_samples(), H_SCALE, V_SCALE, 0.75)
    params = gymapi.TriangleMeshParams()
    params.nb_vertices, params.nb_triangles = len(vertices), len(triangles)
    params.transform.p = gymapi.Vec3(-0.5, -0.5, 0.0)
    gym.add_triangle_mesh(sim, vertices.flatten(), triangles.flatten(), params)


@pytest.mark.parametrize("add_terrain", [_heightfield, _trimesh], ids=["heightfield", "trimesh"])
def test_terrain_heights_and_a_box_resting_on_it(tmp_path, add_terrain):
    gym, sim = _sim(tmp_path, add_terrain)
    hf = _samples() * V_SCALE
    for i, j in ((3, 25), (7, 12), (22, 13), (36, 6)):  # cells on steps (off the boxes)
        flat = hf[i:i + 2, j:j + 2]
        assert (flat == flat[0, 0]).all()  # the cell's 4 corners share a step: no riser inside it
        assert _ground_z(sim, -0.5 + (i + 0.3) * H_SCALE, -0.5 + (j + 0.6) * H_SCALE) == pytest.approx(hf[i, j], abs=1e-3)
    for _ in range(300):
        gym.simulate(sim)
    gym.refresh_actor_root_state_tensor(sim)
    z = gymtorch.wrap_tensor(gym.acquire_actor_root_state_tensor(sim))[:, 2].numpy()
    np.testing.assert_allclose(z, [0.05, hf.max() + 0.05], atol=0.01)  # on the bottom step and on the platform


def test_mesh_far_from_the_origin_samples_back_to_its_heights():
    """legged_gym's terrain mesh spans ~200 m in float32: samples on vertices must still find their
    triangles (a missed sample would fall to the lowest height)."""
    from ambulo.isaac.gym import terrain

    rng = np.random.default_rng(0)
    hf = rng.integers(-40, 40, (200, 300)).astype(np.int16)
    vertices, triangles = terrain_utils.convert_heightfield_to_trimesh(hf, H_SCALE, V_SCALE)
    vertices = (vertices + np.array([230.0, 190.0, 0.0])).astype(np.float32)
    field = terrain.from_mesh(vertices.flatten(), triangles.flatten(), gymapi.TriangleMeshParams())
    assert field.heights_m.shape == hf.shape
    np.testing.assert_allclose(field.heights_m, hf * V_SCALE, atol=1e-3)
    np.testing.assert_allclose(field.origin[:2], [230.0, 190.0], atol=1e-3)
