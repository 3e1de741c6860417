"""A picture of a planned (and optionally simulated) walk: the map, the footsteps, the CoM and
ZMP paths, and the measured ZMP margin over time (matplotlib, imported on use: a dev extra)."""

from __future__ import annotations

import os

import numpy as np

from ..nav.footsteps import FootstepPlan
from ..nav.grid_map import GridMap
from ..robots import humanoid
from .balance import foot_polygon
from .preview import WalkPattern


def plot_walk(grid: GridMap, plan: FootstepPlan, path_png: str | os.PathLike, *, pattern: WalkPattern | None = None,
              result=None, goal_xyyaw_w=None,
              foot_size_m: tuple[float, float] = (humanoid.SOLE_LENGTH_M, humanoid.SOLE_WIDTH_M),
              title: str | None = None, margin_m: float = 0.6) -> None:
    """Write a PNG: top, the map around the walk (occupied cells grey), the soles of the plan
    (left blue, right red, start feet hatched), the reference ZMP and the cart-table CoM path of
    ``pattern``, and, given a ``walk_sim.WalkResult``, the measured CoM and CoP; below (with a
    result) the measured ZMP's margin to the support polygon over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    from .balance import FootShape

    foot = FootShape(length_m=foot_size_m[0], width_m=foot_size_m[1])
    steps = plan.footsteps_xyyaw_w
    pts = [steps[:, :2]]
    if pattern is not None:
        pts.append(pattern.com_pos_w[:, :2])
    if goal_xyyaw_w is not None:
        pts.append(np.asarray(goal_xyyaw_w, float)[None, :2])
    pts = np.concatenate(pts)
    lo, hi = pts.min(0) - margin_m, pts.max(0) + margin_m
    rows = 2 if result is not None else 1
    span = hi - lo
    fig = plt.figure(figsize=(9, 9 * span[1] / max(span[0], 1e-6) * 0.8 + 1.0 + 2.6 * (rows - 1)), dpi=110)
    grid_spec = fig.add_gridspec(rows, 1, height_ratios=[3, 1][:rows])
    ax = fig.add_subplot(grid_spec[0])
    num_y, num_x = grid.shape
    (ox, oy), r = grid.origin_xy_m, grid.resolution_m
    extent = (ox, ox + num_x * r, oy, oy + num_y * r)
    ax.imshow(np.where(grid.occupied, 0.25, np.nan), origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1)
    for i, (pose, side) in enumerate(zip(steps, plan.foot_sides)):
        color = "tab:blue" if side > 0 else "tab:red"
        ax.add_patch(Polygon(foot_polygon(pose, foot), closed=True, fill=i >= 2, alpha=0.35 if i >= 2 else 1.0,
                             ec=color, fc=color, hatch="///" if i < 2 else None, lw=0.8))
    if pattern is not None:
        ax.plot(*pattern.zmp_ref_xy.T, "k--", lw=0.8, label="ZMP reference")
        ax.plot(*pattern.com_pos_w[:, :2].T, "tab:green", lw=1.8, label="CoM (pattern)")
    if result is not None:
        ax.plot(*result.com_w[:, :2].T, color="tab:purple", lw=1.0, ls=":", label="CoM (simulated)")
        cop = result.cop_xy[np.isfinite(result.cop_xy[:, 0])]
        ax.plot(*cop.T, ".", color="tab:orange", ms=1.0, label="ZMP measured (CoP)")
    if goal_xyyaw_w is not None:
        gx, gy, gyaw = goal_xyyaw_w
        ax.plot(gx, gy, marker="*", color="gold", markersize=14, mec="k", label="goal")
        ax.arrow(gx, gy, 0.25 * np.cos(gyaw), 0.25 * np.sin(gyaw), width=0.015, color="k")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set(xlabel="x (m)", ylabel="y (m)")
    ax.legend(loc="best", fontsize=7)
    ax.set_title(title or f"{plan.status.value}: {plan.num_steps} steps")
    if result is not None:
        ax2 = fig.add_subplot(grid_spec[1])
        t = result.time_s
        margin = result.zmp_margin_m * 1e3
        ax2.plot(t, margin, color="0.6", lw=0.6, label="all samples")
        ss = np.where(result.single_support, margin, np.nan)
        ax2.plot(t, ss, color="tab:orange", lw=0.9, label="single support")
        ax2.axhline(0.0, color="k", lw=0.8)
        ax2.set(xlabel="t (s)", ylabel="ZMP margin (mm)",
                title=f"measured ZMP inside the support polygon in {100 * result.zmp_inside_fraction:.1f} % "
                      f"of single-support samples")
        ax2.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    fig.savefig(os.fspath(path_png))
    plt.close(fig)


__all__ = ["plot_walk"]
