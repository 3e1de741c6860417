"""PhysicsCfg: every solver and integration setting of a scene, applied to the spec in one place.

Every app (the Isaac-style ``World``, RL tasks, the data generator) states its physics as a
``PhysicsCfg`` and ``apply_physics`` is the only code that writes ``spec.option``; a robot
file's own ``<option>`` is overridden, so two apps loading the same robot with the same
config simulate the same model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import mujoco

from ..utils.checks import InvalidValueError, check_int, check_positive, check_vector
from ..utils.validate import Checked

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}
_CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}
BROADPHASES = ("auto", "nxn", "sap_tile", "sap_segmented")
"""``PhysicsCfg.broadphase`` values; the last three name MuJoCo Warp's ``BroadphaseType`` members."""
_SOLVERS = {"newton": mujoco.mjtSolver.mjSOL_NEWTON, "cg": mujoco.mjtSolver.mjSOL_CG,
            "pgs": mujoco.mjtSolver.mjSOL_PGS}


@dataclass(kw_only=True)
class PhysicsCfg(Checked):
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
    max_contacts_per_world: int | None = None
    """GPU engine: contact buffer per world (MuJoCo Warp's ``nconmax``); None sizes it from the
    model. Raise it when the engine reports a contact overflow. The CPU engine grows its own."""
    max_constraints_per_world: int | None = None
    """GPU engine: constraint rows per world (``njmax``); None sizes it from the contacts."""
    broadphase: Literal["auto", "nxn", "sap_tile", "sap_segmented"] = "auto"
    """GPU engine: how MuJoCo Warp finds candidate geom pairs. ``nxn`` tests every pair that
    contype/conaffinity allow; the sweep-and-prune kinds sort bounding spheres along one axis per
    world. ``auto`` is MuJoCo Warp's choice (nxn below 250,000 allowed pairs). On humanoid-rough
    (23 robot geoms x 489 terrain boxes: 11,247 pairs a world) nxn is the fastest on an H200,
    sap_tile half as fast (``benchmarks/rough_terrain.py --broadphases``). The CPU engine has its
    own and ignores this."""
    compile_workers: int | None = None
    """GPU engine: threads that compile MuJoCo Warp's kernel modules before a model's first step
    (``engine.warp_precompile``; Warp alone compiles them one at a time at first launch). None:
    the machine's cores, at most 16; 0 or 1: Warp's serial compile. Only a first run on a machine
    (an empty kernel cache) compiles; later runs load the cache either way."""
    compile_processes: int = 0
    """GPU engine: with more than 1, that many forked processes compile the modules into Warp's
    kernel cache before the threads load them (``warp_precompile.compile_in_processes``: within
    one process NVRTC compiles largely one at a time: 16 threads overlapped 2.2 compiles on an H200
    host). 0: threads only (the default until it is timed on a GPU: ``benchmarks/warp_compile.py
    --processes``). Ignored where the OS has no fork."""

    def __post_init__(self):
        self.check()
        super().__post_init__()

    def check(self) -> None:
        """Raise ``InvalidValueError`` (one line: the field, why, the fix) on a bad setting;
        ``apply_physics`` calls it again, for configs edited after construction."""
        check_timestep("timestep_s", self.timestep_s)
        check_vector("gravity_m_s2", self.gravity_m_s2, 3, "pass three finite numbers in m/s^2, e.g. (0, 0, -9.81)")
        for name, table in (("integrator", INTEGRATORS), ("cone", _CONES), ("solver", _SOLVERS)):
            if getattr(self, name) not in table:
                raise InvalidValueError(name, getattr(self, name), f"unknown {name}",
                                        f"use one of {sorted(table)}")
        for name in ("solver_iterations", "ls_iterations"):
            check_int(name, getattr(self, name), f"pass a whole number >= 1, e.g. {name}=50", minimum=1)
        check_positive("impratio", self.impratio, "pass a ratio > 0; 1 is MuJoCo's default")
        check_positive("tolerance", self.tolerance, "pass a small number >= 0, e.g. 1e-8 (0 never stops early)",
                       allow_zero=True)
        if self.broadphase not in BROADPHASES:
            raise InvalidValueError("broadphase", self.broadphase, "unknown broadphase",
                                    f"use one of {list(BROADPHASES)}")
        check_int("compile_processes", self.compile_processes, "pass 0 (threads only) or a whole number of "
                  "processes, e.g. compile_processes=8", minimum=0)
        if self.compile_workers is not None:
            check_int("compile_workers", self.compile_workers, "pass None (the cores) or a whole number >= 0, "
                      "e.g. compile_workers=8 (0: serial)", minimum=0)
        for name in ("max_contacts_per_world", "max_constraints_per_world"):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), f"pass None (sized from the model) or a whole number, "
                          f"e.g. {name}=256", minimum=1)


