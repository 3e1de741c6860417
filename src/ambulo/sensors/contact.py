"""Contact sensor: per-body in-contact flag, contact count, net contact force and air time.

Built on MuJoCo's ``contact`` sensor with ``reduce="netforce"``, one per body,
so the reduction runs in C for every world in the batch. ``update(dt_s)`` (called by
the lifecycle after physics) keeps air and contact timers per body, as legged robots'
gait rewards need (Isaac Lab's / mjlab's ``ContactSensor`` air time).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import torch

from ambulo.core import match_names
from ambulo.utils.checks import InvalidValueError
from ambulo.utils.validate import Checked

from ..core.rows import fill_rows
from .base import Mount, Sensor

_FOUND, _FORCE = 1, 2  # bits of the contact sensor's data specification (mjtConDataField order)
_NETFORCE = 3          # mjtSensor contact reduce: none, mindist, maxforce, netforce


@dataclass(kw_only=True)
class ContactSensorCfg(Checked):
    prim_paths: tuple[str, ...]
    """Bodies to watch: names or glob patterns, on the whole name or its last path component
    (e.g. '/World/robot/*_foot' or '*_foot'); see ``ambulo.core.match_names``."""
    include_subtree: bool = False
    """Count contacts of the bodies' descendants too."""
    force_threshold_n: float = 0.0
    """A body is in contact when a contact exists and the net force exceeds this (N)."""
    against: str | None = None
    """Only count contacts with this geom (its name), e.g. the ground's ``.../geom``."""
    against_body: str | None = None
    """Only count contacts with the geoms of this body (its name), e.g. a terrain made of an hfield
    and boxes (``scenes.terrain.add_terrain``); not together with ``against``."""
    name: str | None = None
    """Component name; defaults to the first prim path."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.against is not None and self.against_body is not None:
            raise InvalidValueError("ContactSensorCfg.against_body", self.against_body,
                                    f"against is {self.against!r} too", "give one of against and against_body")


@dataclass
class ContactData:
    in_contact: torch.Tensor
    """(N, B) bool."""
    num_contacts: torch.Tensor
    """(N, B) int64: contacts involving the body."""
    net_force_w: torch.Tensor
    """(N, B, 3) float64 N: total contact force the environment applies to the body, world frame."""
    current_air_time_s: torch.Tensor
    """(N, B) s since the body last left contact (0 while in contact); advanced by ``update``."""
    last_air_time_s: torch.Tensor
    """(N, B) s of the body's last completed flight (set at touchdown)."""
    current_contact_time_s: torch.Tensor
    """(N, B) s since the body last touched down (0 while in the air)."""
    first_contact: torch.Tensor
    """(N, B) bool: the body touched down during the last ``update`` interval."""


