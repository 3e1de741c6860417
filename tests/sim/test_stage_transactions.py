"""A constructor that fails leaves the stage as it was; a wrong path fails at scene.add."""

import pytest

from ambulo import assets
from ambulo.core.paths import PrimNotFoundError
from ambulo.sim import Articulation, DynamicCuboid, WheeledRobot, World, add_reference_to_stage
from ambulo.sim.camera import Camera


def _stage_state(world):
    return world.stage.to_xml(), dict(world.sim.components)


@pytest.mark.parametrize("make", [
    lambda: WheeledRobot(prim_path="/World/Jetbot", create_robot=True, usd_path=assets.path("jetbot")),
    lambda: DynamicCuboid(prim_path="/World/cube", color=[1.0, 0.5]),
    lambda: DynamicCuboid(prim_path="/World/cube", size=0.0),
    lambda: DynamicCuboid(prim_path="/World/cube", orientation=[0, 0, 0, 0]),
    lambda: Camera(prim_path="/World/camera", resolution=(0, 10)),
], ids=["wheeled-robot-without-wheels", "cuboid-bad-colour", "cuboid-zero-size", "cuboid-zero-quat", "camera-0-px"])
def test_a_failing_constructor_leaves_the_stage_as_it_was_and_a_retry_works(make):
    world = World()
    world.scene.add_default_ground_plane()
    before = _stage_state(world)
    with pytest.raises((ValueError, TypeError)):
        make()
    assert _stage_state(world) == before
    # the same prim path is free again
    robot = world.scene.add(WheeledRobot(prim_path="/World/Jetbot", create_robot=True, usd_path=assets.path("jetbot"),
                                         wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    world.reset()
    assert robot.num_dof == 2


def test_a_wrong_path_added_after_the_first_reset_fails_at_scene_add_with_did_you_mean():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(assets.path("jetbot"), "/World/Jetbot")
    world.reset()
    with pytest.raises(PrimNotFoundError, match="no prim at '/World/Jetbott'. Did you mean '/World/Jetbot"):
        world.scene.add(Articulation(prim_path="/World/Jetbott", name="typo"))
    assert not world.scene.object_exists("typo")
    # a prim put on the stage after the reset is fine: it is initialized at the next reset
    add_reference_to_stage(assets.path("jetbot"), "/World/Second")
    second = world.scene.add(Articulation(prim_path="/World/Second"))
    world.reset()
    assert second.num_dof == 2


@pytest.mark.parametrize("kwargs, message", [({"mass": float("nan")}, "mass is nan"), ({"mass": -1.0}, "mass is -1.0"),
                                             ({"density": 0.0}, "density is 0.0")])
def test_object_mass_and_density_must_be_positive_and_finite(kwargs, message):
    world = World()
    before = _stage_state(world)
    with pytest.raises(ValueError, match=message):
        DynamicCuboid(prim_path="/World/cube", **kwargs)
    assert _stage_state(world) == before
