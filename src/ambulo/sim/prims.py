"""XFormPrim and RigidPrim: Isaac's single-prim API as a thin wrapper over ``ambulo.core.Entity``.

Getters return arrays of shape (N, ...) -- or (...) when the World has one world --
as numpy (Isaac's default backend) or torch; setters accept either shape. Poses
are world frame: position and quaternion (w, x, y, z).

Stage units: positions, translations and linear velocities given to and returned by prims
are in stage units (``World.stage_units_in_meters`` metres each, e.g. cm with 0.01); the
model is in metres. Quaternions, angles, angular velocities and masses (kg) are unchanged.
Every conversion goes through ``_in_len``/``_out_len`` below.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import mujoco
import torch

from ..core import Entity
from ..core.paths import resolve_spec_prim
from ..utils.checks import Described, InvalidValueError, check_positive, check_quat, check_vector
from ..utils.math import quat_mul, quat_rotate, quat_rotate_inverse
from .current import current_world, current_world_or_none
from .states import DynamicState, XFormPrimState
from .transaction import atomic_constructor

if TYPE_CHECKING:
    from .world import World

_CONJ = torch.tensor([1.0, -1.0, -1.0, -1.0], dtype=torch.float64)


class _NotInitialized:
    """Stands in for the World until ``initialize``: any use says what to do."""

    def __init__(self, prim_path: str):
        self._prim_path = prim_path

    def __getattr__(self, name):
        raise RuntimeError(
            f"{self._prim_path} is not initialized: add it to world.scene and call world.reset()"
        )


def place_on_stage(prim_path: str, position, translation, orientation) -> None:
    """Write a pose given at construction into the stage (stage units in, metres stored).

    A referenced file's prim is its frame; any other prim is its body. ``translation`` is
    relative to the parent, ``position`` to the world: the same for prims whose parent is
    the world (objects and references under ``/World``), which is what ambulo places."""
    if position is None and translation is None and orientation is None:
        return
    world = current_world("creating prims with a pose")
    stage = world.stage
    target = resolve_spec_prim(stage, prim_path)
    place = position if position is not None else translation
    if place is not None:
        what = "position" if position is not None else "translation"
        xyz = check_vector(what, place, 3, "pass (x, y, z) in m (in stage units if the World sets stage_units_in_meters), finite")
        target.pos = [v * world.stage_units_in_meters for v in xyz]
    if orientation is not None:
        target.quat = list(check_quat("orientation", orientation))


class XFormPrim:
    """A prim with a world pose: a body (or the root body of a referenced subtree).

    Args:
      prim_path: path of an existing prim, or where subclasses create one.
      name: scene registry name; defaults to the prim path's last component.
      position: (3,) stage units, world frame; for a referenced file, where its prim (the
        file's origin) goes, as in Isaac: the root body keeps its offset in the file.
      translation: (3,) stage units relative to the parent prim (the same under ``/World``).
      orientation: (4,) w x y z.
    """

    _requires_drives = False


    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        atomic_constructor(cls)  # a failing constructor leaves the stage as it was
    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None,
                 translation=None):
        if not prim_path.startswith("/"):
            raise ValueError(f"prim paths are absolute, like '/World/Cube'; got {prim_path!r}")
        self.prim_path = prim_path
        self.name = name or prim_path.rstrip("/").rsplit("/", 1)[-1]
        self._world: World = _NotInitialized(prim_path)
        self.entity: Entity | None = None
        """The batched view this prim wraps (after ``world.reset()``)."""
        self._default_pose: tuple[torch.Tensor | None, torch.Tensor | None] = (None, None)
        self._initial_pose: tuple[torch.Tensor, torch.Tensor] | None = None
        place_on_stage(prim_path, position, translation, orientation)

    # -- lifecycle ------------------------------------------------------------
    def initialize(self, world: World | None = None) -> None:
        """Resolve the prim in the compiled model (``world.reset()`` calls it; Isaac's
        ``initialize(physics_sim_view)`` argument, if given, is ignored for the current World)."""
        if world is None or not hasattr(world, "engine"):
            world = current_world("initializing a prim")
        if world.engine is None:
            raise RuntimeError(f"{self.prim_path}: the World has not been reset yet; call world.reset()")
        self._world = world
        self.entity = Entity(world.engine, self.prim_path, require_drives=self._requires_drives)
        if not self.entity.is_floating:
            world.engine.forward()  # a fixed root's pose is derived
        data = self.entity.data
        self._initial_pose = (data.root_pos_w.clone(), data.root_quat_w.clone())

    def post_reset(self) -> None:
        position, orientation = self._default_pose
        if position is not None or orientation is not None:
            self._write_pose(position, orientation)

    def is_valid(self) -> bool:
        return self.entity is not None

    @property
    def prim(self):
        """The ``Usd.Prim`` at ``prim_path`` on the World's USD stage (``world.usd``)."""
        world = self._world if self.entity is not None else current_world_or_none()
        if world is None:
            raise RuntimeError(f"{self.prim_path}: no World; create a World() first")
        return world.synced_usd().stage.GetPrimAtPath(self.prim_path)

    @property
    def _data(self):
        self._require_initialized()
        return self.entity.data

    def _require_initialized(self) -> None:
        """Raise one line naming the prim and the fix while it has no entity (before ``world.reset()``)."""
        if self.entity is None:
            raise RuntimeError(
                f"{self.prim_path} is not initialized: add it to world.scene and call world.reset()"
            )

    # -- stage units -------------------------------------------------------------
    @property
    def _units(self) -> float:
        """Metres per stage unit."""
        return float(self._world.stage_units_in_meters)

    def _in_len(self, value, trailing: tuple[int, ...], what: str) -> torch.Tensor:
        """A length-valued user input (stage units) as an (N, *trailing) tensor in metres."""
        return self._world._in(value, trailing, what) * self._units

    def _out_len(self, tensor: torch.Tensor):
        """A length-valued (N, ...) tensor in metres as the user's array in stage units."""
        return self._world._out(tensor / self._units)

    # -- pose ------------------------------------------------------------------
    def get_world_pose(self):
        """(position (.., 3) stage units, orientation (.., 4) w x y z) in the world frame."""
        data = self._data
        return self._out_len(data.root_pos_w), self._world._out(data.root_quat_w)

    def set_world_pose(self, position=None, orientation=None) -> None:
        """Move the prim: position (.., 3) stage units and orientation (.., 4) w x y z, world
        frame (the quaternion is normalized; NaN, inf and a zero quaternion are refused)."""
        self._write_pose(*self._pose_in(position, orientation))

    def get_local_pose(self):
        """(translation (.., 3) stage units, orientation (.., 4)) relative to the parent prim:
        the nearest ancestor path that is a body or a referenced file's frame; the world
        (so the same as ``get_world_pose``) for prims directly under ``/World``."""
        data = self._data
        pos, quat = data.root_pos_w, data.root_quat_w
        parent = self._parent_pose()
        if parent is not None:
            p_pos, p_quat = parent
            pos = quat_rotate_inverse(p_quat, pos - p_pos)
            quat = quat_mul(p_quat * _CONJ.to(p_quat.device), quat)
        return self._out_len(pos), self._world._out(quat)

    def set_local_pose(self, translation=None, orientation=None) -> None:
        """Move the prim by a pose relative to its parent prim (see ``get_local_pose``)."""
        pos, quat = self._pose_in(translation, orientation)
        parent = self._parent_pose()
        if parent is not None:
            p_pos, p_quat = parent
            if pos is not None:
                pos = p_pos + quat_rotate(p_quat, pos)
            if quat is not None:
                quat = quat_mul(p_quat, quat / quat.norm(dim=-1, keepdim=True))
        self._write_pose(pos, quat)

    def _parent_pose(self) -> tuple[torch.Tensor, torch.Tensor] | None:
        """World pose (N, 3) m, (N, 4) of the parent prim, or None when it is the world."""
        return _parent_pose(self._world, self.prim_path)

    # -- default state ------------------------------------------------------------
    def get_default_state(self) -> XFormPrimState:
        """The pose ``world.reset()`` restores: set by ``set_default_state``, else the pose at
        initialization (stage units; w x y z)."""
        self._require_initialized()
        position, orientation = self._default_pose
        start_pos, start_quat = self._initial_pose
        return XFormPrimState(
            position=self._out_len(start_pos if position is None else position),
            orientation=self._world._out(start_quat if orientation is None else orientation))

    def set_default_state(self, position=None, orientation=None) -> None:
        """Pose restored by every ``world.reset()`` (stage units; w x y z)."""
        position, orientation = self._pose_in(position, orientation)
        old_pos, old_quat = self._default_pose
        self._default_pose = (old_pos if position is None else position,
                              old_quat if orientation is None else orientation)

    def _pose_in(self, position, orientation):
        world = self._world
        pos = None if position is None else self._in_len(position, (3,), "position")
        quat = None if orientation is None else world._in(orientation, (4,), "orientation")
        if quat is not None and quat.device.type == "cpu" and bool((quat.norm(dim=-1) < 1e-9).any()):
            raise InvalidValueError("orientation", Described("a zero quaternion"), "it is no rotation",
                                    "pass a (w, x, y, z) quaternion such as (1, 0, 0, 0)")
        return pos, quat

    def _write_pose(self, pos: torch.Tensor | None, quat: torch.Tensor | None) -> None:
        self._require_initialized()
        if quat is not None:
            quat = quat / quat.norm(dim=-1, keepdim=True)
        self.entity.write_root_pose(pos, quat)
        self.entity.engine.forward()


class RigidPrim(XFormPrim):
    """A rigid body: pose plus velocities and mass.

    Args (beyond ``XFormPrim``'s): ``mass`` kg or ``density`` kg/m^3 of the body (applied
    at initialization), ``linear_velocity`` (3,) stage units/s and ``angular_velocity``
    (3,) rad/s, world frame: its initial velocity, restored by every ``world.reset()``.
    """

    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None,
                 translation=None, mass: float | None = None, density: float | None = None,
                 linear_velocity=None, angular_velocity=None):
        super().__init__(prim_path, name, position, orientation, translation)
        self._mass = None if mass is None else check_positive("mass", mass, "pass kg, e.g. 1.0")
        self._density = None if density is None else check_positive("density", density,
                                                                       "pass kg/m^3, e.g. 1000 (water)")
        self._init_velocity = (
            None if linear_velocity is None else check_vector("linear_velocity", linear_velocity, 3,
                                                                 "pass (vx, vy, vz) in stage units/s"),
            None if angular_velocity is None else check_vector("angular_velocity", angular_velocity, 3,
                                                                  "pass (wx, wy, wz) in rad/s"))
        self._default_velocity: tuple[torch.Tensor | None, torch.Tensor | None] = (None, None)

    def initialize(self, world: World | None = None) -> None:
        super().initialize(world)
        if self._mass is not None:
            self.set_mass(self._mass)
        elif self._density is not None:
            self.set_density(self._density)
        lin, ang = self._init_velocity
        if (lin is not None or ang is not None) and all(v is None for v in self._default_velocity):
            self.set_default_state(linear_velocity=lin, angular_velocity=ang)
            self.post_reset()

    def post_reset(self) -> None:
        super().post_reset()
        lin, ang = self._default_velocity
        if lin is not None or ang is not None:
            self.entity.write_root_velocity(lin_vel_w=lin, ang_vel_w=ang)
            self.entity.engine.forward()

    # -- velocities ---------------------------------------------------------------
    def get_linear_velocity(self):
        """(.., 3) stage units/s, velocity of the body frame origin, world frame."""
        return self._out_len(self._data.root_lin_vel_w)

    def get_angular_velocity(self):
        """(.., 3) rad/s, world frame."""
        return self._world._out(self._data.root_ang_vel_w)

    def get_velocities(self):
        """(linear (.., 3) stage units/s, angular (.., 3) rad/s), world frame."""
        return self.get_linear_velocity(), self.get_angular_velocity()

    def set_linear_velocity(self, velocity) -> None:
        self._require_initialized()
        self.entity.write_root_velocity(lin_vel_w=self._in_len(velocity, (3,), "velocity"))
        self.entity.engine.forward()

    def set_angular_velocity(self, velocity) -> None:
        self._require_initialized()
        self.entity.write_root_velocity(ang_vel_w=self._world._in(velocity, (3,), "angular velocity"))
        self.entity.engine.forward()

    def get_current_dynamic_state(self) -> DynamicState:
        """Pose and velocities now (stage units, w x y z, stage units/s, rad/s; world frame)."""
        position, orientation = self.get_world_pose()
        return DynamicState(position, orientation, self.get_linear_velocity(), self.get_angular_velocity())

    def get_default_state(self) -> DynamicState:
        """The pose and velocities ``world.reset()`` restores (see ``set_default_state``)."""
        pose = XFormPrim.get_default_state(self)
        lin, ang = self._default_velocity
        zeros = torch.zeros_like(self._initial_pose[0])
        return DynamicState(pose.position, pose.orientation,
                            self._out_len(zeros if lin is None else lin),
                            self._world._out(zeros if ang is None else ang))

    def set_default_state(self, position=None, orientation=None, linear_velocity=None,
                          angular_velocity=None) -> None:
        """Pose (stage units; w x y z) and velocities (stage units/s; rad/s, world frame)
        restored by every ``world.reset()``; None leaves a part as it was."""
        super().set_default_state(position, orientation)
        old_lin, old_ang = self._default_velocity
        if linear_velocity is not None:
            old_lin = self._in_len(linear_velocity, (3,), "linear_velocity").clone()
        if angular_velocity is not None:
            old_ang = self._world._in(angular_velocity, (3,), "angular_velocity").clone()
        self._default_velocity = (old_lin, old_ang)

    # -- mass ------------------------------------------------------------------------
    def get_mass(self):
        """(..,) kg."""
        return self._world._out(self._data.body_mass[:, 0])

    def set_mass(self, mass) -> None:
        """Body mass, kg; the inertia scales with it (the shape's mass distribution is kept)."""
        value = self._world._in(mass, (), "mass")
        if (value <= 0).any():
            raise InvalidValueError("mass", mass, "it must be > 0", "pass kg, e.g. 1.0")
        self._require_initialized()
        engine, body = self.entity.engine, self.entity.root_body_id
        masses = engine.model_field("body_mass")
        ratio = value / masses[:, body].clamp_min(1e-12)
        engine.model_field("body_inertia")[:, body] *= ratio.unsqueeze(-1)
        masses[:, body] = value
        engine.set_const()

    def get_density(self):
        """(..,) kg/m^3: mass over the volume of the body's collision shapes."""
        return self._world._out(self._data.body_mass[:, 0] / self._volume_m3())

    def set_density(self, density) -> None:
        """Set the mass to ``density`` (kg/m^3) times the volume of the body's shapes."""
        value = self._world._in(density, (), "density")
        if (value <= 0).any():
            raise InvalidValueError("density", density, "it must be > 0", "pass kg/m^3, e.g. 1000")
        self.set_mass(value * self._volume_m3())

    def _volume_m3(self) -> float:
        return _body_volume_m3(self._world.model, self.entity.root_body_id, self.prim_path)