class ContactSensor(Sensor):
    def __init__(self, cfg: ContactSensorCfg | None = None, **kwargs):
        cfg = cfg or ContactSensorCfg(**kwargs)
        if isinstance(cfg.prim_paths, str):
            cfg.prim_paths = (cfg.prim_paths,)
        super().__init__(cfg.prim_paths[0])
        self.name = cfg.name or cfg.prim_paths[0]
        self.cfg = cfg
        self.body_names: list[str] = []

    def build(self, spec: mujoco.MjSpec) -> None:
        names = [b.name for b in spec.bodies if b.name]
        matched = []
        for pattern in self.cfg.prim_paths:
            hits = [names[i] for i in match_names(names, pattern)]
            if not hits:
                raise ValueError(f"contact sensor: no body matches {pattern!r}; bodies: {names[:12]}")
            matched += [h for h in hits if h not in matched]
        self.body_names = matched
        self.mount = None
        objtype = mujoco.mjtObj.mjOBJ_XBODY if self.cfg.include_subtree else mujoco.mjtObj.mjOBJ_BODY
        if self.cfg.against is not None:
            ref = {"reftype": mujoco.mjtObj.mjOBJ_GEOM, "refname": self.cfg.against}
        elif self.cfg.against_body is not None:
            ref = {"reftype": mujoco.mjtObj.mjOBJ_BODY, "refname": self.cfg.against_body}
        else:
            ref = {}
        for name in matched:
            spec.add_sensor(name=f"{self.name}:{name}:contact", type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=objtype, objname=name, intprm=[_FOUND | _FORCE, _NETFORCE, 1], **ref)
        self.mount = Mount(body=matched[0])

    def initialize(self, engine) -> None:
        super().initialize(engine)
        model = engine.model
        adr = torch.tensor([int(model.sensor_adr[model.sensor(f"{self.name}:{n}:contact").id])
                            for n in self.body_names], device=engine.device)
        self._block = adr[:, None] + torch.arange(4, device=engine.device)  # found, force xyz
        # the sensors were added one after another: one slice of sensordata (a view) reads them
        start, count = int(adr[0]), len(self.body_names)
        contiguous = bool(torch.equal(adr.cpu(), start + 4 * torch.arange(count)))
        self._slice = slice(start, start + 4 * count) if contiguous else None
        zeros = torch.zeros(engine.num_worlds, len(self.body_names), dtype=engine.dtype, device=engine.device)
        self._air, self._last_air, self._contact_time = zeros, zeros.clone(), zeros.clone()
        self._first = torch.zeros_like(zeros, dtype=torch.bool)
        self.data: ContactData = self._frame(*self._read())
        """The frame of the last ``update`` (what a step's rewards should read: no second read)."""

    def _read(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        data = self.engine.field("sensordata")
        if self._slice is not None:
            block = data[:, self._slice].reshape(data.shape[0], -1, 4)  # (N, B, 4)
        else:
            block = data[:, self._block]
        found = block[..., 0]  # a whole number of contacts, stored as float
        # the sensor reports the force body1 (ours) exerts on body2; we want the reaction
        force = -block[..., 1:4]
        stale = self.engine.acc_stale
        if stale is not None:
            # a world forwarded kinematics-only since the last step (a reset with
            # EnvCfg.reset_forward="kinematics") has no contacts computed for its new state: its
            # sensordata is the pre-reset one, so it reads "no contact, zero force" until the
            # next step, as Isaac Lab's ContactSensor.reset zeroes its buffers
            fresh = ~stale[:, None]
            found = torch.where(fresh, found, 0.0)
            force = torch.where(fresh[..., None], force, 0.0)
        touching = found > 0.5
        if self.cfg.force_threshold_n > 0.0:
            touching &= force.norm(dim=-1) >= self.cfg.force_threshold_n
        return touching, found.long(), force

    def update(self, dt_s: float) -> None:
        """Advance the air/contact timers by ``dt_s`` with the current contact state; ``data``
        then holds the frame of this update."""
        touching, count, force = self._read()
        was_in_air = self._air > 0.0  # the timer is held at 0 while touching
        self._air += dt_s
        # a touchdown ends a flight: remember how long it was
        # in place: a CUDA graph of the env step (envs.graph_step) keeps reading and writing the
        # tensors it captured, so rebinding these would freeze the timers on replay
        torch.logical_and(touching, was_in_air, out=self._first)
        self._last_air.copy_(torch.where(self._first, self._air, self._last_air))
        self._air.masked_fill_(touching, 0.0)
        self._contact_time.copy_(torch.where(touching, self._contact_time + dt_s,
                                             torch.zeros_like(self._contact_time)))
        self.data = self._frame(touching, count, force)

    def reset(self, world_ids: torch.Tensor | None = None) -> None:
        super().reset(world_ids)
        for buf in (self._air, self._last_air, self._contact_time, self._first):
            fill_rows(buf, world_ids, 0)

    def get_current_frame(self) -> ContactData:
        """Contacts read now (current after any state edit and a full ``engine.forward``; a world
        forwarded kinematics-only reads no contact until its next step), with the timers of the
        last ``update``."""
        self._require_initialized()
        return self._frame(*self._read())

    def _frame(self, touching, count, force) -> ContactData:
        return ContactData(in_contact=touching, num_contacts=count, net_force_w=force,
                           current_air_time_s=self._air, last_air_time_s=self._last_air,
                           current_contact_time_s=self._contact_time, first_contact=self._first)
