"""Contact sensor: per-body in-contact flag, contact count and net contact force.

Built on MuJoCo's ``contact`` sensor with ``reduce="netforce"``, one per body,
so the reduction runs in C for every world in the batch.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass

import mujoco
import torch

from .base import Sensor

_FOUND, _FORCE = 1, 2  # bits of the contact sensor's data specification (mjtConDataField order)
_NETFORCE = 3          # mjtSensor contact reduce: none, mindist, maxforce, netforce


@dataclass(kw_only=True)
class ContactSensorCfg:
    prim_paths: tuple[str, ...]
    """Bodies to watch: names or glob patterns (e.g. '/World/robot/*_foot')."""
    include_subtree: bool = False
    """Count contacts of the bodies' descendants too."""
    force_threshold_n: float = 0.0
    """A body is in contact when a contact exists and the net force exceeds this (N)."""


@dataclass
class ContactData:
    in_contact: torch.Tensor
    """(N, B) bool."""
    num_contacts: torch.Tensor
    """(N, B) int64: contacts involving the body."""
    net_force_w: torch.Tensor
    """(N, B, 3) float64 N: total contact force the environment applies to the body, world frame."""


class ContactSensor(Sensor):
    def __init__(self, cfg: ContactSensorCfg | None = None, **kwargs):
        cfg = cfg or ContactSensorCfg(**kwargs)
        if isinstance(cfg.prim_paths, str):
            cfg.prim_paths = (cfg.prim_paths,)
        super().__init__(cfg.prim_paths[0])
        self.cfg = cfg
        self.body_names: list[str] = []

    def _build(self, spec: mujoco.MjSpec) -> None:
        names = [b.name for b in spec.bodies if b.name]
        matched = []
        for pattern in self.cfg.prim_paths:
            hits = [n for n in names if fnmatch.fnmatchcase(n, pattern) or n.rsplit("/", 1)[-1] == pattern]
            if not hits:
                raise ValueError(f"contact sensor: no body matches {pattern!r}; bodies: {names[:12]}")
            matched += [h for h in hits if h not in matched]
        self.body_names = matched
        self.mount = None
        objtype = mujoco.mjtObj.mjOBJ_XBODY if self.cfg.include_subtree else mujoco.mjtObj.mjOBJ_BODY
        for name in matched:
            spec.add_sensor(name=f"{name}:contact", type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=objtype, objname=name,
                            intprm=[_FOUND | _FORCE, _NETFORCE, 1])
        from .base import Mount
        self.mount = Mount(body=matched[0])

    def initialize(self, engine) -> None:
        super().initialize(engine)
        model = engine.model
        self._adr = torch.tensor([int(model.sensor_adr[model.sensor(f"{n}:contact").id])
                                  for n in self.body_names])

    def get_current_frame(self) -> ContactData:
        self._require_initialized()
        s = self.engine.field("sensordata")
        block = s[:, self._adr[:, None] + torch.arange(4)]  # (N, B, 4): found, force xyz
        count = block[..., 0].round().long()
        # the sensor reports the force body1 (ours) exerts on body2; we want the reaction
        force = -block[..., 1:4]
        touching = (count > 0) & (force.norm(dim=-1) >= self.cfg.force_threshold_n)
        return ContactData(in_contact=touching, num_contacts=count, net_force_w=force)
