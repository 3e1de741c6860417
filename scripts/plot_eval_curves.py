"""Several runs' periodic evaluations on one time axis: PNG for docs/images.

    python scripts/plot_eval_curves.py --task humanoid-rough --out docs/images/rough_curve.png \\
        "seed 1=benchmarks/results/h200x2-2026-11-30-s19-rough-fwd-ppo-seed1-evals.csv"
    python scripts/plot_eval_curves.py --out docs/images/locomotion_curves.png \\
        "PPO, 2 GPUs=benchmarks/results/h200x2-2026-11-30-s13-ttw-2gpu-evalsplit-evals.csv" \\
        "FastSAC=benchmarks/results/h200x2-2026-11-30-s13-fast-sac-compile-evals.csv"

Each argument is ``LABEL=EVALS_CSV``: an ``evals.csv`` that ``ambulo train --eval-every`` wrote
(``wall_s`` from the training process's start, kernel compile and earlier evaluations included;
``fall_rate``; ``metrics`` as ``name=value`` pairs). Plots the velocity error and the fall rate
against wall-clock minutes, with the bars of ``--task``'s criterion (humanoid-walk's ``walks`` without it;
``--max-vel-error``, ``--max-fall-rate`` override),
and marks each run's first evaluation that met its criteria (``criteria_met``) on both engines
when the CSV has the CPU-engine columns filled (a circle), or else its first that met them on the
engine it trained on only (a square, labelled so). A run of a task judged in blocks (humanoid-walk-robust:
nominal and 16 transfer corners) plots its worst block at each evaluation (the ``worst_block`` cell),
the numbers its criterion is judged on, not the pooled ones.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from ambulo import envs
from ambulo.envs.humanoid_walk import WALKS
from ambulo.rl.periodic_eval import metrics_from_text, worst_block_from_text


def read_evals(path: Path) -> list[dict]:
    """The rows of an ``evals.csv``: minutes, fall rate, velocity error m/s and whether the
    criteria held (on the CPU engine too where it was checked)."""
    rows = []
    with open(path, newline="") as f:
        for line, raw in enumerate(csv.DictReader(f), start=2):
            try:
                metrics = metrics_from_text(raw["metrics"])
                fall_rate = float(raw["fall_rate"])
                worst = worst_block_from_text(raw.get("worst_block") or "")
                if worst is not None:  # judged in blocks: the worst one's numbers decide
                    metrics = worst[1]
                    fall_rate = metrics["fall_rate"]
                met_training_engine = raw["criteria_met"] == "True"
                met = met_training_engine
                if raw.get("cpu_engine_criteria_met"):
                    met = met and raw["cpu_engine_criteria_met"] == "True"
                rows.append({"minutes": float(raw["wall_s"]) / 60.0, "fall_rate": fall_rate,
                             "vel_error_m_s": metrics["mean_abs_vel_error_m_s"], "met": met,
                             "met_training_engine": met_training_engine})
            except (KeyError, TypeError, ValueError, AttributeError) as error:
                raise SystemExit(f"{path} line {line}: not an evals.csv row of `ambulo train --eval-every` "
                                 f"({type(error).__name__}: {error}); pass the run's evals.csv") from None
    if not rows:
        raise SystemExit(f"{path} has no evaluations")
    return rows


def legend(label: str, rows: list[dict]) -> tuple[str, dict | None, dict | None]:
    """A run's legend entry, its first evaluation that met the criteria on both engines, and
    (when none did) its first that met them on the engine it trained on only: that one is said
    and marked apart, so a sim-to-sim gap is not drawn as walking."""
    met = next((r for r in rows if r["met"]), None)
    gpu_only = None if met else next((r for r in rows if r["met_training_engine"]), None)
    if met:
        return f"{label}: walks at {met['minutes']:.1f} min", met, None
    if gpu_only:
        return f"{label}: criterion at {gpu_only['minutes']:.1f} min, not on the CPU engine", None, gpu_only
    return f"{label}: not yet", None, None


def criterion_bars(task: str | None) -> tuple[float, float]:
    """(velocity error m/s, fall rate): the largest passing values of ``task``'s criterion over both (its
    registry entry), humanoid-walk's ``walks`` when ``task`` is None. The marks come from the CSV's
    ``criteria_met``, so a bar from another task's criterion would be drawn where no mark agrees with it."""
    if task is None:
        criterion = WALKS
    else:
        try:
            spec = envs.spec(task)
        except KeyError as error:
            raise SystemExit(f"--task: {error.args[0]}") from None
        criterion = next((c for c in spec.criteria if {"mean_abs_vel_error_m_s", "fall_rate"} <= c.max_values.keys()),
                         None)
        if criterion is None:
            raise SystemExit(f"--task {task}: no criterion bounds the velocity error and the fall rate; "
                             "give --max-vel-error and --max-fall-rate")
    return criterion.max_values["mean_abs_vel_error_m_s"], criterion.max_values["fall_rate"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="LABEL=EVALS_CSV")
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--title", default=None)
    parser.add_argument("--task", default=None, help="the runs' task: its criterion gives the bars")
    parser.add_argument("--max-vel-error", type=float, default=None,
                        help="the velocity error bar, m/s (default: the task's criterion's)")
    parser.add_argument("--max-fall-rate", type=float, default=None,
                        help="the fall rate bar (default: the task's criterion's)")
    args = parser.parse_args()
    vel_bar, fall_bar = criterion_bars(args.task)
    args.max_vel_error = vel_bar if args.max_vel_error is None else args.max_vel_error
    args.max_fall_rate = fall_bar if args.max_fall_rate is None else args.max_fall_rate
    runs = []
    for item in args.runs:
        label, sep, path = item.partition("=")
        if not sep or not path:
            parser.error(f"{item!r}: give LABEL=EVALS_CSV")
        if not Path(path).is_file():
            parser.error(f"{path}: no such evals.csv")
        runs.append((label, read_evals(Path(path))))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_vel, ax_fall) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    for label, rows in runs:
        minutes = [r["minutes"] for r in rows]
        name, met, gpu_only = legend(label, rows)
        line, = ax_vel.plot(minutes, [r["vel_error_m_s"] for r in rows], marker=".", label=name)
        ax_fall.plot(minutes, [r["fall_rate"] for r in rows], marker=".", color=line.get_color())
        for mark, marker in ((met, "o"), (gpu_only, "s")):
            if mark:
                for ax, key in ((ax_vel, "vel_error_m_s"), (ax_fall, "fall_rate")):
                    ax.plot([mark["minutes"]], [mark[key]], marker=marker, markersize=9, fillstyle="none",
                            color=line.get_color())
    ax_vel.axhline(args.max_vel_error, color="k", linestyle="--", linewidth=0.8)
    ax_fall.axhline(args.max_fall_rate, color="k", linestyle="--", linewidth=0.8)
    ax_vel.set_ylabel("eval velocity error, m/s")
    ax_fall.set_ylabel("eval fall rate")
    ax_fall.set_xlabel("wall-clock minutes from the training process's start (compile and evaluations included)")
    ax_vel.legend(fontsize=8)
    if args.title:
        ax_vel.set_title(args.title, fontsize=10)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
