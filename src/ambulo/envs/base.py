"""RLEnv: N copies of a task stepped together as torch tensors (Isaac Lab's direct workflow).

One ``step(actions)`` is one policy step: the task turns actions into controls once, the
engine advances ``decimation`` physics steps in a single batched call, then terminations,
rewards and observations are computed for all envs at once and the finished envs are reset
in place. Nothing on this path loops over envs in Python.

A task subclasses ``RLEnv`` and fills in the ``_``-methods; sizes (``num_obs``) are derived
from a real reset, not declared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import torch

from ambulo.engine import make_engine


@dataclass(kw_only=True)
class EnvCfg:
    """Settings every task has. Tasks extend it with their own fields."""

    num_envs: int = 64
    """Number of parallel envs (engine worlds)."""
    device: str = "cpu"
    """Engine and tensor device: ``"cpu"`` or ``"cuda[:N]"``."""
    seed: int = 0
    """Seed of the env's random generator (resets, commands, randomization)."""
    num_threads: int = 0
    """CPU engine threads; 0 uses every CPU."""
    physics_dt_s: float = 0.005
    """Physics timestep, s (written into the model)."""
    decimation: int = 4
    """Physics steps per policy step: policy dt = physics_dt_s * decimation."""
    episode_length_s: float = 20.0
    """Episode time limit, s; reaching it is a time-out, not a termination."""
    action_clip: float = 100.0
    """Actions are clipped to [-action_clip, action_clip] before use."""
    reward_weights: dict[str, float] = field(default_factory=dict)
    """Weight per reward term, per second of simulated time."""


