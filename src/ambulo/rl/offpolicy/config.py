"""OffPolicyCfg: the settings of ``ambulo train --algo fast-sac | fast-td3``, per task.

The recipe is FastTD3's (Seo et al. 2025) and FastSAC's (arXiv 2512.01996): many parallel worlds
feed one replay ring on the device, large batches, a categorical (C51) critic with clipped
double Q, n-step returns, observation normalization and several gradient updates per env step.
An *iteration* is ``num_steps_per_env`` env steps of every world followed by
``updates_per_step * num_steps_per_env`` gradient updates, so ``--eval-every``, checkpoints and
``metrics.csv`` count iterations as they do for PPO.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from ambulo.utils.overrides import replace_dotted
from ambulo.utils.validate import Checked, rule

ALGOS = ("fast-sac", "fast-td3")
"""The off-policy algorithms ``--algo`` takes (``ppo`` is rsl-rl-lib's, in ``rl.train``)."""


@dataclass(kw_only=True)
class OffPolicyCfg(Checked):
    """A parallel-env off-policy actor-critic (see the module docstring)."""

    algo: Literal["fast-sac", "fast-td3"] = "fast-sac"
    num_envs: int = field(default=1024, metadata=rule(minimum=1))
    max_iterations: int = field(default=3000, metadata=rule(minimum=1))
    num_steps_per_env: int = field(default=8, metadata=rule(minimum=1))
    """Env steps of every world per iteration."""
    save_interval: int = field(default=100, metadata=rule(minimum=1))
    """Checkpoint every this many iterations (and at the end)."""
    buffer_steps_per_env: int = field(default=256, metadata=rule(minimum=2))
    """Replay ring length: the last this many steps of every world are kept."""
    batch_size: int = field(default=8192, metadata=rule(minimum=1))
    """Transitions per gradient update, drawn uniformly from the whole ring."""
    updates_per_step: int = field(default=2, metadata=rule(minimum=1))
    """Critic updates per env step of all worlds (FastTD3's ``num_updates``)."""
    learning_starts: int = field(default=8, metadata=rule(minimum=1))
    """Env steps per world collected (with random actions for fast-td3's first steps too)
    before the first update; at least ``n_step`` so every sample has its return."""
    random_steps: int = 0
    """Env steps per world with uniform random actions at the start (exploration seed)."""
    n_step: int = field(default=3, metadata=rule(minimum=1))
    """Steps summed in the return before bootstrapping (truncated at episode ends)."""
    gamma: float = field(default=0.99, metadata=rule(minimum=0.0, maximum=1.0))
    tau: float = field(default=0.1, metadata=rule(minimum=0.0, maximum=1.0, strict=True))
    """Polyak factor of the target critics per update (FastTD3 uses 0.1: large batches)."""
    actor_lr: float = field(default=3.0e-4, metadata=rule(minimum=0.0, strict=True))
    critic_lr: float = field(default=3.0e-4, metadata=rule(minimum=0.0, strict=True))
    weight_decay: float = field(default=0.0, metadata=rule(minimum=0.0))
    max_grad_norm: float = field(default=0.0, metadata=rule(minimum=0.0))
    """Clip gradient norms to this (0: no clipping)."""
    actor_hidden_dims: tuple[int, ...] = (512, 256, 128)
    critic_hidden_dims: tuple[int, ...] = (1024, 512, 256)
    critic_layer_norm: bool = True
    """LayerNorm after each hidden layer of the critics (FastSAC's choice)."""
    num_atoms: int = field(default=101, metadata=rule(minimum=2))
    """Atoms of the categorical return distribution."""
    v_min: float = field(default=-10.0, metadata=rule(signed=True))
    v_max: float = field(default=10.0, metadata=rule(signed=True))
    """Support of the return distribution (the task's rewards set it: returns beyond are clipped)."""
    obs_normalization: bool = True
    """Running mean/std of observations (updated from collected steps, exported with the actor)."""
    policy_delay: int = field(default=2, metadata=rule(minimum=1))
    """Actor (and entropy) updates happen every this many critic updates."""
    # fast-td3
    exploration_noise_std_range: tuple[float, float] = (0.001, 0.4)
    """fast-td3: each world draws its Gaussian action-noise std in this range at every reset
    (FastTD3's mixed noise: some worlds explore, some refine)."""
    noise_hold_steps: int = field(default=1, metadata=rule(minimum=1))
    """Exploration noise is drawn anew every this many env steps per world (and at its reset),
    held between (both algorithms; 1: every step). Noise drawn each 20 ms step averages out in the
    legs' dynamics before it moves the robot; held for several steps it is a push in one direction
    that can take a robot up a step it would not otherwise try (gSDE's consistent exploration,
    which made SAC climb Isaac Lab's rough pyramids in A. Raffin's 2025 study)."""
    target_noise_std: float = field(default=0.001, metadata=rule(minimum=0.0))
    """fast-td3: target policy smoothing noise."""
    target_noise_clip: float = field(default=0.5, metadata=rule(minimum=0.0))
    # fast-sac
    init_alpha: float = field(default=0.001, metadata=rule(minimum=0.0, strict=True))
    """fast-sac: initial entropy temperature (small: large batches learn fast, FastSAC)."""
    target_entropy_per_action: float = field(default=0.0, metadata=rule(signed=True))
    """fast-sac: the temperature is tuned so the entropy of the actions stays near this x
    num_actions, nats, in action units: the same noise on the joints whatever the bounds (the tanh
    output's entropy is this less each bound's log). 0 is a uniform spread over a range of 1 per
    action; log 2 (0.693, the walking tasks') that of the tanh output at bound 2."""
    log_std_range: tuple[float, float] = (-5.0, 0.0)
    """fast-sac: the actor's log std is squashed into this range."""
    action_bound: float = field(default=1.0, metadata=rule(minimum=0.0, strict=True))
    """Actions are ``action_bound * tanh(...)``: the task's action units."""
    joint_limit_bounds: bool = False
    """Each action its own bound, the env's ``action_bounds()`` (the joint's farther limit from the
    default pose, in action units), in place of ``action_bound`` (FastSAC's joint-limit-aware
    bounds). One bound that suits flat ground (2.0: 0.5 rad) cannot climb: humanoid-rough's PPO
    walker asks its knees for 3.6 on 0.15 m stairs (99th percentile, CPU engine), and a FastSAC
    policy pinned at its bound saturates the tanh, so its entropy estimate falls and the tuned
    temperature widens the std (session 15's rough run: std 0.21 -> 0.37, falls 0.04 -> 0.73).
    The entropy target is in action units, so wider bounds do not widen the joints' noise. Before
    that was so, session 17's rough run with these bounds still collapsed (training reward peaked
    at iteration ~300, then fell while the tanh std grew 0.12 -> 0.36: up to 2.9 action units of
    noise on a knee bounded at 8)."""
    symmetry: bool = False
    """Replace the second half of every sampled batch with the left-right mirror images of its
    transitions (observations, actions and next observations reflected, returns kept;
    ``envs.symmetry``): each update learns every gait for both legs, at the same batch size and
    cost. FastSAC's ``use_symmetry`` on humanoids. Walking tasks only (a task whose observations
    have no mirror rule is refused)."""
    cpu_threads: int = 1
    """torch intra-op threads while training on the CPU (0: torch's default). The networks are
    small: more threads add waiting on a busy CPU more than they add speed (an update took 10x
    longer with 2 threads than with 1 on a loaded 2-core machine)."""
    amp: bool = False
    """bfloat16 autocast for the networks on CUDA (ignored on the CPU)."""
    compile: bool = False
    """``torch.compile`` the update on CUDA (ignored on the CPU)."""
    cuda_graph: bool = False
    """Replay each gradient update (replay sample, critic step, actor/alpha step, Polyak) as one
    captured CUDA graph: one launch instead of hundreds (``graphs.UpdateGraphs``). Each update
    kind (critic only; critic + actor) runs 3 eager updates, then is captured once; a resumed run
    captures again. Optimizers become ``capturable``; may be combined with ``compile`` (the
    compiled kernels are captured: the walking recipe's default). A capture that fails raises (no silent
    eager fall back). Ignored on the CPU."""

    overlap_collect: bool = False
    """Run each env step's collection while the updates of the steps before it run, on a second
    CUDA stream (``offpolicy.overlap``): the env's and the networks' kernels, each too small to
    fill a GPU, then share it. The worlds act with a copy of the actor refreshed after every
    step's updates (one step behind the sequential order), the observation normalizers are
    updated between steps, and the updates sample everything but the slot being written, with
    their own generator. On the CPU the same order runs one step after another (what the tests
    check). On an H200 a compiled humanoid-walk iteration took 0.111 s against 0.144 s in order
    (``benchmarks/offpolicy_iteration.py``; the ideal, steps x max(env, updates): 0.097 s). The
    rough tasks' fast-sac default; opt-in on flat ground until a time to walk is measured with it."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.v_max <= self.v_min:
            raise ValueError(f"OffPolicyCfg.v_max {self.v_max} must exceed v_min {self.v_min}")
        if self.learning_starts < self.n_step:
            raise ValueError(f"OffPolicyCfg.learning_starts {self.learning_starts} must be >= n_step "
                             f"{self.n_step}: the first samples need their n-step returns")
        if self.buffer_steps_per_env <= self.n_step:
            raise ValueError(f"OffPolicyCfg.buffer_steps_per_env {self.buffer_steps_per_env} must exceed "
                             f"n_step {self.n_step}")


def _cartpole(algo: str) -> dict[str, Any]:
    """Few worlds, small nets and batches, many updates per transition: solved on an idle CPU
    core in about a minute. Returns reach ~2 (0.02 a step)."""
    return dict(num_envs=16, max_iterations=300, num_steps_per_env=8, save_interval=50,
                buffer_steps_per_env=2048, batch_size=256, updates_per_step=4, learning_starts=16,
                random_steps=16, actor_hidden_dims=(64, 64), critic_hidden_dims=(64, 64), num_atoms=51,
                v_min=-1.0, v_max=3.0, tau=0.02, actor_lr=1.0e-3, critic_lr=1.0e-3, policy_delay=1,
                target_entropy_per_action=-1.0)


def _fast_td3_scale() -> dict[str, Any]:
    """FastTD3's humanoid scale: 1024 worlds, 32k batches, 2 updates a step. Actions up to 2 (0.5 rad
    at humanoid-walk's action_scale 0.25): the shipped PPO walker's |action| has a median of 0.18, a
    99th percentile of 1.51 and a maximum of 1.99 over 8 x 100 steps."""
    return dict(num_envs=1024, max_iterations=20000, num_steps_per_env=8, save_interval=250,
                buffer_steps_per_env=1024, batch_size=32768, updates_per_step=2, learning_starts=8,
                v_min=-10.0, v_max=10.0, action_bound=2.0, amp=True,
                # the tanh output's entropy target 0 that the flat walkers were trained with, restated
                # in action units at bound 2 (the joint-limit bounds of the rough tasks then keep the
                # joints' noise where it was on flat ground, not up to 4x wider)
                target_entropy_per_action=math.log(2.0))


def _sac_recipe() -> dict[str, Any]:
    """FastSAC's humanoid recipe (Amazon FAR's holosoma defaults, read, not copied) on
    ``_fast_td3_scale``'s worlds and action bounds: batches of 8192 with 8 updates per env step
    (the same samples per env step as 32k x 2, in updates of a quarter the size that each take a
    third of the time on an H200), the actor every 4th update, discount 0.97, Polyak 0.125, critics
    768-384-192 with weight decay, a +-20 return support, left-right mirror augmentation, and the
    updates compiled (``torch.compile``) and replayed as CUDA graphs: on an H200 a compiled graphed
    update took 1.51 ms against 2.64 ms graphed alone (the fusion removes most of the casts and
    LayerNorm/SiLU passes that bound it). The compile (~43 s on that H200) is paid once a machine:
    Inductor caches what it built (``TORCHINDUCTOR_CACHE_DIR``) as Warp caches its kernels."""
    return dict(_fast_td3_scale(), batch_size=8192, updates_per_step=8, policy_delay=4, gamma=0.97,
                tau=0.125, critic_hidden_dims=(768, 384, 192), weight_decay=1.0e-3, v_min=-20.0, v_max=20.0,
                symmetry=True, cuda_graph=True, compile=True)


def _walking(algo: str) -> dict[str, Any]:
    """Flat walking: ``_sac_recipe`` for fast-sac. On one H200 humanoid-walk met ``walks`` on both
    engines in 3.01-3.17 min (median 3.07, 3 seeds, 4.1 M env steps each) uncompiled, and in 2.72
    min compiled (seed 0, 3.17 uncompiled; Inductor's cache warm, Warp's empty), against 5.47 min and 7.4 M with ``_fast_td3_scale`` plus
    graphs and symmetry, and PPO's median 3.50 min (3.00-4.21, 29.5-39.3 M; sessions 22 and 23,
    benchmarks/results/h200-2026-12-01-session23.md). fast-td3 keeps ``_fast_td3_scale``: the
    recipe is SAC's and has not been tried with TD3."""
    if algo != "fast-sac":
        return _fast_td3_scale()
    return _sac_recipe()


