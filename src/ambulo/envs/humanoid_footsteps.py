"""humanoid-footsteps: the 21-DoF humanoid puts its feet on the next two footsteps of a plan.

The command is what the footstep planner gives the navigator (``nav.footsteps.FootstepPlan``:
sole poses (x, y, yaw) and sides, alternating feet), two footsteps at a time: the target of the
swing foot and the one after it. The actor sees them, in place of humanoid-walk's velocity
command, in the base's heading frame: per target x, y (m), cos and sin of its yaw relative to the
heading, and its side (+1 left, -1 right): 10 values. Plans are drawn per world on the device
(``envs.footstep_sampler``: straight walks, turns, in-place and backward steps, changing lengths
and widths, all within the planner's walker limits) and extended one footstep per touchdown, so a
plan never runs out. On flat ground a target's height (``targets_z_m``) is 0; a terrain variant
(``humanoid_footsteps_stairs``) overrides the hooks ``_next_footstep``, ``_footstep_z_m`` and
``_spawn``.

A *touchdown* is the swing foot (the side of the first target) landing after at least
``min_air_time_s`` in the air, from a take-off after the plan's last advance
(``footstep_gait.swing_touchdown``: a foot already in the air when the plan moved on, as the
stance foot is after a flight phase, is not stepping to the new target). It scores the
placement (sole centre to target distance, yaw error); when it landed within ``advance_radius_m`` of its target the targets advance (the second
becomes the first, a new footstep is drawn after it), else the same foot steps again.
The placement kernels reward the touchdown; ``swing_progress`` rewards the swing foot closing on
its target (a potential: moving away and back earns nothing); ``heading`` keeps the body facing
the targets' mean yaw; ``step_air_time`` pays humanoid-walk's air-time term on a foot's time in
the air while the other foot stood (``footstep_gait.support_air_time``): flight earns nothing;
humanoid-walk's stability terms stay. An episode fails when the robot
falls or loses the plan (its next target more than ``max_target_distance_m`` from the base).

Evaluation: ``placement_error_m`` is each world's latest touchdown error (before the first, the
start distance of the swing foot to its target), held until the next; ``ambulo eval`` averages
step metrics over every step, so it reports the mean of that and ``placement_miss_5cm``, the share
of steps whose latest touchdown missed by more than 5 cm. ``places_feet`` asks that share to be at
most one half (the median of the held errors, each touchdown weighted by how long it is held, at
most 5 cm: the issue's bar), no more than 5 % falls or lost plans and at least 0.5 touchdowns per
second. ``benchmarks/footstep_placement.py`` reports the plain median of the touchdowns.
Everything else (physics, actions, pushes, randomization, transfer) is humanoid-walk's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ambulo.core.rows import fill_rows, num_rows, put_rows, select_rows, take_rows
from ambulo.robots import humanoid
from ambulo.utils.validate import rule

from ..utils.math import yaw_from_quat
from . import rewards
from .commands import VelocityCommandCfg, wrap_to_pi
from .footstep_gait import support_air_time, swing_touchdown
from .footstep_sampler import FootstepSampler, FootstepSamplerCfg, relative_xyyaw, start_feet_xyyaw_w
from .humanoid_walk import HumanoidWalkCfg, HumanoidWalkEnv, as_play, humanoid_walk_cfg, humanoid_walk_ppo
from .registry import Criterion, TaskSpec, register

UNUSED_WALK_TERMS = ("track_lin_vel_xy_exp", "track_ang_vel_z_exp", "feet_air_time")
"""humanoid-walk's reward terms about its velocity command, which this task does not have."""


