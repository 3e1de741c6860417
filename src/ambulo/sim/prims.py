"""XFormPrim and RigidPrim: pose, velocity and mass of any body on the stage, over all worlds.

Getters return arrays of shape (N, ...) -- or (...) when the World has one world --
as numpy (Isaac's default backend) or torch; setters accept either shape. Poses
are world frame: position (m) and quaternion (w, x, y, z).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import torch

from ..utils.math import quat_rotate_inverse
from .paths import resolve_body, resolve_spec_body

if TYPE_CHECKING:
    from .world import World

_FREE = mujoco.mjtJoint.mjJNT_FREE


class _NotInitialized:
    """Stands in for the World until ``initialize``: any use says what to do."""

    def __init__(self, prim_path: str):
        self._prim_path = prim_path

    def __getattr__(self, name):
        raise RuntimeError(
            f"{self._prim_path} is not initialized: add it to world.scene and call world.reset()"
        )


class XFormPrim:
    """A prim with a world pose: a body (or the root body of a referenced subtree).

    Args:
      prim_path: path of an existing prim, or where subclasses create one.
      name: scene registry name; defaults to the prim path's last component.
      position, orientation: if given, set as the prim's initial pose (m; w x y z).
    """

    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None):
        if not prim_path.startswith("/"):
            raise ValueError(f"prim paths are absolute, like '/World/Cube'; got {prim_path!r}")
        self.prim_path = prim_path
        self.name = name or prim_path.rstrip("/").rsplit("/", 1)[-1]
        self._world: World = _NotInitialized(prim_path)
        self._body_id: int | None = None
        self._free_qpos: int | None = None
        self._free_qvel: int | None = None
        self._default_pose: tuple[torch.Tensor | None, torch.Tensor | None] = (None, None)
        if position is not None or orientation is not None:
            from .world import World  # noqa: PLC0415

            world = World.instance()
            if world is None:
                raise RuntimeError("create a World before creating prims")
            # a referenced file's prim is its frame; otherwise move the body itself
            target = world.stage.frame(prim_path) or resolve_spec_body(world.stage, prim_path)
            if position is not None:
                target.pos = [float(v) for v in position]
            if orientation is not None:
                target.quat = [float(v) for v in orientation]

    # -- lifecycle ------------------------------------------------------------
    def initialize(self, world: World) -> None:
        """Resolve the prim in the compiled model (called by ``world.reset()``)."""
        self._world = world
        model = world.model
        self._body_id = resolve_body(model, self.prim_path)
        jnt = model.body_jntadr[self._body_id]
        if model.body_jntnum[self._body_id] >= 1 and model.jnt_type[jnt] == _FREE:
            self._free_qpos = int(model.jnt_qposadr[jnt])
            self._free_qvel = int(model.jnt_dofadr[jnt])
        else:
            self._free_qpos = self._free_qvel = None

    def post_reset(self) -> None:
        position, orientation = self._default_pose
        if position is not None or orientation is not None:
            self._write_pose(position, orientation)

    def is_valid(self) -> bool:
        return self._body_id is not None

    @property
    def _engine(self):
        if self._body_id is None:
            raise RuntimeError(
                f"{self.prim_path} is not initialized: add it to world.scene and call world.reset()"
            )
        return self._world.engine

    # -- pose ------------------------------------------------------------------
    def get_world_pose(self):
        """(position (.., 3) m, orientation (.., 4) w x y z) in the world frame."""
        engine = self._engine
        return (self._world._out(engine.xpos[:, self._body_id]),
                self._world._out(engine.xquat[:, self._body_id]))

    def set_world_pose(self, position=None, orientation=None) -> None:
        world = self._world
        pos = None if position is None else world._in(position, (3,), "position")
        quat = None if orientation is None else world._in(orientation, (4,), "orientation")
        self._write_pose(pos, quat)

    def set_default_state(self, position=None, orientation=None) -> None:
        """Pose restored by every ``world.reset()``."""
        world = self._world
        self._default_pose = (
            None if position is None else world._in(position, (3,), "position"),
            None if orientation is None else world._in(orientation, (4,), "orientation"),
        )

    def _write_pose(self, pos: torch.Tensor | None, quat: torch.Tensor | None) -> None:
        engine = self._engine
        if quat is not None:
            quat = quat / quat.norm(dim=-1, keepdim=True)
        if self._free_qpos is not None:
            a = self._free_qpos
            if pos is not None:
                engine.qpos[:, a:a + 3] = pos
            if quat is not None:
                engine.qpos[:, a + 3:a + 7] = quat
        elif self._world.model.body_parentid[self._body_id] == 0:
            # a static body hanging from the world: move it per world in the model
            if pos is not None:
                engine.model_field("body_pos")[:, self._body_id] = pos
            if quat is not None:
                engine.model_field("body_quat")[:, self._body_id] = quat
        else:
            raise ValueError(
                f"{self.prim_path} is attached to a parent body by joints; move the "
                "articulation's root or set its joint positions instead"
            )
        engine.forward()


class RigidPrim(XFormPrim):
    """A rigid body: pose plus velocities and mass."""

    def get_linear_velocity(self):
        """(.., 3) m/s, velocity of the body frame origin, world frame."""
        return self._world._out(self._linear_velocity_w())

    def get_angular_velocity(self):
        """(.., 3) rad/s, world frame."""
        return self._world._out(self._engine.cvel[:, self._body_id, :3])

    def get_velocities(self):
        return self.get_linear_velocity(), self.get_angular_velocity()

    def _linear_velocity_w(self) -> torch.Tensor:
        engine = self._engine
        # cvel is expressed at the subtree centre of mass of the kinematic tree's root
        root = self._world.model.body_rootid[self._body_id]
        cvel = engine.cvel[:, self._body_id]
        offset = engine.xpos[:, self._body_id] - engine.subtree_com[:, root]
        return cvel[:, 3:] + torch.cross(cvel[:, :3], offset, dim=-1)

    def set_linear_velocity(self, velocity) -> None:
        self._require_free("set_linear_velocity")
        a = self._free_qvel
        self._engine.qvel[:, a:a + 3] = self._world._in(velocity, (3,), "velocity")
        self._engine.forward()

    def set_angular_velocity(self, velocity) -> None:
        self._require_free("set_angular_velocity")
        omega_w = self._world._in(velocity, (3,), "angular velocity")
        quat = self._engine.xquat[:, self._body_id]
        # a free joint's angular velocity is in the body frame
        self._engine.qvel[:, self._free_qvel + 3:self._free_qvel + 6] = quat_rotate_inverse(quat, omega_w)
        self._engine.forward()

    def get_mass(self):
        """(..,) kg."""
        return self._world._out(self._engine.model_field("body_mass")[:, self._body_id])

    def set_mass(self, mass) -> None:
        value = self._world._in(mass, (), "mass")
        if (value <= 0).any():
            raise ValueError("mass must be > 0 kg")
        self._engine.model_field("body_mass")[:, self._body_id] = value
        self._engine.set_const()

    def _require_free(self, what: str) -> None:
        self._engine
        if self._free_qvel is None:
            raise ValueError(f"{what}: {self.prim_path} has no free joint (it is fixed or jointed)")