class RLEnv:
    """Vectorized RL env over one engine of ``cfg.num_envs`` worlds.

    Attributes:
      num_envs: N.
      device: the engine's device; every tensor returned lives there.
      num_obs: observation size (float32, (N, num_obs)).
      num_actions: action size ((N, num_actions)).
      step_dt_s: policy step, s.
      max_episode_length: policy steps per episode before a time-out.
      episode_length_buf: (N,) int64, policy steps since each env's last reset.
    """

    num_actions: int
    success_terminations: tuple[str, ...] = ()
    """Termination names that mean success (e.g. a goal reached), not failure."""

    def __init__(self, cfg: EnvCfg, model: mujoco.MjModel):
        if cfg.decimation < 1:
            raise ValueError(f"decimation must be >= 1, got {cfg.decimation}")
        self.cfg = cfg
        model.opt.timestep = cfg.physics_dt_s
        self.engine = make_engine(model, cfg.num_envs, cfg.device, num_threads=cfg.num_threads)
        self.model = self.engine.model
        self.num_envs = cfg.num_envs
        self.device = torch.device(self.engine.device)
        self.physics_dt_s = cfg.physics_dt_s
        self.step_dt_s = cfg.physics_dt_s * cfg.decimation
        self.max_episode_length = math.ceil(cfg.episode_length_s / self.step_dt_s)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(cfg.seed)
        self.return_final_obs = False
        """When True, ``extras["final_obs"]`` holds every env's observation before resets."""

        n, dev = self.num_envs, self.device
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=dev)
        self.actions = torch.zeros(n, self.num_actions, dtype=torch.float64, device=dev)
        """(N, num_actions) float64: the last (clipped) policy action."""
        self.prev_actions = torch.zeros_like(self.actions)
        self.reward_names = list(cfg.reward_weights)
        self._reward_weights = torch.tensor(
            [cfg.reward_weights[k] for k in self.reward_names], dtype=torch.float64, device=dev
        ) * self.step_dt_s
        self.episode_sums = torch.zeros(n, len(self.reward_names), dtype=torch.float64, device=dev)
        """(N, num_reward_terms): weighted reward per term summed over the current episode."""

        self._setup()
        self.obs_buf = self._reset_all()
        self.num_obs = self.obs_buf.shape[1]
        privileged = self._get_privileged_observations()
        self.num_privileged_obs = 0 if privileged is None else privileged.shape[1]
        unknown = sorted(set(self.reward_names) - set(self._get_rewards()))
        if unknown:
            raise ValueError(
                f"reward_weights name unknown reward terms {unknown}; "
                f"{type(self).__name__} has {sorted(self._get_rewards())}"
            )

    # -- task interface ----------------------------------------------------------
    def _setup(self) -> None:
        """Precompute index tensors and task buffers (after the engine exists)."""

    def _apply_action(self, actions: torch.Tensor) -> None:
        """Write controls for the next ``decimation`` physics steps from (N, A) float64 actions."""
        raise NotImplementedError

    def _pre_physics(self) -> None:
        """Per-policy-step state changes before physics (pushes, ...)."""

    def _post_physics(self) -> None:
        """Update task state after physics and before dones/rewards (contact timers, ...)."""

    def _get_observations(self) -> torch.Tensor:
        """(N, num_obs) float32 policy observations."""
        raise NotImplementedError

    def _get_privileged_observations(self) -> torch.Tensor | None:
        """(N, K) float32 extra observations for a critic, or None."""
        return None

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        """Unweighted reward terms by name, each (N,); ``cfg.reward_weights`` picks and weighs."""
        raise NotImplementedError

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        """(N,) bool masks of task terminations by name (failure or success, not time-outs)."""
        raise NotImplementedError

    def _reset_idx(self, env_ids: torch.Tensor) -> None:
        """Randomize the state of ``env_ids`` after the engine restored their initial state."""

    # -- public API --------------------------------------------------------------
    def reset(self, env_ids: torch.Tensor | None = None) -> torch.Tensor:
        """Reset ``env_ids`` (all if None); return the observations of all envs, (N, num_obs)."""
        if env_ids is None:
            self.obs_buf = self._reset_all()
        else:
            ids = torch.as_tensor(env_ids, device=self.device).reshape(-1).long()
            self._reset_envs(ids)
            self.obs_buf = self._get_observations()
        return self.obs_buf

    def get_observations(self) -> torch.Tensor:
        """Observations after the last ``reset``/``step``, (N, num_obs) float32."""
        return self.obs_buf

    def step(self, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, dict]:
        """Advance every env by one policy step.

        Args:
          actions: (N, num_actions) finite values.

        Returns:
          obs: (N, num_obs) float32, after resets (a finished env shows its new episode).
          rewards: (N,) float32.
          dones: (N,) bool, terminated or timed out (those envs were reset).
          extras: ``time_outs`` (N,) bool, ``terminated`` (N,) bool, ``terminations``
            (the (N,) bool mask of each termination term), ``episode``
            (mean statistics of the episodes that ended, when any did), ``observations``
            (``{"critic": ...}`` when the task has privileged observations).
        """
        actions = self._validate_actions(actions)
        self.prev_actions.copy_(self.actions)
        self.actions.copy_(actions.clamp(-self.cfg.action_clip, self.cfg.action_clip))
        self._apply_action(self.actions)
        self._pre_physics()
        diverged = self.engine.step(self.cfg.decimation).to(self.device)
        self.episode_length_buf += 1
        self._post_physics()

        terminations = self._get_terminations()
        terminated = diverged.clone()
        for mask in terminations.values():
            terminated |= mask
        time_outs = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        terms = self._get_rewards()
        weighted = torch.stack([terms[k] for k in self.reward_names], dim=1) * self._reward_weights
        self.episode_sums += weighted
        rewards = weighted.sum(dim=1).float()

        extras: dict = {"time_outs": time_outs, "terminated": terminated,
                        "terminations": terminations}
        if self.return_final_obs:
            extras["final_obs"] = self._get_observations()
        dones = terminated | time_outs
        reset_ids = dones.nonzero().squeeze(-1)
        if reset_ids.numel():
            extras["episode"] = self._episode_stats(reset_ids, terminations, time_outs, diverged)
            self._reset_envs(reset_ids)
        self.obs_buf = self._get_observations()
        privileged = self._get_privileged_observations()
        if privileged is not None:
            extras["observations"] = {"critic": privileged}
        return self.obs_buf, rewards, dones, extras

    def close(self) -> None:
        """Release resources (the engine is freed with the env)."""

    # -- internals -----------------------------------------------------------------
    def _validate_actions(self, actions: torch.Tensor) -> torch.Tensor:
        if not isinstance(actions, torch.Tensor):
            actions = torch.as_tensor(actions)
        expected = (self.num_envs, self.num_actions)
        if tuple(actions.shape) != expected:
            raise ValueError(
                f"actions have shape {tuple(actions.shape)}, expected {expected} "
                f"(num_envs, num_actions); pass one row of {self.num_actions} values per env"
            )
        actions = actions.to(device=self.device, dtype=torch.float64)
        if not torch.isfinite(actions).all():
            bad = (~torch.isfinite(actions)).any(dim=1).nonzero().squeeze(-1)
            raise ValueError(
                f"actions contain NaN or Inf in {bad.numel()} envs (first: env {int(bad[0])}); "
                "check the policy's outputs (e.g. exploding weights) or sanitize with "
                "torch.nan_to_num before stepping"
            )
        return actions

    def _reset_all(self) -> torch.Tensor:
        self._reset_envs(torch.arange(self.num_envs, device=self.device))
        return self._get_observations()

    def _reset_envs(self, env_ids: torch.Tensor) -> None:
        self.engine.reset(env_ids)
        self.episode_length_buf[env_ids] = 0
        self.actions[env_ids] = 0.0
        self.prev_actions[env_ids] = 0.0
        self.episode_sums[env_ids] = 0.0
        self._reset_idx(env_ids)
        self.engine.forward(env_ids)

    def _episode_stats(self, ids: torch.Tensor, terminations: dict[str, torch.Tensor],
                       time_outs: torch.Tensor, diverged: torch.Tensor) -> dict[str, torch.Tensor]:
        """Means over the episodes ending now: reward sums per term and how they ended."""
        stats = {}
        sums = self.episode_sums[ids].mean(dim=0).float()
        for i, name in enumerate(self.reward_names):
            stats[f"Episode_Reward/{name}"] = sums[i]
        length = self.episode_length_buf[ids].double().mean() * self.step_dt_s
        stats["Episode/length_s"] = length.float()
        for name, mask in terminations.items():
            stats[f"Episode_Termination/{name}"] = mask[ids].float().mean()
        stats["Episode_Termination/time_out"] = time_outs[ids].float().mean()
        stats["Episode_Termination/diverged"] = diverged[ids].float().mean()
        return stats

    def _uniform(self, shape: tuple[int, ...], low: float, high: float) -> torch.Tensor:
        """Uniform float64 samples in [low, high) from the env's generator."""
        sample = torch.rand(shape, generator=self.generator, dtype=torch.float64,
                            device=self.device)
        return low + (high - low) * sample
