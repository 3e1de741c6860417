"""``metrics.csv``: one row of headline numbers per training iteration, safe across resumes.

A run killed after iteration 7 but resumed from ``model_5.pt`` repeats iterations 6 and 7,
so resuming first drops the rows of iterations at or after the resumed start (and a last
line a kill cut in half), rewriting the file atomically; the repeated iterations are then
appended once. Iteration numbers in the file stay unique and increasing.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from ambulo.utils.atomic import atomic_write_text

COLUMNS = ("iteration", "env_steps", "mean_reward", "mean_episode_length_s", "steps_per_s",
           "collect_s", "learn_s", "action_std")


def _number(value: float | None, digits: int) -> str:
    """``value`` with ``digits`` decimals, or an empty field when there is none.

    The mean reward and episode length average the episodes that ended in the last 100; before
    the first episode of a run ends there is no such mean, and an empty field says so where
    ``nan`` would read as a diverged policy (pandas reads the empty field as NaN, csv as '').
    """
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.{digits}f}"


def rows_before(path: Path, start: int) -> list[dict[str, str]]:
    """The complete rows of the CSV at ``path`` whose ``iteration`` is below ``start`` (a line a
    kill cut short, or one without an iteration number, is dropped)."""
    kept = []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            try:
                iteration = int(row.get("iteration") or "")
            except ValueError:  # a line cut short by a kill
                continue
            if iteration < start and None not in row.values():
                kept.append(row)
    return kept


def write_rows(path: Path, columns: tuple[str, ...], rows: list[dict[str, str]]) -> None:
    """Replace the CSV at ``path`` by ``columns``' header and ``rows``, atomically (a temporary
    in the same folder, fsynced, then ``os.replace``: a kill leaves the old file or the new)."""
    out = io.StringIO()
    writer = csv.DictWriter(out, columns, extrasaction="ignore", restval="")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(path, out.getvalue(), fsync=True)


def truncate_csv(path: Path, columns: tuple[str, ...], start: int) -> None:
    """A resume from iteration ``start``: keep only the rows of iterations ``< start`` of the
    per-iteration CSV at ``path`` (a new file with just the header if there is none)."""
    path = Path(path)
    write_rows(path, columns, rows_before(path, start) if start > 0 and path.is_file() else [])


class MetricsCsv:
    """Appends rows to ``<run>/metrics.csv``; ``start`` > 0 (a resume) first drops the rows of
    iterations ``>= start``."""

    def __init__(self, path: Path, start: int = 0):
        self.path = Path(path)
        truncate_csv(self.path, COLUMNS, start)

    def append(self, iteration: int, steps_per_it: int, mean_reward: float | None,
               mean_episode_length_s: float | None, collect_s: float, learn_s: float,
               action_std: float) -> list[str]:
        """Write one iteration's row (``steps_per_it`` env steps an iteration); return it."""
        row = [str(iteration), str((iteration + 1) * steps_per_it), _number(mean_reward, 4),
               _number(mean_episode_length_s, 3),
               str(int(steps_per_it / max(collect_s + learn_s, 1e-9))),
               f"{collect_s:.3f}", f"{learn_s:.3f}", _number(action_std, 4)]
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow(row)
        return row
