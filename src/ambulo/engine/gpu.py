"""GpuEngine: N worlds of one MjModel on MuJoCo Warp, state as zero-copy torch tensors.

The model the CPU engine steps is put on the device once (``mujoco_warp.put_model``) and N
worlds of data are allocated beside it (``put_data``). Every state and output field is a
``wp.to_torch`` view of the Warp array, so writing ``engine.qpos[...]`` writes the
simulation state with no copy, and env code runs unchanged on either engine.

On CUDA the physics of one ``step`` (all its substeps), ``forward`` and resets run as
CUDA graphs captured once per shape and replayed on torch's current stream: nothing on
the step path waits for the device or loops over worlds in Python. Divergence (NaN or
|value| > 1e10 in qpos/qvel/qacc, MuJoCo's ``mj_checkPos/Vel/Acc`` rule) is found with
tensor reductions and those worlds alone are reset by mask, still on the device.

The same class runs on Warp's CPU device (``device="cpu"``), which is how CI tests GPU
code paths and CPU/GPU parity on machines without a GPU.

Differences from ``CpuEngine`` callers should know (see docs/gpu.md):
  * values are float32 (MuJoCo Warp's precision), the CPU engine's float64;
  * ``forward`` on a subset computes all worlds but restores the derived fields the caller
    has bound (``field``) for the others, so observations match the CPU semantics;
    ``forward(kinematics_only=True)`` runs the kinematics kernels alone (a reset's cheap pass);
  * buffer overflows (contacts, constraints) are checked every ``overflow_check_steps``
    steps, which is the only host sync, and raise ``EngineOverflowError``.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

import mujoco
import mujoco_warp as mjw
import numpy as np
import torch
import warp as wp

from .protocol import KINEMATIC_FIELDS, STATE_FIELDS
from .warp_precompile import PrecompileReport, default_workers, precompile

log = logging.getLogger(__name__)
T = TypeVar("T")

WorldIds = Sequence[int] | np.ndarray | torch.Tensor | None

# MuJoCo's mjMAXVAL: a state entry beyond it counts as diverged, as in mj_checkPos/Vel/Acc
_MAX_VALUE = 1e10

# Overflows that drop contacts or constraints (the physics is then wrong). Solver iteration
# limits (ITERATIONS, LS_ITERATIONS) are normal and not errors.
_CAPACITY = {
    mjw.OverflowType.NEFC: ("constraints", "max_constraints_per_world"),
    mjw.OverflowType.NJMAX_NNZ: ("constraint Jacobian entries", "max_constraints_per_world"),
    mjw.OverflowType.BROADPHASE: ("broadphase contact candidates", "max_contacts_per_world"),
    mjw.OverflowType.NARROWPHASE: ("contacts", "max_contacts_per_world"),
    mjw.OverflowType.CCD: ("convex-collision contacts", "max_contacts_per_world"),
}

_CAPACITY_BITS = sum(int(bit) for bit in _CAPACITY)

# mjOption fields MuJoCo Warp's Option also holds (impratio as impratio_invsqrt: not compared)
_OPTIONS = ("timestep", "integrator", "solver", "iterations", "ls_iterations", "tolerance", "ls_tolerance",
            "cone", "noslip_iterations", "noslip_tolerance", "ccd_iterations", "ccd_tolerance",
            "disableflags", "enableflags")

# Every MjData field that is per world state, restored by reset; the protocol's
# STATE_FIELDS plus the solver warm start (part of MuJoCo's integration state).
_RESET_FIELDS = STATE_FIELDS + ("qacc_warmstart", "act_dot", "eq_active", "userdata")


class EngineOverflowError(RuntimeError):
    """A contact or constraint buffer of the GPU engine overflowed."""


def _init_warp() -> None:
    """Initialize Warp once. Without a CUDA driver (a laptop, CI) Warp's native code prints a
    warning on stderr at init that says nothing to a user who asked for Warp's CPU device, so
    stderr is muted for that call only."""
    if torch.cuda.is_available():
        wp.init()
        return
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def warp_device(device: str | torch.device) -> str:
    """The Warp device for a torch device string: ``"cpu"`` or ``"cuda:k"``."""
    dev = torch.device(device)
    if dev.type == "cuda":
        return f"cuda:{dev.index if dev.index is not None else torch.cuda.current_device()}"
    if dev.type == "cpu":
        return "cpu"
    raise ValueError(f"device {device!r}: MuJoCo Warp runs on 'cpu' or 'cuda[:N]'")


def _ids_to_mask(world_ids: WorldIds, num_worlds: int, device: torch.device) -> torch.Tensor | None:
    """An (N,) bool mask on ``device`` for world ids (indices or a mask), None for all."""
    if world_ids is None:
        return None
    ids = torch.as_tensor(world_ids, device=device)
    if ids.dtype == torch.bool:
        if ids.shape != (num_worlds,):
            raise ValueError(f"a world mask has shape {tuple(ids.shape)}; pass ({num_worlds},) booleans")
        return ids
    ids = ids.reshape(-1).long()
    if device.type == "cpu" and ids.numel() and (int(ids.min()) < 0 or int(ids.max()) >= num_worlds):
        bad = int(ids.min()) if int(ids.min()) < 0 else int(ids.max())
        raise IndexError(f"world id {bad} is out of range for {num_worlds} worlds; "
                         f"pass ids in [0, {num_worlds})")
    return torch.zeros(num_worlds, dtype=torch.bool, device=device).index_fill_(0, ids, True)


def _rows(mask: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """``mask`` (N,) shaped to broadcast over ``like`` (N, ...)."""
    return mask.view(-1, *([1] * (like.dim() - 1)))


class _Ticker:
    """Prints elapsed time every ``period_s`` while a slow first compile runs, so a cold start
    shows progress instead of silence (the first Warp compile of a humanoid takes minutes)."""

    def __init__(self, what: str, period_s: float = 15.0, first_s: float = 5.0):
        self.what, self.period_s, self.first_s = what, period_s, first_s
        self._stop = threading.Event()
        self.start_s = time.perf_counter()
        self.announced = False

    def __enter__(self):
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def _run(self):
        if self._stop.wait(self.first_s):
            return
        self.announced = True
        print(f"ambulo: {self.what} (first run of this model on this device; later runs load "
              f"them from {wp.config.kernel_cache_dir})", file=sys.stderr, flush=True)
        while not self._stop.wait(self.period_s):
            print(f"ambulo: still compiling, {time.perf_counter() - self.start_s:.0f} s", file=sys.stderr,
                  flush=True)

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.elapsed_s = time.perf_counter() - self.start_s
        if self.announced:
            print(f"ambulo: kernels ready after {self.elapsed_s:.0f} s", file=sys.stderr, flush=True)


class GpuEngine:
    """N worlds of ``model`` stepped by MuJoCo Warp on ``device``.

    Args:
      model: the compiled model (the same one ``CpuEngine`` takes); the engine keeps a copy.
      num_worlds: N.
      device: ``"cuda[:k]"``, or ``"cpu"`` for Warp's CPU device (tests, parity checks).
      keyframe: keyframe index or name for the initial state, or None for qpos0.
      max_contacts_per_world: contact buffer per world (``nconmax``); None sizes it from the
        model (see ``contact_capacity``).
      max_constraints_per_world: constraint rows per world (``njmax``); None sizes it from the
        model and the contact buffer.
      broadphase: ``"auto"`` (MuJoCo Warp's choice), ``"nxn"``, ``"sap_tile"`` or
        ``"sap_segmented"`` (``PhysicsCfg.broadphase``).
      use_graphs: capture step and forward in CUDA graphs (CUDA only).
      compile_workers: threads that compile a body's Warp modules before its first run
        (``engine.warp_precompile``; None: the cores, at most 16; 0 or 1: Warp's own serial
        compile at first launch).
      compile_processes: with more than 1, that many forked processes first compile the modules
        into Warp's kernel cache (``warp_precompile.compile_in_processes``: NVRTC compiles largely
        one at a time within a process); the threads then load them. 0: threads only.
      overflow_check_steps: steps between the overflow checks (each one host sync).
      num_threads, divergence_dump_dir: accepted for the CpuEngine signature; the first is
        unused, the second dumps diverged worlds (costs a host sync per step).
    """

    dtype = torch.float32

    def __init__(
        self,
        model: mujoco.MjModel,
        num_worlds: int = 1,
        device: str | torch.device = "cuda",
        keyframe: int | str | None = None,
        max_contacts_per_world: int | None = None,
        max_constraints_per_world: int | None = None,
        broadphase: str = "auto",
        use_graphs: bool = True,
        overflow_check_steps: int = 100,
        compile_workers: int | None = None,
        compile_processes: int = 0,
        num_threads: int = 0,
        divergence_dump_dir: str | os.PathLike | None = None,
    ):
        if num_worlds < 1:
            raise ValueError(f"num_worlds must be >= 1, got {num_worlds}")
        del num_threads  # Warp's CPU device runs its own threads
        self.num_worlds = int(num_worlds)
        self.wp_device = warp_device(device)
        self.device = torch.device(self.wp_device)
        if self.device.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device {device!r}: torch sees no CUDA device; use device='cpu'")
        self.model = model.__copy__()
        self.model_version = 0
        """Bumps whenever a model array is replaced (per-world expansion): captured graphs and
        render contexts holding model arrays must be rebuilt when it changes."""
        self.use_graphs = bool(use_graphs) and self.device.type == "cuda"
        self.overflow_check_steps = int(overflow_check_steps)
        self.compile_workers = default_workers() if compile_workers is None else int(compile_workers)
        self.compile_processes = int(compile_processes)
        self.precompile_reports: dict[tuple, PrecompileReport] = {}
        """Per body key, what its parallel precompile loaded (``engine.warp_precompile``)."""
        self.divergence_dump_dir = None if divergence_dump_dir is None else Path(divergence_dump_dir)

        data = mujoco.MjData(self.model)
        if keyframe is not None:
            key = keyframe if isinstance(keyframe, int) else self.model.key(keyframe).id
            mujoco.mj_resetDataKeyframe(self.model, data, key)
        mujoco.mj_forward(self.model, data)
        self.nconmax, self.njmax = contact_capacity(self.model, data, max_contacts_per_world,
                                                    max_constraints_per_world)
        if "AMBULO_WARP_LOG" not in os.environ:  # our progress line replaces one line per module
            wp.config.log_level = wp.LOG_WARNING
        _init_warp()
        with wp.ScopedDevice(self.wp_device):
            self.wp_model = mjw.put_model(self.model)
            self.wp_model.opt.warn_overflow = 0  # checked by check_overflow, not printed per kernel
            if broadphase != "auto":
                self.wp_model.opt.broadphase = mjw.BroadphaseType[broadphase.upper()]
            self.wp_data = mjw.put_data(self.model, data, nworld=self.num_worlds,
                                        nconmax=self.nconmax, njmax=self.njmax)
        self._tensors: dict[str, torch.Tensor] = {}
        self._model_tensors: dict[str, torch.Tensor] = {}
        self._model_keepalive: dict[str, torch.Tensor] = {}
        self._graphs: dict[tuple, object] = {}
        self._capture_stream = wp.Stream(self.wp_device) if self.use_graphs else None
        self._reset_names = [n for n in _RESET_FIELDS if getattr(self.wp_data, n, None) is not None
                             and getattr(self.wp_data, n).size > 0]
        self._state = {n: self.field(n) for n in self._reset_names}
        self.initial_state = {n: t.clone() for n, t in self._state.items()}
        """Per field (N, ...) tensors: the state ``reset`` restores; edit rows to change it."""
        self._diverged_total = torch.zeros((), dtype=torch.long, device=self.device)
        self._steps_since_check = 0
        self.compile_time_s: float | None = None
        """Seconds the first runs of step, forward and set_const took (kernel compile or cache load)."""
        self._warmed: set[tuple] = set()
        self.steps_in_capture = 0
        """``step`` calls recorded into torch CUDA graphs so far (see ``count_steps``)."""
        self.acc_stale: torch.Tensor | None = None
        """None until a ``forward(kinematics_only=True)``, then (N,) bool: worlds whose fields
        outside ``KINEMATIC_FIELDS`` (sensordata, contacts, forces, qacc) predate their state."""

    def option_differences(self) -> dict[str, tuple[float, float]]:
        """``{name: (MjModel's value, MuJoCo Warp's)}`` of the solver and integrator options that
        MuJoCo Warp runs with another value than the CPU engine would. ``put_model`` raises
        ``tolerance`` to at least 1e-6 (float32 cannot resolve less): ambulo's 1e-8 runs as 1e-6
        here; Newton converges in ~2 iterations on contact-rich states, so this changes nothing
        measurable (``benchmarks/sim_to_sim.py``). Any other entry is a new override to look at."""
        def value(name):
            v = getattr(self.wp_model.opt, name)
            return float(v.numpy().ravel()[0] if isinstance(v, wp.array) else v)

        pairs = {name: (float(getattr(self.model.opt, name)), value(name)) for name in _OPTIONS}
        pairs["impratio"] = (float(self.model.opt.impratio), value("impratio_invsqrt") ** -2)
        # float32 storage of float64 values is no difference
        return {k: v for k, v in pairs.items() if not math.isclose(*v, rel_tol=1e-6)}

    # -- fields ---------------------------------------------------------------
    def field(self, name: str) -> torch.Tensor:
        """Live (N, ...) tensor of an MjData field; matrices as (N, n, 9) like MjData."""
        tensor = self._tensors.get(name)
        if tensor is not None:
            return tensor
        array = getattr(self.wp_data, name, None)
        if not isinstance(array, wp.array) or array.shape[0] != self.num_worlds:
            raise ValueError(f"engine field {name!r}: not a per-world MjData field of MuJoCo Warp")
        tensor = wp.to_torch(array)
        if name == "time" or tensor.dim() == 1:
            tensor = tensor.view(self.num_worlds)
        elif tensor.dim() == 4:  # (N, n, 3, 3) matrices: flattened as MjData stores them
            tensor = tensor.view(self.num_worlds, tensor.shape[1], -1)
        self._tensors[name] = tensor
        return tensor

    def __getattr__(self, name: str) -> torch.Tensor:
        # engine.qpos, engine.xpos, ... as on MjData; only for field names
        if name.startswith("_") or not isinstance(getattr(self.__dict__.get("wp_data"), name, None), wp.array):
            raise AttributeError(f"GpuEngine has no attribute {name!r}")
        return self.field(name)

    def model_field(self, name: str) -> torch.Tensor:
        """Live, writable (N, ...) per-world values of an MjModel field (shaped like the CPU
        engine's). The first call for a field gives each world its own copy on the device.
        Fields MuJoCo Warp shares between worlds (``actuator_forcelimited``, ...) are (1, ...)."""
        tensor = self._model_tensors.get(name)
        if tensor is not None:
            return tensor
        array = getattr(self.wp_model, name, None)
        if not isinstance(array, wp.array):
            raise ValueError(f"model field {name!r}: not an array of mujoco_warp.Model")
        if name not in _batchable_fields():
            # MuJoCo Warp shares it between worlds: a (1, ...) view whose writes reach every
            # world, and a per-world write (N rows) fails on its shape instead of half-working
            tensor = wp.to_torch(array).unsqueeze(0)
            self._model_tensors[name] = tensor
            return tensor
        if array.shape[0] != self.num_worlds:
            source = wp.to_torch(array)
            expanded = source[:1].expand(self.num_worlds, *source.shape[1:]).contiguous()
            new = wp.from_torch(expanded, dtype=array.dtype)
            setattr(self.wp_model, name, new)
            self._model_keepalive[name] = expanded
            self._invalidate()
            array = new
        tensor = wp.to_torch(array)
        mj_shape = np.shape(getattr(self.model, name, None))
        if mj_shape and math.prod(mj_shape) * self.num_worlds == tensor.numel():
            tensor = tensor.view(self.num_worlds, *mj_shape)
        self._model_tensors[name] = tensor
        return tensor

    def set_const(self, world_ids: WorldIds = None) -> None:
        """Recompute derived model constants (after writing body masses, inertias, ...) for
        all worlds (MuJoCo Warp has no subset; unchanged worlds recompute the same values)."""
        del world_ids
        # constants derived from per-world inputs must themselves be per world
        if self._model_tensors:
            for name in ("body_subtreemass", "body_invweight0", "dof_invweight0", "actuator_acc0",
                         "tendon_invweight0", "geom_aabb", "geom_rbound", "cam_pos0", "cam_poscom0",
                         "cam_mat0", "light_pos0", "light_poscom0", "light_dir0"):
                if name in _batchable_fields() and getattr(self.wp_model, name).size:
                    self.model_field(name)
        m, d = self.wp_model, self.wp_data

        def body():
            mjw.set_const(m, d)

        def run():
            with self.warp_scope():
                body()

        # run eagerly, never in a graph (it is rare), but its first run precompiled like a step's: its
        # modules (set_const's own, the Cholesky tiles of its inertia solve) compiled serially otherwise,
        # and a task that randomizes masses calls it in envs.make, before any step
        key = ("set_const",)
        if key in self._warmed:
            run()
        else:
            self._first_run(key, body, run)

    # -- stepping -------------------------------------------------------------
    @contextlib.contextmanager
    def warp_scope(self):
        """Run Warp launches on this engine's device, ordered with torch's current stream."""
        if self.device.type != "cuda":
            with wp.ScopedDevice(self.wp_device):
                yield
            return
        stream = warp_stream(torch.cuda.current_stream(self.device))
        with wp.ScopedDevice(self.wp_device), wp.ScopedStream(stream, sync_enter=False):
            yield

    def _run(self, key: tuple, body: Callable[[], None]) -> None:
        """Run ``body`` (Warp launches) as a CUDA graph captured once per ``key``. The first run
        of a key compiles (or loads from Warp's cache) its kernels: timed, with progress lines."""
        if self.torch_capturing():
            # inside an env step being captured by torch (``capture_torch_graph``): the kernels go
            # straight into that graph on the capturing stream (a Warp graph is not nested)
            with self.warp_scope():
                body()
            return
        if key not in self._warmed:
            self._first_run(key, body, lambda: self._run(key, body))
            return
        if not self.use_graphs:
            with self.warp_scope():
                body()
            return
        graph = self._graphs.get(key)
        if graph is None:
            graph = self._capture(body)
            self._graphs[key] = graph
        with self.warp_scope():
            wp.capture_launch(graph)

    def _first_run(self, key: tuple, body: Callable[[], None], run: Callable[[], None]) -> None:
        """The first ``run`` of ``key`` (``body``'s launches, however run), its modules precompiled first:
        it compiles (or loads from Warp's cache) its kernels, timed into ``compile_time_s``, with progress lines."""
        self._warmed.add(key)
        with _Ticker("compiling MuJoCo Warp kernels") as ticker:
            self._precompile(key, body)
            run()
            if self.device.type == "cuda":
                torch.cuda.synchronize(self.device)
        self.compile_time_s = (self.compile_time_s or 0.0) + ticker.elapsed_s
        log.info("GpuEngine: first %s (kernel compile or cache load) took %.1f s", key[0], ticker.elapsed_s)

    def _precompile(self, key: tuple, body: Callable[[], None]) -> None:
        """Compile ``body``'s modules from ``compile_workers`` threads (a dry run records them; its
        copies and fills may touch the state, which is restored as after ``_capture``'s warm-up)."""
        if self.compile_workers <= 1 and self.compile_processes <= 1:
            return
        try:
            with self._state_restored(), self.warp_scope():
                self.precompile_reports[key] = precompile(body, self.compile_workers, self.compile_processes)
        except Exception as error:  # an optimization: the real first run compiles what is missing, serially
            log.warning("GpuEngine: the parallel kernel precompile of %s failed (%s: %s); Warp compiles the "
                        "modules at their first launch instead", key[0], type(error).__name__, error)

    @contextlib.contextmanager
    def _state_restored(self):
        """The state fields as they were before the block, whatever it ran (a warm-up or dry run)."""
        saved = {n: t.clone() for n, t in self._state.items()}
        try:
            yield
        finally:
            for n, t in self._state.items():
                t.copy_(saved[n])

    def _capture(self, body: Callable[[], None]):
        # a capture cannot load modules: run once eagerly (compiling kernels) on a copy of the
        # state, then restore it, so capturing changes nothing
        with self._state_restored(), self.warp_scope():
            body()
        torch.cuda.synchronize(self.device)
        return capture_graph(self.wp_device, self._capture_stream, body)

    def _invalidate(self) -> None:
        self.model_version += 1
        self._warmed.clear()
        self._graphs.clear()

    def step(self, num_substeps: int = 1, refresh: bool = False) -> torch.Tensor:
        """Advance ``num_substeps`` physics steps; return the (N,) bool mask (on the device) of
        worlds that diverged and were reset. Derived fields then describe the state before the
        last substep, as after ``mj_step``; ``refresh=True`` recomputes poses and velocities."""
        m, d = self.wp_model, self.wp_data

        def body():
            for _ in range(num_substeps):
                mjw.step(m, d)
            if refresh:
                mjw.kinematics(m, d)
                mjw.com_pos(m, d)
                mjw.camlight(m, d)
                mjw.com_vel(m, d)

        capturing = self.torch_capturing()
        if capturing and self.divergence_dump_dir is not None:
            raise RuntimeError("divergence_dump_dir reads the device every step: it cannot run in a CUDA graph")
        before = self._dump_before() if self.divergence_dump_dir is not None else None
        self._run(("step", num_substeps, refresh), body)
        if self.acc_stale is not None:
            self.acc_stale.zero_()  # a step computes every field of every world
        diverged = self._diverged()
        self._diverged_total += diverged.sum()
        self._reset_mask(diverged)
        if before is not None:
            self._dump_diverged(diverged, before)
        if capturing:
            # a Python counter does not advance when the graph replays: whoever replays it
            # calls ``count_steps`` with this many calls per replay
            self.steps_in_capture += 1
        else:
            self.count_steps(1)
        return diverged

    def torch_capturing(self) -> bool:
        """Whether torch is capturing a CUDA graph on the current stream (never on the CPU)."""
        return self.device.type == "cuda" and torch.cuda.is_current_stream_capturing()

    def count_steps(self, calls: int) -> None:
        """Count ``calls`` step calls toward the overflow check (one host sync every
        ``overflow_check_steps``); a captured step's replays are counted here by its owner."""
        self._steps_since_check += calls
        if self._steps_since_check >= self.overflow_check_steps:
            self.check_overflow()

    def _diverged(self) -> torch.Tensor:
        # max |x| <= MAX is False for NaN too (amax propagates NaN on CPU and CUDA), so one
        # comparison catches NaN, inf and huge values; one row max over the three fields side by
        # side: 5 kernels a step where a check per field took 12 (an action latency steps 4 times)
        state = torch.cat([self.field("qpos"), self.field("qvel"), self.field("qacc")], dim=1)
        return ~(state.abs().amax(dim=1) <= _MAX_VALUE)

    @property
    def num_diverged(self) -> int:
        """Total number of world divergences detected (and reset) so far (reads the device)."""
        return int(self._diverged_total)

    def check_overflow(self) -> None:
        """Raise ``EngineOverflowError`` if any world overflowed a contact or constraint buffer
        since the last check (one host sync)."""
        self._steps_since_check = 0
        flags = self.field("overflow")
        hit = flags & _CAPACITY_BITS
        if not bool(hit.any()):
            return
        world = int(torch.nonzero(hit)[0, 0])
        bits = int(hit[world])
        what, setting = next(v for b, v in _CAPACITY.items() if bits & int(b))
        limit = self.nconmax if setting == "max_contacts_per_world" else self.njmax
        flags.zero_()
        raise EngineOverflowError(
            f"world {world} overflowed its buffer of {what} ({setting}={limit}), so some were "
            f"dropped and the physics is wrong; raise PhysicsCfg.{setting} (e.g. to {2 * limit})")

    def forward(self, world_ids: WorldIds = None, kinematics_only: bool = False) -> None:
        """Recompute derived fields from the current state. With ``world_ids`` only those
        worlds' bound fields change (all worlds are computed, the others restored).

        ``kinematics_only``: MuJoCo Warp's ``fwd_kinematics`` and ``com_vel`` alone, which write
        ``KINEMATIC_FIELDS`` (poses, com, com velocities); no collision, actuation or constraint
        solve, so every other field (sensordata, qacc, qfrc_actuator, contacts) keeps its value
        and ``acc_stale`` marks the worlds. Why: a masked reset runs a forward every step on a
        GPU, and on Warp's CPU device a full ``forward`` measured 86 % of a whole ``mjw.step``
        against 2.5 % for these kernels; the next step recomputes everything from the state."""
        mask = _ids_to_mask(world_ids, self.num_worlds, self.device)
        m, d = self.wp_model, self.wp_data
        if kinematics_only:
            key = ("forward_kinematics",)

            def body():
                mjw.fwd_kinematics(m, d)
                mjw.com_vel(m, d)
        else:
            key = ("forward",)

            def body():
                mjw.forward(m, d)
        # only the fields the kernels write need saving: a kinematics pass leaves the others alone
        derived = [t for n, t in self._tensors.items()
                   if n not in self._state and (not kinematics_only or n in KINEMATIC_FIELDS)]
        saved = None if mask is None else [t.clone() for t in derived]
        self._run(key, body)
        if saved is not None:
            for t, old in zip(derived, saved):
                t.copy_(torch.where(_rows(mask, t), t, old))
        self._mark_stale(mask, kinematics_only)

    def _mark_stale(self, mask: torch.Tensor | None, stale: bool) -> None:
        """Update ``acc_stale`` in place (graph-safe) for the worlds a forward computed."""
        if self.acc_stale is None:
            if not stale:
                return
            self.acc_stale = torch.zeros(self.num_worlds, dtype=torch.bool, device=self.device)
        if mask is None:
            self.acc_stale.fill_(stale)
        elif stale:
            self.acc_stale |= mask
        else:
            self.acc_stale &= ~mask

    def reset(self, world_ids: WorldIds = None, forward: bool = True) -> None:
        mask = _ids_to_mask(world_ids, self.num_worlds, self.device)
        if mask is None:
            for n, t in self._state.items():
                t.copy_(self.initial_state[n])
        else:
            self._reset_mask(mask)
        if forward:
            self.forward(mask)

    def _reset_mask(self, mask: torch.Tensor) -> None:
        for n, t in self._state.items():
            torch.where(_rows(mask, t), self.initial_state[n], t, out=t)  # in place: one kernel, no copy

    def capture_initial_state(self, world_ids: WorldIds = None) -> None:
        """Make the worlds' current state the one ``reset`` restores."""
        mask = _ids_to_mask(world_ids, self.num_worlds, self.device)
        for n, t in self._state.items():
            init = self.initial_state[n]
            init.copy_(t if mask is None else torch.where(_rows(mask, t), t, init))

    # -- divergence dumps (debugging; syncs) --------------------------------------
    def _dump_before(self) -> dict[str, np.ndarray]:
        return {n: t.detach().cpu().numpy().copy() for n, t in self._state.items()}

    def _dump_diverged(self, diverged: torch.Tensor, before: dict[str, np.ndarray]) -> None:
        ids = torch.nonzero(diverged).flatten().cpu().numpy()
        if not ids.size:
            return
        out = self.divergence_dump_dir
        out.mkdir(parents=True, exist_ok=True)
        if not (out / "model.mjb").is_file():
            mujoco.mj_saveModel(self.model, str(out / "model.mjb"), None)
        path = out / f"diverged_{self.num_diverged:06d}.npz"
        np.savez(path, world_ids=ids, timestep=self.model.opt.timestep,
                 **{n: a[ids] for n, a in before.items()})
        log.warning("diverged worlds %s dumped to %s", ids.tolist()[:8], path)

    # -- single-world access ----------------------------------------------------
    def get_model(self, world: int, model: mujoco.MjModel | None = None) -> mujoco.MjModel:
        """World ``world``'s model: the shared model with its per-world field values."""
        model = self.model.__copy__() if model is None else model
        for name, tensor in self._model_tensors.items():
            target = getattr(model, name, None)
            if isinstance(target, np.ndarray):
                target[...] = tensor[int(world)].detach().cpu().numpy().reshape(target.shape)
        return model

    def get_data(self, world: int, data: mujoco.MjData | None = None) -> mujoco.MjData:
        """World ``world``'s state in an ``MjData`` with every derived field computed
        (``mj_forward`` on that world's model, in float64), ready for a renderer."""
        world = int(world)
        data = mujoco.MjData(self.model) if data is None else data
        for name in self._reset_names:
            value = self._state[name][world].detach().cpu().numpy()
            target = getattr(data, name)
            if isinstance(target, np.ndarray):
                target[...] = value.reshape(target.shape)
            else:
                setattr(data, name, float(value))
        mujoco.mj_forward(self.get_model(world) if self._model_tensors else self.model, data)
        return data

    def ray(self, pnt, vec, geomgroup=None, flg_static: bool = True, bodyexclude: int = -1):
        """Batched ray casts: ``pnt``, ``vec`` (N, R, 3) world frame -> distances (N, R) and
        geom ids (N, R) int32, -1 for a miss (``mujoco_warp.rays``)."""
        pnt = torch.as_tensor(pnt, dtype=torch.float32, device=self.device).contiguous()
        vec = torch.as_tensor(vec, dtype=torch.float32, device=self.device).contiguous()
        n, r = pnt.shape[:2]
        dist = torch.empty(n, r, dtype=torch.float32, device=self.device)
        geom = torch.empty(n, r, dtype=torch.int32, device=self.device)
        normal = torch.empty(n, r, 3, dtype=torch.float32, device=self.device)
        group = tuple(int(g) for g in (geomgroup if geomgroup is not None else (-1,) * 6))
        exclude = torch.full((r,), int(bodyexclude), dtype=torch.int32, device=self.device)
        with self.warp_scope():
            mjw.rays(self.wp_model, self.wp_data, wp.from_torch(pnt, dtype=wp.vec3),
                     wp.from_torch(vec, dtype=wp.vec3), mjw._src.types.vec6(*group), flg_static,
                     wp.from_torch(exclude), wp.from_torch(dist), wp.from_torch(geom),
                     wp.from_torch(normal, dtype=wp.vec3))
        return dist, geom


def capture_graph(device: str, stream: wp.Stream, body: Callable[[], None]):
    """``body``'s Warp launches as a CUDA graph, captured on ``stream``. The capturing stream
    must be the current one: MuJoCo Warp allocates scratch arrays inside ``step``, and an
    allocation on any other stream during a capture fails (CUDA error 900)."""
    with wp.ScopedDevice(device), wp.ScopedStream(stream), wp.ScopedCapture() as capture:
        body()
    return capture.graph


_WARP_STREAMS: dict[tuple[int, int], wp.Stream] = {}


def warp_stream(stream: torch.cuda.Stream) -> wp.Stream:
    """The one Warp wrapper of a torch CUDA stream, kept for the process. A wrapper made per
    call (``wp.stream_from_torch``) unregisters the stream from Warp when it is collected,
    which also frees Warp's radix-sort scratch of that stream: inside a graph capture that is a
    free the capture forbids, after it a buffer the graph still uses."""
    key = (stream.device.index or 0, stream.cuda_stream)
    wrapper = _WARP_STREAMS.get(key)
    if wrapper is None:
        wrapper = _WARP_STREAMS[key] = wp.stream_from_torch(stream)
    return wrapper


def capture_torch_graph(device: torch.device, fn: Callable[[], T], generators=(),
                        stream: torch.cuda.Stream | None = None) -> tuple[object, object, T]:
    """Capture ``fn``'s torch work and Warp launches (an env step: torch ops around MuJoCo Warp's
    kernels) in one torch CUDA graph; returns ``(torch graph, Warp graph, fn's result)``.

    torch opens the capture on a side stream; Warp is told it is capturing there
    (``ScopedCapture(external=True)``) so the scratch arrays MuJoCo Warp allocates inside a
    step are kept alive by the Warp graph object, which must live as long as the torch graph.
    ``GpuEngine`` launches its kernels directly while torch captures (a Warp graph is not
    nested). ``generators``: custom torch CUDA generators the captured code draws from; their
    state advances on every replay (``CUDAGraph.register_generator_state``, torch >= 2.5).
    ``stream``: the side stream to capture on (a new one if None; pass the one warm-up ran on).
    Nothing runs: the caller replays the graph (``graph.replay()``) to execute it."""
    graph = torch.cuda.CUDAGraph()
    if generators and not hasattr(graph, "register_generator_state"):
        raise RuntimeError(f"torch {torch.__version__} cannot advance a custom generator in a CUDA graph "
                           "(CUDAGraph.register_generator_state, torch >= 2.5); use an eager step")
    for generator in generators:
        graph.register_generator_state(generator)
    stream = torch.cuda.Stream(device) if stream is None else stream
    stream.wait_stream(torch.cuda.current_stream(device))
    # one capture mode on both sides, as an external capture must declare it to Warp
    with torch.cuda.graph(graph, stream=stream, capture_error_mode="thread_local"):
        wp_stream = warp_stream(stream)
        with wp.ScopedDevice(warp_device(device)), wp.ScopedStream(wp_stream, sync_enter=False), \
                wp.ScopedCapture(stream=wp_stream, external=True,
                                 capture_mode=wp.CaptureMode.THREAD_LOCAL) as capture:
            result = fn()
    torch.cuda.current_stream(device).wait_stream(stream)
    return graph, capture.graph, result


def synchronize(device: torch.device) -> None:
    """Wait for ``device`` (CUDA); nothing on the CPU. For timing loops, never on a step path."""
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize(device)


def stack_versions() -> dict[str, str]:
    """Versions of the GPU stack, for benchmark results and bug reports."""
    import importlib.metadata

    def dist(name: str) -> str:
        try:
            return importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            return "not installed"

    return {"torch": torch.__version__, "torch_cuda": str(torch.version.cuda), "warp": wp.config.version,
            "mujoco": mujoco.__version__, "mujoco_warp": dist("mujoco-warp"), "rsl_rl": dist("rsl-rl-lib")}


def _batchable_fields() -> frozenset[str]:
    global _BATCHABLE
    if _BATCHABLE is None:
        import dataclasses

        from mujoco_warp._src import types, warp_util
        _BATCHABLE = frozenset(
            f.name for f in dataclasses.fields(types.Model)
            if warp_util.is_array_spec(f.type) and getattr(f.type, "shape", ())[:1] == ("*",))
    return _BATCHABLE


_BATCHABLE: frozenset[str] | None = None


def contact_capacity(model: mujoco.MjModel, data: mujoco.MjData, max_contacts: int | None,
                     max_constraints: int | None) -> tuple[int, int]:
    """Per-world contact and constraint buffer sizes (``nconmax``, ``njmax``).

    Contacts: 4 per geom that can collide with something and moves (a box resting on a plane
    makes 4; geoms of bodies without dofs never touch each other, in MuJoCo Warp as in MuJoCo, so
    a terrain of static boxes adds none: ``scenes.terrain.boxes``' 195-488 would have made
    humanoid-footsteps-stairs' buffers 876 contacts and 3,525 rows), at least 3x the contacts of
    the initial state and MuJoCo Warp's own default. Constraints:
    each contact takes up to ``2 (condim - 1)`` rows (pyramidal) or ``condim`` (elliptic),
    plus one per limited joint, friction-loss dof and equality row.

    A model with a heightfield skips MuJoCo Warp's defaults: for any heightfield they guess
    ``3.5 nv + 45`` contacts and ``40.7 nv + 53`` rows (192 and 1,536 for the 27-dof humanoid),
    where its heightfield collision writes at most 4 contacts per geom pair, the per-geom bound
    here (humanoid-rough: at most 16 contacts and 85 rows in a world over 2 x 128 worlds x 150
    random-action steps with falls, on the training and the hardest tiles). Several solver
    kernels run over every row of ``njmax`` (``_update_constraint_efc``, the dense ``J^T D J``),
    so the guess cost humanoid-rough half its physics time on Warp's CPU device.
    """
    body_moves = np.zeros(model.nbody, dtype=bool)  # joints or mocap on the body or any ancestor
    for b in range(1, model.nbody):  # MuJoCo orders a parent before its children
        body_moves[b] = model.body_dofnum[b] > 0 or model.body_mocapid[b] >= 0 or body_moves[model.body_parentid[b]]
    moves = body_moves[model.geom_bodyid]
    collidable = int(np.count_nonzero(((model.geom_contype != 0) | (model.geom_conaffinity != 0)) & moves))
    hfield = model.nhfield > 0
    default_con = 0 if hfield else mjw._src.io._default_nconmax(model, data)
    nconmax = max_contacts or max(default_con, 4 * collidable, 3 * data.ncon)
    if max_constraints:
        return int(nconmax), int(max_constraints)
    condim = int(model.geom_condim.max()) if model.ngeom else 3
    rows = condim if model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC else max(1, 2 * (condim - 1))
    other = int(np.count_nonzero(model.jnt_limited)) + int(np.count_nonzero(model.dof_frictionloss)) \
        + 6 * model.neq + model.ntendon
    default_rows = 0 if hfield else mjw._src.io._default_njmax(model, data)
    return int(nconmax), int(max(default_rows, rows * nconmax + other, 2 * data.nefc))


__all__ = ["GpuEngine", "EngineOverflowError", "capture_graph", "capture_torch_graph", "contact_capacity", "stack_versions", "synchronize",
           "warp_device"]