@dataclass(kw_only=True)
class HumanoidFootstepsCfg(HumanoidWalkCfg):
    """humanoid-footsteps settings: humanoid-walk's, the plans' and the placement rewards'."""

    sole_sites: tuple[str, str] = humanoid.SOLE_SITES
    """Left and right sole centres (the footstep frames), in ``feet_bodies``' order."""
    start_sole_x_m: float = field(default=humanoid.SOLE_X_M, metadata=rule(signed=True))
    """The soles stand this far ahead of the base at the initial state, m (the plan's start feet)."""
    start_stance_width_m: float = humanoid.STANCE_WIDTH_M
    """Distance between the soles at the initial state, m."""
    plans: FootstepSamplerCfg = field(default_factory=FootstepSamplerCfg)
    min_air_time_s: float = field(default=0.15, metadata=rule(minimum=0.0))
    """A swing foot landing counts as a touchdown after this long in the air: contact chatter and
    shuffles do not advance the plan (at 0.05 s a policy learned 9 stutter steps a second)."""
    advance_radius_m: float = field(default=0.2, metadata=rule(minimum=0.0))
    """A touchdown farther than this from its target is a miss: scored, but the target stays, so
    the swing foot steps again. The plan waits for the robot instead of running away from it
    (misses that advanced it left the robot behind its plan, lost, within ~3 s)."""
    placement_std_m: float = 0.08
    """Width of the touchdown position kernel exp(-(error / std)^2), m."""
    yaw_std_rad: float = 0.25
    """Width of the touchdown yaw kernel, rad."""
    heading_std_rad: float = 0.5
    """Width of the kernel on the base heading's difference from the targets' mean yaw, rad."""
    max_progress_m_s: float = 1.5
    """``swing_progress`` counts at most this closing speed, m/s (a foot dragged by a fall)."""
    max_target_distance_m: float = 1.0
    """The plan is lost (the episode fails) when the next target is this far from the base, m."""


def humanoid_footsteps_cfg() -> HumanoidFootstepsCfg:
    """humanoid-walk's physics, actions, pushes and randomization, with footstep commands.

    The velocity command stays zero (every env "standing"): humanoid-walk's command machinery
    runs but nothing reads it. Weights per second of simulated time: a touchdown lasts one
    policy step (0.02 s), so its weight 40 pays 0.8 for a perfect placement, about what
    ``swing_progress`` (weight 2) pays for the 0.4 m a swing foot covers in a 0.2 m step.
    ``step_air_time`` is humanoid-walk's ``feet_air_time`` (its ``air_time_threshold_s``) paid at
    every landing, without that term's gate on the velocity command, which is zero here: strides
    earn, shuffles cost (without it a policy learned 9 stutter steps a second). It counts a foot's
    air time only while the other foot stood, so a flight phase earns nothing (the policy of
    session 8 learned one: both feet in the air for >= 0.15 s every step)."""
    walk = humanoid_walk_cfg()
    cfg = HumanoidFootstepsCfg(**{name: getattr(walk, name) for name in walk.__dataclass_fields__})
    cfg.commands = VelocityCommandCfg(standing_fraction=1.0, heading_fraction=0.0)
    cfg.curriculum_start_scale = None
    weights = {k: v for k, v in walk.reward_weights.items() if k not in UNUSED_WALK_TERMS}
    cfg.reward_weights = dict(foot_placement=40.0, foot_yaw=10.0, swing_progress=2.0, heading=0.5, step_air_time=1.0,
                              **weights)
    return cfg


def humanoid_footsteps_play_cfg() -> HumanoidFootstepsCfg:
    return as_play(humanoid_footsteps_cfg())


