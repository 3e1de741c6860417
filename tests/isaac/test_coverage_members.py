"""The `*` members added for the coverage table, checked by physics or hand math: tasks on the
World, a viewport's intrinsics, and the camera's motion vectors."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from ambulo.isaac import isaac_names
from ambulo.sim import DynamicCuboid, FixedCuboid, World
from ambulo.sim.camera import Camera
from ambulo.sim.tasks import BaseTask
from ambulo.sim.viewport import get_intrinsics_matrix


class DropTask(BaseTask):
    """Adds a cube (shifted by the task offset) and reports its height."""

    def __init__(self, name, offset=None, x=0.0):
        super().__init__(name, offset)
        self.x, self.calls = x, []

    def set_up_scene(self, scene):
        super().set_up_scene(scene)
        self.calls.append("set_up_scene")
        self._task_objects[self.name] = scene.add(DynamicCuboid(
            prim_path=f"/World/{self.name}", position=[self.x, 0.0, 1.0], size=0.1))
        self._move_task_objects_to_their_frame()

    def pre_step(self, time_step_index, simulation_time):
        self.calls.append(("pre_step", time_step_index, round(simulation_time, 9)))

    def post_reset(self):
        self.calls.append("post_reset")

    def get_observations(self):
        position, _ = self._task_objects[self.name].get_world_pose()
        return {self.name: {"position": position}}

    def calculate_metrics(self):
        return {f"{self.name}_height": float(self.get_observations()[self.name]["position"][2])}

    def is_done(self):
        return self.calculate_metrics()[f"{self.name}_height"] < 0.5


def test_tasks_set_up_at_the_first_reset_step_and_report_through_the_world():
    world = World()
    world.scene.add_default_ground_plane()
    near, far = DropTask("near", x=0.0), DropTask("far", offset=[2.0, 0.0, 0.0], x=0.0)
    world.add_task(near)
    world.add_task(far)
    with pytest.raises(ValueError, match="unique name"):
        world.add_task(DropTask("near"))
    assert world.get_task("far") is far and not world.is_tasks_scene_built()
    world.reset()
    assert world.is_tasks_scene_built() and near.calls == ["set_up_scene", "post_reset"]
    obs = world.get_observations()
    assert set(obs) == {"near", "far"}
    assert obs["far"]["position"][0] == pytest.approx(2.0)  # the task offset moved its cube
    assert world.get_observations("near")["near"]["position"][2] == pytest.approx(1.0)
    for _ in range(15):  # 0.25 s of free fall from 1 m: z = 1 - g t^2 / 2 = 0.69 m
        world.step(render=False)
    assert near.calls[2:4] == [("pre_step", 0, 0.0), ("pre_step", 1, round(1 / 60, 9))]
    assert world.calculate_metrics()["near_height"] == pytest.approx(1.0 - 9.81 * 0.25**2 / 2, abs=0.01)
    assert not world.is_done()
    for _ in range(60):
        world.step(render=False)
    assert world.is_done() and world.is_done("far")
    world.reset()
    assert near.calls.count("set_up_scene") == 1 and near.calls[-1] == "post_reset"
    assert world.get_observations("near")["near"]["position"][2] == pytest.approx(1.0)
    with pytest.raises(KeyError, match="no task named 'nope'"):
        world.get_task("nope")


def test_base_task_is_what_isaac_names_import_and_asks_for_overrides():
    with isaac_names():
        from isaacsim.core.api.tasks import BaseTask as new
        from omni.isaac.core.tasks import BaseTask as old
    assert new is old is BaseTask
    with pytest.raises(NotImplementedError, match="get_observations"):
        BaseTask("bare").get_observations()


def test_viewport_intrinsics_by_hand():
    world = World()
    world.scene.add(FixedCuboid(prim_path="/World/box", position=[0.0, 0.0, 0.5], size=0.2))
    camera = world.scene.add(Camera("/World/cam", position=[0.0, 0.0, 3.0], resolution=(64, 48)))
    world.reset()
    viewport = SimpleNamespace(camera_path="/OmniverseKit_Persp", get_texture_resolution=lambda: (640, 480))
    fy = 240.0 / math.tan(math.radians(float(world.model.vis.global_.fovy)) / 2)  # 45 deg -> 579.4 px
    assert get_intrinsics_matrix(viewport) == pytest.approx(np.array([[fy, 0, 320], [0, fy, 240], [0, 0, 1]]))
    assert fy == pytest.approx(579.41, abs=0.01)
    # a scene camera at a viewport resolution: fx = W f / h_aperture (Isaac's defaults 5.0 and 2.0955)
    on_camera = SimpleNamespace(camera_path="/World/cam", get_texture_resolution=lambda: (128, 96))
    k = get_intrinsics_matrix(on_camera)
    assert k[0, 0] == pytest.approx(128 * 5.0 / 2.0955) and k[1, 1] == pytest.approx(k[0, 0])
    assert get_intrinsics_matrix(camera) == pytest.approx(camera.get_intrinsics_matrix())
    with pytest.raises(TypeError, match="pass the Camera"):
        get_intrinsics_matrix("viewport")


def test_motion_vectors_follow_a_moved_cube_in_pixels():
    world = World()
    world.scene.add_default_ground_plane()
    cube = world.scene.add(DynamicCuboid(prim_path="/World/cube", position=[0.0, 0.0, 0.1], size=0.2))
    down = [math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]  # +X forward pitched to look down
    camera = Camera("/World/cam", position=[0.0, 0.0, 2.0], orientation=down, resolution=(64, 64))
    world.reset()
    camera.initialize()
    camera.add_motion_vectors_to_frame()
    world.step()
    first = camera.get_current_frame()["motion_vectors"]
    assert first.shape == (64, 64, 4) and first.dtype == np.float32 and not first.any()  # no previous render
    corner = np.array([0.06, 0.04, 0.1])  # a point on the top face, off its centre (cube frame)
    yaw = math.radians(30)
    cube.set_world_pose(position=[0.12, 0.1, 0.1], orientation=[math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
    world.step()
    mv = camera.get_current_frame()["motion_vectors"]
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    before, now = np.array([0.0, 0.0, 0.1]) + corner, cube.get_world_pose()[0] + rot @ corner
    (u_before, v_before), (u_now, v_now) = camera.get_image_coords_from_world_points(np.vstack([before, now]))
    row, col = int(v_now), int(u_now)  # the pixel that sees that point now
    expected = (u_before - u_now, v_before - v_now)  # where it was minus where it is: x > 0 moved left
    assert min(abs(expected[0]), abs(expected[1])) > 2.0  # it moved visibly along both image axes
    assert mv[row, col, :2] == pytest.approx(expected, abs=0.6)
    assert not mv[1, 1].any()  # the static ground stays still
