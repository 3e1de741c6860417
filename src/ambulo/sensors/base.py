"""What every sensor shares: a prim path resolved to a mount, and the component lifecycle.

Sensors implement ``ambulo.core.Component``: ``build(spec)`` adds what the sensor
needs to the scene's ``MjSpec`` before compilation (a camera, a site, MuJoCo
sensors); ``initialize(engine)`` resolves ids in the compiled model; ``update(dt_s)``
runs after physics; ``reset(world_ids)`` forgets those worlds' samples. A sensor only
reads the engine's state tensors and never steps it.

Prim paths: models composed by ``World`` name bodies and sites by prim path
(``/World/robot/head``); a sensor's own path is its mount's path plus a leaf
(``/World/robot/head/camera``). Plain MJCF names (``head``, ``imu``) work too.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ..core.rows import fill_rows
from ..utils.checks import check_positive

WORLD_NAMES = ("", "/", "/World", "world")


@dataclass(frozen=True)
class Mount:
    """Where a sensor sits: a body, optionally through one of its sites."""

    body: str
    """Body name ('world' for the world body)."""
    site: str | None = None
    """Site name when the prim path named a site, else None."""


def resolve_mount(spec: mujoco.MjSpec, prim_path: str) -> Mount:
    """The body or site named by ``prim_path`` or else by its parent path (the sensor's own leaf)."""
    path = prim_path.rstrip("/")
    parent = path.rsplit("/", 1)[0] if "/" in path else None
    for candidate in (path, parent):
        if candidate is None:
            continue
        if candidate in WORLD_NAMES:
            return Mount(body="world")
        for name in dict.fromkeys((candidate, candidate.rsplit("/", 1)[-1])):
            site = spec.site(name)
            if site is not None:
                return Mount(body=site.parent.name or "world", site=name)
            if spec.body(name) is not None:
                return Mount(body=name)
    bodies = [b.name for b in spec.bodies][:12]
    raise ValueError(
        f"sensor prim path {prim_path!r} names no body or site (nor does any parent path). "
        f"Mount it on an existing body, e.g. one of {bodies}."
    )


def spec_body(spec: mujoco.MjSpec, mount: Mount):
    return spec.worldbody if mount.body == "world" else spec.body(mount.body)


class MountPose:
    """Batched world pose of a mount, read live from the engine."""

    def __init__(self, engine, mount: Mount):
        self._on_site = mount.site is not None
        model = engine.model
        if mount.site is not None:
            sid = model.site(mount.site).id
            self._pos, self._mat, self._index = engine.field("site_xpos"), engine.field("site_xmat"), sid
            self.body_id = int(model.site_bodyid[sid])
        else:
            bid = 0 if mount.body == "world" else model.body(mount.body).id
            self._pos, self._mat, self._index = engine.field("xpos"), engine.field("xmat"), bid
            self.body_id = bid

    def of_data(self, data) -> tuple[np.ndarray, np.ndarray]:
        """(3,) position and (3, 3) axes of the mount in one world's ``MjData`` (after mj_forward)."""
        if self._on_site:
            return data.site_xpos[self._index].copy(), data.site_xmat[self._index].reshape(3, 3).copy()
        return data.xpos[self._index].copy(), data.xmat[self._index].reshape(3, 3).copy()

    def pos_w(self) -> torch.Tensor:
        """(N, 3) float64 m, world frame, on the engine's device."""
        return self._pos[:, self._index]

    def rot_w(self) -> torch.Tensor:
        """(N, 3, 3) float64: the mount's axes (columns) in the world frame."""
        return self._mat[:, self._index].reshape(-1, 3, 3)


class Sensor:
    """Base of all sensors: prim path, mount, update period and lifecycle state."""

    def __init__(self, prim_path: str, update_period_s: float = 0.0):
        update_period_s = check_positive("update period", update_period_s,
                                         "pass seconds >= 0 (0: a new sample on every read)", allow_zero=True)
        self.prim_path = prim_path
        self.name = prim_path
        """Scene registry name: the prim path, unique where leaf names are not."""
        self.update_period_s = float(update_period_s)
        self.mount: Mount | None = None
        self.engine = None
        self._last_update_s: torch.Tensor | None = None

    @property
    def num_worlds(self) -> int:
        self._require_initialized()
        return self.engine.num_worlds

    def build(self, spec: mujoco.MjSpec) -> None:
        """Add the sensor's elements to ``spec`` (before compilation)."""
        self.mount = resolve_mount(spec, self.prim_path)

    def initialize(self, engine) -> None:
        """Resolve ids in ``engine.model``; call after the spec that ``build`` edited is compiled."""
        if self.mount is None:
            raise RuntimeError(
                f"{type(self).__name__} {self.prim_path!r}: build(spec) was not called before "
                "compiling; add the sensor to the scene before world.reset()"
            )
        self.engine = engine
        self._last_update_s = torch.full((engine.num_worlds,), -np.inf, dtype=engine.dtype,
                                         device=engine.device)

    def update(self, dt_s: float) -> None:
        """After physics advanced ``dt_s``; sensors that sample on read do nothing here."""

    def reset(self, world_ids: torch.Tensor | None = None) -> None:
        """Forget the last sample of ``world_ids`` (None: all): the next read samples anew."""
        if self._last_update_s is not None:
            fill_rows(self._last_update_s, world_ids, -np.inf)

    def _require_initialized(self) -> None:
        if self.engine is None:
            raise RuntimeError(
                f"{type(self).__name__} {self.prim_path!r} is not initialized; "
                "call initialize(engine) (World.reset does it)"
            )

    def _due(self) -> torch.Tensor:
        """(N,) bool: worlds whose simulated time reached the next update (within half a
        physics step: time moves in whole steps, and float32 time on a GPU is off by ulps)."""
        now = self.engine.field("time")
        return now - self._last_update_s >= self.update_period_s - 0.5 * float(self.engine.model.opt.timestep)

    def _mark_updated(self, mask: torch.Tensor) -> None:
        self._last_update_s[mask] = self.engine.field("time")[mask]
