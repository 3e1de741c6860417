"""CpuEngine: N worlds of one MjModel on ``mujoco.batch.Batch``'s thread pool.

State tensors are zero-copy ``torch`` views of the batch's state rows, so writing
``engine.qpos[...]`` writes the simulation state itself; derived fields are views of
the batch's output buffers, refreshed in place by every call. Results are
bit-identical to a loop over one ``MjData`` per world at any thread count
(a property of ``mujoco.batch``), which is what makes seeded runs reproducible.
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np
import torch
from mujoco import batch as mj_batch

from .protocol import KINEMATIC_FIELDS, STATE_FIELDS

log = logging.getLogger(__name__)

# MuJoCo resets a world to qpos0 and bumps these counters when its state turns
# NaN/Inf or huge (mj_checkPos/Vel/Acc); we treat that as divergence. The three
# warnings are adjacent in mjtWarning, so one slice reads them.
_DIVERGENCE = slice(int(mujoco.mjtWarning.mjWARN_BADQPOS), int(mujoco.mjtWarning.mjWARN_BADQACC) + 1)
assert _DIVERGENCE.stop - _DIVERGENCE.start == 3 and int(mujoco.mjtWarning.mjWARN_BADQVEL) == _DIVERGENCE.start + 1

WorldIds = Sequence[int] | np.ndarray | torch.Tensor | None


def _as_ids(world_ids: WorldIds, num_worlds: int) -> np.ndarray | None:
    """Sorted unique int32 world ids for the batch, or None for all worlds."""
    if world_ids is None:
        return None
    if isinstance(world_ids, torch.Tensor):
        world_ids = world_ids.detach().cpu().numpy()
    ids = np.asarray(world_ids)
    if ids.dtype == bool:
        ids = np.flatnonzero(ids)
    ids = np.unique(ids.astype(np.int64).ravel())
    if ids.size and (ids[0] < 0 or ids[-1] >= num_worlds):
        raise IndexError(
            f"world id {ids[0] if ids[0] < 0 else ids[-1]} is out of range for "
            f"{num_worlds} worlds; pass ids in [0, {num_worlds})"
        )
    return ids.astype(np.int32)


def _readonly_tensor(array: np.ndarray) -> torch.Tensor:
    # The batch marks outputs read-only because it overwrites them every call;
    # torch cannot express read-only, so we share the memory and say so in docs.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return torch.from_numpy(array)


class CpuEngine:
    """N worlds of ``model`` stepped by ``mujoco.batch.Batch`` on ``num_threads`` threads.

    Args:
      model: the compiled model; the engine keeps its own copy.
      num_worlds: N.
      num_threads: batch threads; 0 uses every CPU.
      keyframe: keyframe index or name for the initial state, or None for qpos0.
      divergence_dump_dir: if set, every divergence writes the diverged worlds' state before
        the failing step (and the model, once) there to reproduce it; see ``dump_divergence``.
    """

    device = torch.device("cpu")
    dtype = torch.float64

    def __init__(
        self,
        model: mujoco.MjModel,
        num_worlds: int = 1,
        num_threads: int = 0,
        keyframe: int | str | None = None,
        divergence_dump_dir: str | os.PathLike | None = None,
    ):
        if num_worlds < 1:
            raise ValueError(f"num_worlds must be >= 1, got {num_worlds}")
        self.num_worlds = int(num_worlds)
        # Not persistent: one MjData per thread serves all worlds. Measured on the
        # 21-DoF humanoid at N=64, a persistent batch (one MjData per world) stepped
        # at half the rate, so derived fields are refreshed on request instead.
        self._batch = mj_batch.Batch(model, self.num_worlds, num_threads, persistent=False)
        self._scratch_model: mujoco.MjModel | None = None
        self.model = self._batch.model
        self._tensors: dict[str, torch.Tensor] = {}
        self._model_tensors: dict[str, torch.Tensor] = {}
        key = -1
        if keyframe is not None:
            key = keyframe if isinstance(keyframe, int) else self.model.key(keyframe).id
        self._batch.reset(keyframe=key)
        self.initial_state = self._batch.state.copy()
        """(N, nstate) float64: the state ``reset`` restores; edit rows to change it."""
        self._warn_counts = self._divergence_counts()
        self._warn_total = self._warn_counts.sum()
        self.num_diverged = 0
        """Total number of world divergences detected (and reset) so far."""
        self.divergence_dump_dir = None if divergence_dump_dir is None else Path(divergence_dump_dir)
        self._state_before_step: np.ndarray | None = None
        self.acc_stale: torch.Tensor | None = None
        """None until a ``forward(kinematics_only=True)``, then (N,) bool: worlds whose fields
        outside ``KINEMATIC_FIELDS`` (sensordata, contacts, forces, qacc) predate their state."""

    # -- fields ---------------------------------------------------------------
    def field(self, name: str) -> torch.Tensor:
        tensor = self._tensors.get(name)
        if tensor is not None:
            return tensor
        if name in STATE_FIELDS:
            tensor = torch.from_numpy(self._batch.bind(name))
        else:
            try:
                array = self._batch.bind(name)
            except ValueError as err:
                raise ValueError(f"engine field {name!r}: {err}") from None
            tensor = _readonly_tensor(array)
            # a newly bound output is zero until the next call: fill it now
            self._batch.forward(stage=mujoco.mjtStage.mjSTAGE_ACC.value)
            if self.acc_stale is not None:
                self.acc_stale.zero_()
        self._tensors[name] = tensor
        return tensor

    def model_field(self, name: str) -> torch.Tensor:
        tensor = self._model_tensors.get(name)
        if tensor is None:
            try:
                tensor = torch.from_numpy(self._batch.expand(name))
            except ValueError as err:
                raise ValueError(f"model field {name!r}: {err}") from None
            self._model_tensors[name] = tensor
        return tensor

    def set_const(self, world_ids: WorldIds = None) -> None:
        """Recompute derived model constants (after writing body masses/inertias)."""
        self._batch.set_const(_as_ids(world_ids, self.num_worlds))

    def __getattr__(self, name: str) -> torch.Tensor:
        # engine.qpos, engine.xpos, ... as on MjData; only for field names
        if name.startswith("_") or name not in mj_batch.DATA_FIELDS:
            raise AttributeError(f"CpuEngine has no attribute {name!r}")
        return self.field(name)

    # -- stepping -------------------------------------------------------------
    def step(self, num_substeps: int = 1, refresh: bool = False) -> torch.Tensor:
        """Advance ``num_substeps`` physics steps. Derived fields then describe the state
        before the last substep, as after ``mj_step``; ``refresh=True`` recomputes poses
        and velocities at the new state (one extra kinematics pass per world)."""
        failed = np.zeros(0, np.int64)
        stage = mujoco.mjtStage.mjSTAGE_VEL if refresh else mujoco.mjtStage.mjSTAGE_NONE
        if self.divergence_dump_dir is not None:
            # MuJoCo resets a diverging world in place, so the state to dump is the one before
            self._state_before_step = self._batch.state.copy()
            self._ctrl_before_step = self.field("ctrl").numpy().copy()
        try:
            self._batch.step(nstep=num_substeps, stage=stage.value)
        except mj_batch.SimulationError as err:
            failed = np.asarray(err.ids)
        if self.acc_stale is not None:
            self.acc_stale.zero_()  # a step computes every field of every world
        counts = self._divergence_counts()
        if not failed.size and counts.sum() == self._warn_total:
            # the common case: no world's counters moved, nothing to compare per world
            return torch.zeros(self.num_worlds, dtype=torch.bool)
        diverged = (counts > self._warn_counts).any(axis=1)
        diverged[failed] = True
        if diverged.any():
            ids = np.flatnonzero(diverged)
            self.num_diverged += len(ids)
            if self.divergence_dump_dir is not None:
                self.dump_divergence(ids)
            log.warning(
                "%d of %d worlds diverged (NaN or unstable state), first: world %d; "
                "they were reset to their initial state. Lower the timestep, check "
                "actions for NaN/huge values, or raise solver iterations.",
                len(ids), self.num_worlds, ids[0],
            )
            self.reset(ids)
            counts = self._divergence_counts()
        self._warn_counts, self._warn_total = counts, counts.sum()
        return torch.from_numpy(diverged)

    def forward(self, world_ids: WorldIds = None, kinematics_only: bool = False) -> None:
        """Recompute derived fields of ``world_ids`` (None: all) from their state.

        ``kinematics_only`` updates ``KINEMATIC_FIELDS`` alone (poses, com, com velocities) and
        marks the worlds in ``acc_stale``; every other bound field keeps its value there. The
        batch has no kinematics-only stage: it runs up to ``mjSTAGE_VEL`` (``mj_step1``'s stages:
        collisions too, but no actuation or constraint solve), and since an MjData serves many
        worlds, the fields it does not compute would come back holding another world's values,
        so they are put back."""
        ids = _as_ids(world_ids, self.num_worlds)
        if ids is not None and not ids.size:
            return
        rows = slice(None) if ids is None else ids
        if not kinematics_only:
            self._batch.forward(ids)
            if self.acc_stale is not None:
                self.acc_stale[rows] = False
            return
        kept = {name: tensor[rows].clone() for name, tensor in self._tensors.items()
                if name not in STATE_FIELDS and name not in KINEMATIC_FIELDS}
        self._batch.forward(ids, stage=mujoco.mjtStage.mjSTAGE_VEL.value)
        for name, old in kept.items():
            self._tensors[name][rows] = old
        if self.acc_stale is None:
            self.acc_stale = torch.zeros(self.num_worlds, dtype=torch.bool)
        self.acc_stale[rows] = True

    def reset(self, world_ids: WorldIds = None, forward: bool = True) -> None:
        ids = _as_ids(world_ids, self.num_worlds)
        if ids is None:
            self._batch.state[:] = self.initial_state
        elif ids.size:
            self._batch.state[ids] = self.initial_state[ids]
        else:
            return
        if forward:
            self.forward(ids)

    def dump_divergence(self, world_ids: np.ndarray) -> Path:
        """Write the diverged worlds' full physics state before the failing step.

        ``<dir>/diverged_<count>.npz`` holds ``world_ids``, ``state`` (rows of
        ``Batch.state`` in ``mujoco.batch``'s layout), ``ctrl`` and ``timestep``; ``<dir>/model.mjb`` the
        model. Reproduce with ``mujoco.mj_setState`` on an ``MjData`` of that model and ``mj_step``.
        """
        out = self.divergence_dump_dir
        out.mkdir(parents=True, exist_ok=True)
        if not (out / "model.mjb").is_file():
            mujoco.mj_saveModel(self.model, str(out / "model.mjb"), None)
        path = out / f"diverged_{self.num_diverged:06d}.npz"
        np.savez(path, world_ids=world_ids, state=self._state_before_step[world_ids],
                 ctrl=self._ctrl_before_step[world_ids], timestep=self.model.opt.timestep)
        log.warning("diverged worlds %s dumped to %s", world_ids.tolist()[:8], path)
        return path

    def capture_initial_state(self, world_ids: WorldIds = None) -> None:
        """Make the worlds' current state the one ``reset`` restores."""
        ids = _as_ids(world_ids, self.num_worlds)
        rows = slice(None) if ids is None else ids
        self.initial_state[rows] = self._batch.state[rows]

    def _divergence_counts(self) -> np.ndarray:
        return self._batch.warning[:, _DIVERGENCE, 1].copy()

    # -- single-world access ----------------------------------------------------
    def get_data(self, world: int, data: mujoco.MjData | None = None) -> mujoco.MjData:
        """World ``world``'s state in an ``MjData`` with every derived field computed
        (``mj_forward`` on that world's model), ready for a renderer."""
        data = self._batch.get_data(int(world), data)
        mujoco.mj_forward(self._model_of(int(world)), data)
        return data

    def get_model(self, world: int, model: mujoco.MjModel | None = None) -> mujoco.MjModel:
        return self._batch.get_model(int(world), model)

    def _model_of(self, world: int) -> mujoco.MjModel:
        """The shared model, or a scratch copy holding world's per-world fields."""
        if not self._model_tensors:
            return self.model
        if self._scratch_model is None:
            self._scratch_model = self._batch.get_model(world)
        return self._batch.get_model(world, self._scratch_model)

    def ray(self, pnt, vec, **kwargs) -> tuple[torch.Tensor, torch.Tensor]:
        """Batched ``mj_ray``: ``pnt``, ``vec`` (N, R, 3) world frame (tensors or arrays) ->
        distances (N, R) float64 m and geom ids (N, R) int32, -1 for a miss. Keyword
        arguments as ``mujoco.batch.Batch.ray`` (``bodyexclude``, ``geomgroup``, ...)."""
        pnt = pnt.detach().cpu().numpy() if isinstance(pnt, torch.Tensor) else np.asarray(pnt)
        vec = vec.detach().cpu().numpy() if isinstance(vec, torch.Tensor) else np.asarray(vec)
        dist, geom = self._batch.ray(np.ascontiguousarray(pnt), np.ascontiguousarray(vec), **kwargs)
        return torch.from_numpy(dist), torch.from_numpy(geom)

    @property
    def batch(self) -> mj_batch.Batch:
        """The underlying ``mujoco.batch.Batch`` (escape hatch for CPU-only code)."""
        return self._batch
