"""PhysicsMaterial: Isaac's friction/restitution material mapped onto MuJoCo contact parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco

from ..utils.validate import Checked

# MuJoCo's default contact time constant, s (mjOption/geom solref[0] default).
_TIMECONST_S = 0.02


@dataclass(kw_only=True)
class PhysicsMaterial(Checked):
    """Friction and restitution of a surface.

    MuJoCo has one sliding friction coefficient per geom (pairs take the max), so
    ``dynamic_friction`` is used and ``static_friction`` is kept for reference.
    Restitution e is realised by the contact's damping ratio: a mass-spring-damper
    contact with damping ratio zeta returns with e = exp(-zeta pi / sqrt(1 - zeta^2)),
    so zeta = -ln e / sqrt(pi^2 + ln^2 e); e = 0 keeps MuJoCo's critical damping.
    """

    prim_path: str = "/World/PhysicsMaterial"
    static_friction: float = 0.5
    dynamic_friction: float = 0.5
    restitution: float = 0.0

    def __post_init__(self):
        super().__post_init__()  # first: the checks below would let NaN through
        for name in ("static_friction", "dynamic_friction"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0.0 <= self.restitution < 1.0:
            raise ValueError(f"restitution must be in [0, 1), got {self.restitution}")

    def damping_ratio(self) -> float:
        if self.restitution <= 0.0:
            return 1.0
        log_e = math.log(self.restitution)
        return -log_e / math.sqrt(math.pi**2 + log_e**2)

    def apply_to(self, geom: mujoco.MjsGeom) -> None:
        geom.friction = [self.dynamic_friction, geom.friction[1], geom.friction[2]]
        geom.solref = [_TIMECONST_S, self.damping_ratio()]
        # a material-bearing geom decides the contact's solref over a default one
        geom.solmix = 10.0