def _parent_pose(world: World, prim_path: str) -> tuple[torch.Tensor, torch.Tensor] | None:
    """World pose ((N, 3) m, (N, 4)) of the nearest ancestor of ``prim_path`` that is a body of
    the model or a frame of the stage (a referenced file's prim); None when there is none."""
    engine, model, stage = world.engine, world.model, world.stage
    parts = prim_path.rstrip("/").split("/")
    for depth in range(len(parts) - 1, 1, -1):
        path = "/".join(parts[:depth])
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, path)
        if body >= 0:
            return engine.xpos[:, body], engine.xquat[:, body]
        frame = stage.frame(path)
        if frame is not None:
            return _frame_pose(world, frame)
    return None


def _frame_pose(world: World, frame) -> tuple[torch.Tensor, torch.Tensor]:
    """World pose of a stage frame: its chain of frames composed onto its parent body."""
    f64 = dict(dtype=world.engine.dtype, device=world.engine.device)
    body_name = frame.parent.name
    pos, quat = torch.zeros(3, **f64), torch.tensor([1.0, 0.0, 0.0, 0.0], **f64)
    while frame is not None:
        f_quat = torch.tensor(list(frame.quat), **f64)
        f_quat = f_quat / f_quat.norm()
        pos = torch.tensor(list(frame.pos), **f64) + quat_rotate(f_quat, pos)
        quat = quat_mul(f_quat, quat)
        frame = frame.frame
    body = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, body_name)
    if body <= 0:  # on the world body
        return pos.expand(world.num_worlds, 3), quat.expand(world.num_worlds, 4)
    b_pos, b_quat = world.engine.xpos[:, body], world.engine.xquat[:, body]
    return b_pos + quat_rotate(b_quat, pos.expand_as(b_pos)), quat_mul(b_quat, quat.expand_as(b_quat))


