"""Walking pattern by ZMP preview control (Kajita 2003): a few straight steps for the bundled
humanoid's feet turned into reference ZMP, CoM and swing-foot trajectories, drawn to a PNG.

    python examples/nav/preview_walk_pattern.py [--steps 6] [--png out/preview_walk_pattern.png]

The top panel shows the footsteps, the reference ZMP, the ZMP of the generated CoM motion and the
CoM path from above; the lower panels show x and y against time, and the swing-foot height.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ambulo.locomotion.balance import FootShape, foot_polygon, polygon_signed_distance
from ambulo.locomotion.preview import WalkPatternGenerator, walk_pattern_cfg

# the bundled humanoid (assets/data/humanoid.xml): 0.22 x 0.09 m soles whose centres (the
# left_sole/right_sole sites) stand 0.18 m apart; its CoM is 0.90 m high in the "home" pose,
# lower with the knees bent for walking
FOOT = FootShape(length_m=0.22, width_m=0.09)
STEP_WIDTH_M = 0.18
COM_HEIGHT_M = 0.85


def straight_plan(num_steps: int, step_length_m: float) -> list[dict]:
    """The standing feet (left, right), then ``num_steps`` alternating steps forward; the last
    step brings the feet side by side."""
    half = STEP_WIDTH_M / 2
    plan = [{"x": 0.0, "y": half, "yaw": 0.0, "side": "left"}, {"x": 0.0, "y": -half, "yaw": 0.0, "side": "right"}]
    for i in range(num_steps):
        side = "left" if i % 2 == 0 else "right"
        x = step_length_m * min(i + 1, num_steps - 1)
        plan.append({"x": x, "y": half if side == "left" else -half, "yaw": 0.0, "side": side})
    return plan


def draw(pattern, plan, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10, 9), constrained_layout=True)
    grid = fig.add_gridspec(3, 2)
    top = fig.add_subplot(grid[0, :])
    for i, step in enumerate(plan):
        corners = foot_polygon((step["x"], step["y"], step["yaw"]), FOOT)
        color = "tab:gray" if i < 2 else ("tab:blue" if step["side"] == "left" else "tab:red")
        top.fill(corners[:, 0], corners[:, 1], facecolor=color, alpha=0.25, edgecolor=color)
    top.plot(*pattern.zmp_ref_xy.T, "k--", lw=1, label="ZMP reference")
    top.plot(*pattern.zmp_xy.T, "tab:orange", lw=1.5, label="ZMP (cart-table)")
    top.plot(*pattern.com_pos_w[:, :2].T, "tab:green", lw=2, label="CoM")
    top.set(aspect="equal", xlabel="x (m)", ylabel="y (m)", title="footsteps (left blue, right red), ZMP and CoM")
    top.legend(loc="upper left", fontsize=8)
    t = pattern.time_s
    for axis in (0, 1):
        ax = fig.add_subplot(grid[1, axis])
        ax.plot(t, pattern.zmp_ref_xy[:, axis], "k--", lw=1, label="ZMP ref")
        ax.plot(t, pattern.zmp_xy[:, axis], "tab:orange", label="ZMP")
        ax.plot(t, pattern.com_pos_w[:, axis], "tab:green", label="CoM")
        ax.set(xlabel="t (s)", ylabel=f"{'xy'[axis]} (m)")
        ax.legend(fontsize=8)
    feet = fig.add_subplot(grid[2, :])
    feet.plot(t, pattern.foot_pose_w[:, 0, 2], "tab:blue", label="left foot z")
    feet.plot(t, pattern.foot_pose_w[:, 1, 2], "tab:red", label="right foot z")
    feet.set(xlabel="t (s)", ylabel="z (m)")
    feet.legend(fontsize=8)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=6)
    parser.add_argument("--step-length", type=float, default=0.2, help="m")
    parser.add_argument("--png", default="out/preview_walk_pattern.png")
    args = parser.parse_args(argv)

    cfg = walk_pattern_cfg(com_height_m=COM_HEIGHT_M, foot=FOOT, step_time_s=0.8, double_support_ratio=0.2,
                           swing_height_m=0.06)
    plan = straight_plan(args.steps, args.step_length)
    pattern = WalkPatternGenerator(cfg).generate(plan)
    margins = np.array([polygon_signed_distance(pattern.zmp_xy[k], pattern.support_polygon(k))
                        for k in range(len(pattern.time_s))])
    zmp_error = np.abs(pattern.zmp_xy - pattern.zmp_ref_xy).max()
    draw(pattern, plan, Path(args.png))
    print(f"{len(pattern.steps)} steps in {pattern.time_s[-1]:.2f} s; ZMP tracking error max "
          f"{zmp_error * 1e3:.1f} mm; ZMP margin in the support polygon min {margins.min() * 1e3:.1f} mm; "
          f"wrote {args.png}")
    return {"pattern": pattern, "png": args.png, "max_zmp_error_m": float(zmp_error),
            "min_zmp_margin_m": float(margins.min()), "com_travel_m": float(pattern.com_pos_w[-1, 0])}


if __name__ == "__main__":
    main()
