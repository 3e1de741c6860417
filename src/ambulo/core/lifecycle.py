"""The one lifecycle: a scene spec and its components become one model, one engine.

``Simulation`` is what the Isaac-style ``World``, every RL task and the data generator
drive: components (sensors, randomizers, anything that adds elements to the scene)
``build`` into the spec when added, ``start`` compiles the spec with the physics config,
creates the engine and ``initialize``s each component against it; ``step`` advances physics
and ``update``s components; ``reset`` restores worlds and ``reset``s components.
"""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

import mujoco
import torch

from ..engine import Engine, engine_class, make_engine
from ..utils.checks import check_int
from .physics import PhysicsCfg, timestep_warning
from .scene import compile_scene

log = logging.getLogger(__name__)


@runtime_checkable
class Component(Protocol):
    """The public protocol of sensors and randomizers.

    ``build(spec)`` adds what the component needs (cameras, sites, MuJoCo sensors, textures)
    before compilation; ``initialize(engine)`` resolves names to ids in ``engine.model`` and
    allocates (N, ...) buffers on ``engine.device``; ``update(dt_s)`` runs after physics
    advanced ``dt_s`` seconds; ``reset(world_ids)`` clears the state of those worlds
    (None: all). After ``initialize`` a component only reads or writes engine tensors.
    """

    name: str

    def build(self, spec: mujoco.MjSpec) -> None: ...

    def initialize(self, engine: Engine) -> None: ...

    def update(self, dt_s: float) -> None: ...

    def reset(self, world_ids: torch.Tensor | None = None) -> None: ...


class Simulation:
    """A scene (``spec``), its ``PhysicsCfg``, its components and, once started, its engine.

    Args:
      spec: the scene built with ``ambulo.core.scene`` (components add to it).
      physics: applied to the spec at every compile (the only physics settings).
      num_worlds: N parallel copies.
      device: ``"cpu"`` or ``"cuda[:k]"``.
      num_threads: CPU engine threads (0: every CPU).
      engine: ``"auto"`` (MuJoCo's batch on the CPU, MuJoCo Warp on CUDA), ``"mujoco"`` or
        ``"warp"`` (``ambulo.engine.ENGINES``).
    """

    def __init__(self, spec: mujoco.MjSpec, physics: PhysicsCfg, *, num_worlds: int = 1,
                 device: str = "cpu", num_threads: int = 0, engine: str = "auto"):
        if not isinstance(physics, PhysicsCfg):
            raise TypeError(f"physics is a {type(physics).__name__}, not a PhysicsCfg; pass "
                            "ambulo.core.PhysicsCfg(timestep_s=..., ...)")
        self.spec = spec
        self.physics = physics
        self.num_worlds = check_int("num_worlds", num_worlds, "pass a whole number of parallel worlds, "
                                    "e.g. num_worlds=64", minimum=1)
        self.device = str(device)
        self.engine_name = engine
        engine_class(self.device, engine)  # a bad device or engine fails before any compile
        self.num_threads = check_int("num_threads", num_threads, "pass 0 (every CPU) or a thread count",
                                     minimum=0)
        self.components: dict[str, Component] = {}
        self.model: mujoco.MjModel | None = None
        self.engine: Engine | None = None

    def add(self, component: Component) -> Component:
        """Register ``component`` and build it into the spec (compiled in at the next ``start``)."""
        name = component.name
        if self.components.get(name, component) is not component:
            raise ValueError(f"a component named {name!r} already exists; give each a unique name")
        if name not in self.components:
            component.build(self.spec)
            self.components[name] = component
        return component

    def start(self, spec: mujoco.MjSpec | None = None) -> Engine:
        """Compile the spec, create the engine, initialize components, capture the initial state.

        ``spec``: compile this one instead of ``self.spec``, e.g. a copy of it with content that
        is rebuilt at every start (the World's USD-authored prims); components built into
        ``self.spec`` before the copy are in it."""
        self.model = compile_scene(self.spec if spec is None else spec, self.physics)
        warning = timestep_warning(self.model)
        if warning is not None:
            log.warning(warning)
        kwargs = {"num_threads": self.num_threads,
                  "max_contacts_per_world": self.physics.max_contacts_per_world,
                  "max_constraints_per_world": self.physics.max_constraints_per_world,
                  "broadphase": self.physics.broadphase,
                  "compile_workers": self.physics.compile_workers,
                  "compile_processes": self.physics.compile_processes}
        self.engine = make_engine(self.model, self.num_worlds, self.device, self.engine_name, **kwargs)
        for component in self.components.values():
            component.initialize(self.engine)
        return self.engine

    def step(self, num_substeps: int = 1, refresh: bool = False) -> torch.Tensor:
        """Advance ``num_substeps`` MuJoCo steps, then update components; returns the (N,)
        bool mask of worlds that diverged and were reset."""
        diverged = self.engine.step(num_substeps, refresh=refresh)
        self.update(num_substeps * self.physics.timestep_s)
        return diverged

    def update(self, dt_s: float) -> None:
        """Update the components after physics advanced ``dt_s`` seconds. ``step`` does it; a
        caller that advances ``engine.step`` in parts (an action latency, which changes the
        targets between physics steps) calls it once for the whole, so components see the same
        updates with and without the parts."""
        for component in self.components.values():
            component.update(dt_s)

    def reset(self, world_ids: torch.Tensor | None = None, forward: bool = True) -> None:
        """Restore ``world_ids`` (None: all) to the initial state and reset components there.

        ``forward=False`` skips the kinematics pass, for callers that edit the state further
        and then call ``engine.forward`` once.
        """
        self.engine.reset(world_ids, forward=forward)
        for component in self.components.values():
            component.reset(world_ids)


__all__ = ["Component", "Simulation"]
