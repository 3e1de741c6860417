"""Fixtures of the viewer tests."""

import pytest

from ambulo.sim import DynamicCuboid, World


@pytest.fixture
def box_world():
    """A function that makes the scene most viewer tests watch: a new ``World(**world_kwargs)`` (the
    last one cleared) with the default ground plane and a box of side ``size_m`` at ``position_m``
    (``/World/Box``); not reset, so a test may add sensors first."""

    def make(position_m, size_m: float = 0.2, **world_kwargs) -> World:
        World.clear_instance()
        world = World(**world_kwargs)
        world.scene.add_default_ground_plane()
        world.scene.add(DynamicCuboid(prim_path="/World/Box", position=list(position_m), size=size_m))
        return world

    return make
