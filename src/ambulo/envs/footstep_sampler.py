"""Plausible footstep plans, drawn per world on the device, one footstep at a time.

The humanoid-footsteps task needs, in each of thousands of worlds, the kind of plan the footstep
planner (``nav.footsteps``) gives the navigator: alternating feet, each step within the walker's
limits (``FootstepPlannerCfg``: step length, width and yaw change, soles clear of each other),
straight stretches, turns, in-place and backward steps, changing step lengths and widths. The
planner searches a map on the host; here no map constrains the steps, so a sampler stands in for
it: a plan is a chain of *segments* of a few steps, each with a nominal step length, width and
yaw change (a straight walk, a turn, stepping in place), plus per-step jitter.

Poses follow the planner's format (``FootstepPlan.footsteps_xyyaw_w``, ``foot_sides``): a
footstep is (x m, y m, yaw rad) of the sole centre in the world frame and a side, +1 left, -1
right; a step puts the swing foot at (length, width on its own side, yaw change) in the stance
foot's frame (``nav.footstep_lattice``). Everything is (B, ...) tensors; no host sync.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from ambulo.nav.footsteps import FootstepPlannerCfg, humanoid_footstep_cfg
from ambulo.utils.validate import Checked, rule

from .commands import wrap_to_pi

LIMIT_MARGIN = 1e-4
"""Steps keep this far inside every limit (m or rad): float32 world poses, read back in a stance
foot's frame, are off by ~1e-7, and a step drawn on a limit must still pass the planner's check."""


@dataclass(kw_only=True)
class FootstepSamplerCfg(Checked):
    """How plans are drawn; every step stays within ``limits`` (the planner's walker limits)."""

    limits: FootstepPlannerCfg = field(default_factory=humanoid_footstep_cfg)
    """The walker's step limits and sole size, the footstep planner's (``humanoid_footstep_cfg``)."""
    segment_steps: tuple[int, int] = (2, 8)
    """Steps per segment, both ends included."""
    segment_length_range_m: tuple[float, float] = (-0.05, 0.25)
    """Nominal step length of a segment (a draw below 0 is a backward walk, near 0 in place), m."""
    segment_width_range_m: tuple[float, float] = (0.14, 0.26)
    """Nominal step width of a segment, m."""
    turn_fraction: float = 0.4
    """Share of segments that turn (the rest walk straight)."""
    turn_yaw_range_rad: tuple[float, float] = field(default=(0.1, 0.3), metadata=rule(pair=True))
    """|yaw change| per step of a turning segment (its sign drawn too), rad."""
    jitter_length_m: float = field(default=0.03, metadata=rule(minimum=0.0))
    """Each step's length differs from its segment's by up to +-this, m."""
    jitter_width_m: float = field(default=0.02, metadata=rule(minimum=0.0))
    jitter_yaw_rad: float = field(default=0.05, metadata=rule(minimum=0.0))


def compose_xyyaw(pose: torch.Tensor, rel: torch.Tensor) -> torch.Tensor:
    """(..., 3) world pose of ``rel`` (..., 3) given in the frame ``pose`` (..., 3) (x m, y m,
    yaw rad); ``nav.footstep_lattice.compose`` on tensors."""
    c, s = torch.cos(pose[..., 2]), torch.sin(pose[..., 2])
    return torch.stack([pose[..., 0] + c * rel[..., 0] - s * rel[..., 1],
                        pose[..., 1] + s * rel[..., 0] + c * rel[..., 1],
                        wrap_to_pi(pose[..., 2] + rel[..., 2])], dim=-1)


def relative_xyyaw(pose: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """(..., 3) ``other`` expressed in the frame ``pose``; ``compose_xyyaw``'s inverse."""
    c, s = torch.cos(pose[..., 2]), torch.sin(pose[..., 2])
    dx, dy = other[..., 0] - pose[..., 0], other[..., 1] - pose[..., 1]
    return torch.stack([c * dx + s * dy, -s * dx + c * dy, wrap_to_pi(other[..., 2] - pose[..., 2])], dim=-1)


class FootstepSampler:
    """Draws segments and the footstep after a stance foot; ``cfg`` and a generator, no state.

    A segment is a (B, 4) float tensor: nominal length m, width m, yaw change rad, steps left.
    """

    def __init__(self, cfg: FootstepSamplerCfg, generator: torch.Generator, device: torch.device):
        self.cfg, self.gen, self.device = cfg, generator, device
        lim, margin = cfg.limits, LIMIT_MARGIN
        self.length_range_m = (lim.step_length_range_m[0] + margin, lim.step_length_range_m[1] - margin)
        self.max_width_m = lim.step_width_range_m[1] - margin
        self.max_yaw_rad = lim.max_step_yaw_rad - margin
        # the swing sole clears the stance sole (by ``min_foot_gap_m``) whatever the length when its
        # centre is farther sideways than the stance sole's half width plus the rotated swing
        # sole's half extent across: the separating axis y of ``footstep_lattice.rectangles_overlap``
        self._half_m = (lim.foot_size_m[0] / 2 + lim.min_foot_gap_m / 2, lim.foot_size_m[1] / 2 + lim.min_foot_gap_m / 2)
        self.min_width_m = lim.step_width_range_m[0] + margin

    def clear_width_m(self, yaw_change_rad: torch.Tensor) -> torch.Tensor:
        """(B,) smallest step width (m) at which soles at a yaw change of ``yaw_change_rad`` (B,)
        cannot touch, at any length, and the walker's smallest width."""
        hx, hy = self._half_m
        a = yaw_change_rad.abs()
        clear = hy + hx * torch.sin(a) + hy * torch.cos(a) + LIMIT_MARGIN
        return torch.clamp(clear, min=self.min_width_m)

    def _uniform(self, shape, low, high) -> torch.Tensor:
        u = torch.rand(shape, generator=self.gen, device=self.device)
        return low + (high - low) * u

    def draw_segments(self, num: int) -> torch.Tensor:
        """(num, 4) fresh segments (the class docstring's columns)."""
        cfg = self.cfg
        u = torch.rand(num, 5, generator=self.gen, device=self.device)
        lo, hi = cfg.segment_length_range_m
        length = lo + (hi - lo) * u[:, 0]
        lo, hi = cfg.segment_width_range_m
        width = lo + (hi - lo) * u[:, 1]
        lo, hi = cfg.turn_yaw_range_rad
        turn = (lo + (hi - lo) * u[:, 2]) * torch.where(u[:, 3] < 0.5, -1.0, 1.0)
        yaw = torch.where(u[:, 4] < cfg.turn_fraction, turn, torch.zeros_like(turn))
        steps = torch.randint(cfg.segment_steps[0], cfg.segment_steps[1] + 1, (num,), generator=self.gen,
                              device=self.device).float()
        return torch.stack([length, width, yaw, steps], dim=-1)

    def next_footstep(self, stance_xyyaw_w: torch.Tensor, stance_side: torch.Tensor,
                      segment: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The footstep of the other foot after stance feet (B, 3) of sides (B,) (+1 left, -1
        right), world frame, and the segments after it: (B, 3) pose, (B, 4) segments (a segment
        that ran out is replaced by a fresh one, drawn for every row and kept where needed)."""
        cfg, b = self.cfg, stance_xyyaw_w.shape[0]
        jitter = self._uniform((b, 3), -1.0, 1.0) * torch.tensor(
            [cfg.jitter_length_m, cfg.jitter_width_m, cfg.jitter_yaw_rad], device=self.device)
        yaw = (segment[:, 2] + jitter[:, 2]).clamp(-self.max_yaw_rad, self.max_yaw_rad)
        length = (segment[:, 0] + jitter[:, 0]).clamp(*self.length_range_m)
        width = torch.minimum(torch.maximum(segment[:, 1] + jitter[:, 1], self.clear_width_m(yaw)),
                              torch.full_like(yaw, self.max_width_m))
        # the swing foot lands on its own side: left of a right stance foot (dy > 0) and v.v.
        rel = torch.stack([length, -stance_side.to(width.dtype) * width, yaw], dim=-1)
        pose = compose_xyyaw(stance_xyyaw_w, rel.to(stance_xyyaw_w.dtype))
        left = segment[:, 3:] - 1.0
        fresh = self.draw_segments(b)
        segment = torch.where(left > 0.5, torch.cat([segment[:, :3], left], dim=-1), fresh)
        return pose, segment


def start_feet_xyyaw_w(base_xyyaw_w: torch.Tensor, sole_x_m: float, stance_width_m: float) -> torch.Tensor:
    """(B, 2, 3) left and right sole poses of a robot standing at base poses (B, 3), its soles
    ``sole_x_m`` ahead of the base and ``stance_width_m`` apart, parallel to its heading."""
    b = base_xyyaw_w.shape[0]
    rel = base_xyyaw_w.new_zeros(b, 2, 3)
    rel[..., 0] = sole_x_m
    rel[:, 0, 1], rel[:, 1, 1] = stance_width_m / 2, -stance_width_m / 2
    return compose_xyyaw(base_xyyaw_w[:, None].expand(b, 2, 3), rel)


__all__ = ["FootstepSampler", "FootstepSamplerCfg", "compose_xyyaw", "relative_xyyaw", "start_feet_xyyaw_w"]
