"""``World(device="cuda")``: the Isaac-style API on MuJoCo Warp follows the CPU engine's physics.

The Jetbot and humanoid checks of tests/sim/test_physics.py, run through the same ``World`` /
``WheeledRobot`` / ``Robot`` calls on the GPU engine, against the CPU engine (MuJoCo, float64)
from the same scene and commands: the physical outcome holds on the GPU, and the trajectories
agree within float32 and solver-tolerance drift. The ``cuda`` cases need a GPU; the same code
path on Warp's CPU device (``engine="warp"``) is a slow case, to check it without one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from ambulo import assets
from ambulo.sim import DifferentialController, DynamicCuboid, Robot, WheeledRobot, World, add_reference_to_stage

TARGETS = [
    pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")),
    pytest.param("cpu", marks=pytest.mark.slow, id="warp-cpu"),
]


def _world(device: str | None, **kw) -> World:
    """The CPU engine for None, else MuJoCo Warp on ``device``."""
    if device is None:
        return World(**kw)
    return World(device=device, engine="warp", **kw)


def _reset(world: World, device: str | None) -> None:
    world.reset()
    if device is not None:  # the GPU engine really runs it (not the CPU engine under another name)
        assert type(world.engine).__name__ == "GpuEngine"
        assert torch.device(world.engine.device).type == device


def _yaw(quat) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def jetbot_track(device: str | None) -> np.ndarray:
    """(x m, y m, yaw rad) every 0.1 s: 1 s straight at 0.3 m/s, then 1 s turning at 1 rad/s."""
    world = _world(device, physics_dt=0.005)
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(
        prim_path="/World/Fancy_Robot", name="fancy_robot", create_robot=True,
        usd_path=assets.path("jetbot"), wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    _reset(world, device)
    controller = DifferentialController(wheel_radius=0.03, wheel_base=0.1125)
    track = []
    for step in range(400):
        command = [0.3, 0.0] if step < 200 else [0.0, 1.0]
        jetbot.apply_wheel_actions(controller.forward(command))
        world.step()
        if step % 20 == 19:
            pos, quat = jetbot.get_world_pose()
            track.append([float(pos[0]), float(pos[1]), _yaw(np.asarray(quat, dtype=float))])
    return np.array(track)


def humanoid_heights(device: str | None) -> np.ndarray:
    """Root height (m) every 0.05 s over 2 s of the humanoid under its drives' PD hold."""
    world = _world(device, physics_dt=0.005)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid"), prim_path="/World/Humanoid")
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid"))
    _reset(world, device)
    heights = []
    for step in range(400):
        world.step()
        if step % 10 == 9:
            heights.append(float(humanoid.get_world_pose()[0][2]))
    return np.array(heights)


def box_heights(device: str | None) -> np.ndarray:
    world = _world(device)
    world.scene.add_default_ground_plane()
    box = world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0, 0, 1.0], size=0.2, mass=2.0))
    _reset(world, device)
    heights = []
    for _ in range(300):
        world.step()
        heights.append(float(box.get_world_pose()[0][2]))
    return np.array(heights)


@pytest.mark.parametrize("device", TARGETS)
def test_jetbot_drives_and_turns_on_the_gpu_engine_as_on_the_cpu(device):
    cpu, gpu = jetbot_track(None), jetbot_track(device)
    assert gpu[9, 0] == pytest.approx(0.3, rel=0.15)  # 1 s at 0.3 m/s
    assert gpu[-1, 2] - gpu[9, 2] == pytest.approx(1.0, rel=0.15)  # 1 s at 1 rad/s, in place
    # float32 vs float64: 3e-7 m and rad apart on Warp's CPU device (2026-11-28)
    assert np.abs(gpu[:, :2] - cpu[:, :2]).max() < 0.005
    assert np.abs(gpu[:, 2] - cpu[:, 2]).max() < 0.01


@pytest.mark.parametrize("device", TARGETS)
def test_humanoid_stands_under_pd_hold_on_the_gpu_engine_as_on_the_cpu(device):
    cpu, gpu = humanoid_heights(None), humanoid_heights(device)
    assert gpu.min() > 0.9 * gpu[0]
    assert np.abs(gpu - cpu).max() < 0.002  # 2e-7 m apart on Warp's CPU device


@pytest.mark.parametrize("device", TARGETS)
def test_dropped_box_rests_at_half_height_on_the_gpu_engine_as_on_the_cpu(device):
    cpu, gpu = box_heights(None), box_heights(device)
    assert gpu[:80].min() < 0.5 and gpu[-1] == pytest.approx(0.1, abs=0.002)
    assert np.abs(gpu - cpu).max() < 0.002  # 4e-7 m apart on Warp's CPU device
