"""The one scene builder: an empty scene, the ground plane, lights, robots, and compilation.

Every app builds its ``MjSpec`` with these functions: the Isaac-style ``World`` (through
``Scene.add_default_ground_plane`` and ``add_reference_to_stage``), RL tasks, the data
generator. So a robot file is loaded by the same importers (MJCF, URDF, USD, with drive
conversion), stands on the same ground, and compiles with the physics options of one
``PhysicsCfg``. Element names are prim paths (``/World/robot/pelvis``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .. import assets
from ..utils.validate import Checked
from .drives import DriveDefaults
from .importers import load_spec
from .materials import PhysicsMaterial
from .names import DOF_JOINT_TYPES
from .physics import PhysicsCfg, apply_physics, match_options


def new_scene(name: str = "World") -> mujoco.MjSpec:
    """An empty scene whose offscreen buffer fits cameras up to 1280x960."""
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 1280, 960
    return spec


@dataclass(kw_only=True)
class GroundCfg(Checked):
    """A static plane with a checker texture, optionally with a sky and a sun light."""

    prim_path: str = "/World/defaultGroundPlane"
    """Body name; the plane geom is ``<prim_path>/geom``."""
    z_m: float = 0.0
    """Height of the plane, m."""
    static_friction: float = 0.5
    dynamic_friction: float = 0.5
    """Sliding friction of the plane (MuJoCo uses one coefficient; pairs take the larger)."""
    restitution: float = 0.0
    color: tuple[float, float, float] = (0.35, 0.4, 0.45)
    size_m: float = 100.0
    """Rendered extent (collision is infinite), m."""
    render_grid_m: float = 5.0
    """Render grid spacing, m: MuJoCo draws (size / spacing)^2 quads, and a 0.1 m grid on a
    100 m plane is a million quads (20 ms a frame on a software rasterizer)."""
    checker_m: float = 1.0
    """Edge of one checker square, m."""
    sky: bool = True
    """Add a gradient skybox."""
    sun: bool = True
    """Add a directional light (``/World/defaultLight``) unless one exists."""

    def material(self) -> PhysicsMaterial:
        return PhysicsMaterial(prim_path=self.prim_path + "/physicsMaterial",
                               static_friction=self.static_friction,
                               dynamic_friction=self.dynamic_friction, restitution=self.restitution)


def add_ground(spec: mujoco.MjSpec, cfg: GroundCfg) -> mujoco.MjsGeom:
    """Add the ground plane of ``cfg`` (the only place ambulo builds one)."""
    path = cfg.prim_path
    if spec.body(path) is not None:
        raise ValueError(f"a prim already exists at {path!r}; give the ground another prim_path")
    body = spec.worldbody.add_body(name=path, pos=[0.0, 0.0, float(cfg.z_m)])
    spec.add_texture(name=path + "/grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                     rgb1=list(cfg.color), rgb2=[c * 0.85 for c in cfg.color])
    repeat = cfg.size_m / (2.0 * cfg.checker_m)
    material = spec.add_material(name=path + "/material", texrepeat=[repeat, repeat])
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = path + "/grid"
    geom = body.add_geom(name=path + "/geom", type=mujoco.mjtGeom.mjGEOM_PLANE,
                         size=[cfg.size_m / 2, cfg.size_m / 2, cfg.render_grid_m],
                         material=path + "/material")
    cfg.material().apply_to(geom)
    if cfg.sun and not any(light.name == "/World/defaultLight" for light in spec.lights):
        add_light(spec, "/World/defaultLight", kind="distant", direction=(0.3, 0.2, -1.0),
                  intensity=0.7)
    if cfg.sky and spec.texture("/World/sky") is None:
        spec.add_texture(name="/World/sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=256, height=256,
                         rgb1=[0.55, 0.7, 0.9], rgb2=[0.1, 0.12, 0.18])
    return geom


def add_light(spec: mujoco.MjSpec, prim_path: str, *, kind: str = "distant",
              position=(0.0, 0.0, 3.0), direction=(0.0, 0.0, -1.0), intensity: float = 0.6,
              color=(1.0, 1.0, 1.0), ambient: float = 0.0, cast_shadows: bool = False):
    """Add a light: ``kind`` "distant" (sun-like) or "sphere"/"spot" (local).

    ``intensity`` in [0, 1] scales the diffuse colour. Shadows default off: on a software
    rasterizer they cost 10-20x frame rate.
    """
    kinds = {"distant": mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
             "sphere": mujoco.mjtLightType.mjLIGHT_POINT, "spot": mujoco.mjtLightType.mjLIGHT_SPOT}
    if kind not in kinds:
        raise ValueError(f"unknown light kind {kind!r}; use 'distant', 'sphere' or 'spot'")
    light = spec.worldbody.add_light(name=prim_path, pos=list(position), dir=list(direction))
    light.type = kinds[kind]
    light.diffuse = [intensity * c for c in color]
    light.specular = [0.2 * intensity] * 3
    light.ambient = [ambient] * 3
    light.castshadow = cast_shadows
    return light


@dataclass(kw_only=True)
class RobotCfg(Checked):
    """A robot (or any articulated/rigid asset) file placed at a prim path."""

    file: str
    """MJCF, URDF or USD path, or a bundled asset name (``ambulo.assets.names()``)."""
    prim_path: str = "/World/robot"
    pos_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Position of the file's root frame in the world, m."""
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Orientation (w, x, y, z) of the file's root frame in the world."""
    drives: DriveDefaults = field(default_factory=DriveDefaults)
    """Gains of joints that arrive without an actuator."""
    fixed_base: bool = False
    """Weld the root body to the world (URDF: no free joint; MJCF/USD: remove it)."""