def _rough_walking(algo: str) -> dict[str, Any]:
    """Each joint bounded by its limits (``joint_limit_bounds``: stairs and stones need knee and
    ankle targets past 0.5 rad from the default pose). fast-sac: ``_sac_recipe`` with exploration
    noise held 4 steps and collection beside the updates (``overlap_collect``). On one H200
    (session 24, ``--eval-every 100 --eval-async``) humanoid-rough met ``walks_rough`` on both
    engines at 6.05 min and 11.5 M env steps (seed 0), against PPO's median of 13.3 min and
    127.8 M; seed 1 had not by 7.6 min (falls 0.08-0.12, most on stepping stones). Its
    evaluations at equal iterations matched session 23's sequential run (0.213 m/s, falls 0.07-0.08
    at iteration 1199), so the overlap does not cost learning; ``gamma=0.99`` did (0.32-0.38 m/s,
    falls 0.16-0.25 to 9.1 min). Seeds 0, 1, 2 run to 12 min (session 29) met it on both engines
    at 11.16, 5.89 and 4.96 min: a median of 5.89 min and 13.1 M env steps against PPO's 18.0 min and
    157.3 M on both engines. The hardest stepping stones still fall on about a quarter of their
    episodes (these walkers step onto them where PPO's stay on their platform); a quarter of the
    worlds on the stones (``curriculum.kind_weights``) made them fall more (session 28). fast-td3
    keeps ``_fast_td3_scale``."""
    if algo != "fast-sac":
        return dict(_fast_td3_scale(), joint_limit_bounds=True)
    return dict(_sac_recipe(), joint_limit_bounds=True, noise_hold_steps=4, overlap_collect=True)


