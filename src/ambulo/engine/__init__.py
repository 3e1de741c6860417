"""Physics engines: N worlds of one MjModel with state as torch tensors."""

from .cpu import CpuEngine
from .protocol import STATE_FIELDS, Engine


def make_engine(model, num_worlds: int = 1, device: str = "cpu", **kwargs) -> Engine:
    """The engine for ``device``: ``"cpu"`` (mujoco.batch) or ``"cuda"`` (MuJoCo Warp)."""
    if str(device).startswith("cuda"):
        try:
            from .gpu import GpuEngine  # noqa: PLC0415 - optional dependency
        except ImportError as err:
            raise RuntimeError(
                f"device={device!r} needs the GPU engine (mujoco-warp): "
                f"pip install 'ambulo[gpu]' ({err})"
            ) from None
        return GpuEngine(model, num_worlds, device=device, **kwargs)
    if str(device) != "cpu":
        raise ValueError(f"unknown device {device!r}; use 'cpu' or 'cuda[:N]'")
    return CpuEngine(model, num_worlds, **kwargs)


__all__ = ["Engine", "CpuEngine", "make_engine", "STATE_FIELDS"]
