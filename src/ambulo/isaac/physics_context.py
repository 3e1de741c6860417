"""Isaac's ``PhysicsContext``: the physics scene's settings, on the World's USD stage and physics.

Isaac authors a ``PhysicsScene`` prim; so does this (gravity is read from it at every
``reset()``). Settings PhysX has and MuJoCo does not (GPU dynamics, broadphase type, CCD) are
accepted and logged, since they change performance, not the physics a script expects.
"""

from __future__ import annotations

import logging

from ambulo.sim.current import current_world_or_none

from .stage_utils import get_current_stage, get_stage_units

_log = logging.getLogger("ambulo.isaac")


class PhysicsContext:
    def __init__(self, physics_dt: float | None = None, prim_path: str = "/physicsScene", sim_params=None,
                 set_defaults: bool = True):
        from pxr import Gf, UsdPhysics

        stage = get_current_stage()
        path = prim_path if prim_path.startswith("/World") else "/World" + prim_path
        self._scene = UsdPhysics.Scene.Define(stage, path)
        self.prim_path = path
        if set_defaults:
            self._scene.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
            self._scene.CreateGravityMagnitudeAttr(9.81 / get_stage_units())
        if physics_dt is not None:
            self.set_physics_dt(physics_dt)

    def _world(self):
        world = current_world_or_none()
        if world is None:
            raise RuntimeError("create a World before changing its time step")
        return world

    def set_physics_dt(self, dt: float = 1.0 / 60.0, substeps: int = 1) -> None:
        self._world().set_simulation_dt(physics_dt=dt)

    def get_physics_dt(self) -> float:
        return self._world().get_physics_dt()

    def set_gravity(self, value: float) -> None:
        """Gravity along the up axis in stage units/s² (Isaac passes -9.81 for Earth's)."""
        from pxr import Gf

        self._scene.GetGravityDirectionAttr().Set(Gf.Vec3f(0.0, 0.0, -1.0 if value <= 0 else 1.0))
        self._scene.GetGravityMagnitudeAttr().Set(abs(float(value)))

    def get_gravity(self):
        direction = self._scene.GetGravityDirectionAttr().Get()
        return tuple(direction), float(self._scene.GetGravityMagnitudeAttr().Get())

    def _accepted(self, name: str, value) -> None:
        _log.info("PhysicsContext.%s(%r): a PhysX setting MuJoCo has no counterpart for; ignored", name, value)

    def enable_gpu_dynamics(self, flag: bool) -> None:
        self._accepted("enable_gpu_dynamics", flag)

    def set_broadphase_type(self, broadphase_type: str) -> None:
        self._accepted("set_broadphase_type", broadphase_type)

    def enable_ccd(self, flag: bool) -> None:
        self._accepted("enable_ccd", flag)

    def set_solver_type(self, solver_type: str) -> None:
        if solver_type not in ("TGS", "PGS"):
            raise ValueError(f"solver_type must be 'TGS' or 'PGS', got {solver_type!r}")
        self._accepted("set_solver_type", solver_type)


__all__ = ["PhysicsContext"]
