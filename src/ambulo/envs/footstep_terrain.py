"""Footsteps on terrain: a drawn footstep moves along its step until its sole lies flat on one tread.

The footstep sampler (``footstep_sampler``) draws steps with no map under them; on stairs a sole
drawn across a riser edge asks the robot for a foothold the footstep planner would never give
(``nav.footsteps``: ``max_foothold_spread_m``). ``TreadSnap`` tries, besides the drawn step, a
grid of steps over the walker's whole length and width range (the sampler's limits; the yaw
change stays) and keeps the flat candidate nearest the drawn step (L1 in length and width): one
whose sole, widened by a margin, reads one height at every sample (a tread, not an edge); when
none is flat, the flattest. Small shifts are not enough: a step along the edges (a side step on a
stair) clears them only by moving across, and a stance foot just before an edge can only step
back or over the whole next tread. The target's height
is the ground under the sole's centre. Everything is (B, ...) tensors on the device, no host sync.

Why the margin: the physics hfield ramps a riser over one sample spacing (5 cm on the terrain of
``scenes.terrain``), and a sole that ends right at the ramp's foot stands on its lip.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from ambulo.utils.math import rotate_yaw
from ambulo.utils.validate import Checked, rule

from .footstep_sampler import FootstepSampler, compose_xyyaw, relative_xyyaw


@dataclass(kw_only=True)
class TreadSnapCfg(Checked):
    """How far a drawn step may move to find a tread, and what counts as flat."""

    grid_step_m: float = field(default=0.0125, metadata=rule(minimum=1e-3))
    """Spacing of the tried step lengths and widths, m (29 x 15 candidates on the humanoid's
    -0.10..0.25 m lengths and 0.12..0.30 m widths): finer than the ~1 cm of room a sole at 45
    degrees has on a tread."""
    margin_m: float = field(default=0.0, metadata=rule(minimum=0.0))
    """The sole is tested this much larger on every side, m. 0: a 0.30 m tread of the terrain is
    flat over 0.25 m (its riser ramps over one 5 cm sample), and a sole at 45 degrees to the edges
    spans 0.23 m across them (at most 0.24 m, sqrt(0.22^2 + 0.10^2)): no room for a margin."""
    max_spread_m: float = field(default=0.001, metadata=rule(minimum=0.0))
    """A foothold is flat when its samples' heights differ by at most this, m."""
    samples: tuple[int, int] = (5, 3)
    """Height samples along and across the widened sole; their spacing (5.5 cm along, 5 across at
    the defaults) stays below a tread, so no edge passes between two samples unseen."""


class TreadSnap:
    """``snap(stance, step) -> (step, z)``; see the module docstring.

    ``height_at``: (..., 2) world xy -> (...) ground heights, m (``TerrainHeights.height_at``);
    ``sampler``: the plans' ``FootstepSampler`` (its step limits: a moved step stays within them)."""

    def __init__(self, cfg: TreadSnapCfg, height_at: Callable[[torch.Tensor], torch.Tensor],
                 sampler: FootstepSampler, device: torch.device):
        self.cfg, self.height_at, self.sampler = cfg, height_at, sampler
        lengths, widths = sampler.length_range_m, (sampler.min_width_m, sampler.max_width_m)
        gl, gw = torch.meshgrid(*(torch.linspace(lo, hi, max(int(round((hi - lo) / cfg.grid_step_m)), 1) + 1,
                                                 device=device) for lo, hi in (lengths, widths)), indexing="ij")
        self.grid_m = torch.stack([gl.reshape(-1), gw.reshape(-1)], dim=-1)
        """(G, 2) tried step lengths and widths (the swing foot's side of the stance foot), m."""
        foot_size_m = sampler.cfg.limits.foot_size_m
        half_x, half_y = foot_size_m[0] / 2 + cfg.margin_m, foot_size_m[1] / 2 + cfg.margin_m
        gx, gy = torch.meshgrid(torch.linspace(-half_x, half_x, cfg.samples[0], device=device),
                                torch.linspace(-half_y, half_y, cfg.samples[1], device=device), indexing="ij")
        self.sole_points_m = torch.stack([gx.reshape(-1), gy.reshape(-1)], dim=-1)
        """(P, 2) height samples in the sole's frame, m."""

    def spread_m(self, soles_xyyaw_w: torch.Tensor) -> torch.Tensor:
        """(...) max - min ground height under each (..., 3) sole pose (widened by the margin), m."""
        return self._spread_m(soles_xyyaw_w[..., None, :2], soles_xyyaw_w[..., 2])[..., 0]

    def _spread_m(self, centers_xy_w: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
        """(..., C) spread under soles at (..., C, 2) centres that share each (...) yaw, rad: the
        sample offsets are rotated once per yaw, not per candidate (the snap's C is ~400)."""
        offsets = rotate_yaw(yaw[..., None], self.sole_points_m)  # (..., P, 2)
        h = self.height_at(centers_xy_w[..., :, None, :] + offsets[..., None, :, :])  # (..., C, P)
        return h.amax(dim=-1) - h.amin(dim=-1)

    def snap(self, stance_xyyaw_w: torch.Tensor, step_xyyaw_w: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The step (B, 3) after stance feet (B, 3), moved onto a tread: (B, 3) pose and (B,) the
        ground height under its centre, m."""
        rel = relative_xyyaw(stance_xyyaw_w, step_xyyaw_w)  # (B, 3): length, signed width, yaw change
        b, g = rel.shape[0], len(self.grid_m)
        # candidate 0 the drawn step, then the grid on the drawn step's side, with its yaw change
        length = torch.cat([rel[:, :1], self.grid_m[:, 0].expand(b, g)], dim=1)  # (B, 1 + G)
        width = torch.cat([rel[:, 1:2].abs(), self.grid_m[:, 1].expand(b, g)], dim=1)
        valid = width >= self.sampler.clear_width_m(rel[:, 2])[:, None]  # the grid keeps the other limits
        valid[:, 0] = True  # the sampler's own step is valid
        cand = torch.stack([length, torch.sign(rel[:, 1:2]) * width, rel[:, 2:].expand(-1, 1 + g)], dim=-1)
        poses = compose_xyyaw(stance_xyyaw_w[:, None].expand(-1, 1 + g, 3), cand)  # (B, 1 + G, 3)
        spread = self._spread_m(poses[..., :2], poses[:, 0, 2])
        flat = valid & (spread <= self.cfg.max_spread_m)
        # a flat candidate nearest the drawn step; none flat: the flattest valid one (metres of
        # spread outweigh any shift within the limits)
        shift = (length - length[:, :1]).abs() + (width - width[:, :1]).abs()
        cost = torch.where(flat, shift, 10.0 + spread * 1e3)
        best = torch.where(valid, cost, torch.full_like(cost, float("inf"))).argmin(dim=1)
        pose = poses.gather(1, best[:, None, None].expand(-1, 1, 3)).squeeze(1)
        return pose, self.height_at(pose[:, :2])


__all__ = ["TreadSnap", "TreadSnapCfg"]
