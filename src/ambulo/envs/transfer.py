"""Randomization for sim-to-real transfer: what a real robot has that the model does not.

Per world, on the engine's device, through the one randomization layer (``core.randomize``):

- at start (Isaac Lab's "startup" events): PD gains (``kp``, ``kd`` scales per joint), motor
  strength (a torque scale per joint), joint friction (Coulomb ``frictionloss`` added, N m) and
  armature (reflected rotor inertia, scaled), centre-of-mass offsets of chosen bodies (in a +-c cube or a given box, a fixed corner included);
- per episode, at each reset: action latency (0-20 ms: the joint targets a world's physics sees
  lag the policy's by a whole number of physics steps) and observation delay (the actor reads
  observations a whole number of policy steps old; the critic reads current ones).

The latency acts inside the policy step: with 5 ms physics and a 20 ms policy step, a world
with 10 ms latency runs its first two physics steps on the previous targets and its last two on
the new ones, so the engine steps one physics step at a time while any latency is possible.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from ambulo.core import randomize
from ambulo.core.rows import num_rows, put_rows, select_rows, take_rows
from ambulo.utils.validate import Checked, rule

from .delay import DelayBuffer

PLAY_KEEPS = "play_keeps"
"""Field metadata key: a task config's ``transfer`` field (and a rough task's ``curriculum``,
humanoid-footsteps-stairs' ``levels``) carries ``metadata={PLAY_KEEPS: True}``: a training-only
setting that play and evaluation envs keep at the play variant's value whatever the run trained
with (``rl.runs.play_overrides``), also where the training default equals it."""


@dataclass(kw_only=True)
class TransferCfg(Checked):
    """Transfer randomization ranges; None turns a term off."""

    kp_scale_range: tuple[float, float] | None = None
    """Factor on each joint's stiffness kp, e.g. (0.8, 1.2) for +-20 %."""
    kd_scale_range: tuple[float, float] | None = None
    """Factor on each joint's damping kd."""
    motor_strength_range: tuple[float, float] | None = None
    """Factor on each joint's whole torque (gains and force limit), e.g. (0.9, 1.1)."""
    joint_friction_range_n_m: tuple[float, float] | None = None
    """Coulomb friction added to each joint (MuJoCo ``frictionloss``), N m."""
    armature_scale_range: tuple[float, float] | None = None
    """Factor on each joint's armature (rotor inertia)."""
    com_offset_m: float | None = None
    """Each of ``com_bodies``' centres of mass moves by up to +-this along x, y and z, m."""
    com_offset_box_m: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """((x, y, z) low, (x, y, z) high): each of ``com_bodies``' centres of mass moves by a draw in
    this box, m; low = high fixes the offset (a corner of the +-3 cm cube, for the robustness
    table's corner rows). Exclusive with ``com_offset_m``, its symmetric shorthand."""
    com_bodies: tuple[str, ...] = ("pelvis", "torso")
    action_latency_range_s: tuple[float, float] | None = field(default=None, metadata=rule(minimum=0.0))
    """Delay between the policy's action and the drives, s, drawn per episode and rounded to
    whole physics steps (0-20 ms is 0-4 steps of 5 ms)."""
    observation_delay_range_steps: tuple[int, int] | None = None
    """Policy steps the actor's observations lag by, drawn per episode (both ends included)."""

    def __post_init__(self):
        box = self.com_offset_box_m
        if box is not None and self.com_offset_m is not None:
            raise ValueError("TransferCfg: set com_offset_m (+-c on every axis) or com_offset_box_m, not both")
        if box is not None and any(lo > hi for lo, hi in zip(*box)):
            raise ValueError(f"TransferCfg.com_offset_box_m is {box}: each low must be <= its high; "
                             "pass ((x, y, z) low, (x, y, z) high) in m")
        super().__post_init__()

    def com_offset_bounds_m(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """The (low, high) (x, y, z) box the CoM offsets are drawn from, m; None: no offset."""
        if self.com_offset_m is not None:
            c = self.com_offset_m
            return (-c, -c, -c), (c, c, c)
        return self.com_offset_box_m


def transfer_cfg_wide() -> TransferCfg:
    """The issue's robustness ranges: gains +-20 %, strength +-10 %, joint friction up to 0.5 N m,
    armature +-20 %, CoM +-3 cm, 0-20 ms action latency, 0-1 policy step of observation delay."""
    return TransferCfg(kp_scale_range=(0.8, 1.2), kd_scale_range=(0.8, 1.2), motor_strength_range=(0.9, 1.1),
                       joint_friction_range_n_m=(0.0, 0.5), armature_scale_range=(0.8, 1.2), com_offset_m=0.03,
                       action_latency_range_s=(0.0, 0.02), observation_delay_range_steps=(0, 1))


def transfer_corners() -> dict[str, TransferCfg]:
    """The issue's three terms (gains, action latency, CoM; issue 30: "walks with gains +-20 %,
    0-20 ms latency and CoM +-3 cm") at the corners of ``transfer_cfg_wide``'s ranges, 16 fixed
    conditions by name: every joint's kp and kd both at the low or high scale, the latency at
    its low or high end, the pelvis and torso CoM at (+-c, +-c, +c) (z up: a raised CoM is the
    harder one; the lowered half would double the count for the easier side). The robustness
    table's corner rows (``benchmarks/robustness.py --set corners``) and humanoid-walk-robust's
    evaluation blocks, one definition. Names read like ``gains0.8_lat20ms_com-3+3+3cm``."""
    wide = transfer_cfg_wide()
    c = wide.com_offset_m
    corners = {}
    for gain in wide.kp_scale_range:
        for latency_s in wide.action_latency_range_s:
            for x, y in itertools.product((-c, c), repeat=2):
                com = (x, y, c)
                name = f"gains{gain:g}_lat{latency_s * 1e3:.0f}ms_com" + "".join(f"{v * 100:+.0f}" for v in com) + "cm"
                corners[name] = TransferCfg(kp_scale_range=(gain, gain), kd_scale_range=(gain, gain),
                                            action_latency_range_s=(latency_s, latency_s),
                                            com_offset_box_m=(com, com))
    return corners


class TransferRandomization:
    """The terms of a ``TransferCfg`` on one env: startup writes, per-episode delays, the delay lines.

    The env calls ``startup()`` at its first reset, ``reset(rows)`` from every reset,
    ``simulate(targets)`` in place of stepping the engine, and ``observe(obs)`` on the actor's
    observations.
    """

    def __init__(self, cfg: TransferCfg, env, blocks: Sequence[TransferCfg] = ()):
        """``blocks``: evaluation layouts (the env's ``transfer_blocks``): the worlds split into
        ``len(blocks)`` contiguous equal blocks, block b under ``blocks[b]`` instead of ``cfg``;
        empty: every world under ``cfg``."""
        self.cfg, self.env = cfg, env
        n, dev = env.num_envs, env.device
        if blocks and n % len(blocks):
            raise ValueError(f"transfer_blocks: {len(blocks)} blocks do not split {n} worlds evenly; "
                             f"give num_envs a multiple of {len(blocks)}")
        per = n // max(len(blocks), 1)
        self.blocks: list[tuple[torch.Tensor | None, TransferCfg]] = (
            [(None, cfg)] if not blocks else
            [(torch.arange(b * per, (b + 1) * per, device=dev), block) for b, block in enumerate(blocks)])
        """(world ids or None for all, the ``TransferCfg`` they run under), one per block."""
        dt = env.physics_dt_s
        latency = [tuple(int(round(t / dt)) for t in (c.action_latency_range_s or (0.0, 0.0))) for _, c in self.blocks]
        obs_delay = [tuple(c.observation_delay_range_steps or (0, 0)) for _, c in self.blocks]
        self.latency_steps = (min(lo for lo, _ in latency), max(hi for _, hi in latency))
        """(low, high) action latency in physics steps (over every block)."""
        self.obs_delay_steps = (min(lo for lo, _ in obs_delay), max(hi for _, hi in obs_delay))
        self._bounds = None if not blocks else {
            name: tuple(torch.tensor(ends, device=dev).repeat_interleave(per) for ends in zip(*pairs))
            for name, pairs in (("latency", latency), ("obs_delay", obs_delay))}
        """Per-world (N,) low and high delays by term, in block mode (else the ranges above hold)."""
        self.action_delay = DelayBuffer(self.latency_steps[1], n, (env.robot.num_joints,), device=dev,
                                        dtype=env.engine.dtype) if self.latency_steps[1] > 0 else None
        self.obs_delay: DelayBuffer | None = None  # sized by the first observation
        self._obs_delay = torch.zeros(n, dtype=torch.long, device=dev)
        """(N,) policy steps each world's actor observations lag by (the obs buffer's ``delay``)."""
        self.factors: dict[str, torch.Tensor] = {}
        """The startup draws by term name, (N, k) each (for tests and logs); in block mode the
        rows of a block without the term are NaN."""
        self.started = False
        self._observed_this_step = False

    def startup(self) -> None:
        """Draw and write the start terms, once. Gains scale what the drives hold now (world 0's,
        the same in every world before this): a task may set its gains after compiling (g1-walk
        from its URDF), so the env calls this at its first reset, after its whole setup. Blocks
        are written last to first, so world 0 still holds the nominal gains the others read."""
        if self.started:
            return
        self.started = True
        const = False
        for rows, cfg in reversed(self.blocks):
            const |= self._start_terms(cfg, rows)
        if const:
            self.env.engine.set_const()

    def _start_terms(self, cfg: TransferCfg, rows: torch.Tensor | None) -> bool:
        """Write ``cfg``'s start terms for the worlds ``rows`` (None: all); whether derived model
        constants need recomputing (``set_const``)."""
        env, gen = self.env, self.env.generator
        robot = env.robot
        uniform = randomize.uniform
        drawn = dict(randomize.drive_gains(
            robot, gen, kp_scale=None if cfg.kp_scale_range is None else uniform(*cfg.kp_scale_range),
            kd_scale=None if cfg.kd_scale_range is None else uniform(*cfg.kd_scale_range),
            strength=None if cfg.motor_strength_range is None else uniform(*cfg.motor_strength_range),
            rows=rows, nominal_world=0))
        if cfg.joint_friction_range_n_m is not None:
            drawn["joint_friction_n_m"] = randomize.joint_dof_field(
                robot, "dof_frictionloss", uniform(*cfg.joint_friction_range_n_m), gen, rows=rows, operation="add")
        if cfg.armature_scale_range is not None:
            drawn["armature_scale"] = randomize.joint_dof_field(
                robot, "dof_armature", uniform(*cfg.armature_scale_range), gen, rows=rows, operation="scale")
        com_box = cfg.com_offset_bounds_m()
        if com_box is not None:
            drawn["com_w"] = randomize.body_com_offset(robot, uniform(*com_box), gen, rows=rows,
                                                       bodies=list(cfg.com_bodies))
        for name, values in drawn.items():
            if rows is None:
                self.factors[name] = values
                continue
            if name not in self.factors:
                self.factors[name] = torch.full((env.num_envs, *values.shape[1:]), torch.nan, dtype=values.dtype,
                                                device=values.device)
            self.factors[name][rows.to(values.device)] = values
        return com_box is not None or cfg.armature_scale_range is not None

    def reset(self, rows: torch.Tensor | None) -> None:
        """Draw the reset worlds' latency and observation delay for their new episode."""
        if self.action_delay is not None:
            put_rows(self.action_delay.delay[:, None], slice(None), self._draw("latency", self.latency_steps, rows),
                     rows)
        if self.obs_delay_steps[1] > 0:
            put_rows(self._obs_delay[:, None], slice(None), self._draw("obs_delay", self.obs_delay_steps, rows), rows)

    def _draw(self, term: str, bounds: tuple[int, int], rows: torch.Tensor | None) -> torch.Tensor:
        """(n, 1) whole delays for the worlds ``rows`` selects, uniform within their (block's) range."""
        env, n = self.env, num_rows(rows, self.env.num_envs)
        if self._bounds is None:
            return torch.randint(bounds[0], bounds[1] + 1, (n, 1), generator=env.generator, device=env.device)
        low, high = (take_rows(ends, rows) for ends in self._bounds[term])
        u = torch.rand(n, generator=env.generator, device=env.device)
        return (low + torch.minimum((u * (high - low + 1)).long(), high - low))[:, None]

    def simulate(self, targets: torch.Tensor, decimation: int) -> torch.Tensor:
        """Step the engine ``decimation`` physics steps driving the joints to ``targets`` (N, J)
        rad, each world's lagging by its latency; return the (N,) diverged mask."""
        env = self.env
        self._observed_this_step = False
        if self.action_delay is None:
            env.robot.set_joint_targets(targets)
            return env.sim.step(decimation)
        diverged = None
        for _ in range(decimation):
            self.action_delay.push(targets)
            env.robot.set_joint_targets(self.action_delay.read())
            step = env.engine.step(1)
            diverged = step if diverged is None else diverged | step
        # the sensors see the whole policy step once, as without latency: updated after every
        # physics step, the feet's contact sensor kept only the last one's touchdowns in
        # first_contact (what feet_air_time pays on) and cost a GPU its kernels four times
        env.sim.update(decimation * env.physics_dt_s)
        return diverged

    def start_episode_targets(self, rows: torch.Tensor | None, targets: torch.Tensor) -> None:
        """A reset world's past targets are its start pose (not the last episode's actions)."""
        if self.action_delay is not None:
            self.action_delay.fill(rows, targets)

    def observe(self, obs: torch.Tensor, fresh: torch.Tensor) -> torch.Tensor:
        """The actor's observations (N, D) ``obs`` delayed per world; ``fresh`` (N,) bool marks
        worlds whose episode just started (their history is filled with ``obs``). One push per
        policy step: observations computed again within a step (the post-reset ones after a
        ``final_obs``, a public ``reset``) replace that step's entry instead of adding one."""
        if self.obs_delay_steps[1] == 0:
            return obs
        if self.obs_delay is None:
            self.obs_delay = DelayBuffer(self.obs_delay_steps[1], obs.shape[0], tuple(obs.shape[1:]),
                                         device=obs.device, dtype=obs.dtype)
            self.obs_delay.delay = self._obs_delay
        if self._observed_this_step:
            self.obs_delay.overwrite_latest(obs)
        else:
            self.obs_delay.push(obs)
            self._observed_this_step = True
        rows = select_rows(fresh)
        if rows is not None:
            self.obs_delay.fill(rows, obs)
        return self.obs_delay.read()


__all__ = ["PLAY_KEEPS", "TransferCfg", "TransferRandomization", "transfer_cfg_wide", "transfer_corners"]
