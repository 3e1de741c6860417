"""``cuda_on_cpu``: a script's CUDA tensors and models on the CPU, for hosts without a GPU.

Isaac Gym scripts hard-code ``device="cuda:0"``, ``torch.zeros(..., device=self.device)`` and
``policy.cuda()``; on a CPU-only host each of those lines fails although nothing in them needs a
GPU. Inside ``cuda_on_cpu()`` a torch function mode rewrites every CUDA device a torch call asks
for (``device=`` arguments, ``Tensor.cuda``, ``Tensor.to``) to the CPU, so the script runs as
written; the tensors it makes report ``device(type='cpu')``.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator

import torch
from torch.overrides import TorchFunctionMode

_CPU = torch.device("cpu")


def _is_cuda(device) -> bool:
    if isinstance(device, torch.device):
        return device.type == "cuda"
    if isinstance(device, str):
        return device.startswith("cuda")
    return isinstance(device, int) and not isinstance(device, bool)  # torch takes an int as a CUDA index


class CudaOnCpu(TorchFunctionMode):
    """Torch function mode mapping requested CUDA devices to the CPU (see the module docstring)."""

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = dict(kwargs or {})
        if func is torch.Tensor.cuda:
            return args[0]
        if _is_cuda(kwargs.get("device")):
            kwargs["device"] = _CPU
        if func is torch.Tensor.to and len(args) > 1 and _is_cuda(args[1]):
            args = (args[0], _CPU, *args[2:])
        return func(*args, **kwargs)


@contextlib.contextmanager
def cuda_on_cpu() -> Iterator[None]:
    """Inside the block, torch calls that ask for a CUDA device get the CPU. ``torch.compile``d
    functions (rl_games compiles its models) run eagerly there: dynamo cannot trace through a
    Python torch function mode."""
    with _eager_compile(), CudaOnCpu():
        yield


@contextlib.contextmanager
def _eager_compile() -> Iterator[None]:
    """``torch.compile`` as a no-op inside the block. Importing dynamo costs seconds, so when a
    script has not imported it yet, its own switch (``TORCH_COMPILE_DISABLE``, read at import) is
    set instead, and dynamo's ``config.disable`` put back after the block if the script imported it."""
    if "torch._dynamo" in sys.modules:
        with torch.compiler.set_stance("force_eager"):
            yield
        return
    previous = os.environ.get(_DISABLE)
    os.environ[_DISABLE] = "1"
    try:
        yield
    finally:
        if previous is None:
            del os.environ[_DISABLE]
        else:
            os.environ[_DISABLE] = previous
        if "torch._dynamo" in sys.modules:
            sys.modules["torch._dynamo"].config.disable = previous == "1"


_DISABLE = "TORCH_COMPILE_DISABLE"


__all__ = ["CudaOnCpu", "cuda_on_cpu"]
