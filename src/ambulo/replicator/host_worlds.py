"""The batched path's randomization: every world's draws applied on the host, then one copy per field.

A randomizer's ``apply`` writes one world (``SceneContext.world``) through ``write_field``. On a
CUDA engine each of those writes is a few kernel launches and a host-to-device copy, and
``Scatter2D`` reads its world's ``qpos`` back twice a frame (a device sync each), so applying N
worlds one by one costs ~20 N launches and ~5 N syncs a batch. ``HostWorlds`` hands the
randomizers an engine whose fields are host tensors with the device fields' shapes and dtypes,
runs the same ``sample``/``apply`` code world by world on them, and then writes each field it
handed out to the device in one copy (``upload``).

The draws stay the CPU path's, number for number: the host tensors round like the device ones
(float32 ``qpos``), so the draws that depend on applied state (``Scatter2D`` checks collisions
against the robot's randomized joints) see the values the device would hold; the camera offsets
are set by ``TiledCamera.set_local_pose`` itself, run on host copies of its offset tensors.
"""

from __future__ import annotations

import copy

import torch


class HostWorlds:
    """An engine for ``SceneContext.engine`` whose fields live on the host (see the module docstring).

    Model fields (``model_field``) are host copies kept across batches: every randomizer rewrites
    the entries it owns each frame, so the copy and the device agree after each ``upload``. State
    fields (``field``, ``qpos``, ...) start each batch from the engine's initial state, as the
    device's ``reset`` does. A field a randomizer never asks for is never copied.
    """

    def __init__(self, engine, cameras: dict):
        self._engine = engine
        self.model = engine.model
        self.num_worlds = engine.num_worlds
        self.device = torch.device("cpu")
        self.dtype = getattr(engine, "dtype", torch.float32)
        self._model: dict[str, torch.Tensor] = {}
        self._state: dict[str, torch.Tensor] = {}
        self._initial: dict[str, torch.Tensor] = {}
        self._device_cameras = dict(cameras)
        self.cameras = {name: _host_camera(cam, self) for name, cam in cameras.items()}
        """For ``SceneContext.cameras``: host copies of the engine's cameras (``_host_camera``)."""

    def model_field(self, name: str) -> torch.Tensor:
        """Host copy of ``engine.model_field(name)`` (N, ...), written to the device by ``upload``."""
        host = self._model.get(name)
        if host is None:
            host = self._model[name] = self._engine.model_field(name).detach().cpu().clone()
        return host

    def field(self, name: str) -> torch.Tensor:
        """Host copy of state field ``name`` (N, ...), the initial state at each ``begin``."""
        host = self._state.get(name)
        if host is None:
            initial = self._engine.initial_state.get(name)
            if initial is None:
                raise ValueError(f"{name!r} is not a state field the engine resets; on the batched path a "
                                 f"randomizer writes state ({sorted(self._engine.initial_state)}) and model fields")
            self._initial[name] = initial.detach().cpu().clone()
            host = self._state[name] = self._initial[name].clone()
        return host

    def __getattr__(self, name: str) -> torch.Tensor:
        # engine.qpos as on the engines; only for state fields (else AttributeError, as hasattr expects)
        if name.startswith("_") or name not in self._engine.initial_state:
            raise AttributeError(f"HostWorlds has no attribute {name!r}")
        return self.field(name)

    def begin(self) -> None:
        """A new batch: state fields back to the initial state and camera offsets to their
        default, as ``Simulation.reset`` and ``TiledCamera.reset_pose`` leave the device."""
        for name, host in self._state.items():
            host.copy_(self._initial[name])
        for camera in self.cameras.values():
            camera.reset_pose()

    def rows(self, start: int, count: int) -> dict:
        """Worlds ``[start, start + count)`` of every field handed out, as NumPy copies keyed by
        (kind, name): what ``set_rows`` writes into another ``HostWorlds`` (``draw_pool``)."""
        part = slice(start, start + count)
        out: dict = {("model", name): host[part].numpy().copy() for name, host in self._model.items()}
        out |= {("state", name): host[part].numpy().copy() for name, host in self._state.items()}
        for name, camera in self.cameras.items():
            out["camera_pos", name] = camera._offset_pos[part].numpy().copy()
            out["camera_rot_gl", name] = camera._offset_rot_gl[part].numpy().copy()
        return out

    def set_rows(self, start: int, rows: dict) -> None:
        """Write ``rows`` (from ``rows``) into worlds from ``start`` on."""
        for (kind, name), values in rows.items():
            if kind == "model":
                host = self.model_field(name)
            elif kind == "state":
                host = self.field(name)
            else:
                camera = self.cameras[name]
                host = camera._offset_pos if kind == "camera_pos" else camera._offset_rot_gl
            host[start:start + len(values)] = torch.from_numpy(values)

    def upload(self, count: int) -> None:
        """Write worlds ``[0, count)`` of every field handed out to the device: one copy each."""
        engine = self._engine
        for name, host in self._model.items():
            _copy_rows(engine.model_field(name), host, count)
        for name, host in self._state.items():
            _copy_rows(engine.field(name), host, count)
        for name, host_camera in self.cameras.items():
            camera = self._device_cameras[name]
            # TiledCamera's per-world offsets (what set_local_pose writes), then a render is due
            _copy_rows(camera._offset_pos, host_camera._offset_pos, count)
            _copy_rows(camera._offset_rot_gl, host_camera._offset_rot_gl, count)
            camera._outdated = True


def _host_camera(camera, host: HostWorlds):
    """A shallow copy of a ``TiledCamera`` whose pose offsets are host tensors: its own
    ``set_local_pose``/``reset_pose`` run on them (the same arithmetic, the same float32 values)."""
    mirror = copy.copy(camera)
    mirror.engine = host
    mirror._default_offset = tuple(t.detach().cpu().clone() for t in camera._default_offset)
    mirror._offset_pos = camera._offset_pos.detach().cpu().clone()
    mirror._offset_rot_gl = camera._offset_rot_gl.detach().cpu().clone()
    return mirror


def _copy_rows(device: torch.Tensor, host: torch.Tensor, count: int) -> None:
    """``device[:count] = host[:count]``; to a GPU through pinned memory without waiting for it
    (torch's pinned-memory pool keeps the staging block until the copy has run, so the host
    copy may be rewritten for the next batch at once)."""
    rows = host[:count]
    if device.device.type == "cuda":
        device[:count].copy_(rows.pin_memory(), non_blocking=True)
    else:
        device[:count].copy_(rows)


__all__ = ["HostWorlds"]
