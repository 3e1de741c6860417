"""ReplayRing: the last ``capacity`` steps of every world, kept as tensors on the env's device.

One slot holds one env step of all ``num_envs`` worlds (a (capacity, num_envs, ...) tensor per
field), so adding a step is one indexed copy per field and no Python loop over worlds. Sampling
draws ``(slot, world)`` pairs from uniform floats and gathers n-step returns with tensor
arithmetic: nothing on the path reads a device value back to the host. The write position and
fill are host counters (``add`` indexes with them) mirrored in 0-dim device tensors that
``sample`` and ``transitions`` read, so one captured CUDA graph of a sample stays right as the
ring fills and wraps (``OffPolicyCfg.cuda_graph``); the eager path uses the same formulas, so
both draw the same batch from one generator state.

n-step returns (the FastTD3 recipe): for a sample at slot ``t`` of world ``e`` the return sums
``gamma**j * r[t+j]`` for ``j = 0 .. k``, where ``k`` is the first of: an episode end at ``t+k``
(termination or time-out), ``n_step - 1``, or the newest slot written. The bootstrap uses the
observation after step ``t+k`` (stored per step: at an episode end, the final observation before
the reset) with discount ``gamma**(k+1)``, zero when step ``t+k`` terminated (a time-out still
bootstraps).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class Batch:
    """Sampled transitions, each (B, ...): observations, actions, n-step returns and the
    discount of the bootstrap (0 at a termination), and the bootstrap's observations."""

    obs: torch.Tensor
    critic_obs: torch.Tensor
    actions: torch.Tensor
    returns: torch.Tensor
    discount: torch.Tensor
    next_obs: torch.Tensor
    next_critic_obs: torch.Tensor


