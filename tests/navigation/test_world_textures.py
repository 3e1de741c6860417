"""A user's world of plain colours is flagged before full mode's visual odometry loses its pose in it."""

import pytest

from ambulo.navigation.world import NavWorld

ROOM = """<mujoco><asset>{asset}</asset><worldbody>
  <geom type="plane" size="5 5 0.1" {floor}/>
  <geom type="box" pos="0 3 1" size="3 0.1 1" {wall}/>
  <geom type="box" pos="0 -3 1" size="3 0.1 1" rgba="0.5 0.5 0.5 1"/>
  <geom type="box" pos="2 0 1" size="0.1 0.1 1" rgba="0.5 0.5 0.5 0"/>
</worldbody></mujoco>"""
TEXTURE = ('<texture name="t" type="2d" builtin="checker" rgb1="0 0 0" rgb2="1 1 1" width="64" height="64"/>'
           '<material name="m" texture="t"/><material name="plain" rgba="0.2 0.4 0.6 1"/>')


@pytest.mark.parametrize("floor, wall, textured", [
    ('rgba="0.8 0.8 0.8 1"', 'rgba="0.6 0.5 0.4 1"', 0),
    ('material="plain"', 'material="plain"', 0),  # a material without a texture is still a plain colour
    ('material="m"', 'rgba="0.6 0.5 0.4 1"', 1),
    ('material="m"', 'material="m"', 2),
])
def test_textured_surfaces_are_counted_apart_from_the_robot_and_invisible_geoms(tmp_path, floor, wall, textured):
    file = tmp_path / "room.xml"
    file.write_text(ROOM.format(asset=TEXTURE, floor=floor, wall=wall))
    world = NavWorld.from_file(file, (-1.0, 0.0, 0.0))
    try:
        # floor, two walls; the transparent post is not seen, the humanoid (textured or not) is not the world
        assert world.textured_geoms() == (textured, 3)
    finally:
        world.close()
