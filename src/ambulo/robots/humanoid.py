"""The bundled 21-DoF humanoid (``assets/data/humanoid.xml``): the one home of its facts.

Element names are the MJCF's own; a scene built with ``ambulo.core`` prefixes them with the
robot's prim path (``/World/robot/left_sole``). The numbers are the model's geometry, and
``tests/robots/test_humanoid.py`` checks every one against the compiled model. The shipped
walking policy's physics step is read from its contract, not restated.
"""

from __future__ import annotations

import json
import math

from .. import assets

ASSET = "humanoid"
"""The bundled asset: ``assets.path(ASSET)``, ``RobotCfg(file=ASSET)``."""

PRIM_PATH = "/World/robot"
"""Where the apps built on ``ambulo.core.scene`` (walking controller, RL task, replicator,
perception) place the humanoid: its elements are named ``/World/robot/<name>``."""
STAGE_PRIM_PATH = "/World/Humanoid"
"""Where the Isaac-style apps (``ambulo.demo``, the ROS 2 bridge) reference it onto the stage."""

BASE_BODY = "pelvis"
"""The floating base (on the free joint ``root``)."""
FOOT_BODIES = ("left_foot", "right_foot")
SOLE_SITES = ("left_sole", "right_sole")
"""Sole centres on the ground, x forward: the foot frames of walking patterns."""
LEG_BODIES = ("left_thigh", "left_shank", "left_foot", "right_thigh", "right_shank", "right_foot")
"""The legs' bodies below the pelvis, hip to foot (each has one capsule or box; a terrain task adds
sole spheres to the feet)."""
LEG_JOINTS = ("hip_roll", "hip_yaw", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
"""One leg's joints, hip to ankle; the joints are ``left_<name>`` and ``right_<name>``."""
IMU_SITE = "imu"
"""On the pelvis."""

HEAD_CAMERA_SITE = "head_camera_mount"
"""The head's camera mount (site on the ``head`` body, 0.095 m ahead of and 0.09 m above its origin;
x forward, z up). The camera on it is ``head_camera_cfg``: pitched ``HEAD_CAMERA_PITCH_DEG`` down, 525 px focal at
640 px wide; an app may pitch it otherwise (``pitch_deg``)."""
HEAD_CAMERA_LEAF = "camera"
"""A head camera's prim is the mount site's prim plus this leaf."""


def head_camera_prim(prim_path: str = PRIM_PATH) -> str:
    """The head camera's prim path on the humanoid at ``prim_path``."""
    return f"{prim_path}/{HEAD_CAMERA_SITE}/{HEAD_CAMERA_LEAF}"


HEAD_CAMERA_PRIM = head_camera_prim()
"""``/World/robot/head_camera_mount/camera``: the head camera on the humanoid at ``PRIM_PATH``."""
HEAD_CAMERA_FOCAL_PX_AT_640 = 525.0
"""The head camera's focal length at 640 px wide, px (TUM RGB-D's Kinect: 525 px at 640x480): the
same field of view at any size (``head_camera_focal_px``)."""
HEAD_CAMERA_PITCH_DEG = 18.0
"""The head camera pitched down on its mount, deg: the navigator's floor is in view from ~1.6 m ahead
(``NavWorldCfg.camera_pitch_deg``; the apartment-objects dataset sees what the navigator sees)."""
HEAD_LAMP_DIFFUSE = 0.8
"""The head lamp's diffuse intensity (MuJoCo's headlight, ``add_head_lamp``). The apartments are lit for
their overview and read ~28/255 with a contrast of ~5 levels from the head camera facing a wall: too
dark for the odometry's corners, and dataset frames without it were half as bright as the robot's."""
HEAD_LAMP_AMBIENT = 0.1
"""The head lamp's ambient term (MuJoCo's headlight ambient)."""


def head_camera_focal_px(width: int) -> float:
    """The head camera's focal length at ``width`` px wide, px (``HEAD_CAMERA_FOCAL_PX_AT_640`` scaled)."""
    return HEAD_CAMERA_FOCAL_PX_AT_640 * width / 640


def head_camera_cfg(width: int, height: int, *, pitch_deg: float = HEAD_CAMERA_PITCH_DEG,
                    focal_length_px: float | None = None, **camera):
    """The head camera's ``CameraCfg`` at ``width`` x ``height`` on the humanoid at ``PRIM_PATH``:
    pitched ``pitch_deg`` down about the mount's y axis, ``focal_length_px`` (None:
    ``head_camera_focal_px(width)``); ``camera`` holds the app's other ``CameraCfg`` fields (annotators,
    clipping range)."""
    # sensors is imported here, not at the top: the facts above are read by light modules (2 s of
    # torch and renderer imports for a prim path is too much)
    from ..sensors import CameraCfg

    half_pitch = math.radians(pitch_deg) / 2
    return CameraCfg(prim_path=HEAD_CAMERA_PRIM, width=width, height=height,
                     focal_length_px=focal_length_px or head_camera_focal_px(width),
                     offset_quat=(math.cos(half_pitch), 0.0, math.sin(half_pitch), 0.0), **camera)


def add_head_lamp(spec, diffuse: float = HEAD_LAMP_DIFFUSE) -> None:
    """Light ``spec`` (an ``mujoco.MjSpec``) with the robot's head lamp: MuJoCo's headlight, which rides
    the rendering camera, ``diffuse`` grey (0: leave the scene's headlight as it is)."""
    if diffuse > 0:
        spec.visual.headlight.active = 1
        spec.visual.headlight.diffuse = [diffuse] * 3
        spec.visual.headlight.ambient = [HEAD_LAMP_AMBIENT] * 3


SOLE_LENGTH_M = 0.22
SOLE_WIDTH_M = 0.09
"""The sole box (0.22 x 0.09 m) is centred on the ``*_sole`` site."""
STANCE_WIDTH_M = 0.18
"""Distance between the soles in the ``home`` pose and at the initial state (hips 0.18 m apart), m."""
SOLE_X_M = 0.03
"""The sole centres stand this far ahead of the pelvis in ``home`` and at the initial state, m."""
WALK_STEP_LENGTH_RANGE_M = (-0.10, 0.25)
"""Step lengths the walk controller (``ambulo.locomotion``: preview control at a 0.80 m CoM,
0.8 s steps) walks, m: the swing foot's x in the stance foot's frame. Found in simulation
(``WalkSimulation``, seed 1, either foot first): 3 m straight walks of 0.25 m steps arrive; with
0.30 m and 0.326 m steps the feet slip and the robot ends 0.16 m short, and issue 24 saw it fall
after about 1 m of a plan at 0.326 m (issue 14's module limit was 0.35 m). Backwards: issue 14's
0.10 m."""
WALK_STEP_WIDTH_RANGE_M = (0.12, 0.30)
"""Step widths (|y| of the swing foot in the stance foot's frame), m: issue 14's module limits;
the planner's walks along its body path keep ``STANCE_WIDTH_M``."""
WALK_MAX_STEP_YAW_RAD = 0.30
"""Largest yaw change per step, rad (issue 14). Found in simulation: a 90 degree arc turning
0.3 rad a step while stepping 0.2 m or 0.25 m, between two straight 1 m stretches, is walked
without a fall (seed 1, either foot first)."""
PELVIS_HEIGHT_M = 0.92
"""The pelvis height standing straight-legged (the model's initial state, all joints 0) with the
soles on z = 0, m. (The ``home`` keyframe crouches slightly, to 0.904 m.)"""

BODY_RADIUS_M = 0.265
"""Radius of the smallest vertical cylinder around the standing humanoid seen from above (upper
arms at y = +-0.20 m with 0.04 m capsules, feet 0.22 m long: hypot(0.11, 0.24) m; the hands reach
0.260 m in the ``home`` keyframe). The clearance a path or a costmap keeps for the body, m."""
HEAD_HEIGHT_M = 1.62
"""Top of the head standing straight with the soles on z = 0, m: the top of the body band that
2-D occupancy maps describe."""

POLICY_TASK = "humanoid-walk"
"""The task of the shipped walking policy (``assets/data/policies/humanoid_walk``)."""
POLICY_CONTRACT_FILE = assets.policy_folder(POLICY_TASK) / "contract.json"
POLICY_PHYSICS_DT_S = float(json.loads(POLICY_CONTRACT_FILE.read_text())["physics_dt_s"])
"""The physics step the shipped walking policy was trained at, s (its contract's ``physics_dt_s``):
a World that runs the policy steps this."""

__all__ = [
    "ASSET", "BASE_BODY", "FOOT_BODIES", "HEAD_CAMERA_FOCAL_PX_AT_640", "HEAD_CAMERA_LEAF", "HEAD_CAMERA_PITCH_DEG",
    "HEAD_CAMERA_PRIM", "HEAD_CAMERA_SITE", "HEAD_LAMP_AMBIENT", "HEAD_LAMP_DIFFUSE", "IMU_SITE", "LEG_JOINTS",
    "PELVIS_HEIGHT_M", "POLICY_CONTRACT_FILE", "POLICY_PHYSICS_DT_S", "POLICY_TASK", "PRIM_PATH", "SOLE_LENGTH_M",
    "SOLE_SITES", "SOLE_WIDTH_M", "SOLE_X_M", "STAGE_PRIM_PATH", "STANCE_WIDTH_M", "WALK_MAX_STEP_YAW_RAD",
    "WALK_STEP_LENGTH_RANGE_M", "WALK_STEP_WIDTH_RANGE_M", "add_head_lamp", "head_camera_cfg", "head_camera_focal_px",
    "head_camera_prim",
]
