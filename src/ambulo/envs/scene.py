"""Task scenes: a ground plane, light and the robot attached under a name prefix.

RL tasks build their model here at the engine level (as Isaac Lab's direct envs do);
the robot's MJCF is attached with ``MjSpec`` so its names become ``robot/<name>``.
"""

from __future__ import annotations

import mujoco

ROBOT_PREFIX = "robot/"


def scene_spec(robot_file: str, *, robot_pos: tuple[float, float, float] = (0.0, 0.0, 0.0),
               floor_friction: tuple[float, float, float] = (1.0, 0.005, 0.0001)) -> mujoco.MjSpec:
    """An ``MjSpec`` with a textured floor named ``floor``, a light, and the robot file's root body.

    The physics options (timestep, integrator) are taken from the robot file so that its
    author's choices hold, and so attaching raises no option conflict.
    """
    robot = mujoco.MjSpec.from_file(robot_file)
    spec = mujoco.MjSpec()
    spec.option.timestep = robot.option.timestep
    spec.option.integrator = robot.option.integrator
    spec.visual.headlight.ambient = [0.4, 0.4, 0.4]
    spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                     rgb1=[0.2, 0.3, 0.4], rgb2=[0.1, 0.2, 0.3])
    spec.add_material(name="grid", texrepeat=[1, 1], reflectance=0.1).textures[
        mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    # size[2] is only the render grid spacing; a fine grid costs software rasterizers dearly
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1.0],
                            material="grid", friction=list(floor_friction))
    spec.worldbody.add_light(pos=[0, 0, 4], dir=[0, 0, -1],
                             type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    frame = spec.worldbody.add_frame(pos=list(robot_pos))
    frame.attach_body(robot.worldbody.first_body(), ROBOT_PREFIX, "")
    return spec


def add_floor_contact_sensor(spec: mujoco.MjSpec, body: str, name: str) -> None:
    """A sensor counting contacts between ``body`` (with its subtree) and the floor.

    Its value (``found``, stage POS) is current after every engine step.
    """
    spec.add_sensor(
        name=name, type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=mujoco.mjtObj.mjOBJ_XBODY,
        objname=body, reftype=mujoco.mjtObj.mjOBJ_GEOM, refname="floor",
        intprm=[1, 0, 1],  # data="found", reduce=none, num=1
    )


__all__ = ["ROBOT_PREFIX", "add_floor_contact_sensor", "scene_spec"]
