"""FastOffPolicy: the gradient updates of fast-sac and fast-td3 on a ``replay.Batch``.

Both: a twin categorical critic (``categorical``) trained by cross-entropy against the projected
n-step target; clipped double Q, the FastTD3 way for distributions: of the two target critics'
next-state distributions, the one with the smaller mean is projected; Polyak-averaged target
critics; the actor updated every ``policy_delay`` critic updates against the smaller of the two
critics' means.

fast-sac: the target's returns carry the entropy bonus (``- discount * alpha * log pi(a'|s')``),
the actor minimizes ``alpha * log pi - Q`` and ``alpha`` is tuned so the entropy of the actions (in
action units, whatever their bounds) tracks ``target_entropy_per_action * num_actions``. fast-td3: a deterministic actor, target actions
smoothed by clipped Gaussian noise.

Every loss and statistic stays on the device; ``stats`` sums them for one read per iteration.

``update_from(ring, generator)`` is the runner's entry: a sample and an update, eager, or with
``cuda_graph`` on CUDA one replayed CUDA graph per update (``graphs.UpdateGraphs``; the
optimizers are then ``capturable`` and autocast keeps no cast cache).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import torch
from torch import nn

from . import categorical
from .config import OffPolicyCfg
from .graphs import UpdateGraphs
from .networks import Actor, TwinCategoricalCritic
from .replay import Batch, ReplayRing

if TYPE_CHECKING:
    from ambulo.envs.symmetry import TaskMirror

STAT_NAMES = ("critic_loss", "actor_loss", "alpha", "entropy", "q_mean", "action_std")
"""What ``FastOffPolicy.stats`` accumulates (per update; actor terms per actor update)."""


def compiled_step(update: Callable[[Batch], None], name: str,
                  compile_fn: Callable[[Callable], Callable] = torch.compile) -> Callable[[Batch], None]:
    """``compile_fn(update)`` (``torch.compile``) whose failure at its first call (where
    torch.compile builds: a missing compiler or Triton, an unsupported op) raises one RuntimeError
    naming the setting to turn it off. ``compile`` is a walking task's default, not a user's
    choice. Later calls run unguarded: an error there is the update's own."""
    compiled = compile_fn(update)
    built = False

    def step(batch: Batch) -> None:
        nonlocal built
        if built:
            return compiled(batch)
        try:
            compiled(batch)
        except Exception as error:
            first = (str(error).strip().splitlines() or [""])[0][:200]
            raise RuntimeError(f"OffPolicyCfg.compile: torch.compile of the {name} update failed "
                               f"({type(error).__name__}: {first}); train without it: "
                               "`--algo-cfg compile=false`") from error
        built = True

    return step