TASK_DEFAULTS = {"cartpole": _cartpole, "humanoid-walk": _walking, "humanoid-rough": _rough_walking,
                 "g1-walk": _walking, "g1-rough": _rough_walking}
"""Per-task settings over ``OffPolicyCfg``'s defaults, a function of the algorithm (tasks not named take
the defaults)."""


def offpolicy_cfg(task: str, algo: str = "fast-sac", *, num_envs: int | None = None,
                  max_iterations: int | None = None, **overrides: Any) -> OffPolicyCfg:
    """The settings ``ambulo train TASK --algo ALGO`` uses, with ``overrides`` (field names,
    checked against ``OffPolicyCfg``'s types)."""
    if algo not in ALGOS:
        raise ValueError(f"unknown off-policy algorithm {algo!r}; one of {', '.join(ALGOS)}")
    base = OffPolicyCfg(algo=algo, **TASK_DEFAULTS.get(task, lambda algo: {})(algo))
    given = {k: v for k, v in dict(num_envs=num_envs, max_iterations=max_iterations).items() if v is not None}
    return replace_dotted(base, {**given, **overrides}, check_types=True)


def cfg_from_info(info: dict[str, Any]) -> OffPolicyCfg:
    """A run's settings from its ``run.json`` (JSON lists become the declared tuples)."""
    names = {f.name for f in dataclasses.fields(OffPolicyCfg)}
    return replace_dotted(OffPolicyCfg(), {k: v for k, v in info["offpolicy"].items() if k in names},
                          check_types=True)


__all__ = ["ALGOS", "OffPolicyCfg", "TASK_DEFAULTS", "cfg_from_info", "offpolicy_cfg"]
