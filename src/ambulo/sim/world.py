"""World: the Isaac-style face of ``ambulo.core.Simulation`` (stage, physics, engine, clock).

Lifecycle, as in Isaac Sim: build the stage (``scene.add...``,
``add_reference_to_stage``), then ``reset()`` compiles it into one ``MjModel`` through the
core lifecycle (the physics of one ``PhysicsCfg``), starts the engine with ``num_worlds``
copies and initializes every scene object (articulation properties are None before that).
Later ``reset()`` calls restore the initial state; a stage edited after compiling is
recompiled at the next ``reset()``.
"""

from __future__ import annotations

import logging
from typing import Callable, Literal

import mujoco
import numpy as np
import torch

from ..core import PhysicsCfg, Simulation, new_scene
from ..core.physics import check_timestep
from ..engine import Engine
from ..utils.checks import (
    Described, InvalidValueError, check_all_finite, check_int, check_positive, check_real_dtype,
)
from .current import current_world_or_none, set_current_world
from .scene import Scene

log = logging.getLogger(__name__)


class World:
    """The simulation: stage, physics settings, ``num_worlds`` parallel copies, clock.

    Args:
      physics_dt: s, simulated time of one physics step (what physics callbacks receive).
      rendering_dt: s, simulated time of one ``World.step``; None means ``physics_dt``.
      substeps: MuJoCo steps per physics step (each of ``physics_dt / substeps``).
      solver_iterations, gravity, integrator: see ``ambulo.core.PhysicsCfg``; ``physics``
        (a whole ``PhysicsCfg``) overrides them and ``physics_dt``/``substeps``' timestep.
      num_worlds: parallel copies of the scene (the single-robot API is N = 1).
      device: ``"cpu"`` (MuJoCo) or ``"cuda"`` (MuJoCo Warp).
      backend: ``"numpy"`` (Isaac's default) or ``"torch"`` for object getters.
      stage_units_in_meters: accepted for Isaac compatibility; must be 1.0.
    """

    def __init__(
        self,
        physics_dt: float = 0.005,
        rendering_dt: float | None = None,
        *,
        substeps: int = 1,
        solver_iterations: int = 50,
        gravity=(0.0, 0.0, -9.81),
        integrator: str = "implicitfast",
        physics: PhysicsCfg | None = None,
        num_worlds: int = 1,
        device: str = "cpu",
        backend: Literal["numpy", "torch"] = "numpy",
        stage_units_in_meters: float = 1.0,
        num_threads: int = 0,
    ):
        if stage_units_in_meters != 1.0:
            raise InvalidValueError("stage_units_in_meters", stage_units_in_meters, "ambulo stages are in metres",
                                    "pass stage_units_in_meters=1.0 and give lengths in m")
        substeps = check_int("substeps", substeps, "pass a whole number of MuJoCo steps per physics step, e.g. 1",
                             minimum=1)
        if backend not in ("numpy", "torch"):
            raise InvalidValueError("backend", backend, "not a backend", "pass 'numpy' or 'torch'")
        if physics is None:
            physics_dt = check_positive("physics_dt", physics_dt, "pass seconds, e.g. physics_dt=0.005")
            check_timestep("physics_dt / substeps", physics_dt / substeps)
            physics = PhysicsCfg(timestep_s=physics_dt / substeps, gravity_m_s2=gravity,
                                 integrator=integrator, solver_iterations=solver_iterations)
        else:
            physics_dt = physics.timestep_s * substeps
        self.physics_dt = float(physics_dt)
        self.rendering_dt = rendering_dt
        self.substeps = int(substeps)
        self._physics_steps_per_step = self._steps_per_render(rendering_dt)
        self.device = device
        self.backend = backend
        self.sim = Simulation(new_scene("World"), physics, num_worlds=num_worlds, device=device,
                              num_threads=num_threads)
        """The core lifecycle object this World drives."""
        self.num_worlds = self.sim.num_worlds
        self.scene = Scene(self)
        self._compiled_signature: int | None = None
        self._physics_callbacks: dict[str, Callable[[float], None]] = {}
        self._playing = False
        self._step_index = 0
        self.viewport_camera = mujoco.MjvCamera()
        """Free camera used by recordings and the viewer; see ``set_camera_view``."""
        self.viewport_camera.lookat[:] = (0.0, 0.0, 0.3)
        self.viewport_camera.distance, self.viewport_camera.azimuth = 3.0, 135.0
        self.viewport_camera.elevation = -25.0
        set_current_world(self)

    @classmethod
    def instance(cls) -> World | None:
        """The most recently created World (Isaac's ``World.instance()``)."""
        return current_world_or_none()

    def _steps_per_render(self, rendering_dt: float | None) -> int:
        if rendering_dt is not None:
            rendering_dt = check_positive("rendering_dt", rendering_dt,
                                          "pass seconds (a whole multiple of physics_dt), or None for physics_dt")
        steps = (rendering_dt or self.physics_dt) / self.physics_dt
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise InvalidValueError(
                "rendering_dt", rendering_dt, f"not a whole multiple of physics_dt ({self.physics_dt} s)",
                f"pass e.g. rendering_dt={max(1, round(steps)) * self.physics_dt:g}")
        return round(steps)

    # -- the core objects ------------------------------------------------------
    @property
    def stage(self) -> mujoco.MjSpec:
        """The ``MjSpec`` being built: Isaac's USD stage."""
        return self.sim.spec

    @property
    def physics(self) -> PhysicsCfg:
        """The physics settings applied at every compile."""
        return self.sim.physics

    @property
    def engine(self) -> Engine | None:
        return self.sim.engine

    @property
    def model(self) -> mujoco.MjModel | None:
        return self.sim.model

    # -- settings -------------------------------------------------------------
    def get_physics_dt(self) -> float:
        return self.physics_dt

    def get_rendering_dt(self) -> float:
        return self.physics_dt * self._physics_steps_per_step

    def set_simulation_dt(self, physics_dt: float | None = None, rendering_dt: float | None = None):
        """Change the time steps; takes effect at the next ``reset()``."""
        if physics_dt is not None:
            physics_dt = check_positive("physics_dt", physics_dt, "pass seconds, e.g. physics_dt=0.005")
            check_timestep("physics_dt / substeps", physics_dt / self.substeps)
        old_physics_dt, old_rendering_dt = self.physics_dt, self.rendering_dt
        if physics_dt is not None:
            self.physics_dt = physics_dt
        if rendering_dt is not None:
            self.rendering_dt = rendering_dt
        try:
            self._physics_steps_per_step = self._steps_per_render(self.rendering_dt)
        except ValueError:  # leave the World as it was
            self.physics_dt, self.rendering_dt = old_physics_dt, old_rendering_dt
            raise
        self.physics.timestep_s = self.physics_dt / self.substeps
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
            self.sim.reset(forward=False)  # one kinematics pass below, after post_reset
        self._step_index = 0
        for obj in self.scene.prims():
            obj.post_reset()
        self.engine.forward()
        self._playing = True

    def initialize_physics(self) -> None:
        """Compile the stage and start the engine without resetting objects' states."""
        self._compile()

    def _compile(self) -> None:
        self.sim.start()
        self._compiled_signature = self._stage_signature()
        for obj in self.scene.prims():
            obj.initialize(self)
        # the initial state includes what objects set in initialize (default poses)
        self.engine.forward()
        self.engine.capture_initial_state()

    def _stage_signature(self) -> int:
        # the spec has no dirty flag; its XML is a cheap, faithful fingerprint
        return hash((self.stage.to_xml(), repr(self.physics)))

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
        self._require_engine()
        if not (step_sim and self._playing):
            return
        for _ in range(self._physics_steps_per_step):
            for callback in list(self._physics_callbacks.values()):
                callback(self.physics_dt)
            # the scene API promises current poses after every step
            self.sim.step(self.substeps, refresh=True)
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
        """User input as a float64 (N, *trailing) tensor, broadcasting a single value.

        Text, complex numbers, NaN and inf are refused; a CUDA tensor is checked by shape and
        dtype only (reading its values would sync the GPU)."""
        device = self.engine.device if self.engine is not None else "cpu"
        fix = f"pass finite real numbers of shape {trailing} or {(self.num_worlds, *trailing)}"
        check_real_dtype(what, value, fix)
        try:
            array = value if torch.is_tensor(value) else np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidValueError(what, value, "not an array of numbers", fix) from None
        check_all_finite(what, torch.as_tensor(array), fix)
        tensor = torch.as_tensor(array, dtype=torch.float64, device=device)
        want = (self.num_worlds, *trailing)
        if tensor.shape == trailing:
            tensor = tensor.expand(want)
        if tuple(tensor.shape) != want:
            raise InvalidValueError(what, Described(f"of shape {tuple(tensor.shape)}"),
                                    f"expected shape {trailing} or {want}", fix)
        return tensor
