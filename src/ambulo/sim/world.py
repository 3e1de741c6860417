"""World: the Isaac-style face of ``ambulo.core.Simulation`` (stage, physics, engine, clock).

Lifecycle, as in Isaac Sim: build the stage (``scene.add...``,
``add_reference_to_stage``), then ``reset()`` compiles it into one ``MjModel`` through the
core lifecycle (the physics of one ``PhysicsCfg``), starts the engine with ``num_worlds``
copies and initializes every scene object (articulation properties are None before that).
Later ``reset()`` calls restore the initial state; a stage edited after compiling is
recompiled at the next ``reset()``.

The World also holds a real USD stage (``self.usd``, see ``usd_stage.py``): prims a script
authors there with pxr are converted and compiled in with the rest at every ``reset()``.
Defaults follow Isaac Sim: a physics step of 1/60 s, which the engine splits into MuJoCo
substeps of at most ``MAX_SUBSTEP_S`` so that stiff robots stay stable.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable
from typing import Literal

import mujoco
import numpy as np
import torch

from ..core import PhysicsCfg, Simulation, new_scene
from ..core.physics import check_timestep
from ..engine import Engine, sim_time_s
from ..utils.checks import (
    Described,
    InvalidValueError,
    check_all_finite,
    check_int,
    check_positive,
    check_real_dtype,
)
from .callbacks import NamedCallbacks
from .current import current_world_or_none, set_current_world
from .scene import Scene
from .stage_view import StageView
from .tasks import TaskHost
from .usd_stage import authored_labels, stage_for_new_world
from .viewers import open_viewer

log = logging.getLogger(__name__)

MAX_SUBSTEP_S = 0.005
"""s, the longest MuJoCo step the World takes by default: the bundled humanoid's stiffest drive
needs dt < ~0.014 s (``ambulo.core.physics.timestep_warning``) and contacts stay crisp at 5 ms."""


MAX_PHYSICS_DT_S = 0.1
"""s, the longest ``physics_dt`` a World accepts. It is the period of the physics callbacks, an
Isaac script's control loop, whose commands hold for the whole step; robots are controlled at
10 Hz or faster (Isaac Sim's default is 60 Hz, ros2_control's 100 Hz and more), so a longer step
is open-loop motion no script means, and ``physics_dt=10`` is almost always milliseconds passed as
seconds. (The World splits the step into MuJoCo substeps of at most ``MAX_SUBSTEP_S``: this bound
is about control; ``check_timestep`` bounds the integration step.)"""

MAX_RENDERING_DT_S = 1.0
"""s, the longest ``rendering_dt`` (simulated time of one ``World.step``, one rendered frame). A
frame per simulated second is already a slide show for a viewer or a camera, and a larger value
is almost always milliseconds passed as seconds; to advance longer, call ``step`` again."""


def check_physics_dt(value, what: str = "physics_dt") -> float:
    """``value`` as a physics step in (0, ``MAX_PHYSICS_DT_S``] s; ``InvalidValueError`` if not."""
    value = check_positive(what, value, "pass seconds, e.g. physics_dt=1/60")
    if value > MAX_PHYSICS_DT_S:
        raise InvalidValueError(
            what, value, f"a physics step holds every command for {value:g} s, slower than any control loop "
            f"(the limit is {MAX_PHYSICS_DT_S} s, 10 Hz)", "pass seconds, e.g. physics_dt=1/60 (10 ms is 0.01)")
    return value


def default_substeps(physics_dt: float) -> int:
    """MuJoCo steps per physics step so that each is at most ``MAX_SUBSTEP_S``."""
    return max(1, math.ceil(physics_dt / MAX_SUBSTEP_S - 1e-9))


class World(TaskHost):
    """The simulation: stage, physics settings, ``num_worlds`` parallel copies, clock.

    Args:
      physics_dt: s, simulated time of one physics step (what physics callbacks receive);
        1/60 as in Isaac Sim.
      rendering_dt: s, simulated time of one ``World.step``; None means ``physics_dt``. When it
        is not a whole multiple of ``physics_dt`` (1/60 and 1/500), each step runs the physics
        steps that fit in the time accumulated so far, as Kit's loop does.
      substeps: MuJoCo steps per physics step (each of ``physics_dt / substeps``); None picks
        enough for steps of at most ``MAX_SUBSTEP_S``.
      solver_iterations, gravity, integrator: see ``ambulo.core.PhysicsCfg``; ``physics``
        (a whole ``PhysicsCfg``) overrides them and ``physics_dt``/``substeps``' timestep.
      num_worlds: parallel copies of the scene (the single-robot API is N = 1).
      device: ``"cpu"`` (MuJoCo) or ``"cuda"`` (MuJoCo Warp).
      engine: ``"auto"``, ``"mujoco"`` or ``"warp"`` (MuJoCo Warp on any device, see
        ``ambulo.engine.ENGINES``).
      backend: ``"numpy"`` (Isaac's default) or ``"torch"`` for object getters.
      stage_units_in_meters: metres per stage unit of the USD stage and of positions, lengths
        and linear velocities at the prim API (Isaac's ``World(stage_units_in_meters=0.01)``
        works in centimetres); the MuJoCo model is always in metres.
      viewer: ``"web"`` opens a browser viewer on 127.0.0.1:``viewer_port`` (``ambulo.viewer``,
        imported first); it is ``self.viewer`` (None without one).
    """

    def __init__(
        self,
        physics_dt: float = 1.0 / 60.0,
        rendering_dt: float | None = None,
        *,
        substeps: int | None = None,
        solver_iterations: int = 50,
        gravity=(0.0, 0.0, -9.81),
        integrator: str = "implicitfast",
        physics: PhysicsCfg | None = None,
        num_worlds: int = 1,
        device: str = "cpu",
        backend: Literal["numpy", "torch"] = "numpy",
        stage_units_in_meters: float = 1.0,
        num_threads: int = 0,
        engine: str = "auto",
        viewer: str | None = None,
        viewer_port: int = 8080,
    ):
        self.stage_units_in_meters = check_positive(
            "stage_units_in_meters", stage_units_in_meters, "pass metres per stage unit, e.g. 1.0 (m) or 0.01 (cm)")
        self._auto_substeps = substeps is None
        if backend not in ("numpy", "torch"):
            raise InvalidValueError("backend", backend, "not a backend", "pass 'numpy' or 'torch'")
        if physics is None:
            physics_dt = check_physics_dt(physics_dt)
            substeps = default_substeps(physics_dt) if substeps is None else substeps
            substeps = check_int("substeps", substeps, "pass a whole number of MuJoCo steps per physics step, e.g. 1",
                                 minimum=1)
            check_timestep("physics_dt / substeps", physics_dt / substeps)
            physics = PhysicsCfg(timestep_s=physics_dt / substeps, gravity_m_s2=gravity,
                                 integrator=integrator, solver_iterations=solver_iterations)
        else:
            substeps = check_int("substeps", 1 if substeps is None else substeps,
                                 "pass a whole number of MuJoCo steps per physics step, e.g. 1", minimum=1)
            self._auto_substeps = False
            physics_dt = check_physics_dt(physics.timestep_s * substeps, "physics.timestep_s * substeps")
        self.physics_dt = float(physics_dt)
        self.rendering_dt = rendering_dt
        self.substeps = int(substeps)
        self._physics_steps_per_step = self._steps_per_render(rendering_dt)
        self.device = device
        self.backend = backend
        self.sim = Simulation(new_scene("World"), physics, num_worlds=num_worlds, device=device, engine=engine,
                              num_threads=num_threads)
        """The core lifecycle object this World drives."""
        self.num_worlds = self.sim.num_worlds
        self.scene = Scene(self)
        self.usd = stage_for_new_world(self.stage_units_in_meters)
        """The USD stage (``ambulo.sim.usd_stage.UsdStage``) scripts author with pxr."""
        self._compiled_signature: int | None = None
        self._time_debt_s = 0.0
        self._render_callbacks = NamedCallbacks("render")
        self._physics_callbacks = NamedCallbacks("physics")
        self._playing = False
        self._step_index = 0
        self.viewport_camera = mujoco.MjvCamera()
        """Free camera used by recordings and the viewer; see ``set_camera_view``."""
        self.viewport_camera.lookat[:] = (0.0, 0.0, 0.3)
        self.viewport_camera.distance, self.viewport_camera.azimuth = 3.0, 135.0
        self.viewport_camera.elevation = -25.0
        set_current_world(self)
        adopted, self.usd.on_adopt = self.usd.on_adopt, []
        for attach in adopted:  # what a script imported onto the stage before this World existed
            attach(self)
        self.viewer = open_viewer(self, viewer, viewer_port)  # None: none, unless a block asks (viewers.py)

    @classmethod
    def instance(cls) -> World | None:
        """The most recently created World (Isaac's ``World.instance()``)."""
        return current_world_or_none()

    def _steps_per_render(self, rendering_dt: float | None) -> float:
        """Physics steps per ``World.step`` (a fraction when the ratio is not whole)."""
        if rendering_dt is not None:
            rendering_dt = check_positive("rendering_dt", rendering_dt, "pass seconds, or None for physics_dt")
            if rendering_dt > MAX_RENDERING_DT_S:
                raise InvalidValueError(
                    "rendering_dt", rendering_dt, f"one World.step would advance {rendering_dt:g} s, a frame per "
                    f"{rendering_dt:g} s of simulated time (the limit is {MAX_RENDERING_DT_S} s)",
                    "pass seconds, e.g. rendering_dt=1/60 (10 ms is 0.01), or None for physics_dt")
        steps = (rendering_dt or self.physics_dt) / self.physics_dt
        if steps < 1 - 1e-9:
            raise InvalidValueError(
                "rendering_dt", rendering_dt, f"shorter than physics_dt ({self.physics_dt:g} s): a rendered frame "
                "would not advance physics", f"pass rendering_dt >= {self.physics_dt:g}, or lower physics_dt")
        return round(steps) if abs(steps - round(steps)) < 1e-9 else steps

    # -- the core objects ------------------------------------------------------
    @property
    def stage(self) -> StageView:
        """The stage: the ``MjSpec`` being built (its snake_case members) and, for Isaac scripts,
        the USD stage (``GetPrimAtPath`` and the other ``Usd.Stage`` methods); see ``StageView``."""
        return StageView(self)

    def synced_usd(self):
        """``self.usd`` with every object the API made mirrored on it (the one place that syncs)."""
        self.usd.mirror_spec(self.sim.spec)
        return self.usd

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
        return self.rendering_dt or self.physics_dt

    def set_simulation_dt(self, physics_dt: float | None = None, rendering_dt: float | None = None):
        """Change the time steps; takes effect at the next ``reset()``."""
        if physics_dt is not None:
            physics_dt = check_positive("physics_dt", physics_dt, "pass seconds, e.g. physics_dt=0.005")
            substeps = default_substeps(physics_dt) if self._auto_substeps else self.substeps
            check_timestep("physics_dt / substeps", physics_dt / substeps)
            check_physics_dt(physics_dt)
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
        if self._auto_substeps:
            self.substeps = default_substeps(self.physics_dt)
        self.physics.timestep_s = self.physics_dt / self.substeps
        self._time_debt_s = 0.0
        self._compiled_signature = None

    @property
    def current_time(self) -> float:
        """s of simulated time since the last reset (world 0)."""
        if self.engine is None:
            return 0.0
        return sim_time_s(self.engine)

    @property
    def current_time_step_index(self) -> int:
        return self._step_index

    # -- lifecycle --------------------------------------------------------------
    def reset(self) -> None:
        """Compile the stage if it changed, then put every world in its initial state.

        Tasks (``add_task``) set up their scenes at the first reset, as in Isaac."""
        self._tasks_before_reset()
        self.synced_usd()  # the objects the API made since the last reset appear on the USD stage
        if self.engine is None or self._stage_signature() != self._compiled_signature:
            self._compile()
        else:
            self.sim.reset(forward=False)  # one kinematics pass below, after post_reset
        self._step_index = 0
        self._time_debt_s = 0.0
        for obj in self.scene.prims():
            obj.post_reset()
        self.engine.forward()
        self._playing = True
        self._tasks_after_reset()

    def initialize_physics(self) -> None:
        """Compile the stage and start the engine without resetting objects' states."""
        self._compile()

    def _compile(self) -> None:
        """Compile the spec plus the prims authored on the USD stage, start the engine, initialize objects."""
        gravity = self.usd.scene_gravity_m_s2()
        if gravity is not None:
            self.physics.gravity_m_s2 = gravity
        iterations = self.usd.solver_iterations()
        if iterations is not None:
            self.physics.solver_iterations = iterations
        steps_per_second = self.usd.changed_time_steps_per_second()
        if steps_per_second is not None:  # PhysX's physics step, which Isaac's physics_dt also sets
            self.set_simulation_dt(physics_dt=1.0 / steps_per_second)
        authored = self.usd.physics_spec()
        self.sim.start(spec=None if authored is None else self._with_authored(authored))
        self._compiled_signature = self._stage_signature()
        for obj in self.scene.prims():
            obj.initialize(self)
        if authored is not None:
            self._write_authored_velocities()
        # the initial state includes what objects set in initialize (default poses)
        self.engine.forward()
        self.engine.capture_initial_state()

    def _with_authored(self, authored: mujoco.MjSpec) -> mujoco.MjSpec:
        """A copy of the stage with the USD-authored prims attached under ``/World``, labelled."""
        from ..core.physics import match_options
        from ..core.semantics import set_semantic_label

        spec = self.stage.copy()
        match_options(authored, spec)
        frame = spec.worldbody.add_frame(name="/World")
        spec.attach(authored, prefix="/World/", frame=frame)
        for path, label in authored_labels(self.usd.stage).items():
            if spec.body(path) is not None:
                set_semantic_label(spec, path, label)
        return spec

    def _write_authored_velocities(self) -> None:
        """Initial velocities authored with ``physics:velocity`` on free bodies (world frame in;
        MuJoCo's free joint takes the angular part in the body frame)."""
        from ..utils.rotations import quat_to_mat

        model, qvel = self.engine.model, self.engine.field("qvel")
        for name, (lin, ang) in self.usd.initial_velocities().items():
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "/World/" + name)
            if body < 0 or model.body_jntnum[body] == 0:
                continue
            joint = model.body_jntadr[body]
            if model.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
                continue
            adr = model.jnt_dofadr[joint]
            ang_b = quat_to_mat(model.body_quat[body]).T @ np.asarray(ang)
            qvel[:, adr:adr + 6] = torch.as_tensor(np.concatenate([lin, ang_b]), dtype=qvel.dtype, device=qvel.device)

    def _stage_signature(self) -> int:
        # the spec has no dirty flag; its XML (and the USD layer's text) is a cheap, faithful fingerprint
        return hash((self.stage.to_xml(), self.usd.signature(), repr(self.physics)))

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
        """Advance by ``rendering_dt``: the physics steps that fit, each after the callbacks.

        With a whole ratio that is ``rendering_dt / physics_dt`` steps every time; otherwise
        the time left over carries to the next call (1/60 over 1/500 gives 8 or 9 steps, 8.33 on
        average). A paused world does not advance. ``render=True`` then does what ``render()``
        does (the kinematics pass only if no physics step just ran one).
        """
        self._require_engine()
        self._tasks_pre_step()
        steps = 0
        if step_sim and self._playing:
            self._time_debt_s += self._physics_steps_per_step * self.physics_dt
            steps = math.floor(self._time_debt_s / self.physics_dt + 1e-9)
            self._time_debt_s = max(0.0, self._time_debt_s - steps * self.physics_dt)
            for _ in range(steps):
                for callback in list(self._physics_callbacks.values()):
                    callback(self.physics_dt)
                # the scene API promises current poses after every step
                self.sim.step(self.substeps, refresh=True)
                self._step_index += 1
        if render:
            self._render(kinematics_fresh=steps > 0)

    def render(self) -> None:
        """Refresh what observers see without advancing physics: kinematics, then render callbacks
        (cameras render on request, at their own frequency)."""
        self._render(kinematics_fresh=False)

    def _render(self, kinematics_fresh: bool) -> None:
        if not kinematics_fresh:  # a physics step with refresh=True has just computed them
            self._require_engine().forward()
        for callback in list(self._render_callbacks.values()):
            callback({"world": self})

    def is_simulating(self) -> bool:
        return self._playing

    # -- Isaac's coroutine forms (extension-workflow samples await them) ----------------------
    async def reset_async(self, soft: bool = False) -> None:
        self.reset()

    async def play_async(self) -> None:
        self.play()

    async def pause_async(self) -> None:
        self.pause()

    async def stop_async(self) -> None:
        self.stop()

    async def step_async(self, step_size: float | None = None) -> None:
        """``step(render=False)``; ``step_size`` (Isaac's argument) must be the World's physics_dt,
        not another step silently ignored."""
        if step_size is not None:
            step_size = check_physics_dt(step_size, "step_size")
            if not math.isclose(step_size, self.physics_dt, rel_tol=1e-6):
                raise InvalidValueError("step_size", step_size, f"the World steps physics_dt ({self.physics_dt:g} s)",
                                        "call set_simulation_dt(physics_dt=...) first, or pass no step_size")
        self.step(render=False)

    async def render_async(self) -> None:
        self.render()

    async def initialize_simulation_context_async(self) -> None:
        await asyncio.sleep(0)

    # -- callbacks -------------------------------------------------------------
    def add_physics_callback(self, callback_name: str, callback_fn: Callable[[float], None]) -> None:
        """Call ``callback_fn(step_size_s)`` before every physics step."""
        self._physics_callbacks.add(callback_name, callback_fn)

    def remove_physics_callback(self, callback_name: str) -> None:
        self._physics_callbacks.remove(callback_name)

    def physics_callback_exists(self, callback_name: str) -> bool:
        return callback_name in self._physics_callbacks

    def clear_physics_callbacks(self) -> None:
        self._physics_callbacks.clear()

    def add_render_callback(self, callback_name: str, callback_fn: Callable[[object], None]) -> None:
        """Call ``callback_fn(event)`` after every ``render()``."""
        self._render_callbacks.add(callback_name, callback_fn)

    def remove_render_callback(self, callback_name: str) -> None:
        self._render_callbacks.remove(callback_name)

    def render_callback_exists(self, callback_name: str) -> bool:
        return callback_name in self._render_callbacks

    def clear_render_callbacks(self) -> None:
        self._render_callbacks.clear()

    @classmethod
    def clear_instance(cls) -> None:
        """Forget the current World (Isaac's singleton reset); the next ``World()`` starts anew."""
        set_current_world(None)

    # -- conversions for object getters ------------------------------------------
    def _out(self, tensor: torch.Tensor):
        """A copy of a (N, ...) tensor for users: squeezed to (...) when N == 1."""
        value = tensor.detach().clone()
        if self.num_worlds == 1:
            value = value[0]
        return value.cpu().numpy() if self.backend == "numpy" else value

    def _in(self, value, trailing: tuple[int, ...], what: str) -> torch.Tensor:
        """User input as a (N, *trailing) tensor in the engine's dtype, broadcasting a single value.

        Text, complex numbers, NaN and inf are refused; a CUDA tensor is checked by shape and
        dtype only (reading its values would sync the GPU)."""
        device = self.engine.device if self.engine is not None else "cpu"
        dtype = self.engine.dtype if self.engine is not None else torch.float64
        fix = f"pass finite real numbers of shape {trailing} or {(self.num_worlds, *trailing)}"
        check_real_dtype(what, value, fix)
        try:
            array = value if torch.is_tensor(value) else np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidValueError(what, value, "not an array of numbers", fix) from None
        check_all_finite(what, torch.as_tensor(array), fix)
        tensor = torch.as_tensor(array, dtype=dtype, device=device)
        want = (self.num_worlds, *trailing)
        if tensor.shape == trailing:
            tensor = tensor.expand(want)
        if tuple(tensor.shape) != want:
            raise InvalidValueError(what, Described(f"of shape {tuple(tensor.shape)}"),
                                    f"expected shape {trailing} or {want}", fix)
        return tensor