MAX_TIMESTEP_S = 0.05
"""The largest MuJoCo step ambulo accepts, s. MuJoCo's default contact time constant is 0.02 s
and it silently raises any constraint's time constant to 2 timesteps, so above ~0.01 s contacts
already soften, and at 0.05 s an object falling at 2 m/s moves 0.1 m in one step (through
most collision geoms before a contact exists); a drive of typical gains (kp 100 N m/rad on a 0.01 kg m^2 link, period 0.06 s) is unstable there. Larger
steps are almost always a unit mistake (ms for s) or a rendering step passed as the physics one."""


def check_timestep(what: str, value) -> float:
    """``value`` as a MuJoCo timestep in (0, ``MAX_TIMESTEP_S``] s; ``InvalidValueError`` if not."""
    value = check_positive(what, value, "pass seconds, e.g. 0.005")
    if value > MAX_TIMESTEP_S:
        raise InvalidValueError(
            what, value, f"steps above {MAX_TIMESTEP_S} s make contacts soft and stiff drives unstable",
            f"pass a step <= {MAX_TIMESTEP_S} s (e.g. 0.005) and render less often with rendering_dt "
            "or decimation instead")
    return value


def fastest_drive(model: mujoco.MjModel) -> tuple[str, float] | None:
    """(joint name, natural period s) of the stiffest joint drive, ``T = 2 pi sqrt(I / kp)`` with
    ``I = 1 / dof_invweight0`` (the joint's inertia at the initial pose); None without drives.

    The position gain is integrated explicitly (only damping is implicit in implicitfast), and
    semi-implicit Euler on a spring is stable only for ``omega dt < 2``: ``dt < T / pi``."""
    best = None
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        kp = -float(model.actuator_biasprm[a, 1])
        dof = int(model.jnt_dofadr[model.actuator_trnid[a, 0]])
        invweight = float(model.dof_invweight0[dof])
        if kp <= 0 or invweight <= 0:
            continue
        period = 2 * math.pi * math.sqrt(1.0 / invweight / kp)
        if best is None or period < best[1]:
            best = (model.joint(int(model.actuator_trnid[a, 0])).name, period)
    return best


def timestep_warning(model: mujoco.MjModel) -> str | None:
    """A one-line warning when the model's timestep is too large for its stiffest drive, else None
    (a warning, not an error: contacts and joint limits change the effective inertia)."""
    fastest = fastest_drive(model)
    dt = float(model.opt.timestep)
    if fastest is None or dt * math.pi < fastest[1]:
        return None
    joint, period = fastest
    return (f"timestep {dt:g} s is too large for the drive of joint {joint!r} (natural period "
            f"{period:.3g} s): it may oscillate or diverge; use a timestep below {period / math.pi:.2g} s "
            "or lower that joint's stiffness")


def apply_physics(spec: mujoco.MjSpec, cfg: PhysicsCfg) -> None:
    """Write ``cfg`` into ``spec.option`` (the one place ambulo sets physics options)."""
    cfg.check()
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


__all__ = ["INTEGRATORS", "MAX_TIMESTEP_S", "PhysicsCfg", "apply_physics", "check_timestep", "fastest_drive",
           "match_options", "timestep_warning"]
