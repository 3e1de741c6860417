"""The main demo: a Jetbot circling a humanoid that walks a small circle of its own (driven by
the walking policy that ships with ambulo), run headless, recorded to MP4."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import assets
from .robots import humanoid as humanoid_facts
from .sim import (
    ArticulationAction,
    DifferentialController,
    DynamicCuboid,
    HumanoidWalkingPolicy,
    Robot,
    WheeledRobot,
    World,
    set_camera_view,
)

HUMANOID_COMMAND = (0.25, 0.0, 0.6)
"""(vx m/s, vy m/s, yaw rate rad/s): a circle of radius v / w = 0.42 m, inside the Jetbot's."""


def build_demo_world(num_worlds: int = 1, viewer: str | None = None,
                     viewer_port: int = 8080) -> tuple[World, WheeledRobot, Robot]:
    """The demo stage: ground, a Jetbot at (1, 0), the 21-DoF humanoid at the origin, two crates.
    ``viewer="web"``: watched in a browser (``World(viewer=...)``)."""
    world = World(physics_dt=humanoid_facts.POLICY_PHYSICS_DT_S, rendering_dt=0.02, num_worlds=num_worlds,
                  viewer=viewer, viewer_port=viewer_port)
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(
        prim_path="/World/Jetbot", name="jetbot", create_robot=True, usd_path=assets.path("jetbot"),
        wheel_dof_names=["left_wheel_joint", "right_wheel_joint"], position=[1.0, 0.0, 0.0],
        orientation=[np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)],  # facing +y: circles the origin
    ))
    from .sim import add_reference_to_stage

    add_reference_to_stage(usd_path=assets.path(humanoid_facts.ASSET), prim_path=humanoid_facts.STAGE_PRIM_PATH)
    humanoid = world.scene.add(Robot(prim_path=humanoid_facts.STAGE_PRIM_PATH, name="humanoid"))
    for i, (x, y) in enumerate(((-0.8, 0.6), (-0.6, -0.9))):
        world.scene.add(DynamicCuboid(prim_path=f"/World/Crate_{i}", position=[x, y, 0.15], size=0.3,
                                      mass=3.0, color=[0.8, 0.55, 0.2], semantic_label="crate"))
    set_camera_view(eye=[2.8, -2.8, 1.9], target=[0.0, 0.0, 0.6], world=world)
    return world, jetbot, humanoid


@dataclass(kw_only=True)
class DemoReport:
    simulated_s: float
    wall_s: float
    jetbot_path_m: float
    jetbot_radius_m: float
    humanoid_min_pelvis_height_m: float
    humanoid_path_m: float
    humanoid_stood: bool
    video: str | None
    frames: int

    def lines(self) -> list[str]:
        return [
            f"simulated {self.simulated_s:.1f} s in {self.wall_s:.1f} s wall "
            f"({self.simulated_s / max(self.wall_s, 1e-9):.1f}x real time)",
            f"jetbot drove {self.jetbot_path_m:.2f} m around a circle of radius {self.jetbot_radius_m:.2f} m "
            f"(commanded 0.25 m/s, 0.25 rad/s -> 1.00 m)",
            f"humanoid walked {self.humanoid_path_m:.2f} m with the shipped walking policy "
            f"(commanded {HUMANOID_COMMAND[0]} m/s, {HUMANOID_COMMAND[2]} rad/s) and "
            f"{'stayed up' if self.humanoid_stood else 'FELL'}; lowest pelvis height "
            f"{self.humanoid_min_pelvis_height_m:.3f} m",
            f"video: {self.video} ({self.frames} frames)" if self.video else "video: not recorded",
        ]


def run_demo(seconds: float = 8.0, video: str | None = "out/demo.mp4", progress: bool = True,
             renderer: str = "raster", viewer: str | None = None, viewer_port: int = 8080) -> DemoReport:
    """Run the demo; with ``viewer="web"`` it is watched in a browser, whose velocity command
    (when the page teleoperates) replaces ``HUMANOID_COMMAND``."""
    world, jetbot, humanoid = build_demo_world(viewer=viewer, viewer_port=viewer_port)
    try:
        return _run(world, jetbot, humanoid, seconds, video, progress, renderer)
    finally:
        if world.viewer is not None:
            world.viewer.close()


def _run(world, jetbot, humanoid, seconds, video, progress, renderer) -> DemoReport:
    from tqdm import tqdm

    world.reset()
    walker = HumanoidWalkingPolicy(humanoid)
    walker.initialize()

    def humanoid_command():
        return HUMANOID_COMMAND if world.viewer is None else world.viewer.velocity_command(HUMANOID_COMMAND)

    world.add_physics_callback("humanoid_walk", lambda dt: walker.forward(dt, humanoid_command()))
    controller = DifferentialController(wheel_radius=0.03, wheel_base=0.1125)
    # a 1 m circle: v = w r
    wheel_command = controller.forward([0.25, 0.25])
    recorder = None
    if video:
        from .sim.recorder import Recorder

        recorder = Recorder(world, video, width=640, height=480, fps=25, renderer=renderer)
    start = time.perf_counter()
    path_m, last = 0.0, jetbot.get_world_pose()[0]
    pelvis_start = float(humanoid.get_world_pose()[0][2])
    pelvis_min = pelvis_start
    walked_m, humanoid_last = 0.0, humanoid.get_world_pose()[0]
    steps = int(round(seconds / world.get_rendering_dt()))
    for _ in tqdm(range(steps), desc="demo", unit="step", disable=not progress):
        jetbot.apply_wheel_actions(ArticulationAction(joint_velocities=wheel_command.joint_velocities))
        world.step(render=recorder is not None)
        pos = jetbot.get_world_pose()[0]
        path_m += float(np.linalg.norm(pos[:2] - last[:2]))
        last = pos
        humanoid_pos = humanoid.get_world_pose()[0]
        walked_m += float(np.linalg.norm(humanoid_pos[:2] - humanoid_last[:2]))
        humanoid_last = humanoid_pos
        pelvis_min = min(pelvis_min, float(humanoid_pos[2]))
        if recorder:
            recorder.capture()
    wall = time.perf_counter() - start
    out = str(recorder.close()) if recorder else None
    return DemoReport(
        simulated_s=world.current_time, wall_s=wall, jetbot_path_m=path_m,
        jetbot_radius_m=float(np.linalg.norm(last[:2])), humanoid_min_pelvis_height_m=pelvis_min,
        humanoid_path_m=walked_m, humanoid_stood=pelvis_min > 0.8 * pelvis_start, video=out,
        frames=recorder.num_frames if recorder else 0,
    )
