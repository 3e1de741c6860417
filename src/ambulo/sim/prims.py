"""XFormPrim and RigidPrim: Isaac's prim API as a thin wrapper over ``ambulo.core.Entity``.

Getters return arrays of shape (N, ...) -- or (...) when the World has one world --
as numpy (Isaac's default backend) or torch; setters accept either shape. Poses
are world frame: position (m) and quaternion (w, x, y, z).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from ..core import Entity
from ..core.paths import resolve_spec_body
from ..utils.checks import Described, InvalidValueError, check_quat, check_vector
from .current import current_world

if TYPE_CHECKING:
    from .world import World


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

    _requires_drives = False

    def __init__(self, prim_path: str, name: str | None = None, position=None, orientation=None):
        if not prim_path.startswith("/"):
            raise ValueError(f"prim paths are absolute, like '/World/Cube'; got {prim_path!r}")
        self.prim_path = prim_path
        self.name = name or prim_path.rstrip("/").rsplit("/", 1)[-1]
        self._world: World = _NotInitialized(prim_path)
        self.entity: Entity | None = None
        """The batched view this prim wraps (after ``world.reset()``)."""
        self._default_pose: tuple[torch.Tensor | None, torch.Tensor | None] = (None, None)
        if position is not None or orientation is not None:
            stage = current_world("creating prims with a pose").stage
            # a referenced file's prim is its frame; otherwise move the body itself
            target = stage.frame(prim_path) or resolve_spec_body(stage, prim_path)
            if position is not None:
                target.pos = list(check_vector("position", position, 3, "pass (x, y, z) in m, finite"))
            if orientation is not None:
                target.quat = list(check_quat("orientation", orientation))

    # -- lifecycle ------------------------------------------------------------
    def initialize(self, world: World) -> None:
        """Resolve the prim in the compiled model (called by ``world.reset()``)."""
        self._world = world
        self.entity = Entity(world.engine, self.prim_path, require_drives=self._requires_drives)

    def post_reset(self) -> None:
        position, orientation = self._default_pose
        if position is not None or orientation is not None:
            self._write_pose(position, orientation)

    def is_valid(self) -> bool:
        return self.entity is not None

    @property
    def _data(self):
        if self.entity is None:
            raise RuntimeError(
                f"{self.prim_path} is not initialized: add it to world.scene and call world.reset()"
            )
        return self.entity.data

    # -- pose ------------------------------------------------------------------
    def get_world_pose(self):
        """(position (.., 3) m, orientation (.., 4) w x y z) in the world frame."""
        data = self._data
        return self._world._out(data.root_pos_w), self._world._out(data.root_quat_w)

    def set_world_pose(self, position=None, orientation=None) -> None:
        """Move the prim: position (.., 3) m and orientation (.., 4) w x y z, world frame
        (the quaternion is normalized; NaN, inf and a zero quaternion are refused)."""
        self._write_pose(*self._pose_in(position, orientation))

    def set_default_state(self, position=None, orientation=None) -> None:
        """Pose restored by every ``world.reset()``."""
        self._default_pose = self._pose_in(position, orientation)

    def _pose_in(self, position, orientation):
        world = self._world
        pos = None if position is None else world._in(position, (3,), "position")
        quat = None if orientation is None else world._in(orientation, (4,), "orientation")
        if quat is not None and quat.device.type == "cpu" and bool((quat.norm(dim=-1) < 1e-9).any()):
            raise InvalidValueError("orientation", Described("a zero quaternion"), "it is no rotation",
                                    "pass a (w, x, y, z) quaternion such as (1, 0, 0, 0)")
        return pos, quat

    def _write_pose(self, pos: torch.Tensor | None, quat: torch.Tensor | None) -> None:
        self._data
        if quat is not None:
            quat = quat / quat.norm(dim=-1, keepdim=True)
        self.entity.write_root_pose(pos, quat)
        self.entity.engine.forward()


class RigidPrim(XFormPrim):
    """A rigid body: pose plus velocities and mass."""

    def get_linear_velocity(self):
        """(.., 3) m/s, velocity of the body frame origin, world frame."""
        return self._world._out(self._data.root_lin_vel_w)

    def get_angular_velocity(self):
        """(.., 3) rad/s, world frame."""
        return self._world._out(self._data.root_ang_vel_w)

    def get_velocities(self):
        return self.get_linear_velocity(), self.get_angular_velocity()

    def set_linear_velocity(self, velocity) -> None:
        self._data
        self.entity.write_root_velocity(lin_vel_w=self._world._in(velocity, (3,), "velocity"))
        self.entity.engine.forward()

    def set_angular_velocity(self, velocity) -> None:
        self._data
        self.entity.write_root_velocity(ang_vel_w=self._world._in(velocity, (3,), "angular velocity"))
        self.entity.engine.forward()

    def get_mass(self):
        """(..,) kg."""
        return self._world._out(self._data.body_mass[:, 0])

    def set_mass(self, mass) -> None:
        value = self._world._in(mass, (), "mass")
        if (value <= 0).any():
            raise InvalidValueError("mass", mass, "it must be > 0", "pass kg, e.g. 1.0")
        self._data
        self.entity.engine.model_field("body_mass")[:, self.entity.root_body_id] = value
        self.entity.engine.set_const()
