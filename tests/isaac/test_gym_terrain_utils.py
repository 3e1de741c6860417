"""isaacgym.terrain_utils: legged_gym's rough terrain tiles and the mesh it hands to add_triangle_mesh."""

import numpy as np
import pytest

from ambulo.isaac.gym import terrain_utils as tu


def _tile(size=80):
    return tu.SubTerrain("t", width=size, length=size, vertical_scale=0.005, horizontal_scale=0.1)


def test_pyramid_stairs_rise_by_the_step_to_a_flat_platform():
    tile = tu.pyramid_stairs_terrain(_tile(), step_width=0.5, step_height=0.1, platform_size=3.0)
    hf = tile.height_field_raw
    assert hf.dtype == np.int16 and hf[0, 0] == 0
    assert hf[5, 40] == 20 and hf[10, 40] == 40  # 0.1 m steps (20 units) every 0.5 m (5 cells)
    centre = hf[35:45, 35:45]
    assert (centre == centre[0, 0]).all() and centre[0, 0] == hf.max()


def test_pyramid_slope_has_its_slope_and_a_clipped_top():
    hf = tu.pyramid_sloped_terrain(_tile(), slope=0.2, platform_size=2.0).height_field_raw
    rise_per_cell = (hf[20, 40] - hf[10, 40]) / 10
    assert rise_per_cell * 0.005 / 0.1 == pytest.approx(0.2, rel=0.1)
    assert hf[40, 40] == hf[31, 31]  # the platform is flat at the height of its edge


def test_random_uniform_stays_in_range():
    np.random.seed(3)
    hf = tu.random_uniform_terrain(_tile(), min_height=-0.05, max_height=0.05, step=0.005,
                                   downsampled_scale=0.2).height_field_raw
    assert hf.min() >= -10 and hf.max() <= 10 and hf.std() > 0


def test_heightfield_mesh_vertices_triangles_and_walls():
    hf = np.zeros((4, 3), np.int16)
    hf[2:, :] = 100  # a 0.5 m step between rows 1 and 2
    vertices, triangles = tu.convert_heightfield_to_trimesh(hf, 0.1, 0.005)
    assert vertices.shape == (12, 3) and triangles.shape == (2 * 3 * 2, 3) and triangles.dtype == np.uint32
    np.testing.assert_allclose(vertices[2 * 3 + 1], [0.2, 0.1, 0.5])
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    assert (np.cross(b - a, c - a)[:, 2] > 0).all()  # every triangle faces up
    walled, _ = tu.convert_heightfield_to_trimesh(hf, 0.1, 0.005, slope_threshold=0.75)
    # the foot of the step moves under its top: a vertical riser at x = 0.2
    assert walled[1 * 3, 0] == pytest.approx(0.2) and walled[1 * 3, 2] == 0.0