def _pick(values: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """values[i, index[i]] for (N, F, ...) values and (N,) int64 indices -> (N, ...)."""
    shape = (values.shape[0], 1, *values.shape[2:])
    return values.gather(1, index.view(-1, *([1] * (values.dim() - 1))).expand(shape)).squeeze(1)


class HumanoidFootstepsEnv(HumanoidWalkEnv):
    """Footstep following; see the module docstring.

    Attributes (all (N, ...) on the env's device, float32 unless said):
      targets_xyyaw_w: (N, 2, 3) the next two footsteps, sole centre x, y m and yaw rad, world frame.
      target_sides: (N, 2) their sides, +1 left, -1 right (the first is the swing foot's).
      targets_z_m: (N, 2) the ground height under each target's sole centre, world z, m (0 on flat
        ground; a given plan's ``foot_z_m``; on terrain, ``_footstep_z_m``).
      touchdown: (N,) bool, the swing foot touched down in the last step (``footstep_gait.swing_touchdown``).
      flight_landing: (N,) bool, the swing foot landed in the last step from a take-off before the
        plan's last advance (not a touchdown: not scored, the plan stays).
      since_advance_s: (N,) time since the targets last advanced (or the plan started), s.
      last_support_air_s: (N, 2) per foot, its last flight's time while the other foot stood, s.
      touchdown_error_m, touchdown_yaw_error_rad: (N,) that touchdown's placement errors (0 elsewhere).
      placement_error_m, yaw_error_rad: (N,) the latest touchdown's errors, held.
      steps_taken: (N,) int64 touchdowns this episode.
    """

    cfg: HumanoidFootstepsCfg

    def _setup(self) -> None:
        super()._setup()
        n, dev, cfg = self.num_envs, self.device, self.cfg
        self.sampler = FootstepSampler(cfg.plans, self.generator, dev)
        self.sole_site_ids = torch.tensor([self.robot.names.site_id(s) for s in cfg.sole_sites], device=dev)
        f32 = dict(dtype=torch.float32, device=dev)
        self.targets_xyyaw_w = torch.zeros(n, 2, 3, **f32)
        self.target_sides = torch.ones(n, 2, **f32)
        self.targets_z_m = torch.zeros(n, 2, **f32)
        self._segments = torch.zeros(n, 4, **f32)
        self.touchdown = torch.zeros(n, dtype=torch.bool, device=dev)
        self.flight_landing = torch.zeros(n, dtype=torch.bool, device=dev)
        self.since_advance_s = torch.zeros(n, **f32)
        self._support_air_s = torch.zeros(n, 2, **f32)  # ``footstep_gait.support_air_time``'s timers
        self.last_support_air_s = torch.zeros(n, 2, **f32)
        self.touchdown_error_m = torch.zeros(n, **f32)
        self.touchdown_yaw_error_rad = torch.zeros(n, **f32)
        self.placement_error_m = torch.zeros(n, **f32)
        self.yaw_error_rad = torch.zeros(n, **f32)
        self.steps_taken = torch.zeros(n, dtype=torch.long, device=dev)
        self._swing_distance_m = torch.zeros(n, **f32)
        """(N,) planar distance of the swing sole to its target after the last step, m."""
        self._progress_m = torch.zeros(n, **f32)
        """(N,) how much closer the swing sole came to its target in the last step, m."""
        self._plan_xyyaw_w: torch.Tensor | None = None  # given plans (``follow_plans``), (N, K, 3)
        self._plan_z_m: torch.Tensor | None = None  # their foot heights, (N, K)
        self._plan_rows = torch.zeros(n, dtype=torch.long, device=dev)  # rows of each given plan, 0: none
        self._plan_next = torch.zeros(n, dtype=torch.long, device=dev)  # its row the next new target takes

    # -- plan state ---------------------------------------------------------------------------
    def soles_xyyaw_w(self) -> torch.Tensor:
        """(N, 2, 3) left and right sole centres x, y (m) and yaw (rad), world frame."""
        xy = self.engine.site_xpos[:, self.sole_site_ids, :2]
        yaw = yaw_from_quat(self.robot.data.body_quat_w[:, self.feet_body_ids])
        return torch.cat([xy, yaw[..., None]], dim=-1).float()

    def _swing_index(self) -> torch.Tensor:
        """(N,) int64: 0 when the left foot swings (its target is first), 1 for the right."""
        return (self.target_sides[:, 0] < 0).long()

    def _base_xyyaw_w(self) -> torch.Tensor:
        data = self.robot.data
        return torch.cat([data.root_pos_w[:, :2], data.heading_w[:, None]], dim=-1).float()

    # -- footsteps on the ground: hooks a terrain variant (``humanoid_footsteps_stairs``) overrides
    def _next_footstep(self, stance_xyyaw_w: torch.Tensor, stance_side: torch.Tensor,
                       segments: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The drawn footstep after stance feet (B, 3) of sides (B,): (B, 3) pose, (B,) the ground
        height under it (m) and (B, 4) the segments after it (``FootstepSampler.next_footstep``)."""
        pose, segments = self.sampler.next_footstep(stance_xyyaw_w, stance_side, segments)
        return pose, self._footstep_z_m(pose[:, :2]), segments

    def _footstep_z_m(self, xy_w: torch.Tensor) -> torch.Tensor:
        """(...) ground height (m) under (..., 2) world points: 0, flat ground."""
        return torch.zeros_like(xy_w[..., 0])

    def _spawn(self, rows) -> None:
        """Place the robots ``rows`` selects before their plans are drawn (flat ground: where
        humanoid-walk's reset put them)."""

    def follow_plans(self, footsteps_xyyaw_w: torch.Tensor, foot_sides: torch.Tensor,
                     num_steps: torch.Tensor, foot_z_m: torch.Tensor | None = None) -> torch.Tensor:
        """Follow given footstep plans from now on, in place of the drawn ones; return the
        observations (N, num_obs), recomputed for the new targets.

        ``footsteps_xyyaw_w`` (N, K, 3): each world's plan in the planner's layout
        (``FootstepPlan.footsteps_xyyaw_w``, padded to K rows): rows 0 and 1 the start feet where
        the robot stands (row 0 the first to move), row i >= 2 step i - 1; ``foot_sides`` (N, K)
        their sides (``FootstepPlan.foot_sides``: +1 left, -1 right, alternating); ``num_steps``
        (N,) int: each plan's steps (>= 2); ``foot_z_m`` (N, K) the ground height under each
        footstep (``FootstepPlan.foot_z_m``, m), None: the env's ground (``_footstep_z_m``).
        The targets become rows 2 and 3 and advance through the plan; past its end the sampler
        continues it. ``steps_taken`` restarts at 0, so touchdown k <= num_steps lands on step k.
        A reset ends a world's plan."""
        n = self.num_envs
        if footsteps_xyyaw_w.shape[0] != n or footsteps_xyyaw_w.shape[2] != 3 or footsteps_xyyaw_w.shape[1] < 4:
            raise ValueError(f"footsteps_xyyaw_w has shape {tuple(footsteps_xyyaw_w.shape)}; pass ({n}, K >= 4, 3): "
                             "one plan per world in the planner's layout")
        steps = torch.as_tensor(num_steps, device=self.device).long()
        if bool((steps < 2).any()) or bool((steps + 2 > footsteps_xyyaw_w.shape[1]).any()):
            raise ValueError("num_steps must be >= 2 and fit the plans' rows (K - 2)")
        plans = footsteps_xyyaw_w.to(device=self.device, dtype=torch.float32)
        sides = torch.as_tensor(foot_sides, device=self.device).float()
        if bool((sides[:, 1:] != -sides[:, :-1]).any()):
            raise ValueError("foot_sides must alternate (+1 left, -1 right) along each plan, padding included")
        first_side = sides[:, 2]
        self._plan_xyyaw_w = plans
        self._plan_z_m = (self._footstep_z_m(plans[..., :2]) if foot_z_m is None
                          else torch.as_tensor(foot_z_m, device=self.device, dtype=torch.float32))
        if self._plan_z_m.shape != plans.shape[:2]:
            raise ValueError(f"foot_z_m has shape {tuple(self._plan_z_m.shape)}; pass {tuple(plans.shape[:2])}: "
                             "one height per footstep")
        self.targets_z_m.copy_(self._plan_z_m[:, 2:4])
        self._plan_rows, self._plan_next = steps + 2, torch.full_like(steps, 4)
        self.targets_xyyaw_w.copy_(plans[:, 2:4])
        self.target_sides.copy_(torch.stack([first_side, -first_side], dim=-1))
        self._swing_distance_m = self._swing_to_target_m(self.soles_xyyaw_w())
        self.placement_error_m.copy_(self._swing_distance_m)
        self.steps_taken.zero_()
        self.since_advance_s.zero_()  # the plan starts now: a foot in the air is not stepping to it
        self.obs_buf = self._compute_observations()
        return self.obs_buf

    def _advance(self, rows: torch.Tensor | None) -> None:
        """In the worlds ``rows`` selects (``core.rows``: indices on the CPU, so only touchdowns
        draw; a mask on a GPU): the second target becomes the first, a new one follows it (the
        next row of a given plan, else a drawn footstep)."""
        if rows is None:
            return
        stance, stance_side = take_rows(self.targets_xyyaw_w[:, 1], rows), take_rows(self.target_sides[:, 1], rows)
        new, new_z, segments = self._next_footstep(stance, stance_side, take_rows(self._segments, rows))
        if self._plan_xyyaw_w is not None:
            next_row = take_rows(self._plan_next, rows)
            row = next_row.clamp(max=self._plan_xyyaw_w.shape[1] - 1)
            in_plan = next_row < take_rows(self._plan_rows, rows)
            new = torch.where(in_plan[:, None], _pick(take_rows(self._plan_xyyaw_w, rows), row), new)
            new_z = torch.where(in_plan, _pick(take_rows(self._plan_z_m, rows), row), new_z)
            put_rows(self._plan_next[:, None], slice(None), next_row[:, None] + 1, rows)
        put_rows(self.targets_xyyaw_w.view(self.num_envs, 6), slice(None), torch.cat([stance, new], dim=-1), rows)
        put_rows(self.targets_z_m, slice(None), torch.stack([take_rows(self.targets_z_m[:, 1], rows), new_z], dim=-1),
                 rows)
        put_rows(self.target_sides, slice(None), torch.stack([stance_side, -stance_side], dim=-1), rows)
        put_rows(self._segments, slice(None), segments, rows)
        put_rows(self.steps_taken[:, None], slice(None), take_rows(self.steps_taken, rows)[:, None] + 1, rows)

    def _post_physics(self) -> None:
        super()._post_physics()
        feet = self.feet.data
        self.update_plan(self.soles_xyyaw_w(), feet.first_contact, feet.last_air_time_s)
        self.update_support_air(feet.in_contact, feet.first_contact)

    def update_support_air(self, in_contact: torch.Tensor, first_contact: torch.Tensor) -> None:
        """Advance the single-support air timers given the feet's (N, 2) ``in_contact`` and
        ``first_contact``; the env calls it after every step (a test, with contacts set by hand)."""
        self._support_air_s, landed_s = support_air_time(self._support_air_s, in_contact, first_contact,
                                                         self.step_dt_s)
        self.last_support_air_s = torch.where(first_contact, landed_s, self.last_support_air_s)

    def update_plan(self, soles_xyyaw_w: torch.Tensor, first_contact: torch.Tensor,
                    last_air_time_s: torch.Tensor) -> None:
        """Score touchdowns and advance the targets, given the soles (N, 2, 3) (``soles_xyyaw_w``)
        and the feet's contact sensor's (N, 2) ``first_contact`` and ``last_air_time_s``; the
        env calls it after every step (a test, with contacts set by hand)."""
        cfg, soles = self.cfg, soles_xyyaw_w
        swing = self._swing_index()
        error = relative_xyyaw(self.targets_xyyaw_w[:, 0], _pick(soles, swing))  # sole in the target's frame
        distance = torch.linalg.vector_norm(error[:, :2], dim=-1)
        limit = cfg.max_progress_m_s * self.step_dt_s
        self._progress_m = (self._swing_distance_m - distance).clamp(-limit, limit)
        self.since_advance_s += self.step_dt_s
        touchdown, self.flight_landing = swing_touchdown(_pick(first_contact, swing), _pick(last_air_time_s, swing),
                                                         self.since_advance_s, cfg.min_air_time_s, self.step_dt_s)
        yaw_error = error[:, 2].abs()
        zero = torch.zeros_like(distance)
        self.touchdown = touchdown
        self.touchdown_error_m = torch.where(touchdown, distance, zero)
        self.touchdown_yaw_error_rad = torch.where(touchdown, yaw_error, zero)
        self.placement_error_m = torch.where(touchdown, distance, self.placement_error_m)
        self.yaw_error_rad = torch.where(touchdown, yaw_error, self.yaw_error_rad)
        # only a touchdown on (or near) its target moves the plan on; a miss is scored above
        advanced = touchdown & (distance <= cfg.advance_radius_m)
        self._advance(select_rows(advanced))
        self.since_advance_s = torch.where(advanced, zero, self.since_advance_s)
        # progress counts from here: after a touchdown, towards the new target
        self._swing_distance_m = self._swing_to_target_m(soles)

    def _swing_to_target_m(self, soles_xyyaw_w: torch.Tensor) -> torch.Tensor:
        """(N,) distance from the swing sole (of (N, 2, 3) ``soles_xyyaw_w``) to the next target, m."""
        swing = _pick(soles_xyyaw_w, self._swing_index())
        return torch.linalg.vector_norm(swing[:, :2] - self.targets_xyyaw_w[:, 0, :2], dim=-1)

    # -- RLEnv hooks ----------------------------------------------------------------------------
    def footstep_command(self) -> torch.Tensor:
        """(N, 10) the actor's command: per target x, y (m), cos, sin of the yaw relative to the
        base heading, side (+1 left, -1 right), in the base's heading frame."""
        rel = relative_xyyaw(self._base_xyyaw_w()[:, None].expand(-1, 2, -1), self.targets_xyyaw_w)
        cmd = torch.cat([rel[..., :2], torch.cos(rel[..., 2:]), torch.sin(rel[..., 2:]), self.target_sides[..., None]],
                        dim=-1)
        return cmd.reshape(self.num_envs, 10)

    def _policy_terms(self) -> dict[str, torch.Tensor]:
        # humanoid-walk's terms in their order, the footsteps where its velocity command was
        return {("footsteps" if k == "velocity_commands" else k): (self.footstep_command() if k == "velocity_commands"
                                                                     else v)
                for k, v in super()._policy_terms().items()}

    def _privileged_terms(self) -> dict[str, torch.Tensor]:
        terms = super()._privileged_terms()
        base = self._base_xyyaw_w()[:, None].expand(-1, 2, -1)
        terms["soles_b"] = relative_xyyaw(base, self.soles_xyyaw_w()).reshape(self.num_envs, 6)
        return terms

    def _get_terminations(self) -> dict[str, torch.Tensor]:
        terms = super()._get_terminations()
        base_xy = self.robot.data.root_pos_w[:, :2].float()
        lost = torch.linalg.vector_norm(self.targets_xyyaw_w[:, 0, :2] - base_xy, dim=-1) > self.cfg.max_target_distance_m
        self._fell = self._fell | lost  # the termination penalty covers a lost plan too
        return {**terms, "lost_plan": lost}

    def _get_rewards(self) -> dict[str, torch.Tensor]:
        cfg = self.cfg
        terms = {k: v for k, v in super()._get_rewards().items() if k not in UNUSED_WALK_TERMS}
        yaw = self.targets_xyyaw_w[..., 2]
        mean_yaw = torch.atan2(torch.sin(yaw).sum(dim=1), torch.cos(yaw).sum(dim=1))
        heading_error = wrap_to_pi(mean_yaw - self.robot.data.heading_w.float())
        touchdown = self.touchdown.float()
        feet = self.feet.data
        always_stepping = torch.ones(self.num_envs, 1, device=self.device)  # passes feet_air_time's command gate
        return {
            **terms,
            "foot_placement": touchdown * torch.exp(-torch.square(self.touchdown_error_m / cfg.placement_std_m)),
            "foot_yaw": touchdown * torch.exp(-torch.square(self.touchdown_yaw_error_rad / cfg.yaw_std_rad)),
            "swing_progress": self._progress_m / self.step_dt_s,
            "heading": torch.exp(-torch.square(heading_error / cfg.heading_std_rad)),
            "step_air_time": rewards.feet_air_time(self.last_support_air_s, feet.first_contact,
                                                   cfg.air_time_threshold_s, always_stepping),
        }

    def _reset_idx(self, rows: torch.Tensor) -> None:
        super()._reset_idx(rows)  # the root's yaw and the joints are drawn there
        self._spawn(rows)
        cfg, n = self.cfg, num_rows(rows, self.num_envs)
        feet = start_feet_xyyaw_w(take_rows(self._base_xyyaw_w(), rows), cfg.start_sole_x_m, cfg.start_stance_width_m)
        # (n,) side of the first foot to move, +1 left
        first = torch.where(torch.rand(n, generator=self.generator, device=self.device) < 0.5, 1.0, -1.0)
        left_first = (first > 0)[:, None]
        swing_start, stance = torch.where(left_first, feet[:, 0], feet[:, 1]), torch.where(left_first, feet[:, 1], feet[:, 0])
        segments = self.sampler.draw_segments(n)
        target0, z0, segments = self._next_footstep(stance, -first, segments)
        target1, z1, segments = self._next_footstep(target0, first, segments)
        put_rows(self.targets_xyyaw_w.view(self.num_envs, 6), slice(None), torch.cat([target0, target1], dim=-1), rows)
        put_rows(self.targets_z_m, slice(None), torch.stack([z0, z1], dim=-1), rows)
        put_rows(self.target_sides, slice(None), torch.stack([first, -first], dim=-1), rows)
        put_rows(self._segments, slice(None), segments, rows)
        start = relative_xyyaw(target0, swing_start)
        distance = torch.linalg.vector_norm(start[:, :2], dim=-1, keepdim=True)
        for buf, value in ((self._swing_distance_m, distance), (self.placement_error_m, distance),
                           (self.yaw_error_rad, start[:, 2:].abs())):
            put_rows(buf[:, None], slice(None), value, rows)
        for buf in (self.touchdown, self.flight_landing, self.touchdown_error_m, self.touchdown_yaw_error_rad,
                    self._progress_m, self.steps_taken, self._plan_rows, self.since_advance_s, self._support_air_s,
                    self.last_support_air_s):
            fill_rows(buf, rows, 0)


PLACEMENT_BAR_M = 0.05
"""The issue's bar on the median foot placement error, m."""

PLACES_FEET = Criterion("places_feet", max_values={"fall_rate": 0.05, "mean_placement_miss_5cm": 0.5},
                        min_values={"mean_touchdowns_per_s": 0.5})
"""Feet on the footsteps (module docstring: the median held touchdown error <= 5 cm), no more
than 5 % falls or lost plans, and stepping (at least one touchdown every 2 s)."""


def humanoid_footsteps_metrics(env: HumanoidFootstepsEnv) -> dict[str, torch.Tensor]:
    return {"placement_error_m": env.placement_error_m,
            "placement_miss_5cm": (env.placement_error_m > PLACEMENT_BAR_M).float(),
            "yaw_error_rad": env.yaw_error_rad, "touchdowns_per_s": env.touchdown.float() / env.step_dt_s}


register(TaskSpec(
    name="humanoid-footsteps",
    env_cls=HumanoidFootstepsEnv,
    cfg_fn=humanoid_footsteps_cfg,
    play_cfg_fn=humanoid_footsteps_play_cfg,
    ppo_cfg_fn=humanoid_walk_ppo,
    description="21-DoF humanoid places its feet on the next two footsteps of a plan (the footstep planner's "
                "format), drawn per world",
    step_metrics=humanoid_footsteps_metrics,
    criteria=(PLACES_FEET,),
))

__all__ = ["HumanoidFootstepsCfg", "HumanoidFootstepsEnv", "PLACEMENT_BAR_M", "PLACES_FEET", "humanoid_footsteps_cfg",
           "humanoid_footsteps_play_cfg"]