class FastOffPolicy(nn.Module):
    """Networks, optimizers and the update of one off-policy learner (see the module docstring)."""

    def __init__(self, cfg: OffPolicyCfg, num_obs: int, num_critic_obs: int, num_actions: int,
                 device: torch.device | str, action_bounds: torch.Tensor | None = None,
                 mirror: TaskMirror | None = None):
        """``action_bounds``: (num_actions,) each action's bound (``cfg.joint_limit_bounds``: the
        env's ``action_bounds()``); None: ``cfg.action_bound`` for every action. ``mirror``: the
        task's mirror maps (``envs.symmetry.task_mirror``), required by ``cfg.symmetry``."""
        super().__init__()
        if cfg.symmetry and mirror is None:
            raise ValueError("OffPolicyCfg.symmetry needs the task's mirror maps (envs.symmetry.task_mirror)")
        self.mirror = mirror if cfg.symmetry else None
        self.cfg, self.num_actions = cfg, num_actions
        self.sac = cfg.algo == "fast-sac"
        self.actor = Actor(num_obs, num_actions, cfg.actor_hidden_dims, stochastic=self.sac,
                           action_bound=cfg.action_bound if action_bounds is None else action_bounds.float().cpu(),
                           log_std_range=cfg.log_std_range,
                           obs_normalization=cfg.obs_normalization)
        self.critic = TwinCategoricalCritic(num_critic_obs, num_actions, cfg.critic_hidden_dims, cfg.num_atoms,
                                            layer_norm=cfg.critic_layer_norm,
                                            obs_normalization=cfg.obs_normalization)
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.log_alpha = nn.Parameter(torch.tensor(math.log(cfg.init_alpha)), requires_grad=self.sac)
        self.to(device)
        self.device = torch.device(device)
        self.atoms = categorical.support(cfg.v_min, cfg.v_max, cfg.num_atoms, self.device)
        # the target is the entropy of the actions themselves (joint targets in action units); the
        # log-probabilities are of the tanh output, whose entropy is the actions' less sum(log bound):
        # a joint bounded at 8 explores in a tanh range 4x narrower than one bounded at 2, so wider
        # (joint-limit) bounds keep the same noise on the joints instead of multiplying it
        self.target_entropy = cfg.target_entropy_per_action * num_actions \
            - float(self.actor.action_bound.log().sum())
        self.graphed = cfg.cuda_graph and self.device.type == "cuda"
        """Updates replayed as CUDA graphs (``cuda_graph``; CUDA only)."""
        # fused: the step counts live on the device (the default Adam reads each one back per step);
        # capturable: what a CUDA graph capture of step() requires (the same fused kernel)
        opt = dict(weight_decay=cfg.weight_decay, fused=True, capturable=self.graphed)
        self.actor_opt = torch.optim.AdamW(self.actor.parameters(), lr=cfg.actor_lr, **opt)
        self.critic_opt = torch.optim.AdamW(self.critic.parameters(), lr=cfg.critic_lr, **opt)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=cfg.critic_lr, fused=True, capturable=self.graphed)
        self.num_updates = 0
        """Critic updates so far (host counter: picks the actor's turns)."""
        self.stats = torch.zeros(len(STAT_NAMES) + 2, device=self.device)
        """Sums of ``STAT_NAMES`` and the numbers of critic and actor updates they cover."""
        self.autocast = cfg.amp and self.device.type == "cuda"
        self._autocast_cache = not self.graphed
        """Autocast's cache of cast weights: off with CUDA graphs (torch's rule for captures)."""
        self.graphs: UpdateGraphs | None = None
        """The CUDA graphs of ``update_from`` (made on its first call, with the caller's generator)."""
        self._graph_source: tuple | None = None
        self._critic_step = self._critic_update
        self._actor_step = self._actor_update
        if cfg.compile and self.device.type == "cuda":
            self._critic_step = compiled_step(self._critic_update, "critic")
            self._actor_step = compiled_step(self._actor_update, "actor")

    # -- acting ----------------------------------------------------------------------------------
    @torch.no_grad()
    def explore(self, obs: torch.Tensor, noise_std: torch.Tensor | None = None,
                noise: torch.Tensor | None = None, actor: Actor | None = None) -> torch.Tensor:
        """Training actions: sampled (fast-sac) or the actor's plus Gaussian noise of per-world
        ``noise_std`` (N, 1), clipped to the action bound (fast-td3). ``noise``: (N, A) standard
        normal draws to use (``noise_hold_steps``); None draws fresh ones. ``actor``: a copy to act
        with (``overlap_collect``); default the one being trained."""
        actor = self.actor if actor is None else actor
        with torch.autocast(self.device.type, torch.bfloat16, enabled=self.autocast):
            if self.sac:
                actions = actor.sample(obs, noise)[0]
            else:
                actions = actor(obs)
                actions = actions + (torch.randn_like(actions) if noise is None else noise) * noise_std
        bound = actor.action_bound
        return torch.clamp(actions.float(), -bound, bound)

    def train_mode(self) -> None:
        """What ``PeriodicEval`` calls after evaluating (rsl-rl's name): training mode."""
        self.train()

    # -- learning --------------------------------------------------------------------------------
    def update(self, batch: Batch) -> None:
        """One critic update and, every ``policy_delay`` updates, one actor (and alpha) update."""
        self._update(batch, self._actor_turn())
        self.num_updates += 1

    def update_from(self, ring: ReplayRing, generator: torch.Generator | None = None) -> None:
        """``update(ring.sample(...))`` with ``cfg``'s batch size, n-step and gamma, drawn with
        ``generator``; with ``graphed``, the same work replayed as a CUDA graph (the first
        ``warmup`` calls of each update kind run eagerly, then the kind is captured)."""
        cfg = self.cfg
        if not self.graphed:
            self.update(ring.sample(cfg.batch_size, cfg.n_step, cfg.gamma, generator))
            return
        with_actor = self._actor_turn()
        source = self._graph_source
        if self.graphs is None or source is None or source[0] is not ring or source[1] is not generator:
            # the graphs read this ring's tensors and advance this generator
            self.graphs = UpdateGraphs(self.device, generators=() if generator is None else (generator,))
            self._graph_source = (ring, generator)
        self.graphs(with_actor, lambda: self._update(ring.sample(cfg.batch_size, cfg.n_step, cfg.gamma, generator),
                                                     with_actor))
        self.num_updates += 1

    def _actor_turn(self) -> bool:
        """Whether the next update also steps the actor (every ``policy_delay`` critic updates)."""
        return self.num_updates % self.cfg.policy_delay == 0

    def _update(self, batch: Batch, with_actor: bool) -> None:
        """A critic update, an actor (and alpha) update if ``with_actor``, the target's Polyak
        step: device work only (what a CUDA graph captures; no host counter changes)."""
        if self.mirror is not None:
            batch = self._mirror_half(batch)
        self._critic_step(batch)
        if with_actor:
            self._actor_step(batch)
        with torch.no_grad():  # Polyak for weights, the normalizer's statistics copied
            target, online = list(self.critic_target.parameters()), list(self.critic.parameters())
            torch._foreach_lerp_(target, online, self.cfg.tau)
            torch._foreach_copy_(list(self.critic_target.buffers()), list(self.critic.buffers()))

    def _mirror_half(self, batch: Batch) -> Batch:
        """``batch`` with its second half replaced by the mirror images of those transitions
        (``cfg.symmetry``). The returns and discounts stay: the mirror image of a transition earns
        the same reward. The replay ring keeps only what the worlds did."""
        m, half = self.mirror, batch.obs.shape[0] // 2
        critic = m.critic or m.policy  # no privileged observations: the critic reads the policy's

        def mirrored(x: torch.Tensor, reflect) -> torch.Tensor:
            return torch.cat([x[:half], reflect(x[half:])])

        return Batch(obs=mirrored(batch.obs, m.policy), critic_obs=mirrored(batch.critic_obs, critic),
                     actions=mirrored(batch.actions, m.actions), returns=batch.returns, discount=batch.discount,
                     next_obs=mirrored(batch.next_obs, m.policy),
                     next_critic_obs=mirrored(batch.next_critic_obs, critic))

    def _critic_update(self, batch: Batch) -> None:
        cfg = self.cfg
        with torch.no_grad(), torch.autocast(self.device.type, torch.bfloat16, enabled=self.autocast,
                                             cache_enabled=self._autocast_cache):
            if self.sac:
                next_actions, next_log_prob, _ = self.actor.sample(batch.next_obs)
                returns = batch.returns - batch.discount * self.log_alpha.exp() * next_log_prob.float()
            else:
                next_actions = self.actor(batch.next_obs)
                noise = (torch.randn_like(next_actions) * cfg.target_noise_std).clamp(
                    -cfg.target_noise_clip, cfg.target_noise_clip)
                bound = self.actor.action_bound
                next_actions = torch.clamp(next_actions + noise, -bound, bound)
                returns = batch.returns
            next_probs = torch.softmax(self.critic_target(batch.next_critic_obs, next_actions).float(), dim=-1)
            means = categorical.expected(next_probs, self.atoms)  # (2, B)
            smaller = torch.where((means[0] <= means[1])[:, None], next_probs[0], next_probs[1])
            target = categorical.project(smaller, returns, batch.discount, cfg.v_min, cfg.v_max)
        with torch.autocast(self.device.type, torch.bfloat16, enabled=self.autocast,
                            cache_enabled=self._autocast_cache):
            logits = self.critic(batch.critic_obs, batch.actions).float()
        loss = -(target[None] * torch.log_softmax(logits, dim=-1)).sum(dim=-1).mean(dim=1).sum()
        self.critic_opt.zero_grad(set_to_none=True)
        loss.backward()
        self._clip(self.critic)
        self.critic_opt.step()
        with torch.no_grad():
            q = categorical.expected(torch.softmax(logits, dim=-1), self.atoms).mean()
            self.stats[0] += loss.detach()
            self.stats[4] += q
            self.stats[6] += 1.0

    def _actor_update(self, batch: Batch) -> None:
        with torch.autocast(self.device.type, torch.bfloat16, enabled=self.autocast,
                            cache_enabled=self._autocast_cache):
            if self.sac:
                actions, log_prob, std = self.actor.sample(batch.obs)
                log_prob = log_prob.float()
            else:
                actions = self.actor(batch.obs)
            probs = torch.softmax(self.critic(batch.critic_obs, actions).float(), dim=-1)
        q = categorical.expected(probs, self.atoms).min(dim=0).values
        alpha = self.log_alpha.exp().detach()
        loss = (alpha * log_prob - q).mean() if self.sac else -q.mean()
        self.actor_opt.zero_grad(set_to_none=True)
        loss.backward()
        self._clip(self.actor)
        self.actor_opt.step()
        with torch.no_grad():
            self.stats[1] += loss.detach()
            self.stats[2] += alpha
            self.stats[7] += 1.0
        if self.sac:
            alpha_loss = -(self.log_alpha * (log_prob.detach() + self.target_entropy)).mean()
            self.alpha_opt.zero_grad(set_to_none=True)
            alpha_loss.backward()
            self.alpha_opt.step()
            with torch.no_grad():
                self.stats[3] += -log_prob.detach().mean()
                self.stats[5] += std.detach().float().mean()

    def _clip(self, module: nn.Module) -> None:
        if self.cfg.max_grad_norm > 0:
            nn.utils.clip_grad_norm_(module.parameters(), self.cfg.max_grad_norm)

    def read_stats(self) -> dict[str, float]:
        """Means of ``STAT_NAMES`` since the last read (one host read), then reset."""
        values = self.stats.tolist()
        self.stats.zero_()
        critic_n, actor_n = max(values[6], 1.0), max(values[7], 1.0)
        per = (critic_n, actor_n, actor_n, actor_n, critic_n, actor_n)
        return {name: values[i] / per[i] for i, name in enumerate(STAT_NAMES)}

    # -- checkpoints -------------------------------------------------------------------------------
    def state(self) -> dict:
        return {"model": self.state_dict(), "actor_opt": self.actor_opt.state_dict(),
                "critic_opt": self.critic_opt.state_dict(), "alpha_opt": self.alpha_opt.state_dict(),
                "num_updates": self.num_updates}

    def load_state(self, saved: dict, *, optimizers: bool = True) -> None:
        self.load_state_dict(saved["model"])  # copies into the parameters: their addresses stay
        if optimizers:
            for opt, name in ((self.actor_opt, "actor_opt"), (self.critic_opt, "critic_opt"),
                              (self.alpha_opt, "alpha_opt")):
                opt.load_state_dict(saved[name])
                for group in opt.param_groups:  # the saved groups carry the saving run's flag
                    group["capturable"] = self.graphed
            self.num_updates = int(saved["num_updates"])
        if self.graphs is not None:  # the optimizers' states are new tensors: capture again
            self.graphs.reset()


__all__ = ["STAT_NAMES", "FastOffPolicy", "compiled_step"]
