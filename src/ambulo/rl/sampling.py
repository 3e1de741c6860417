"""SyncFreeGaussian: rsl-rl-lib's Gaussian action head, sampled without waiting for the GPU.

rsl-rl's ``GaussianDistribution.sample`` calls ``torch.distributions.Normal.sample``, that is
``torch.normal(mean, std)`` with a tensor ``std``. ATen checks that such a ``std`` is
non-negative by reading ``std.min() >= 0`` back to the host: one device-to-host copy and one
host sync per policy step, in every rollout step of training (``benchmarks/profile_gpu.py``
flagged it in ``torch/distributions/normal.py``). The std here is clamped to ``std_range``
(positive) before it is used, so the check can never fail; this head draws
``mean + std * randn`` instead, which is what ``torch.normal`` computes after its check
(ATen fills N(0, 1), then multiplies by ``std`` and adds ``mean``): the same values from the
same generator state, bit for bit on the CPU, with no sync.

Everything else (log-probabilities, entropy, KL, the learnable ``std_param``, checkpoints and
exported policies) is rsl-rl's: the state dict keys are the same, so runs trained with the
stock head load and resume with this one.
"""

from __future__ import annotations

import torch
from rsl_rl.modules.distribution import GaussianDistribution


class SyncFreeGaussian(GaussianDistribution):
    """``GaussianDistribution`` whose ``sample`` is ``mean + std * randn`` (no host sync)."""

    def sample(self) -> torch.Tensor:
        mean, std = self.mean, self.std  # (N, A); std broadcast from (A,) by Normal
        with torch.no_grad():
            return torch.randn_like(mean).mul_(std).add_(mean)


__all__ = ["SyncFreeGaussian"]
