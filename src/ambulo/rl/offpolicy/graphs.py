"""UpdateGraphs: gradient updates replayed as CUDA graphs (``OffPolicyCfg.cuda_graph``).

An update of FastSAC at batch 32k is a few hundred small kernels (sample, critic forward and
backward, fused AdamW, actor and alpha, Polyak): launched one by one from Python it takes ~9 ms
on an H200 where its FLOPs need ~2. Captured once and replayed, it is one launch.

What is captured is a call of ``fn`` per *kind* of update (the learner's kinds: critic only,
critic + actor/alpha): each kind runs ``warmup`` eager calls (real updates) on a side stream
first, so everything made lazily on a first call (optimizer states, cuBLAS handles and
workspaces for that stream) exists before its capture, which could not make it. The capture
runs nothing, so the call that captures then replays once: every call is one update.

Rules the captured code keeps (torch's "CUDA Graphs" notes, whole-network capture): no host
sync and no Python decision on device values (the replay reruns no Python); persistent tensors
(parameters, optimizer states, the statistics, the replay ring, its device ``ptr``/``size``)
change in place, so the graph reads their current values; random draws come from generators
registered with the graph (the default CUDA generator always is; the runner's sampling
generator through ``register_generator_state``), whose states then advance on every replay as
the eager calls would; optimizers are ``capturable``; autocast runs with ``cache_enabled=False``.
Anything that replaces those tensors (``load_state_dict`` of an optimizer, a new ring) must
``reset`` the graphs, which capture again after their warm-up.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable, Hashable

import torch


class UpdateGraphs:
    """CUDA graphs of update calls, one per kind (see the module docstring). ``generators``:
    custom CUDA generators the calls draw from."""

    def __init__(self, device: torch.device, warmup: int = 3, generators: tuple[torch.Generator, ...] = ()):
        if device.type != "cuda":
            raise ValueError(f"CUDA graphs need a CUDA device, not {device}")
        if generators and not hasattr(torch.cuda.CUDAGraph, "register_generator_state"):
            raise RuntimeError(f"OffPolicyCfg.cuda_graph: torch {torch.__version__} cannot advance the sampling "
                               "generator inside a CUDA graph (CUDAGraph.register_generator_state, torch >= 2.5); "
                               "set cuda_graph=false (`--algo-cfg cuda_graph=false`)")
        self.device, self.warmup, self.generators = device, warmup, tuple(generators)
        self.stream = torch.cuda.Stream(device)
        """The side stream of the warm-up calls and the captures."""
        self.graphs: dict[Hashable, torch.cuda.CUDAGraph] = {}
        self.eager_calls: dict[Hashable, int] = {}
        """Warm-up calls run per kind since the last ``reset``."""
        self.captures = 0
        self.replays = 0

    def reset(self) -> None:
        """Forget the graphs (they hold the addresses of replaced tensors); the next calls warm
        up and capture again."""
        self.graphs.clear()
        self.eager_calls.clear()

    def __call__(self, kind: Hashable, fn: Callable[[], None]) -> None:
        """One ``fn()`` of ``kind``: an eager warm-up call, or a replay of its graph (captured first
        if this is the kind's first call after its warm-up)."""
        graph = self.graphs.get(kind)
        if graph is None:
            done = self.eager_calls.get(kind, 0)
            if done < self.warmup:
                self.eager_calls[kind] = done + 1
                with self._side_stream(), warnings.catch_warnings():
                    # capturable optimizers warn once when stepped outside a capture: here on purpose
                    warnings.filterwarnings("ignore", message=".*capturable=True.*")
                    fn()
                return
            graph = self.graphs[kind] = self._capture(fn)
        graph.replay()
        self.replays += 1

    @contextlib.contextmanager
    def _side_stream(self):
        """Run on ``self.stream``, ordered after and before the current stream's work."""
        current = torch.cuda.current_stream(self.device)
        self.stream.wait_stream(current)
        with torch.cuda.stream(self.stream):
            yield
        current.wait_stream(self.stream)

    def _capture(self, fn: Callable[[], None]) -> torch.cuda.CUDAGraph:
        graph = torch.cuda.CUDAGraph()
        for generator in self.generators:
            graph.register_generator_state(generator)
        current = torch.cuda.current_stream(self.device)
        self.stream.wait_stream(current)
        try:
            # thread_local: other threads (an evaluation, a viewer) may allocate meanwhile
            with torch.cuda.graph(graph, stream=self.stream, capture_error_mode="thread_local"):
                fn()
        except Exception as error:  # one clear error, never a silent fall back to eager updates
            raise RuntimeError(f"OffPolicyCfg.cuda_graph: capturing the update failed ({type(error).__name__}: "
                               f"{error}); train with cuda_graph=false (eager updates: "
                               "`--algo-cfg cuda_graph=false`) instead") from error
        current.wait_stream(self.stream)
        self.captures += 1
        return graph


__all__ = ["UpdateGraphs"]
