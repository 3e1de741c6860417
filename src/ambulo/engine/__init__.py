"""Physics engines: N worlds of one MjModel with state as torch tensors."""

from ..utils.checks import InvalidValueError
from .cpu import CpuEngine
from .protocol import STATE_FIELDS, Engine


def engine_class(device: str) -> type:
    """The engine class for ``device`` (``"cpu"`` or ``"cuda[:N]"``), or a one-line error saying
    why there is none: callers check a device before they write anything."""
    if str(device).startswith("cuda"):
        try:
            from .gpu import GpuEngine  # noqa: PLC0415 - optional dependency
        except ImportError as err:
            if getattr(err, "name", None) == f"{__name__}.gpu":  # ambulo itself has none yet
                raise InvalidValueError("device", device, "this ambulo has no GPU engine yet",
                                        "use device='cpu'") from None
            raise InvalidValueError("device", device, f"needs the GPU engine's packages ({err})",
                                    "pip install 'ambulo[gpu]', or use device='cpu'") from None
        return GpuEngine
    if str(device) != "cpu":
        raise InvalidValueError("device", device, "unknown device", "use 'cpu' or 'cuda[:N]'")
    return CpuEngine


def make_engine(model, num_worlds: int = 1, device: str = "cpu", **kwargs) -> Engine:
    """The engine for ``device``: ``"cpu"`` (mujoco.batch) or ``"cuda"`` (MuJoCo Warp)."""
    cls = engine_class(device)
    if cls is CpuEngine:
        return CpuEngine(model, num_worlds, **kwargs)
    return cls(model, num_worlds, device=device, **kwargs)


__all__ = ["Engine", "CpuEngine", "engine_class", "make_engine", "STATE_FIELDS"]
