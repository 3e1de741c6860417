"""Draw seeded apartments' ground-truth occupancy with a sampled start, goal and geodesic path.

    python scripts/apartments_figure.py [--seeds 0 1 3 8 11 13] [--out docs/images/apartments.png]

Each panel: the body-band occupancy (``Apartment.occupancy``, black), where the humanoid's centre
may stand (clearance ``BODY_RADIUS_M``, pale green), the doors (orange ticks), a start (arrow:
its yaw) and a goal (star) from ``Apartment.sample_start_goal(seed)`` and the geodesic path
between them. ``tests/scenes/test_apartment.py`` runs it; the committed
``docs/images/apartments.png`` is its default output.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from ambulo.robots.humanoid import BODY_RADIUS_M
from ambulo.scenes.apartment import apartment

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 3, 8, 11, 13])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "apartments.png")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = 3
    rows = math.ceil(len(args.seeds) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.0 * cols, 4.6 * rows), squeeze=False)
    for ax in axes.ravel()[len(args.seeds):]:
        ax.axis("off")
    for ax, seed in zip(axes.ravel(), args.seeds):
        t0 = time.perf_counter()
        apt = apartment(seed)
        made_s = time.perf_counter() - t0
        ep = apt.sample_start_goal(seed)
        grid = apt.occupancy
        x0, y0, x1, y1 = grid.extent_xy_m()
        image = np.ones(grid.shape + (3,))
        image[apt.paths.clearance_field_m >= BODY_RADIUS_M] = (0.86, 0.95, 0.86)
        image[grid.occupied()] = (0.1, 0.1, 0.12)
        ax.imshow(image, origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest")
        for door in apt.doors:
            (cx, cy), half = door.center_xy_m, door.width_m / 2
            xs, ys = ([cx - half, cx + half], [cy, cy]) if door.along_x else ([cx, cx], [cy - half, cy + half])
            ax.plot(xs, ys, color="tab:orange", lw=3, solid_capstyle="butt")
        path = ep.path_xy_m
        ax.plot(path[:, 0], path[:, 1], color="tab:blue", lw=2)
        sx, sy, yaw = ep.start_pose
        ax.add_patch(plt.Circle((sx, sy), BODY_RADIUS_M, fill=False, color="tab:green", lw=1.5))
        ax.arrow(sx, sy, 0.45 * math.cos(yaw), 0.45 * math.sin(yaw), width=0.04, color="tab:green")
        ax.plot(*ep.goal_xy_m, marker="*", ms=16, color="tab:red", mec="k")
        rooms = sum(not r.is_corridor for r in apt.rooms)
        ax.set_title(f"seed {seed}: {rooms} rooms, {len(apt.doors)} doors, geodesic {ep.geodesic_m:.2f} m",
                     fontsize=10)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        print(f"seed {seed}: {rooms} rooms, {len(apt.solids)} solids, grid {grid.shape}, "
              f"made in {made_s * 1000:.0f} ms, geodesic {ep.geodesic_m:.3f} m")
    fig.suptitle("scenes.apartment(seed): body-band occupancy (black), where the humanoid fits (green), "
                 "doors (orange), start, goal and geodesic", fontsize=11)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    plt.close(fig)
    return args.out


if __name__ == "__main__":
    print(main())
