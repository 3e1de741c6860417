"""``metrics.csv``: one row of headline numbers per training iteration, safe across resumes.

A run killed after iteration 7 but resumed from ``model_5.pt`` repeats iterations 6 and 7,
so resuming first drops the rows of iterations at or after the resumed start (and a last
line a kill cut in half), rewriting the file atomically; the repeated iterations are then
appended once. Iteration numbers in the file stay unique and increasing.

Columns: ``COLUMNS`` for every task, then the run's extras (``TERRAIN_LEVEL`` on a task whose
env has a terrain curriculum: ``progress.TrainingProgress``); other tasks' files are exactly
``COLUMNS``. A resume never drops a recorded column: it rewrites the file with the run's columns
followed by any other column the file's header has (``resumed_columns``), so an old file without
``terrain_level`` gains it, its earlier rows empty there (not recorded, not level 0), and a file
with a column this run does not write keeps it, the new rows empty there.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from ambulo.utils.atomic import atomic_write_text

COLUMNS = ("iteration", "env_steps", "mean_reward", "mean_episode_length_s", "steps_per_s",
           "collect_s", "learn_s", "action_std")
TERRAIN_LEVEL = "terrain_level"
"""The extra column of a task with a terrain curriculum: the mean level of the robots' tiles (of
rank 0's envs), read when the row is written (``envs.terrain_ground.TerrainGround.mean_terrain_level``)."""


def _number(value: float | None, digits: int) -> str:
    """``value`` with ``digits`` decimals, or an empty field when there is none.

    The mean reward and episode length average the episodes that ended in the last 100; before
    the first episode of a run ends there is no such mean, and an empty field says so where
    ``nan`` would read as a diverged policy (pandas reads the empty field as NaN, csv as '').
    """
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.{digits}f}"


def header(path: Path) -> tuple[str, ...]:
    """The column names on the first line of the CSV at ``path`` (none for a missing or empty file)."""
    if not path.is_file():
        return ()
    with open(path, newline="") as f:
        return tuple(next(csv.reader(f), ()))


def resumed_columns(path: Path, columns: tuple[str, ...], start: int) -> tuple[str, ...]:
    """The header of the CSV at ``path`` once a run writing ``columns`` resumes from ``start``:
    ``columns``, then the file's other columns in their order (a resume keeps every recorded value).
    A new run (``start`` 0) starts a new file: ``columns``."""
    if start <= 0:
        return columns
    return columns + tuple(name for name in header(Path(path)) if name and name not in columns)


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
    iterations ``>= start``. ``extra_columns`` (e.g. ``(TERRAIN_LEVEL,)``) follow ``COLUMNS``;
    ``columns`` is the file's header (``resumed_columns``)."""

    def __init__(self, path: Path, start: int = 0, extra_columns: tuple[str, ...] = ()):
        self.path = Path(path)
        self.extra_columns = tuple(extra_columns)
        self.columns = resumed_columns(self.path, COLUMNS + self.extra_columns, start)
        truncate_csv(self.path, self.columns, start)

    def append(self, iteration: int, steps_per_it: int, mean_reward: float | None,
               mean_episode_length_s: float | None, collect_s: float, learn_s: float,
               action_std: float, extras: dict[str, float | None] | None = None) -> list[str]:
        """Write one iteration's row (``steps_per_it`` env steps an iteration) in ``columns``'
        order; return it (``COLUMNS``' fields first). ``extras``: the ``extra_columns``' values
        (4 decimals; a missing or non-finite one is an empty field)."""
        row = [str(iteration), str((iteration + 1) * steps_per_it), _number(mean_reward, 4),
               _number(mean_episode_length_s, 3),
               str(int(steps_per_it / max(collect_s + learn_s, 1e-9))),
               f"{collect_s:.3f}", f"{learn_s:.3f}", _number(action_std, 4)]
        row += [_number((extras or {}).get(name), 4) for name in self.extra_columns]
        row += [""] * (len(self.columns) - len(row))  # columns only an older segment wrote
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow(row)
        return row
