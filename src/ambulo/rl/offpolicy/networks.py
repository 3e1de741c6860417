"""The networks of the off-policy learners: observation normalizer, actor, twin categorical critic.

``Actor.forward`` is the deterministic policy (normalizer, MLP, ``action_bound * tanh`` of the
mean): what evaluation, ``play`` and ``export`` run, and what TorchScript and ONNX take in one
piece. Sampling for exploration and for the SAC losses are other methods.
"""

from __future__ import annotations

import math

import torch
from torch import nn


class RunningNorm(nn.Module):
    """Running mean and variance of observations (all worlds' steps), applied as
    ``(x - mean) / sqrt(var + eps)``. ``update`` merges a batch's moments (Chan et al.) on the
    device: no host sync."""

    def __init__(self, dim: int, enabled: bool = True, eps: float = 1.0e-4):
        super().__init__()
        self.enabled, self.eps = enabled, eps
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("var", torch.ones(dim))
        self.register_buffer("count", torch.zeros(()))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        if not self.enabled:
            return
        n = float(x.shape[0])
        batch_mean = x.mean(dim=0)
        batch_var = x.var(dim=0, unbiased=False)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * (n / total)
        self.var.copy_((self.var * self.count + batch_var * n + delta.square() * (self.count * n / total)) / total)
        self.count.copy_(total)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.enabled:
            return x
        return (x - self.mean) / torch.sqrt(self.var + self.eps)


def mlp(inputs: int, hidden: tuple[int, ...], outputs: int, layer_norm: bool = False) -> nn.Sequential:
    """Linear layers with SiLU (and LayerNorm after each hidden Linear when asked)."""
    layers: list[nn.Module] = []
    width = inputs
    for h in hidden:
        layers.append(nn.Linear(width, h))
        if layer_norm:
            layers.append(nn.LayerNorm(h))
        layers.append(nn.SiLU())
        width = h
    layers.append(nn.Linear(width, outputs))
    return nn.Sequential(*layers)


class Actor(nn.Module):
    """A tanh-squashed policy. ``stochastic`` (fast-sac): the MLP also gives a log std per action
    (squashed into ``log_std_range``); otherwise (fast-td3) only the mean."""

    def __init__(self, num_obs: int, num_actions: int, hidden: tuple[int, ...], *, stochastic: bool,
                 action_bound: float | torch.Tensor = 1.0, log_std_range: tuple[float, float] = (-5.0, 0.0),
                 obs_normalization: bool = True):
        super().__init__()
        self.num_obs, self.num_actions, self.stochastic = num_obs, num_actions, stochastic
        # (A,) bound of each action: one number for all, or each joint's own (joint-limit bounds); not
        # in the state dict (a checkpoint's actor is rebuilt with the bounds its run's settings give)
        bound = torch.as_tensor(action_bound, dtype=torch.float32).expand(num_actions).clone()
        if not bool(torch.isfinite(bound).all() and (bound > 0).all()):
            raise ValueError(f"Actor action bounds must be finite and > 0; got {bound.tolist()}")
        self.register_buffer("action_bound", bound, persistent=False)
        self.log_std_min, self.log_std_max = float(log_std_range[0]), float(log_std_range[1])
        self.normalizer = RunningNorm(num_obs, enabled=obs_normalization)
        self.net = mlp(num_obs, hidden, 2 * num_actions if stochastic else num_actions)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Deterministic actions (B, num_actions) from raw observations (B, num_obs)."""
        out = self.net(self.normalizer(obs))
        return self.action_bound * torch.tanh(out[:, :self.num_actions])

    def distribution(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, log std) before the tanh, each (B, num_actions) (stochastic actors)."""
        out = self.net(self.normalizer(obs))
        mean, raw = out[:, :self.num_actions], out[:, self.num_actions:]
        log_std = self.log_std_min + 0.5 * (self.log_std_max - self.log_std_min) * (torch.tanh(raw) + 1.0)
        return mean, log_std

    def sample(self, obs: torch.Tensor, noise: torch.Tensor | None = None
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Reparameterized actions (B, A), their log-probabilities (B,) under the squashed
        Gaussian, and the std (B, A). ``noise``: (B, A) standard normal draws to use (held
        exploration noise); None draws fresh ones."""
        mean, log_std = self.distribution(obs)
        mean, log_std = mean.float(), log_std.float()  # log-probabilities in float32 under autocast
        std = log_std.exp()
        pre = mean + std * (torch.randn_like(mean) if noise is None else noise)
        squashed = torch.tanh(pre)
        # log N(pre; mean, std) - log|d tanh/d pre|, the latter written stably
        log_prob = (-0.5 * ((pre - mean) / std).square() - log_std - 0.5 * math.log(2 * math.pi)).sum(dim=1)
        log_prob = log_prob - (2.0 * (math.log(2.0) - pre - nn.functional.softplus(-2.0 * pre))).sum(dim=1)
        return self.action_bound * squashed, log_prob, std

    @torch.jit.unused
    def get_dummy_inputs(self) -> tuple[torch.Tensor]:
        """A batch of one observation: the example input of ``torch.onnx.export``."""
        return (torch.zeros(1, self.num_obs, device=self.normalizer.mean.device),)


class TwinCategoricalCritic(nn.Module):
    """Two critics, each mapping (critic observation, action) to logits over ``num_atoms``
    returns; inputs normalized by one running normalizer of the critic observations."""

    def __init__(self, num_obs: int, num_actions: int, hidden: tuple[int, ...], num_atoms: int, *,
                 layer_norm: bool = True, obs_normalization: bool = True):
        super().__init__()
        self.normalizer = RunningNorm(num_obs, enabled=obs_normalization)
        self.q1 = mlp(num_obs + num_actions, hidden, num_atoms, layer_norm)
        self.q2 = mlp(num_obs + num_actions, hidden, num_atoms, layer_norm)

    def forward(self, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Logits (2, B, num_atoms)."""
        x = torch.cat([self.normalizer(obs), actions], dim=1)
        return torch.stack([self.q1(x), self.q2(x)])


__all__ = ["Actor", "RunningNorm", "TwinCategoricalCritic", "mlp"]
