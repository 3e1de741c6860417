"""Terrain runs side by side: falls by tile kind and the curriculum's levels, as Markdown tables.

    python scripts/compare_runs.py --from-iteration 899 --level-kind stepping_stones \\
        "s27 seed 0=benchmarks/results/h200-2026-12-02-s27-rough-fastsac-seed0-evals.csv" \\
        "s28 seed 0, weights=benchmarks/results/h200-2026-12-02-s28-kw-seed0.tgz"

Each argument is ``LABEL=PATH``. PATH is a run folder of ``ambulo train --eval-every``, a ``.tgz`` of one (as the
device scripts pack them), or an ``evals.csv``, whose ``metrics.csv`` is read from beside it (``X-evals.csv`` ->
``X-metrics.csv``) when there is one.

The first table averages, over every periodic evaluation from ``--from-iteration`` on, the pooled fall rate
(``fall_rate``: the engine each row names in ``eval_engine``) and each kind's (the ``by_kind`` cell). A single
evaluation holds ~14 episodes of a kind, so one row decides little; the average over a plateau says which kinds
hold the pooled rate up. The second table gives the training curriculum's mean level (``metrics.csv``'s
``terrain_level`` or, with ``--level-kind``, ``terrain_level_<kind>``) at the last logged iteration at or before
each of ``--at``, and at the run's last.
"""

from __future__ import annotations

import argparse
import csv
import io
import tarfile
from pathlib import Path

from ambulo.rl.eval_kinds import kinds_from_text


def _rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text))) if text else []


def read_run(path: Path) -> tuple[list[dict[str, str]], list[dict[str, str]]]:
    """(evals rows, metrics rows) of the run at ``path`` (module docstring); metrics rows are [] when the run has
    no ``metrics.csv``. SystemExit, one line, when ``path`` holds no ``evals.csv``."""
    texts: dict[str, str] = {}
    if path.is_dir():
        for name in ("evals.csv", "metrics.csv"):
            if (path / name).is_file():
                texts[name] = (path / name).read_text()
    elif path.name.endswith((".tgz", ".tar.gz")):
        try:
            with tarfile.open(path) as tar:
                for member in tar.getmembers():
                    name = Path(member.name).name
                    if name in ("evals.csv", "metrics.csv") and member.isfile():
                        texts[name] = tar.extractfile(member).read().decode()
        except (tarfile.TarError, OSError) as error:
            raise SystemExit(f"{path}: not a readable .tgz ({error}); pass a run folder, its .tgz or its evals.csv") from None
    elif path.is_file():
        texts["evals.csv"] = path.read_text()
        if path.name.endswith("evals.csv"):
            beside = path.with_name(path.name[: -len("evals.csv")] + "metrics.csv")
            if beside.is_file():
                texts["metrics.csv"] = beside.read_text()
    if "evals.csv" not in texts:
        raise SystemExit(f"{path}: no evals.csv there; pass a run folder of `ambulo train --eval-every`, "
                         "its .tgz or its evals.csv")
    return _rows(texts["evals.csv"]), _rows(texts.get("metrics.csv", ""))


def falls_by_kind(evals: list[dict[str, str]], from_iteration: int) -> tuple[int, float, dict[str, float]]:
    """(evaluations counted, mean pooled fall rate, kind -> mean fall rate) over the rows whose iteration is at
    least ``from_iteration``; a kind's mean is over the rows that report it. nan and {} when no row counts."""
    rows = [r for r in evals if int(r["iteration"]) >= from_iteration]
    if not rows:
        return 0, float("nan"), {}
    sums: dict[str, list[float]] = {}
    for r in rows:
        for kind, values in kinds_from_text(r.get("by_kind") or "").items():
            sums.setdefault(kind, []).append(values[0])
    pooled = sum(float(r["fall_rate"]) for r in rows) / len(rows)
    return len(rows), pooled, {kind: sum(v) / len(v) for kind, v in sums.items()}


def levels_at(metrics: list[dict[str, str]], column: str, iterations: list[int]) -> list[float | None]:
    """``column`` of the last row at or before each of ``iterations`` (None before the first row or where the
    run has no such column), then of the run's last row."""
    if not metrics or column not in metrics[0]:
        return [None] * (len(iterations) + 1)
    out: list[float | None] = []
    for t in iterations:
        before = [r for r in metrics if int(r["iteration"]) <= t]
        out.append(float(before[-1][column]) if before else None)
    return out + [float(metrics[-1][column])]


def _cell(value: float | None, digits: int) -> str:
    return "-" if value is None or value != value else f"{value:.{digits}f}"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="LABEL=PATH: a run folder, its .tgz or its evals.csv")
    parser.add_argument("--from-iteration", type=int, default=0,
                        help="average the evaluations from this iteration on (default: all)")
    parser.add_argument("--at", default="1000,1500,2000,2500",
                        help="iterations at which to read the curriculum's level (comma-separated)")
    parser.add_argument("--level-kind", default=None,
                        help="read terrain_level_<KIND> (e.g. stepping_stones); default: the mean over every kind")
    args = parser.parse_args(argv)
    try:
        at = [int(x) for x in args.at.split(",") if x.strip()]
    except ValueError:
        parser.error(f"--at {args.at!r}: give iterations as integers separated by commas, e.g. 1000,2000")
    runs = []
    for item in args.runs:
        label, sep, path = item.partition("=")
        if not sep or not path:
            parser.error(f"{item!r}: give LABEL=PATH")
        if not Path(path).exists():
            parser.error(f"{path}: no such run folder or file")
        runs.append((label, Path(path)))

    column = "terrain_level" if args.level_kind is None else f"terrain_level_{args.level_kind}"
    kinds: list[str] = []
    summaries = []
    for label, path in runs:
        try:
            evals, metrics = read_run(path)
            n, pooled, by_kind = falls_by_kind(evals, args.from_iteration)
            levels = levels_at(metrics, column, at)
            last_iteration = metrics[-1]["iteration"] if metrics else None
        except (KeyError, ValueError) as error:  # a missing column, a cell that is not a number, not UTF-8
            raise SystemExit(f"{path}: not the evals.csv / metrics.csv of `ambulo train --eval-every` "
                             f"({type(error).__name__}: {error}); pass a run folder, its .tgz or its evals.csv") from None
        kinds += [k for k in by_kind if k not in kinds]
        summaries.append((label, n, pooled, by_kind, levels, last_iteration))
    print(f"Falls, mean over the evaluations from iteration {args.from_iteration} on:\n")
    print("| run | evaluations | pooled | " + " | ".join(kinds) + " |")
    print("|---|---|---|" + "---|" * len(kinds))
    for label, n, pooled, by_kind, _, _ in summaries:
        print(f"| {label} | {n} | {_cell(pooled, 3)} | " + " | ".join(_cell(by_kind.get(k), 2) for k in kinds) + " |")

    print(f"\nTraining's mean `{column}` (metrics.csv) at or before each iteration:\n")
    print("| run | " + " | ".join(f"it {t}" for t in at) + " | last |")
    print("|---|" + "---|" * (len(at) + 1))
    for label, _, _, _, levels, last_iteration in summaries:
        last = "-" if last_iteration is None else f"{_cell(levels[-1], 2)} ({last_iteration})"
        print(f"| {label} | " + " | ".join(_cell(v, 2) for v in levels[:-1]) + f" | {last} |")


if __name__ == "__main__":
    main()
