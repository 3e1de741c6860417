"""Fixtures of the navigation tests: a small user world (MJCF)."""

import pytest

ROOM_XML = """
<mujoco model="test_room">
  <worldbody>
    <geom name="floor" type="plane" size="6 6 0.1"/>
    <light pos="0 0 3" dir="0 0 -1"/>
    <body name="wall_north" pos="1.5 2.0 0.75"><geom type="box" size="2.5 0.05 0.75" rgba="0.7 0.6 0.5 1"/></body>
    <body name="wall_south" pos="1.5 -2.0 0.75"><geom type="box" size="2.5 0.05 0.75" rgba="0.6 0.7 0.5 1"/></body>
    <body name="crate" pos="1.5 0.9 0.3"><geom type="box" size="0.3 0.2 0.3" rgba="0.3 0.4 0.8 1"/></body>
    <body name="post" pos="1.5 -1.0 0.5"><geom type="cylinder" size="0.1 0.5" rgba="0.8 0.3 0.3 1"/></body>
    <body name="rail" pos="0.0 -1.5 0.9" euler="0 90 0"><geom type="capsule" size="0.05 0.4" rgba="0.3 0.3 0.3 1"/></body>
    <body name="rug" pos="3.0 0.0 0.005"><geom type="box" size="0.5 0.5 0.005" rgba="0.9 0.2 0.2 1"/></body>
    <body name="shelf" pos="-1.5 1.0 2.0"><geom type="box" size="0.3 0.3 0.05"/></body>
  </worldbody>
</mujoco>
"""
"""A 5 m x 4 m strip between two walls: a crate and a post to walk past, a rail at hip height
(a capsule lying along x), a rug (walked over) and a shelf above the head (walked under)."""


@pytest.fixture(scope="session")
def room(tmp_path_factory):
    """``ROOM_XML`` written to a file."""
    path = tmp_path_factory.mktemp("world") / "room.xml"
    path.write_text(ROOM_XML)
    return path


@pytest.fixture
def room_nav(room):
    """A navigator in ``room`` (mapping mode unless asked: ``room_nav("full")``), the robot at
    (-1, 0) facing +x, a 64 x 48 camera; closed after the test."""
    from ambulo.navigation import Navigator, NavigatorCfg, NavWorld, NavWorldCfg

    worlds = []

    def make(mode: str = "mapping", **navigator_kw):
        world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0),
                                   cfg=NavWorldCfg(camera_width=64, camera_height=48, record_gyro=mode == "full"))
        worlds.append(world)
        return Navigator(world, NavigatorCfg(mode=mode, **navigator_kw))

    yield make
    for world in worlds:
        world.close()


@pytest.fixture
def fix_map():
    """``fix_map(nav, occ_of)``: the navigator plans on the map ``occ_of(cx, cy)`` (cell centres, m ->
    ``maps`` codes) on its own grid, kept fixed (no frame is fused into it)."""
    import numpy as np

    from ambulo.maps import Grid2D

    def fix(nav, occ_of) -> None:
        g = nav.mapper.grid
        iy, ix = np.mgrid[0:g.shape[0], 0:g.shape[1]]
        cx, cy = g.cell_center_xy_m(iy, ix)
        nav.mapper.grid = Grid2D(occupancy=occ_of(cx, cy).astype(np.int8), origin_xy_m=g.origin_xy_m,
                                 resolution_m=g.resolution_m)
        nav.mapper.refresh = lambda time_s, xy=None: False

    return fix
