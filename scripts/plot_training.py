"""Plot a training run's learning curve (mean return and episode length vs env steps) to a PNG.

    python scripts/plot_training.py runs/humanoid-walk/<time> [--out curve.png]

Reads the run's ``metrics.csv`` (written by ``ambulo train``). The committed
``docs/images/humanoid_walk_cpu_curve.png`` came from
``ambulo train humanoid-walk --num-envs 512 --max-iterations 300 --seed 1`` on 2 CPU cores.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(csv.DictReader(open(args.run / "metrics.csv")))
    if not rows:
        raise SystemExit(f"{args.run / 'metrics.csv'} has no rows yet: train first")
    steps_m = [int(r["env_steps"]) / 1e6 for r in rows]
    fig, (ret_ax, len_ax) = plt.subplots(1, 2, figsize=(11, 4))
    ret_ax.plot(steps_m, [float(r["mean_reward"]) for r in rows])
    ret_ax.set_ylabel("mean episode return")
    len_ax.plot(steps_m, [float(r["mean_episode_length_s"]) for r in rows])
    len_ax.set_ylabel("mean episode length (s)")
    for ax in (ret_ax, len_ax):
        ax.set_xlabel("env steps (M)")
        ax.grid(alpha=0.3)
    fig.suptitle(f"{args.run.parent.name}: {len(rows)} PPO iterations")
    fig.tight_layout()
    out = args.out or args.run / "curve.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")
    for r in rows[:: max(1, len(rows) // 10)] + [rows[-1]]:
        print(f"iteration {r['iteration']:>4}  steps {int(r['env_steps']):>9}  return {float(r['mean_reward']):7.2f}"
              f"  episode {float(r['mean_episode_length_s']):5.2f} s")


if __name__ == "__main__":
    main()
