"""A picture of a footstep plan on its map (matplotlib, imported on use: it is a dev extra)."""

from __future__ import annotations

import os

import numpy as np

from .footstep_lattice import compose
from .footsteps import FootstepPlan
from .grid_map import GridMap


def plot_plan(grid: GridMap, plan: FootstepPlan, path_png: str | os.PathLike | None, *,
              foot_size_m: tuple[float, float] = (0.22, 0.10), goal_xyyaw_w=None, title: str | None = None,
              ax=None) -> None:
    """Write a PNG of the occupancy (grey), the height map (if any, shaded), the soles of the plan
    (left blue, right red, start feet hatched), the swing-foot path and, if given, the goal pose.
    With ``ax`` (a matplotlib Axes) draw there instead and write nothing (``path_png`` unused)."""
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    num_y, num_x = grid.shape
    (ox, oy), r = grid.origin_xy_m, grid.resolution_m
    extent = (ox, ox + num_x * r, oy, oy + num_y * r)
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 7 * num_y / max(num_x, 1) + 0.3), dpi=120)
    if grid.height_m is not None and np.ptp(grid.height_m) > 0:
        ax.imshow(grid.height_m, origin="lower", extent=extent, cmap="YlGn", alpha=0.6)
    ax.imshow(np.where(grid.occupied, 0.25, np.nan), origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1)
    half = np.array(foot_size_m) / 2
    corners = np.array([[half[0], half[1], 0], [-half[0], half[1], 0], [-half[0], -half[1], 0], [half[0], -half[1], 0]])
    for i, (pose, side) in enumerate(zip(plan.footsteps_xyyaw_w, plan.foot_sides)):
        poly = compose(pose, corners)[:, :2]
        color = "tab:blue" if side > 0 else "tab:red"
        ax.add_patch(Polygon(poly, closed=True, fill=i >= 2, alpha=0.45 if i >= 2 else 1.0, ec=color,
                             fc=color, hatch="///" if i < 2 else None, lw=0.8))
    for side, style in ((1, "tab:blue"), (-1, "tab:red")):
        xy = plan.footsteps_xyyaw_w[plan.foot_sides == side, :2]
        ax.plot(xy[:, 0], xy[:, 1], color=style, lw=0.6, alpha=0.6)
    if goal_xyyaw_w is not None:
        gx, gy, gyaw = goal_xyyaw_w
        ax.plot(gx, gy, marker="*", color="gold", markersize=14, mec="k")
        ax.arrow(gx, gy, 0.3 * np.cos(gyaw), 0.3 * np.sin(gyaw), width=0.02, color="k")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title or f"{plan.status.value}: {plan.num_steps} steps, {plan.planning_time_s * 1e3:.1f} ms")
    if fig is not None:
        fig.tight_layout()
        fig.savefig(os.fspath(path_png))
        plt.close(fig)
