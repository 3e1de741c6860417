"""Physics engines: N worlds of one MjModel with state as torch tensors."""

import os

from ..utils.checks import InvalidValueError
from .cpu import CpuEngine
from .protocol import STATE_FIELDS, Engine, sim_time_s

ENGINES = ("auto", "mujoco", "warp")
"""``auto``: MuJoCo's batch on the CPU, MuJoCo Warp on CUDA; ``mujoco``: the CPU engine;
``warp``: MuJoCo Warp on any device (on ``cpu`` it runs on Warp's CPU device: slower than
``mujoco``, used to test GPU code paths and CPU/GPU parity without a GPU)."""


def engine_class(device: str, engine: str = "auto") -> type:
    """The engine class for ``device`` (``"cpu"`` or ``"cuda[:N]"``) and ``engine`` (one of
    ``ENGINES``), or a one-line error saying why there is none: callers check a device before
    they write anything."""
    device = str(device)
    if engine == "auto":  # AMBULO_ENGINE=warp runs any program or test suite on MuJoCo Warp
        engine = os.environ.get("AMBULO_ENGINE", "auto")
    if engine not in ENGINES:
        raise InvalidValueError("engine", engine, "unknown engine", f"use one of {', '.join(ENGINES)}")
    if device != "cpu" and not device.startswith("cuda"):
        raise InvalidValueError("device", device, "unknown device", "use 'cpu' or 'cuda[:N]'")
    if engine == "mujoco" and device != "cpu":
        raise InvalidValueError("engine", engine, f"MuJoCo's batch engine runs on the CPU, not {device}",
                                "use engine='warp' (or 'auto') on CUDA")
    if engine == "warp" or device.startswith("cuda"):
        try:
            from .gpu import GpuEngine  # optional dependency
        except ImportError as err:
            raise InvalidValueError("device", device, f"needs the GPU engine's packages ({err})",
                                    "pip install 'ambulo[gpu]', or use device='cpu'") from None
        if device.startswith("cuda"):
            import torch

            if not torch.cuda.is_available():
                raise InvalidValueError("device", device, "torch sees no CUDA device (a CPU-only torch "
                                        "build, or no GPU)", "use device='cpu'")
        return GpuEngine
    return CpuEngine


def make_engine(model, num_worlds: int = 1, device: str = "cpu", engine: str = "auto", **kwargs) -> Engine:
    """The engine for ``device`` and ``engine``: MuJoCo's batch (CPU) or MuJoCo Warp."""
    cls = engine_class(device, engine)
    if cls is CpuEngine:
        kwargs.pop("max_contacts_per_world", None)
        kwargs.pop("max_constraints_per_world", None)
        kwargs.pop("broadphase", None)
        kwargs.pop("compile_workers", None)
        kwargs.pop("compile_processes", None)
        return CpuEngine(model, num_worlds, **kwargs)
    return cls(model, num_worlds, device=device, **kwargs)


__all__ = ["Engine", "CpuEngine", "ENGINES", "engine_class", "make_engine", "sim_time_s", "STATE_FIELDS"]
