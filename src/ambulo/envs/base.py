"""RLEnv: N copies of a task stepped together as torch tensors (Isaac Lab's direct workflow).

The scene is built by the core (``ambulo.core``): the task's robot through ``add_robot``
(the same importers and drives as ``World``), the ground through ``add_ground``, physics
from the config's ``PhysicsCfg``, sensors as lifecycle components of one ``Simulation``.
The robot is read and driven through an ``ambulo.core.Entity``.

One ``step(actions)`` is one policy step: the task turns actions into drive targets once, the
engine advances ``decimation`` physics steps in a single batched call, sensors update, then
terminations, rewards and observations are computed for all envs at once and the finished
envs are reset in place through masks. No Python loop over envs and no host sync on this path:
resets, action checks and episode statistics are tensor operations, and the worlds a reset
touches are row selectors (``ambulo.core.rows``): indices on the CPU, where finding them is
free and only their values are drawn, a mask on a GPU.

A task subclasses ``RLEnv`` and fills in the ``_``-methods; sizes (``num_obs``) are derived
from a real reset, not declared.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from typing import Literal

import torch

from ambulo.core import Entity, GroundCfg, PhysicsCfg, RobotCfg, Simulation, add_ground, add_robot, new_scene
from ambulo.core.entity import InitState
from ambulo.core.rows import fill_rows, num_rows, select_rows
from ambulo.utils.checks import check_int, check_real_dtype
from ambulo.utils.validate import Checked, check_fields, rule

from .episode_stats import EpisodeStats
from .graph_step import GraphStep, StepOutputs


@dataclass(kw_only=True)
class EnvCfg(Checked):
    """Settings every task has. Tasks extend it with their own fields."""

    num_envs: int = 64
    """Number of parallel envs (engine worlds)."""
    device: str = "cpu"
    """Engine and tensor device: ``"cpu"`` or ``"cuda[:N]"``."""
    engine: str = "auto"
    """``"auto"`` (MuJoCo's batch on the CPU, MuJoCo Warp on CUDA), ``"mujoco"`` or ``"warp"``
    (MuJoCo Warp, also on Warp's CPU device: how GPU code paths are tested without a GPU)."""
    seed: int = 0
    """Seed of the env's random generator (resets, commands, randomization, noise)."""
    num_threads: int = 0
    """CPU engine threads; 0 uses every CPU."""
    torch_threads: int = 1
    """torch intra-op threads while a CPU env steps: MuJoCo's batch threads already use every
    core, and torch's pool competing for them cost a third of a humanoid step (issue #7)."""
    physics: PhysicsCfg = field(default_factory=PhysicsCfg)
    """Solver and integrator settings (``timestep_s`` is the physics step)."""
    decimation: int = field(default=4, metadata=rule(minimum=1))
    """Physics steps per policy step: policy dt = physics.timestep_s * decimation."""
    episode_length_s: float = 20.0
    """Episode time limit, s; reaching it is a time-out, not a termination."""
    action_clip: float = field(default=100.0, metadata=rule(minimum=0.0, strict=True))
    """Actions are clipped to [-action_clip, action_clip] before use."""
    reward_weights: dict[str, float] = field(default_factory=dict)
    """Weight per reward term, per second of simulated time."""
    robot: RobotCfg
    """The robot file, where it stands and its drive defaults."""
    robot_keyframe: str | None = None
    """Keyframe of the robot file giving the default joint pose and root height (None: qpos0)."""
    default_joint_pos: dict[str, float] = field(default_factory=dict)
    """Default pose overrides per joint name (relative to the robot's prim path), rad or m."""
    soft_joint_limit_factor: float = 0.9
    """``robot.soft_joint_pos_limits``: this fraction of each joint's range about its middle."""
    ground: GroundCfg | None = field(default_factory=GroundCfg)
    """The ground plane (its friction, restitution); None for none."""
    observation_noise: dict[str, float] = field(default_factory=dict)
    """Uniform noise half-width per policy observation term (actor only; the critic sees
    clean values), in the term's units after scaling."""
    diverged_speed_bound: float | None = field(default=1000.0, metadata=rule(minimum=0.0, strict=True))
    """A world with any velocity entry (``qvel``: joint speeds in rad/s or m/s, a free base's
    linear m/s and angular rad/s) beyond this after a step is diverged, like the engine's own
    check (NaN or beyond mjMAXVAL, 1e10): terminated, counted in ``Episode_Termination/diverged``,
    its reward for that step zeroed. Why: a world that runs away below 1e10 (MuJoCo Warp on
    humanoid-rough) gave squared-velocity rewards of -1e10 that wrecked PPO's value targets.
    None: only the engine's check."""
    cuda_graph: bool = False
    """On CUDA, replay the step's device work (actions, physics, terminations, rewards,
    statistics, masked resets with their draws, observations) as one CUDA graph captured after
    ``cuda_graph_warmup_steps`` eager steps (``envs.graph_step``): one launch per step instead
    of hundreds. Ignored on the CPU. Results equal the eager step's (tests/envs/test_graph_step_gpu.py)."""
    cuda_graph_warmup_steps: int = field(default=3, metadata=rule(minimum=1))
    """Eager steps before the capture: they load kernels and allocate every lazily made buffer."""
    reset_forward: Literal["full", "kinematics"] = "full"
    """The derived-field pass after a reset (``engine.forward`` of the reset worlds). ``"full"``:
    MuJoCo's whole forward (collisions, actuation, constraint solve, every sensor). ``"kinematics"``:
    poses, com and com velocities only (``engine.protocol.KINEMATIC_FIELDS``); the reset worlds'
    sensordata, contacts, forces and qacc keep their pre-reset values until the next physics step
    (``engine.acc_stale``), and the contact sensor reads them as no contact, zero force. What
    observations built from qpos/qvel, poses and body velocities read is the same (humanoid-walk's
    policy terms; its critic's ``feet_contact`` reads 0 on a reset row), and so is the next step.
    Why: on a GPU the masked reset runs every step, over all worlds; at 4096 humanoid-walk worlds
    on an H200 the env step cost 8.06 ms (CUDA graph) against 5.72 ms of raw physics, and a full
    forward measured 86 % of a whole physics step on Warp's CPU device against 2.5 % for the
    kinematics (docs/gpu.md)."""
    stats_interval_steps: int = field(default=24, metadata=rule(minimum=1))
    """Episode statistics (``extras["episode"]``) cover the episodes that ended in windows of
    this many policy steps, so the step path needs no host sync to find ended episodes."""


class RLEnv:
    """Vectorized RL env over one ``Simulation`` of ``cfg.num_envs`` worlds.

    Attributes:
      num_envs: N.
      device: the engine's device; every tensor returned lives there.
      num_obs: observation size (float32, (N, num_obs)).
      num_actions: action size ((N, num_actions)).
      step_dt_s: policy step, s.
      max_episode_length: policy steps per episode before a time-out.
      episode_length_buf: (N,) int64, policy steps since each env's last reset.
      robot: the ``Entity`` of ``cfg.robot``.
    """

    num_actions: int

    def __init__(self, cfg: EnvCfg):
        check_int("num_envs", cfg.num_envs, "pass a whole number of parallel envs, e.g. num_envs=64",
                  minimum=1)
        check_fields(cfg)  # again: a config edited after it was built (cfg.episode_length_s = -5)
        self.cfg = cfg
        spec = new_scene(type(self).__name__)
        if cfg.ground is not None:
            add_ground(spec, cfg.ground)
        self.robot_asset = add_robot(spec, cfg.robot)
        self.sim = Simulation(spec, cfg.physics, num_worlds=cfg.num_envs, device=cfg.device,
                              num_threads=cfg.num_threads, engine=cfg.engine)
        self._design_scene(spec)
        self.engine = self.sim.start()
        self.model = self.engine.model
        self.num_envs = cfg.num_envs
        self.device = torch.device(self.engine.device)
        self.physics_dt_s = cfg.physics.timestep_s
        self.step_dt_s = cfg.physics.timestep_s * cfg.decimation
        self.max_episode_length = math.ceil(cfg.episode_length_s / self.step_dt_s)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(cfg.seed)
        self.return_final_obs = False
        """When True, ``extras["final_obs"]`` holds every env's observation before resets."""
        self.robot = self._make_robot()
        self.num_actions = self._num_actions()

        n, dev, f32 = self.num_envs, self.device, dict(dtype=torch.float32, device=self.device)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=dev)
        self.actions = torch.zeros(n, self.num_actions, **f32)
        """(N, num_actions) float32: the last (clipped) policy action."""
        self.prev_actions = torch.zeros_like(self.actions)
        self.reward_names = list(cfg.reward_weights)
        self._reward_weights = torch.tensor([cfg.reward_weights[k] for k in self.reward_names], **f32) \
            * self.step_dt_s
        self.episode_sums = torch.zeros(n, len(self.reward_names), **f32)
        """(N, num_reward_terms): weighted reward per term summed over the current episode."""
        self._nonfinite_actions = torch.zeros((), dtype=torch.long, device=dev)

        self._setup()
        self._terms_seen: list[str] | None = None
        self._noise_scale: torch.Tensor | None = None
        self.obs_buf = self._reset_all()
        self.num_obs = self.obs_buf.shape[1]
        self.num_privileged_obs = 0 if self._critic_buf is None else self._critic_buf.shape[1]
        unknown = sorted(set(self.reward_names) - set(self._get_rewards()))
        if unknown:
            raise ValueError(f"reward_weights name unknown reward terms {unknown}; "
                             f"{type(self).__name__} has {sorted(self._get_rewards())}")
        noisy = sorted(set(cfg.observation_noise) - set(self._terms_seen))
        if noisy:
            raise ValueError(f"observation_noise names unknown observation terms {noisy}; "
                             f"{type(self).__name__} has {self._terms_seen}")
        self._stats = EpisodeStats(self)
        self._graph = GraphStep(self) if cfg.cuda_graph and self.device.type == "cuda" else None

    # -- task interface ----------------------------------------------------------
    def _design_scene(self, spec) -> None:
        """Add task elements to ``spec`` (markers) and components to ``self.sim`` (sensors)."""

    def _make_robot(self) -> Entity:
        """The robot's ``Entity``, started in its initial state: ``cfg.robot_keyframe`` of the
        robot's file (or the model's ``qpos0``) with ``cfg.default_joint_pos`` over it."""
        cfg = self.cfg
        if cfg.robot_keyframe is None:
            init = InitState(joint_pos=dict(cfg.default_joint_pos))
        else:
            key = self.robot_asset.keyframes.get(cfg.robot_keyframe)
            if key is None:
                raise ValueError(f"{cfg.robot.file} has no keyframe {cfg.robot_keyframe!r} "
                                 f"(has {sorted(self.robot_asset.keyframes)}); set robot_keyframe=None")
            init = InitState.from_keyframe(key, cfg.robot, joint_pos=cfg.default_joint_pos)
        robot = Entity(self.engine, cfg.robot.prim_path, init_state=init,
                       soft_limit_factor=cfg.soft_joint_limit_factor)
        robot.apply_init_state()
        return robot

    def _num_actions(self) -> int:
        """Action size; default: one per robot joint."""
        return self.robot.num_joints

    def _setup(self) -> None:
        """Precompute index tensors and task buffers (after the engine and robot exist)."""

    def action_bounds(self) -> torch.Tensor | None:
        """(A,) float32 the largest useful |action| of each action, where the task knows it (a joint
        target task: the farther joint limit from the default pose, in action units); None here."""
        return None

    def _apply_action(self, actions: torch.Tensor) -> None:
        """Write drive targets for the next ``decimation`` physics steps from (N, A) float32 actions."""
        raise NotImplementedError

    def _simulate(self) -> torch.Tensor:
        """Advance the physics one policy step; return the (N,) bool mask of diverged worlds.
        Default: ``decimation`` physics steps in one batched call (a task whose drives change
        within the policy step, such as an action latency, steps them itself)."""
        return self.sim.step(self.cfg.decimation)

    def _pre_physics(self) -> None:
        """Per-policy-step state changes before physics (pushes, command updates, ...)."""

    def _post_physics(self) -> None:
        """Update task state after physics and sensors, before dones/rewards."""

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        """Policy observation terms by name, each (N, k); concatenated in order."""
        raise NotImplementedError

    def _privileged_terms(self) -> dict[str, torch.Tensor] | None:
        """Extra critic-only terms, each (N, k), or None."""
        return None

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        """Unweighted reward terms by name, each (N,); ``cfg.reward_weights`` picks and weighs."""
        raise NotImplementedError

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        """(N,) bool masks of task terminations by name (failure or success, not time-outs)."""
        raise NotImplementedError

    graph_audited: bool = False
    """Set True on a task class (itself, not inherited: a subclass's step is other code) whose step was
    checked to keep its state in place: a replay reruns kernels, never Python, so a persistent tensor the
    step rebinds (``self.timer = self.timer + dt``) is read frozen and the replayed results are silently
    wrong. The check to copy: tests/envs/test_graph_step.py::test_step_keeps_its_state_in_place. On the CPU
    this rebinds state in humanoid-footsteps (its touchdown timers and errors) and jetbot-goal (the
    previous distance its progress reward reads), which stay eager."""

    def _graph_unsafe_reason(self) -> str | None:
        """Why this env's step cannot be replayed as a CUDA graph (``cfg.cuda_graph``), or None.
        A task whose step keeps Python state that changes from step to step says so here."""
        if not type(self).__dict__.get("graph_audited", False):
            return (f"{type(self).__name__}'s step is not audited for replays (graph_audited: it may rebind "
                    "the tensors a graph reads)")
        return None

    def _reset_idx(self, rows: torch.Tensor) -> None:
        """Randomize the envs ``rows`` selects (``ambulo.core.rows``: indices on the CPU, an (N,)
        mask on a GPU) after the engine restored their initial state. Draw ``num_rows(rows)``
        values per quantity and write them through entity writes / ``put_rows``."""

    # -- public API --------------------------------------------------------------
    def reset(self, env_ids: torch.Tensor | None = None) -> torch.Tensor:
        """Reset ``env_ids`` (indices or an (N,) bool mask; all if None); return all observations."""
        if env_ids is None:
            self.obs_buf = self._reset_all()
        else:
            ids = torch.as_tensor(env_ids, device=self.device).reshape(-1)
            mask = ids if ids.dtype == torch.bool else torch.zeros(
                self.num_envs, dtype=torch.bool, device=self.device).index_fill_(0, ids.long(), True)
            self._reset_envs(mask)
            self.obs_buf = self._compute_observations()
        return self.obs_buf

    def use_cuda_graph(self) -> bool:
        """From the next step on, replay the step's device work as one CUDA graph (as
        ``cfg.cuda_graph`` does from the start) if this env runs on CUDA and its task allows it
        (``_graph_unsafe_reason``); return whether it does. For evaluations: at ~100 worlds a step's
        hundreds of small kernels cost more to launch than to run, so a replay is what bounds it."""
        if self._graph is None and self.device.type == "cuda" and self._graph_unsafe_reason() is None:
            self._graph = GraphStep(self)
        return self._graph is not None

    def get_observations(self) -> torch.Tensor:
        """Observations after the last ``reset``/``step``, (N, num_obs) float32."""
        return self.obs_buf

    def get_privileged_observations(self) -> torch.Tensor | None:
        """Critic observations after the last ``reset``/``step``: the clean policy terms and the
        privileged terms, (N, num_privileged_obs) float32, or None."""
        return self._critic_buf

    def step(self, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, dict]:
        """Advance every env by one policy step.

        Args:
          actions: (N, num_actions) finite values.

        Returns:
          obs: (N, num_obs) float32, after resets (a finished env shows its new episode).
          rewards: (N,) float32.
          dones: (N,) bool, terminated or timed out (those envs were reset).
          extras: ``time_outs`` (N,) bool, ``terminated`` (N,) bool, ``terminations`` (the
            (N,) bool mask of each termination term), ``episode`` (means over the episodes
            that ended in the last ``stats_interval_steps`` steps, every that many steps),
            ``observations`` (``{"critic": ...}`` when the task has privileged observations).
        """
        with self._torch_threads():
            return self._step(actions)

    def _step(self, actions):
        actions = self._validate_actions(actions)
        if self._graph is not None:
            out = self._graph.step(actions)
        else:
            out = self._device_step(actions)
        extras: dict = {"time_outs": out.time_outs, "terminated": out.terminated,
                        "terminations": out.terminations}
        if out.final_obs is not None:
            extras["final_obs"] = out.final_obs
        stats = self._stats.publish()  # a Python counter: every stats_interval_steps steps
        if stats is not None:
            extras["episode"] = stats
        if out.critic_obs is not None:
            extras["observations"] = {"critic": out.critic_obs}
        return out.obs, out.rewards, out.dones, extras

    def _device_step(self, actions: torch.Tensor) -> StepOutputs:
        """The step's work on the device, from checked (N, A) float32 ``actions``: what a CUDA
        graph captures (``envs.graph_step``). No host sync and, on a GPU, no Python decision
        on device values; Python state it changes must be the same every step (a replay does
        not rerun Python), persistent tensors change in place."""
        if self.device.type != "cpu":
            actions = self._sanitize_actions(actions)
        self.prev_actions.copy_(self.actions)
        self.actions.copy_(actions.clamp(-self.cfg.action_clip, self.cfg.action_clip))
        self._apply_action(self.actions)
        self._pre_physics()
        diverged = self._simulate().to(self.device) | self._runaway()
        self.episode_length_buf += 1
        self._post_physics()

        terminations = self._get_terminations()
        terminated = diverged.clone()
        for mask in terminations.values():
            terminated |= mask
        time_outs = (self.episode_length_buf >= self.max_episode_length) & ~terminated
        terms = self._get_rewards()
        # one stack (promoting to the widest dtype) and one conversion, not one per term
        weighted = torch.stack([terms[k] for k in self.reward_names], dim=1).float() * self._reward_weights
        # a diverged world's terms describe a broken (or already restored) state: they earn nothing
        weighted = torch.where(diverged[:, None], 0.0, weighted)
        self.episode_sums += weighted
        rewards = weighted.sum(dim=1)

        final_obs = self._compute_observations() if self.return_final_obs else None
        dones = terminated | time_outs
        self._stats.add(dones, terminations, time_outs, diverged)
        self._reset_envs(dones)
        self.obs_buf = self._compute_observations()
        return StepOutputs(obs=self.obs_buf, rewards=rewards, dones=dones, time_outs=time_outs,
                           terminated=terminated, terminations=terminations, final_obs=final_obs,
                           critic_obs=self._critic_buf)

    def close(self) -> None:
        """Release resources (the engine is freed with the env)."""

    # -- internals -----------------------------------------------------------------
    def _runaway(self) -> torch.Tensor:
        """(N,) bool: worlds whose speeds left ``cfg.diverged_speed_bound`` (NaN included: the
        comparison is False for it). A mask on the device: no host sync."""
        bound = self.cfg.diverged_speed_bound
        if bound is None:
            return torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        return ~(self.engine.field("qvel").abs() <= bound).all(dim=1).to(self.device)

    def _torch_threads(self):
        if self.device.type != "cpu" or self.cfg.torch_threads <= 0:
            return contextlib.nullcontext()
        return _TorchThreads(self.cfg.torch_threads)

    def _validate_actions(self, actions: torch.Tensor) -> torch.Tensor:
        # by dtype only (free, no sync): a cast to float32 would drop an imaginary part silently
        # and turn a bool mask into 0/1 actions; text would fail deep in torch
        fix = f"pass real numbers of shape ({self.num_envs}, {self.num_actions}) (num_envs, num_actions)"
        check_real_dtype("actions", actions, fix, allow_bool=False)
        if not isinstance(actions, torch.Tensor):
            actions = check_real_dtype("actions", torch.as_tensor(actions), fix, allow_bool=False)
        expected = (self.num_envs, self.num_actions)
        if tuple(actions.shape) != expected:
            raise ValueError(
                f"actions have shape {tuple(actions.shape)}, expected {expected} "
                f"(num_envs, num_actions); pass one row of {self.num_actions} values per env"
            )
        actions = actions.to(device=self.device, dtype=torch.float32)
        if self.device.type == "cpu":
            # free on the CPU: no device to wait for; NaN and Inf survive a sum, so one
            # reduction tells whether to look closer
            if math.isfinite(float(actions.sum(dtype=torch.float64))):
                return actions
            finite = torch.isfinite(actions)
            if not bool(finite.all()):
                bad = (~finite).any(dim=1).nonzero().squeeze(-1)
                raise ValueError(
                    f"actions contain NaN or Inf in {bad.numel()} envs (first: env {int(bad[0])}); "
                    "check the policy's outputs (e.g. exploding weights) or sanitize with "
                    "torch.nan_to_num before stepping")
            return actions
        return actions

    def _sanitize_actions(self, actions: torch.Tensor) -> torch.Tensor:
        # on a GPU a check would wait for the device: zero bad actions and count them instead
        finite = torch.isfinite(actions)
        self._nonfinite_actions += (~finite).any(dim=1).sum()
        return torch.where(finite, actions, torch.zeros_like(actions))

    def _reset_all(self) -> torch.Tensor:
        self._reset_envs(torch.ones(self.num_envs, dtype=torch.bool, device=self.device))
        return self._compute_observations()

    def _reset_envs(self, mask: torch.Tensor) -> None:
        rows = select_rows(mask)
        if rows is None:
            return
        # one kinematics pass at the end, after the task has written its randomized state
        self.sim.reset(rows, forward=False)
        for buf in (self.episode_length_buf, self.actions, self.prev_actions, self.episode_sums):
            fill_rows(buf, rows, 0)
        self._reset_idx(rows)
        self.engine.forward(rows, kinematics_only=self.cfg.reset_forward == "kinematics")

    def _compute_observations(self) -> torch.Tensor:
        terms = self._policy_terms()
        self._terms_seen = list(terms)
        clean = torch.cat([t.float() for t in terms.values()], dim=1)  # faster than cat-then-convert
        if self.cfg.observation_noise:
            if self._noise_scale is None:  # (num_obs,) half-width per column, from the term sizes
                noise = self.cfg.observation_noise
                self._noise_scale = torch.cat([torch.full((t.shape[1],), noise.get(k, 0.0), device=self.device)
                                               for k, t in terms.items()])
            noise = torch.empty_like(clean).uniform_(-1.0, 1.0, generator=self.generator)
            obs = noise.mul_(self._noise_scale).add_(clean)
        else:
            obs = clean
        privileged = self._privileged_terms()
        self._critic_buf = None if privileged is None else torch.cat(
            [clean, *(t.float() for t in privileged.values())], dim=1)
        return obs

    def _num_rows(self, rows: torch.Tensor | None) -> int:
        return num_rows(rows, self.num_envs)

    def _uniform(self, shape: tuple[int, ...], low, high, dtype=torch.float32) -> torch.Tensor:
        """Uniform samples in [low, high) from the env's generator (``low``/``high`` broadcast).
        Drawn in float64 whatever ``dtype``, so both engines (float64, float32 state) see the
        same random stream from one seed."""
        sample = torch.rand(shape, generator=self.generator, dtype=torch.float64, device=self.device).to(dtype)
        if not isinstance(low, (int, float)) or not isinstance(high, (int, float)):
            low = torch.as_tensor(low, dtype=dtype, device=self.device)
            high = torch.as_tensor(high, dtype=dtype, device=self.device)
        return low + (high - low) * sample


class _TorchThreads:
    """Context: torch's intra-op pool at ``n`` threads (set/restore cost ~0.2 us)."""

    def __init__(self, n: int):
        self.n = n

    def __enter__(self):
        self.previous = torch.get_num_threads()
        if self.previous != self.n:
            torch.set_num_threads(self.n)

    def __exit__(self, *exc):
        if self.previous != self.n:
            torch.set_num_threads(self.previous)


__all__ = ["EnvCfg", "RLEnv"]
