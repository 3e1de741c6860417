"""OverlappedSteps: each env step collected while the updates of the steps before it run
(``OffPolicyCfg.overlap_collect``).

In the sequential order an env step (the worlds' physics and the actor) and its
``updates_per_step`` gradient updates queue one after the other on one CUDA stream; at humanoid
scale neither fills a GPU (1024 worlds; batches of 8,192 through 768-wide layers), so each waits
for the other. Here, at every env step: the ring publishes the steps added so far
(``ReplayRing.publish``, the slot about to be written left out), the updates of that data are
queued on a side stream, the step is collected on the current stream with a copy of the actor,
then the current stream waits for the updates, the learner's observation normalizers take the
step's observations, and the copy is refreshed. So the worlds act with the actor of one update
round before (FastTD3/FastSAC's collect-then-update acts with the freshest), the updates draw
from their own generator, and nothing one stream writes is read by the other while it runs. On
the CPU the same order runs one step after another.
"""

from __future__ import annotations

import contextlib
import copy
import time
from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:
    from .runner import OffPolicyRunner


class OverlappedSteps:
    """See the module docstring. ``seed`` seeds the updates' sampling generator."""

    def __init__(self, runner: OffPolicyRunner, seed: int):
        self.runner = runner
        self.acting = copy.deepcopy(runner.alg.actor).requires_grad_(False)
        """The actor the worlds act with: the learner's as of the last step's end."""
        self.generator = torch.Generator(device=runner.device)
        self.generator.manual_seed(seed + 1)
        """Replay sampling (the runner's generator draws the exploration noise)."""
        self.stream = torch.cuda.Stream(runner.device) if runner.device.type == "cuda" else None
        runner.ring.write_ahead = True
        self._learner = [*runner.alg.actor.parameters(), *runner.alg.actor.buffers()]
        self._copy = [*self.acting.parameters(), *self.acting.buffers()]

    @contextlib.contextmanager
    def _updates_stream(self):
        """The side stream, after everything queued so far on the current one (CUDA only)."""
        if self.stream is None:
            yield
            return
        self.stream.wait_stream(torch.cuda.current_stream(self.runner.device))
        with torch.cuda.stream(self.stream):
            yield

    def step(self) -> tuple[float, float]:
        """One env step of every world, beside the updates of the steps already in the ring;
        returns the host seconds spent (collecting, queueing the updates and joining)."""
        runner, cfg = self.runner, self.runner.cfg
        began = time.perf_counter()
        if runner.env_steps >= cfg.learning_starts:
            runner.ring.publish()
            with self._updates_stream():
                for _ in range(cfg.updates_per_step):
                    runner.alg.update_from(runner.ring, self.generator)
        queued = time.perf_counter()
        obs, critic_obs = runner._obs, runner._critic_obs
        runner._collect(acting=self.acting)
        collected = time.perf_counter()
        if self.stream is not None:
            torch.cuda.current_stream(runner.device).wait_stream(self.stream)
        runner.update_normalizers(obs, critic_obs)  # after the updates that read them
        self.refresh()
        return collected - queued, (queued - began) + (time.perf_counter() - collected)

    def refresh(self) -> None:
        """The acting copy := the learner's actor (weights and normalizer), on the current stream."""
        with torch.no_grad():
            torch._foreach_copy_(self._copy, self._learner)


__all__ = ["OverlappedSteps"]
