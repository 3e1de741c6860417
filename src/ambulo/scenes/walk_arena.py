"""The walk arena: the bundled humanoid at ``robots.humanoid.PRIM_PATH`` on the core's ground plane
(z = 0, with its sky and sun), and optional static boxes standing on the floor (a map's obstacles).

The scene of ``ambulo.locomotion``'s walks (``ambulo plan --simulate``, ``benchmarks/zmp_walk.py``),
with the physics the walking controller was tuned with (``walk_physics``). Friction is authored
before compiling: the floor's through its ``GroundCfg``, and since MuJoCo gives a contact the
larger of its two geoms' frictions, every other geom (the robot's, the boxes') gets the same
coefficient, so the arena's friction is what it says also below the robot file's 1.0.
"""

from __future__ import annotations

import mujoco

from ..core import AttachedRobot, GroundCfg, PhysicsCfg, RobotCfg, add_ground, add_robot, compile_scene, new_scene
from ..robots import humanoid

GROUND_GEOM = "/World/defaultGroundPlane/geom"
"""The floor geom (``core.GroundCfg``'s plane)."""
OBSTACLES_PRIM_PATH = "/World/obstacles"
"""The obstacle boxes are the geoms ``/World/obstacles/obstacle<i>``."""
FLOOR_COLOR = (0.32, 0.36, 0.40)


def walk_physics(timestep_s: float = 0.005) -> PhysicsCfg:
    """The physics the walking controller was tuned with: the humanoid file's own options
    (implicitfast) and MuJoCo's solver defaults (Newton, 100 iterations, 50 line-search steps)."""
    return PhysicsCfg(timestep_s=timestep_s, integrator="implicitfast", solver="newton", solver_iterations=100,
                      ls_iterations=50)


def walk_arena(*, friction: float = 1.0, obstacles=()) -> tuple[mujoco.MjSpec, AttachedRobot]:
    """The arena's scene spec and the humanoid placed in it (its file's keyframes: ``home`` is
    where a walk's robot starts, ``core.entity.InitState.from_keyframe``).

    ``friction``: sliding friction of the floor and of every other geom. ``obstacles``: boxes
    ``(center_x, center_y, size_x, size_y, height)`` in m standing on the floor (static geoms
    ``/World/obstacles/obstacle<i>``)."""
    spec = new_scene("walk")
    robot = add_robot(spec, RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH))
    floor = add_ground(spec, GroundCfg(static_friction=friction, dynamic_friction=friction, color=FLOOR_COLOR))
    for i, (cx, cy, sx, sy, height) in enumerate(obstacles):
        spec.worldbody.add_geom(name=f"{OBSTACLES_PRIM_PATH}/obstacle{i}", type=mujoco.mjtGeom.mjGEOM_BOX,
                                pos=[cx, cy, height / 2], size=[sx / 2, sy / 2, height / 2],
                                rgba=[0.55, 0.42, 0.30, 1.0])
    for geom in spec.geoms:
        if geom.name != floor.name:
            geom.friction = [friction, geom.friction[1], geom.friction[2]]
    return spec, robot


def walk_model(*, friction: float = 1.0, timestep_s: float = 0.005, obstacles=()) -> mujoco.MjModel:
    """``walk_arena`` compiled with ``walk_physics(timestep_s)``: for code that needs the model only
    (inverse kinematics); a walk starts it on ``core.Simulation`` (``locomotion.walk_world``)."""
    spec, _ = walk_arena(friction=friction, obstacles=obstacles)
    return compile_scene(spec, walk_physics(timestep_s))


__all__ = ["FLOOR_COLOR", "GROUND_GEOM", "OBSTACLES_PRIM_PATH", "walk_arena", "walk_model", "walk_physics"]