class ReplayRing:
    """See the module docstring. ``critic_obs_dim`` 0: the critic reads the policy observations."""

    def __init__(self, num_envs: int, capacity: int, obs_dim: int, critic_obs_dim: int, action_dim: int,
                 device: torch.device | str):
        self.num_envs, self.capacity = num_envs, capacity
        f32 = dict(dtype=torch.float32, device=device)
        self.obs = torch.zeros(capacity, num_envs, obs_dim, **f32)
        self.next_obs = torch.zeros_like(self.obs)
        self.critic_obs = torch.zeros(capacity, num_envs, critic_obs_dim, **f32) if critic_obs_dim else None
        self.next_critic_obs = torch.zeros_like(self.critic_obs) if critic_obs_dim else None
        self.actions = torch.zeros(capacity, num_envs, action_dim, **f32)
        self.rewards = torch.zeros(capacity, num_envs, **f32)
        self.terminated = torch.zeros(capacity, num_envs, dtype=torch.bool, device=device)
        self.ended = torch.zeros_like(self.terminated)
        """Terminated or timed out: the episode does not continue into the next slot."""
        self.ptr = 0
        """The slot the next step goes to (host counter)."""
        self.size = 0
        """Slots written so far, up to ``capacity``."""
        self.ptr_device = torch.zeros((), dtype=torch.int64, device=device)
        self.size_device = torch.zeros((), dtype=torch.int64, device=device)
        """``ptr`` and ``size`` on the device (``fill_`` from the host counters: a kernel argument,
        no sync): what sampling reads, so a CUDA graph of it sees the current ring."""
        self.base_device = torch.zeros((), dtype=torch.int64, device=device)
        """The slot that sample index 0 maps to: 0, or with ``write_ahead`` the oldest slot kept."""
        self.write_ahead = False
        """Sampling runs while the next step is written (``OffPolicyCfg.overlap_collect``): ``add``
        leaves the device counters alone, ``publish`` sets them from the host's, and sampling
        skips the slot the next ``add`` overwrites. The other stream then reads counters that
        nothing changes under it and never a half-written slot."""

    def add(self, obs: torch.Tensor, critic_obs: torch.Tensor | None, actions: torch.Tensor,
            rewards: torch.Tensor, next_obs: torch.Tensor, next_critic_obs: torch.Tensor | None,
            terminated: torch.Tensor, ended: torch.Tensor) -> None:
        """One env step of every world: (N, ...) each; ``next_*`` are the observations after the
        step and before any reset."""
        i = self.ptr
        self.obs[i] = obs
        self.next_obs[i] = next_obs
        if self.critic_obs is not None:
            self.critic_obs[i] = critic_obs
            self.next_critic_obs[i] = next_critic_obs
        self.actions[i] = actions
        self.rewards[i] = rewards
        self.terminated[i] = terminated
        self.ended[i] = ended
        self.ptr = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        if not self.write_ahead:
            self.ptr_device.fill_(self.ptr)
            self.size_device.fill_(self.size)

    def publish(self) -> None:
        """``write_ahead``: make the steps added so far what sampling draws from, less the slot
        the next ``add`` overwrites (the oldest, once the ring is full): ``capacity - 1`` slots
        at most, from ``(ptr - size) mod capacity`` on. Call it on the stream that adds, before
        the sampling stream waits for that stream."""
        size = min(self.size, self.capacity - 1)
        self.ptr_device.fill_(self.ptr)
        self.size_device.fill_(size)
        self.base_device.fill_((self.ptr - size) % self.capacity)

    def sample(self, batch_size: int, n_step: int, gamma: float,
               generator: torch.Generator | None = None) -> Batch:
        """``batch_size`` transitions drawn uniformly over the written slots and worlds, with
        their n-step returns (see the module docstring)."""
        if self.size == 0:  # host counter: under a CUDA graph it was checked at capture
            raise RuntimeError("the replay ring is empty; add steps before sampling")
        dev = self.rewards.device
        # floor(u * n) of u ~ U[0, 1): uniform over 0 .. n-1 (to float32's 2**-24 grain); the clamp
        # catches u * n rounding up to n. n is the device size: no host value is baked into a graph
        t = (torch.rand(batch_size, generator=generator, device=dev) * self.size_device).long()
        t = (t.clamp_max(self.size_device - 1) + self.base_device) % self.capacity
        e = (torch.rand(batch_size, generator=generator, device=dev) * self.num_envs).long()
        e = e.clamp_max(self.num_envs - 1)
        return self.transitions(t, e, n_step, gamma)

    def transitions(self, t: torch.Tensor, e: torch.Tensor, n_step: int, gamma: float) -> Batch:
        """The transitions starting at slots ``t`` of worlds ``e`` (each (B,) int64), with their
        n-step returns: what ``sample`` returns for the pairs it drew."""
        dev = self.rewards.device
        # slots newer than t: a return never reads past the newest step written
        age = (self.ptr_device - 1 - t) % self.capacity
        j = torch.arange(n_step, device=dev)
        slots = (t[:, None] + j) % self.capacity  # (B, n)
        worlds = e[:, None].expand(-1, n_step)
        rewards = self.rewards[slots, worlds]
        stop = self.ended[slots, worlds] | (j == n_step - 1) | (j == age[:, None])
        # alive[:, j]: no stop before j, so step j is part of the return; the last alive step is k
        alive = torch.cat([torch.ones_like(stop[:, :1]), ~stop[:, :-1]], dim=1).cumprod(dim=1).float()
        powers = gamma ** j.float()
        returns = (rewards * alive * powers).sum(dim=1)
        k = alive.sum(dim=1).long() - 1
        last = slots.gather(1, k[:, None]).squeeze(1)
        discount = (gamma ** (k + 1).float()) * (~self.terminated[last, e]).float()
        critic = self.critic_obs if self.critic_obs is not None else self.obs
        next_critic = self.next_critic_obs if self.next_critic_obs is not None else self.next_obs
        return Batch(obs=self.obs[t, e], critic_obs=critic[t, e], actions=self.actions[t, e],
                     returns=returns, discount=discount, next_obs=self.next_obs[last, e],
                     next_critic_obs=next_critic[last, e])


__all__ = ["Batch", "ReplayRing"]
