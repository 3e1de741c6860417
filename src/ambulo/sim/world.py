"""World: the stage (an ``MjSpec``), the physics settings, the engine and the clock.

Lifecycle, as in Isaac Sim: build the stage (``scene.add...``,
``add_reference_to_stage``), then ``reset()`` compiles it into one ``MjModel``,
starts the engine with ``num_worlds`` copies and initializes every scene object
(articulation properties are None before that). Later ``reset()`` calls restore the
initial state; a stage edited after compiling is recompiled at the next ``reset()``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable, Literal

import mujoco
import numpy as np
import torch

from ..engine import Engine, make_engine
from .scene import Scene, is_prim

log = logging.getLogger(__name__)

_INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}


@dataclass(kw_only=True)
class PhysicsSettings:
    """Physics settings of a World; every field has a sane default."""

    physics_dt: float = 0.005
    """s, simulated time of one physics step (what physics callbacks receive)."""
    rendering_dt: float | None = None
    """s, simulated time of one ``World.step``; None means ``physics_dt``."""
    substeps: int = 1
    """MuJoCo steps per physics step (each of ``physics_dt / substeps``)."""
    solver_iterations: int = 50
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    """m/s^2, world frame."""
    integrator: Literal["euler", "implicitfast", "implicit", "rk4"] = "implicitfast"
    """implicitfast integrates drive damping implicitly (Isaac's implicit PD)."""


class World:
    """The simulation: stage, physics settings, ``num_worlds`` parallel copies, clock.

    Args:
      physics_dt, rendering_dt, substeps, solver_iterations, gravity, integrator:
        see ``PhysicsSettings``.
      num_worlds: parallel copies of the scene (the single-robot API is N = 1).
      device: ``"cpu"`` (MuJoCo) or ``"cuda"`` (MuJoCo Warp).
      backend: ``"numpy"`` (Isaac's default) or ``"torch"`` for object getters.
      stage_units_in_meters: accepted for Isaac compatibility; must be 1.0.
    """

    _instance: World | None = None

    def __init__(
        self,
        physics_dt: float = 0.005,
        rendering_dt: float | None = None,
        *,
        substeps: int = 1,
        solver_iterations: int = 50,
        gravity=(0.0, 0.0, -9.81),
        integrator: str = "implicitfast",
        num_worlds: int = 1,
        device: str = "cpu",
        backend: Literal["numpy", "torch"] = "numpy",
        stage_units_in_meters: float = 1.0,
        num_threads: int = 0,
    ):
        if stage_units_in_meters != 1.0:
            raise ValueError("ambulo stages are in metres: pass stage_units_in_meters=1.0")
        if integrator not in _INTEGRATORS:
            raise ValueError(f"unknown integrator {integrator!r}; use one of {sorted(_INTEGRATORS)}")
        if physics_dt <= 0 or substeps < 1:
            raise ValueError("physics_dt must be > 0 and substeps >= 1")
        if backend not in ("numpy", "torch"):
            raise ValueError(f"backend must be 'numpy' or 'torch', got {backend!r}")
        self.physics = PhysicsSettings(
            physics_dt=physics_dt, rendering_dt=rendering_dt, substeps=substeps,
            solver_iterations=solver_iterations, gravity=tuple(gravity), integrator=integrator,
        )
        steps = (rendering_dt or physics_dt) / physics_dt
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise ValueError(
                f"rendering_dt ({rendering_dt}) must be a whole multiple of physics_dt ({physics_dt})"
            )
        self._physics_steps_per_step = round(steps)
        self.num_worlds = int(num_worlds)
        self.device = device
        self.backend = backend
        self._num_threads = num_threads
        self.stage = mujoco.MjSpec()
        """The ``MjSpec`` being built: Isaac's USD stage."""
        self.stage.modelname = "World"
        self._apply_settings(self.stage)
        self.scene = Scene(self)
        self.engine: Engine | None = None
        self.model: mujoco.MjModel | None = None
        self._compiled_signature: int | None = None
        self._physics_callbacks: dict[str, Callable[[float], None]] = {}
        self._playing = False
        self._step_index = 0
        self.viewport_camera = mujoco.MjvCamera()
        """Free camera used by recordings and the viewer; see ``set_camera_view``."""
        self.viewport_camera.lookat[:] = (0.0, 0.0, 0.3)
        self.viewport_camera.distance, self.viewport_camera.azimuth = 3.0, 135.0
        self.viewport_camera.elevation = -25.0
        World._instance = self

    @classmethod
    def instance(cls) -> World | None:
        """The most recently created World (Isaac's ``World.instance()``)."""
        return cls._instance

    # -- settings -------------------------------------------------------------
    def get_physics_dt(self) -> float:
        return self.physics.physics_dt

    def get_rendering_dt(self) -> float:
        return self.physics.physics_dt * self._physics_steps_per_step

    def set_simulation_dt(self, physics_dt: float | None = None, rendering_dt: float | None = None):
        """Change the time steps; takes effect at the next ``reset()``."""
        if physics_dt is not None:
            self.physics.physics_dt = physics_dt
        if rendering_dt is not None:
            self.physics.rendering_dt = rendering_dt
        self._physics_steps_per_step = max(1, round(self.get_rendering_dt() / self.physics.physics_dt))
        self._compiled_signature = None

    @property
    def current_time(self) -> float:
        """s of simulated time since the last reset (world 0)."""
        if self.engine is None:
            return 0.0
        return float(self.engine.time[0])

    @property
    def current_time_step_index(self) -> int:
        return self._step_index

    # -- lifecycle --------------------------------------------------------------
    def reset(self) -> None:
        """Compile the stage if it changed, then put every world in its initial state."""
        if self.engine is None or self._stage_signature() != self._compiled_signature:
            self._compile()
        else:
            self.engine.reset()
        self._step_index = 0
        for obj in self.scene.objects():
            if hasattr(obj, "post_reset"):
                obj.post_reset()
        self.engine.forward()
        self._playing = True

    def initialize_physics(self) -> None:
        """Compile the stage and start the engine without resetting objects' states."""
        self._compile()

    def _apply_settings(self, spec: mujoco.MjSpec) -> None:
        p = self.physics
        spec.option.timestep = p.physics_dt / p.substeps
        spec.option.gravity = list(p.gravity)
        spec.option.iterations = p.solver_iterations
        spec.option.integrator = _INTEGRATORS[p.integrator]

    def _compile(self) -> None:
        self._apply_settings(self.stage)
        try:
            self.model = self.stage.compile()
        except ValueError as err:
            raise ValueError(f"the stage does not compile: {err}") from None
        self.engine = make_engine(self.model, self.num_worlds, self.device,
                                  **({"num_threads": self._num_threads} if self.device == "cpu" else {}))
        self._compiled_signature = self._stage_signature()
        for obj in self.scene.objects():
            # prims resolve against the World; sensors only read the engine
            obj.initialize(self if is_prim(obj) else self.engine)
        # the initial state includes what objects set in initialize (default poses)
        self.engine.forward()
        self.engine.capture_initial_state()

    def _stage_signature(self) -> int:
        # the spec has no dirty flag; its XML is a cheap, faithful fingerprint
        return hash((self.stage.to_xml(), self.physics.physics_dt, self.physics.substeps,
                     self.physics.solver_iterations, self.physics.gravity, self.physics.integrator))

    def _require_engine(self) -> Engine:
        if self.engine is None:
            raise RuntimeError("the World has not been reset yet: call world.reset() after building the scene")
        return self.engine

    # -- running --------------------------------------------------------------
    def play(self) -> None:
        if self.engine is None:
            self.reset()
        self._playing = True

    def pause(self) -> None:
        self._playing = False

    def stop(self) -> None:
        self._playing = False

    def is_playing(self) -> bool:
        return self._playing

    def is_stopped(self) -> bool:
        return not self._playing

    def step(self, render: bool = True, step_sim: bool = True) -> None:
        """Advance by ``rendering_dt``: that many physics steps, each after the callbacks.

        A paused world does not advance. ``render`` is accepted for Isaac
        compatibility; recording is done by ``ambulo.sim.Recorder``, which calls
        ``render`` on its own schedule.
        """
        engine = self._require_engine()
        if not (step_sim and self._playing):
            return
        dt = self.physics.physics_dt
        for _ in range(self._physics_steps_per_step):
            for callback in list(self._physics_callbacks.values()):
                callback(dt)
            # the scene API promises current poses after every step
            engine.step(self.physics.substeps, refresh=True)
            self._step_index += 1

    # -- callbacks -------------------------------------------------------------
    def add_physics_callback(self, callback_name: str, callback_fn: Callable[[float], None]) -> None:
        """Call ``callback_fn(step_size_s)`` before every physics step."""
        if not callable(callback_fn):
            raise TypeError(f"physics callback {callback_name!r} must be callable")
        self._physics_callbacks[callback_name] = callback_fn

    def remove_physics_callback(self, callback_name: str) -> None:
        if callback_name not in self._physics_callbacks:
            raise KeyError(f"no physics callback named {callback_name!r}; have {sorted(self._physics_callbacks)}")
        del self._physics_callbacks[callback_name]

    def physics_callback_exists(self, callback_name: str) -> bool:
        return callback_name in self._physics_callbacks

    def clear_physics_callbacks(self) -> None:
        self._physics_callbacks.clear()

    # -- conversions for object getters ------------------------------------------
    def _out(self, tensor: torch.Tensor):
        """A copy of a (N, ...) tensor for users: squeezed to (...) when N == 1."""
        value = tensor.detach().clone()
        if self.num_worlds == 1:
            value = value[0]
        return value.cpu().numpy() if self.backend == "numpy" else value

    def _in(self, value, trailing: tuple[int, ...], what: str) -> torch.Tensor:
        """User input as a float64 (N, *trailing) tensor, broadcasting a single value."""
        tensor = torch.as_tensor(np.asarray(value, dtype=np.float64) if not torch.is_tensor(value) else value,
                                 dtype=torch.float64)
        want = (self.num_worlds, *trailing)
        if tensor.shape == trailing:
            tensor = tensor.expand(want)
        if tuple(tensor.shape) != want:
            raise ValueError(
                f"{what}: expected shape {trailing} or {want}, got {tuple(tensor.shape)}"
            )
        if torch.isnan(tensor).any():
            raise ValueError(f"{what}: contains NaN; pass finite values")
        return tensor