@dataclass
class KeyPose:
    """A keyframe of a robot file by joint name: what attaching drops, kept for defaults."""

    joint_pos: dict[str, float]
    """Hinge/slide joint positions by name relative to the prim path, rad or m."""
    root_pos_m: np.ndarray | None
    """(3,) free-joint position in the file's frame, m; None for a fixed base."""
    root_quat: np.ndarray | None
    """(4,) free-joint orientation (w, x, y, z); None for a fixed base."""


@dataclass
class AttachedRobot:
    """What ``add_robot`` placed: its prim path, the frame holding it, the file's keyframes."""

    prim_path: str
    frame: mujoco.MjsFrame
    keyframes: dict[str, KeyPose]


def resolve_file(file: str | os.PathLike) -> str:
    """A path as given if it exists; a bare name as the bundled asset of that name. (Isaac library
    paths, ``<root>/Isaac/Robots/...``, are the Isaac layer's: ``ambulo.sim.isaac_assets``.)"""
    text = str(file)
    if os.path.exists(text):
        return text
    if os.sep in text or "." in os.path.basename(text):
        return text
    return assets.path(text)


def add_robot(spec: mujoco.MjSpec, cfg: RobotCfg) -> AttachedRobot:
    """Load ``cfg.file`` through the importers and attach it at ``cfg.prim_path``.

    The file's default prim becomes ``prim_path``, so its body ``pelvis`` is named
    ``<prim_path>/pelvis`` (the only place ambulo attaches a robot to a scene).
    """
    path = cfg.prim_path.rstrip("/")
    if not path.startswith("/"):
        raise ValueError(f"prim_path must be absolute, like '/World/robot'; got {cfg.prim_path!r}")
    if spec.frame(path) is not None or spec.body(path) is not None:
        raise ValueError(f"{path!r} is already on the stage; place the robot at another prim path")
    child = load_spec(resolve_file(cfg.file), drives=cfg.drives, fixed_base=cfg.fixed_base)
    keyframes = _keyframes(child)
    # one robot's keyframes do not fit a scene with others: they are returned instead
    for key in list(child.keys):
        child.delete(key)
    match_options(child, spec)
    frame = spec.worldbody.add_frame(name=path, pos=list(cfg.pos_m), quat=list(cfg.quat))
    spec.attach(child, prefix=path + "/", frame=frame)
    return AttachedRobot(path, frame, keyframes)


def _keyframes(child: mujoco.MjSpec) -> dict[str, KeyPose]:
    if not child.keys:
        return {}
    model = child.compile()
    out = {}
    for k in range(model.nkey):
        qpos = model.key_qpos[k]
        joints, root_pos, root_quat = {}, None, None
        for j in range(model.njnt):
            adr, kind = model.jnt_qposadr[j], int(model.jnt_type[j])
            if kind == mujoco.mjtJoint.mjJNT_FREE.value and root_pos is None:
                root_pos, root_quat = qpos[adr:adr + 3].copy(), qpos[adr + 3:adr + 7].copy()
            elif kind in DOF_JOINT_TYPES:
                joints[model.joint(j).name] = float(qpos[adr])
        out[model.key(k).name or str(k)] = KeyPose(joints, root_pos, root_quat)
    return out


def geom_collides(geom: mujoco.MjsGeom) -> bool:
    """Whether a spec geom takes part in contacts (either of its contype/conaffinity bit fields set);
    one with both 0 is visual only."""
    return bool(geom.contype or geom.conaffinity)


def compile_scene(spec: mujoco.MjSpec, physics: PhysicsCfg) -> mujoco.MjModel:
    """Apply ``physics`` to ``spec`` and compile it, with a one-line error if it does not."""
    apply_physics(spec, physics)
    try:
        return spec.compile()
    except ValueError as err:
        raise ValueError(f"the scene does not compile: {err}") from None


__all__ = ["AttachedRobot", "GroundCfg", "KeyPose", "RobotCfg", "add_ground", "add_light",
           "add_robot", "compile_scene", "geom_collides", "new_scene", "resolve_file"]
