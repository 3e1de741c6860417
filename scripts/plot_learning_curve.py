"""Plot a run's learning curve against wall-clock minutes: PNG for docs/images.

    python scripts/plot_learning_curve.py RUN --out docs/images/humanoid_walk_curve.png

Reads the run's TensorBoard events (mean episode reward, each point's wall time) and
``evals.csv`` (``--eval-every`` evaluations, whose ``wall_s`` counts from the process start),
and marks the first evaluation that met the task's criterion (``time_to_criterion.json``).
Time zero is the start of the training process: the first evaluation's event wall time minus
its ``wall_s``. A resumed run's later process continues the time axis where the earlier one
stopped (the time between the two processes is left out and the plot says so).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from ambulo.envs.humanoid_walk import WALKS
from ambulo.rl.periodic_eval import metrics_from_text


def scalars(event_file: Path, tag: str) -> list[tuple[float, int, float]]:
    acc = EventAccumulator(str(event_file), size_guidance={"scalars": 0})
    acc.Reload()
    if tag not in acc.Tags()["scalars"]:
        return []
    return [(e.wall_time, e.step, e.value) for e in acc.Scalars(tag)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default=None)
    args = p.parse_args()
    run = Path(args.run)
    info = json.loads((run / "run.json").read_text())
    evals = list(csv.DictReader(open(run / "evals.csv")))
    eval_wall = {int(r["iteration"]): float(r["wall_s"]) for r in evals}
    reward, gaps = [], 0
    for event_file in sorted(run.glob("events.out.tfevents.*")):
        points = scalars(event_file, "Train/mean_reward")
        if not points:
            continue
        if not reward:  # process 1: align event wall times to the evaluation wall_s
            marks = {step: wall for wall, step, _ in scalars(event_file, "eval/fall_rate")}
            first = min(marks)
            zero_s = marks[first] - eval_wall[first]
        else:  # a resumed process: its first point continues from the last one
            zero_s = points[0][0] - reward[-1][0] * 60.0
            gaps += 1
        reward += [((wall - zero_s) / 60.0, value) for wall, _, value in points]
    reached = json.loads((run / "time_to_criterion.json").read_text()) if (run / "time_to_criterion.json").is_file() else None

    fig, axes = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    axes[0].plot(*zip(*reward), color="tab:blue", lw=1)
    axes[0].set_ylabel("mean episode reward")
    minutes = [float(r["wall_s"]) / 60 for r in evals]
    axes[1].plot(minutes, [metrics_from_text(r["metrics"])["mean_abs_vel_error_m_s"] for r in evals],
                 "o-", ms=3, color="tab:orange")
    axes[1].axhline(WALKS.max_values["mean_abs_vel_error_m_s"], color="k", ls="--", lw=0.8)
    axes[1].set_ylabel("eval velocity error, m/s")
    axes[2].plot(minutes, [float(r["fall_rate"]) for r in evals], "o-", ms=3, color="tab:red")
    axes[2].axhline(WALKS.max_values["fall_rate"], color="k", ls="--", lw=0.8)
    axes[2].set_ylabel("eval fall rate")
    axes[2].set_xlabel("wall-clock minutes from `ambulo train` starting (kernel compile and evaluations included)")
    if reached:
        for ax in axes:
            ax.axvline(reached["wall_s"] / 60, color="tab:green", lw=1)
        axes[0].text(reached["wall_s"] / 60, axes[0].get_ylim()[0], f"  walks: {reached['wall_s'] / 60:.1f} min",
                     color="tab:green", va="bottom")
    title = args.title or f"{info['task']} on {info['device']}, {info['ppo']['num_envs']} envs, seed {info['seed']}"
    if gaps:
        title += f"\n(resumed {gaps}x: the time between processes is left out)"
    axes[0].set_title(title, fontsize=10)
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
