"""OffPolicyRunner: collects every world's steps into the replay ring and updates the learner.

It offers what ambulo's training machinery asks of rsl-rl's ``OnPolicyRunner``, so the same
progress bar, ``metrics.csv``, TensorBoard, periodic evaluation, early stop, signal handling,
``play``, ``eval`` and ``export`` serve both: ``learn``, ``save``, ``current_learning_iteration``,
``get_inference_policy`` (a policy that takes the TensorDict observations of ``vecenv`` and has
rsl-rl's ``as_jit``/``as_onnx``/``obs_groups``), ``alg.train_mode``, ``logger.writer``, ``env``.

The step path has no host sync: actions, noise, the ring's writes and samples and the updates
are device work queued one after another; the host reads the device once an iteration (the
loss means, the episode statistics and, on a terrain curriculum, the mean level ``metrics.csv``
records: ``progress.terrain_level_reader``).

Time-outs bootstrap: the env returns each world's observation before its reset
(``RLEnv.return_final_obs``), stored as the step's next observation. The critic's observation
of that moment (clean terms plus privileged ones) is recorded by ``FinalCriticObs``.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from pathlib import Path

import torch

from ambulo.envs import RLEnv
from ambulo.envs.symmetry import task_mirror

from ..checkpoints import atomic_torch_save, check_same_shapes
from ..episodes import EpisodeStats
from ..vecenv import RslRlVecEnv
from .config import OffPolicyCfg
from .learner import FastOffPolicy
from .networks import Actor
from .overlap import OverlappedSteps
from .replay import ReplayRing


class FinalCriticObs:
    """Records the critic observations the env computes for ``extras["final_obs"]``.

    ``RLEnv.step`` computes the observations twice when ``return_final_obs`` is set: before the
    resets (the final ones) and after; its critic buffer holds the second. This wraps the env's
    ``_compute_observations`` to keep the critic buffer of the first call of each step."""

    def __init__(self, env: RLEnv):
        self.env, self.calls, self.final = env, 0, None
        self.captured: torch.Tensor | None = None
        """The first call's critic buffer of the last step that ran Python: with the env step as a
        CUDA graph (``EnvCfg.cuda_graph``) that is the capture, and the graph rewrites this tensor
        (memory of its pool, kept alive here) with the final critic obs on every replay."""
        compute = env._compute_observations

        def recorded():
            obs = compute()
            if self.calls == 0:
                self.final = self.captured = env._critic_buf
            self.calls += 1
            return obs

        env._compute_observations = recorded

    def step(self, step: Callable):
        """Run ``step()`` (the env's step) and return its result with the final critic obs (a
        view the next step overwrites when the env replays a graph: use it before then)."""
        self.calls, self.final = 0, None
        result = step()
        if self.calls == 0:  # a replayed graph ran no Python: its output is the captured buffer
            self.final = self.captured
        return result, self.final


class InferencePolicy:
    """The deterministic actor as ambulo's evaluation and export code use rsl-rl's policies:
    called on the TensorDict observations, ``as_jit``/``as_onnx`` copies for export."""

    obs_groups = ("policy",)

    def __init__(self, actor: Actor):
        self.actor = actor

    def __call__(self, obs) -> torch.Tensor:
        return self.actor(obs["policy"])

    def as_jit(self) -> Actor:
        return copy.deepcopy(self.actor)

    def as_onnx(self, verbose: bool = False) -> Actor:
        return copy.deepcopy(self.actor)


class _Logger:
    """``runner.logger`` as ``interrupt`` and ``periodic_eval`` read it: the TensorBoard writer."""

    def __init__(self, writer):
        self.writer = writer


class OffPolicyRunner:
    """Training (or, with ``training=False``, only the networks for play/eval/export) of
    ``cfg.algo`` on ``env``. ``on_iteration(it, collect_s, learn_s, action_std)`` runs at the end
    of each iteration (``progress.TrainingProgress.iteration_done``)."""

    def __init__(self, env: RLEnv, cfg: OffPolicyCfg, *, episodes: EpisodeStats | None = None,
                 writer=None, on_iteration: Callable[[int, float, float, float], None] | None = None,
                 training: bool = True, seed: int = 0, run_dir: Path | None = None):
        self.cfg, self.raw_env, self.run_dir = cfg, env, run_dir
        """``run_dir``: where ``learn`` saves ``model_<it>.pt`` (None: no periodic saves)."""
        self.env = RslRlVecEnv(env, episodes)
        self.episodes, self.on_iteration = episodes, on_iteration
        self.device = env.device
        self.logger = _Logger(writer)
        critic_obs = env.num_privileged_obs or env.num_obs
        self.alg = FastOffPolicy(cfg, env.num_obs, critic_obs, env.num_actions, env.device,
                                 action_bounds=joint_limit_bounds(env) if cfg.joint_limit_bounds else None,
                                 mirror=task_mirror(env) if cfg.symmetry else None)
        self.current_learning_iteration = 0
        self.started_s = time.monotonic()
        """``time.monotonic()`` the run's wall time counts from (``train_offpolicy`` sets it; a
        resume moves it back by the checkpoint's elapsed time)."""
        self._action_std = 0.0
        self.env_steps = 0
        """Env steps per world collected by this process (host counter)."""
        self.generator = torch.Generator(device=env.device)
        self.generator.manual_seed(seed)
        """Replay sampling and exploration-noise draws."""
        self.overlap: OverlappedSteps | None = None
        """Collection beside the updates (``cfg.overlap_collect``, set below when training), or None."""
        if not training:
            return
        env.return_final_obs = True
        self._final_critic = FinalCriticObs(env) if env.num_privileged_obs else None
        self.ring = ReplayRing(env.num_envs, cfg.buffer_steps_per_env, env.num_obs, env.num_privileged_obs,
                               env.num_actions, env.device)
        self._noise_std = torch.zeros(env.num_envs, 1, device=env.device)
        self._draw_noise(torch.ones(env.num_envs, dtype=torch.bool, device=env.device))
        # held exploration noise (noise_hold_steps > 1): (N, A) standard normal draws and (N,) the
        # steps each world has held them; a world redraws when the count wraps or it resets
        self._held_noise = torch.zeros(env.num_envs, env.num_actions, device=env.device)
        self._held_steps = torch.zeros(env.num_envs, dtype=torch.long, device=env.device)
        obs = self.env.get_observations()
        self._obs, self._critic_obs = obs["policy"], obs.get("critic", None)
        if cfg.overlap_collect:
            self.overlap = OverlappedSteps(self, seed)

    def _draw_noise(self, worlds: torch.Tensor) -> None:
        """fast-td3's per-world exploration std, drawn anew where ``worlds`` (N,) is set."""
        low, high = self.cfg.exploration_noise_std_range
        fresh = torch.rand(self.raw_env.num_envs, 1, generator=self.generator, device=self.device)
        self._noise_std = torch.where(worlds[:, None], low + (high - low) * fresh, self._noise_std)

    def _collect(self, acting: Actor | None = None) -> None:
        """One env step of every world into the ring. ``acting``: the actor copy to act with
        (``overlap.OverlappedSteps``, which then updates the normalizers itself)."""
        cfg, env = self.cfg, self.raw_env
        obs, critic_obs = self._obs, self._critic_obs
        if acting is None:
            self.update_normalizers(obs, critic_obs)
        if self.env_steps < cfg.random_steps:
            actions = (torch.rand(env.num_envs, env.num_actions, generator=self.generator, device=self.device)
                       * 2.0 - 1.0) * self.alg.actor.action_bound
        elif cfg.noise_hold_steps > 1:
            actions = self.alg.explore(obs, self._noise_std, self._hold_noise(), actor=acting)
        else:
            actions = self.alg.explore(obs, self._noise_std, actor=acting)
        if self._final_critic is not None:
            (next_obs, rewards, dones, extras), final_critic = self._final_critic.step(
                lambda: self.env.step(actions))
        else:
            (next_obs, rewards, dones, extras), final_critic = self.env.step(actions), None
        ended = dones.bool()
        self.ring.add(obs, critic_obs, actions, rewards, extras["final_obs"], final_critic,
                      extras["terminated"], ended)
        self._obs, self._critic_obs = next_obs["policy"], next_obs.get("critic", None)
        if not self.alg.sac:
            self._draw_noise(ended)
        if cfg.noise_hold_steps > 1:  # a reset world draws new noise at its next step
            self._held_steps = torch.where(ended, 0, self._held_steps)
        self.env_steps += 1

    def update_normalizers(self, obs: torch.Tensor, critic_obs: torch.Tensor | None) -> None:
        """The learner's observation normalizers take one step's (N, ...) observations
        (``cfg.obs_normalization``; the critic's reads the policy's when there are no privileged ones)."""
        if self.cfg.obs_normalization:
            self.alg.actor.normalizer.update(obs)
            self.alg.critic.normalizer.update(obs if critic_obs is None else critic_obs)

    def _hold_noise(self) -> torch.Tensor:
        """(N, A) the exploration noise of this step: drawn anew in the worlds whose hold has run
        out (or that reset), the held draws elsewhere. One fresh draw for all worlds, selected
        with a mask: no host sync."""
        fresh = torch.randn(self._held_noise.shape, generator=self.generator, device=self.device)
        redraw = self._held_steps == 0
        self._held_noise = torch.where(redraw[:, None], fresh, self._held_noise)
        self._held_steps = (self._held_steps + 1) % self.cfg.noise_hold_steps
        return self._held_noise

    def learn(self, num_learning_iterations: int, init_at_random_ep_len: bool = False) -> None:
        """Run ``num_learning_iterations`` iterations from ``current_learning_iteration``."""
        threads = torch.get_num_threads()
        if self.device.type == "cpu" and self.cfg.cpu_threads > 0:
            torch.set_num_threads(self.cfg.cpu_threads)
        try:
            self._learn(num_learning_iterations, init_at_random_ep_len)
        finally:
            torch.set_num_threads(threads)

    def _learn(self, num_learning_iterations: int, init_at_random_ep_len: bool) -> None:
        cfg = self.cfg
        if init_at_random_ep_len:  # spread the resets in time, as rsl-rl's runner does
            high = max(int(self.raw_env.max_episode_length), 1)
            self.env.episode_length_buf = torch.randint(0, high, (self.raw_env.num_envs,),
                                                        generator=self.generator, device=self.device)
        start = self.current_learning_iteration
        if self.overlap is not None:  # act with the weights this run starts from (a resume's, an init's)
            self.overlap.refresh()
        for it in range(start, start + num_learning_iterations):
            self.current_learning_iteration = it
            collect_s = learn_s = 0.0
            for _ in range(cfg.num_steps_per_env):
                if self.overlap is not None:
                    collected_s, queued_s = self.overlap.step()
                    collect_s, learn_s = collect_s + collected_s, learn_s + queued_s
                    continue
                began = time.perf_counter()
                self._collect()
                collected = time.perf_counter()
                collect_s += collected - began
                if self.env_steps >= cfg.learning_starts:
                    for _ in range(cfg.updates_per_step):
                        self.alg.update_from(self.ring, self.generator)
                learn_s += time.perf_counter() - collected
            if self.device.type == "cuda":  # once an iteration: the times cover the queued work
                began = time.perf_counter()
                torch.cuda.synchronize(self.device)
                learn_s += time.perf_counter() - began
            self._log(it)
            if self.on_iteration is not None:
                self.on_iteration(it, collect_s, learn_s, self._action_std)
            if it % cfg.save_interval == 0 and self.run_dir is not None:
                self.save(str(self.run_dir / f"model_{it}.pt"))
        if self.run_dir is not None:
            self.save(str(self.run_dir / f"model_{self.current_learning_iteration}.pt"))

    def _log(self, it: int) -> None:
        stats = self.alg.read_stats()
        if not self.alg.sac:
            stats["action_std"] = float(self._noise_std.mean())
        self._action_std = stats["action_std"]
        writer = self.logger.writer
        if writer is None:
            return
        for name, value in stats.items():
            writer.add_scalar(("Loss/" if "loss" in name else "Policy/") + name, value, it)
        if self.episodes is not None:
            reward, length = self.episodes.means()
            if reward is not None:
                writer.add_scalar("Train/mean_reward", reward, it)
                writer.add_scalar("Train/mean_episode_length", length, it)

    # -- checkpoints and policies ----------------------------------------------------------------
    def save(self, path: str, infos: dict | None = None) -> None:
        saved = {"iter": self.current_learning_iteration, "algo": self.cfg.algo, **self.alg.state(),
                 "env_steps": self.env_steps,
                 "infos": {**(infos or {}), "env_rng": self.raw_env.generator.get_state(),
                           "torch_rng": torch.get_rng_state(), "sampling_rng": self.generator.get_state(),
                           **({"overlap_rng": self.overlap.generator.get_state()} if self.overlap else {}),
                           "episode_returns": self.episodes.returns() if self.episodes is not None else [],
                           "episode_lengths": self.episodes.lengths() if self.episodes is not None else [],
                           "wall_s": time.monotonic() - self.started_s}}
        atomic_torch_save(saved, Path(path))

    def load(self, path: str | Path, *, optimizers: bool = True) -> dict:
        saved = torch.load(path, weights_only=False, map_location=str(self.device))
        self.alg.load_state(saved, optimizers=optimizers)
        self.current_learning_iteration = int(saved["iter"])
        return saved

    def load_for_resume(self, path: Path) -> int:
        """Weights, optimizers and RNG states of ``path``; return the next iteration. The replay
        ring is not in checkpoints (hundreds of MB): it refills, and updates wait for
        ``learning_starts`` steps again."""
        saved = self.load(path)
        infos = saved.get("infos", {})
        self.raw_env.generator.set_state(infos["env_rng"].cpu())
        torch.set_rng_state(infos["torch_rng"].cpu())
        self.generator.set_state(infos["sampling_rng"].cpu())
        if self.overlap is not None and "overlap_rng" in infos:
            self.overlap.generator.set_state(infos["overlap_rng"].cpu())
        if self.episodes is not None:
            self.episodes.restore(infos.get("episode_returns", []), infos.get("episode_lengths", []))
        self.started_s -= float(infos.get("wall_s", 0.0))  # the earlier segments' wall time (PPO's runner does too)
        self.current_learning_iteration += 1
        return self.current_learning_iteration

    def load_for_init(self, path: Path, task: str) -> None:
        """``ambulo train --init-from``: the networks of ``path`` (actor, critics, their targets and
        normalizers, SAC's temperature), after checking they have this run's shapes; not its
        optimizers, update count, iteration or RNG states (a new run starts at 0). The optimizers
        start fresh: a fine-tune's changed reward moves the value targets, so Adam's moment
        estimates of the old run's gradients would mislead the first updates."""
        saved = torch.load(path, weights_only=False, map_location=str(self.device))
        check_same_shapes(path, saved, {"model": self.alg.state_dict()}, task)
        self.alg.load_state(saved, optimizers=False)

    def get_inference_policy(self, device: str | None = None) -> InferencePolicy:
        self.alg.eval()
        return InferencePolicy(self.alg.actor)


def joint_limit_bounds(env: RLEnv) -> torch.Tensor:
    """(A,) the env's own action bounds (``OffPolicyCfg.joint_limit_bounds``); a ValueError in one
    line for a task that has none."""
    bounds = env.action_bounds()
    if bounds is None:
        raise ValueError(f"{type(env).__name__} gives no per-action bounds (joint_limit_bounds=true); "
                         "train it with one action_bound for all (--algo-cfg joint_limit_bounds=false)")
    return bounds


def load_runner(info: dict, env: RLEnv, checkpoint: Path) -> OffPolicyRunner:
    """The networks of an off-policy run (its ``run.json`` ``info``) on ``env``, with the weights
    of ``checkpoint``: what ``runs.load_runner`` returns for ``play``, ``eval`` and ``export``."""
    from .config import cfg_from_info

    runner = OffPolicyRunner(env, cfg_from_info(info), training=False)
    runner.load(checkpoint, optimizers=False)
    return runner


__all__ = ["FinalCriticObs", "InferencePolicy", "OffPolicyRunner", "joint_limit_bounds", "load_runner"]