_G = mujoco.mjtGeom


def _body_volume_m3(model: mujoco.MjModel, body: int, prim_path: str) -> float:
    """Volume of the body's collision shapes (primitives only), m^3."""
    volume = 0.0
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != body or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        kind, (a, b, c) = model.geom_type[g], model.geom_size[g]
        if kind == _G.mjGEOM_BOX:
            volume += 8.0 * a * b * c
        elif kind == _G.mjGEOM_SPHERE:
            volume += 4.0 / 3.0 * math.pi * a**3
        elif kind == _G.mjGEOM_ELLIPSOID:
            volume += 4.0 / 3.0 * math.pi * a * b * c
        elif kind == _G.mjGEOM_CYLINDER:
            volume += math.pi * a**2 * 2.0 * b
        elif kind == _G.mjGEOM_CAPSULE:
            volume += math.pi * a**2 * 2.0 * b + 4.0 / 3.0 * math.pi * a**3
        else:
            raise ValueError(f"{prim_path}: density needs primitive shapes (box, sphere, ellipsoid, cylinder, "
                             "capsule); this body has a mesh or plane: use set_mass(kg) instead")
    if volume <= 0.0:
        raise ValueError(f"{prim_path} has no collision shapes, so no volume: use set_mass(kg) instead")
    return volume


atomic_constructor(XFormPrim)
