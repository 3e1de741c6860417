"""PhysicsCfg: every solver and integration setting of a scene, applied to the spec in one place.

Every app (the Isaac-style ``World``, RL tasks, the data generator) states its physics as a
``PhysicsCfg`` and ``apply_physics`` is the only code that writes ``spec.option``; a robot
file's own ``<option>`` is overridden, so two apps loading the same robot with the same
config simulate the same model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import mujoco

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}
_CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}
_SOLVERS = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG,
            "pgs": mujoco.mjtSolver.mjSOL_PGS}


@dataclass(kw_only=True)
class PhysicsCfg:
    """MuJoCo solver and integrator settings (``mjOption``), the same for every world."""

    timestep_s: float = 0.005
    """Simulated time of one MuJoCo step, s."""
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    """Gravity in the world frame, m/s^2."""
    integrator: Literal["euler", "implicitfast", "implicit", "rk4"] = "implicitfast"
    """implicitfast integrates drive damping implicitly (Isaac's implicit PD drives)."""
    solver: Literal["newton", "cg", "pgs"] = "newton"
    solver_iterations: int = 50
    """Main solver iterations; Newton converges in a few, 50 bounds hard contact cases."""
    ls_iterations: int = 50
    """Line-search iterations per solver iteration."""
    cone: Literal["pyramidal", "elliptic"] = "pyramidal"
    """Friction cone; elliptic is more accurate for sliding, pyramidal cheaper."""
    impratio: float = 1.0
    """Frictional-to-normal constraint impedance ratio (>1 reduces slip, elliptic cones only)."""
    tolerance: float = 1e-8
    """Solver early-termination tolerance."""

    def __post_init__(self):
        if self.timestep_s <= 0:
            raise ValueError(f"timestep_s must be > 0, got {self.timestep_s}")
        for name, table in (("integrator", INTEGRATORS), ("cone", _CONES), ("solver", _SOLVERS)):
            if getattr(self, name) not in table:
                raise ValueError(f"unknown {name} {getattr(self, name)!r}; use one of {sorted(table)}")
        if self.solver_iterations < 1 or self.ls_iterations < 1:
            raise ValueError("solver_iterations and ls_iterations must be >= 1")


def apply_physics(spec: mujoco.MjSpec, cfg: PhysicsCfg) -> None:
    """Write ``cfg`` into ``spec.option`` (the one place ambulo sets physics options)."""
    option = spec.option
    option.timestep = cfg.timestep_s
    option.gravity = list(cfg.gravity_m_s2)
    option.integrator = INTEGRATORS[cfg.integrator]
    option.solver = _SOLVERS[cfg.solver]
    option.iterations = cfg.solver_iterations
    option.ls_iterations = cfg.ls_iterations
    option.cone = _CONES[cfg.cone]
    option.impratio = cfg.impratio
    option.tolerance = cfg.tolerance


_OPTION_FIELDS = [f for f in dir(mujoco.MjSpec().option) if not f.startswith("_")]


def match_options(child: mujoco.MjSpec, parent: mujoco.MjSpec) -> None:
    """Give ``child`` the options of ``parent`` before attaching it: MuJoCo refuses to attach a
    spec whose options conflict, and ``apply_physics`` sets the scene's options at compile."""
    for name in _OPTION_FIELDS:
        setattr(child.option, name, getattr(parent.option, name))


__all__ = ["INTEGRATORS", "PhysicsCfg", "apply_physics", "match_options"]
