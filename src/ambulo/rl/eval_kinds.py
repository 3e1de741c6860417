"""A terrain task's evaluation, tile kind by tile kind: which tiles the policy fails on.

humanoid-rough, g1-rough and humanoid-footsteps-stairs are evaluated with every robot on the
hardest level of the terrain grid, env ``i`` on kind column ``i % num_kinds`` (flat, rough, slopes,
stairs, stepping stones). A pooled "falls 14 %, 0.43 m/s" does not say whether the stairs or the
stones fail, so ``run_episodes`` also summarizes each kind's episodes alone (``result["by_kind"]``:
kind name -> its episode count, fall rate, mean return and episode length and the task's step
metrics), grouping the finished episodes once at the end. These are REPORTED, NOT JUDGED: the
task's criteria are judged on the pooled episodes exactly as without them. An env is on the terrain
when it has ``tile_kinds()`` (``envs.terrain_ground.TerrainGround``); any other task's result has
no ``by_kind``.

``ambulo eval`` prints ``kinds_table`` after its JSON (eval.json holds ``by_kind`` whole);
``--eval-every``'s ``evals.csv`` holds ``kinds_cell`` in its ``by_kind`` column
(``kinds_from_text`` reads it back), and its console line names the kind with the most falls
(``most_falls_text``).
"""

from __future__ import annotations

from typing import Any

import torch

from ambulo import envs

POOLED_MEANS = ("mean_return", "mean_episode_length_s")
"""``summarize``'s ``mean_*`` numbers that are not step metrics."""


def tile_kinds(env) -> tuple[tuple[str, ...], torch.Tensor] | None:
    """(kind names, (N,) int64 each env's index into them) of an env on the terrain, else None."""
    kinds = getattr(env, "tile_kinds", None)  # only the terrain mixin has it
    return None if kinds is None else kinds()


def reported(summary: dict[str, Any], task: envs.TaskSpec) -> dict[str, Any]:
    """``summarize``'s result for one kind's episodes less what judges or repeats the whole: the
    task name, episode length, criteria and their verdicts."""
    judged = {"task", "episode_length_s", "criteria", *(c.name for c in task.criteria)}
    return {k: v for k, v in summary.items() if k not in judged}


def step_metrics(kind: dict[str, Any]) -> list[str]:
    """The ``mean_<step metric>`` keys of one kind's numbers, in the task's order."""
    return [k for k in kind if k.startswith("mean_") and k not in POOLED_MEANS]


def kinds_table(by_kind: dict[str, dict[str, Any]]) -> str:
    """One line per tile kind: episodes, fall rate, mean episode length (s) and the step metrics'
    means (headed without ``mean_``); then a line saying the criteria were judged on the pooled
    episodes."""
    first = next(iter(by_kind.values()))
    keys = ["fall_rate", "mean_episode_length_s", *step_metrics(first)]
    heads = [k.removeprefix("mean_") for k in keys]
    width = max(len("tile kind"), *(len(name) for name in by_kind))
    lines = [f"{'tile kind':{width}s}  episodes  " + "  ".join(f"{h:>{max(len(h), 6)}s}" for h in heads)]
    for name, kind in by_kind.items():
        lines.append(f"{name:{width}s}  {kind['episodes']:>8d}  "
                     + "  ".join(f"{kind[k]:>{max(len(h), 6)}.3f}" for k, h in zip(keys, heads)))
    lines.append("by tile kind: reported, not judged (the criteria hold or fail on the pooled episodes)")
    return "\n".join(lines)


def kinds_cell(result: dict[str, Any]) -> str:
    """``evals.csv``'s ``by_kind`` cell: ``kind:fall/err`` for each kind, separated by spaces, ``fall``
    the kind's fall rate and ``err`` its first step metric (humanoid-rough, g1-rough: the velocity
    error, m/s; humanoid-footsteps-stairs: the placement error, m); '' without tile kinds."""
    by_kind = result.get("by_kind")
    if not by_kind:
        return ""
    cells = []
    for name, kind in by_kind.items():
        metrics = step_metrics(kind)
        cells.append(f"{name}:{kind['fall_rate']:.3f}" + (f"/{kind[metrics[0]]:.4f}" if metrics else ""))
    return " ".join(cells)


def most_falls_text(result: dict[str, Any]) -> str:
    """``most falls on KIND tiles (fall rate x, metric y)`` for a result with tile kinds, the first
    such kind in column order; '' without them (the training console's evaluation line)."""
    by_kind = result.get("by_kind")
    if not by_kind:
        return ""
    name, kind = max(by_kind.items(), key=lambda item: item[1]["fall_rate"])
    metrics = "".join(f", {k.removeprefix('mean_')} {kind[k]:.3f}" for k in step_metrics(kind)[:1])
    return f"most falls on {name} tiles (fall rate {kind['fall_rate']:.2f}{metrics})"


def kinds_from_text(text: str) -> dict[str, tuple[float, ...]]:
    """A ``by_kind`` cell as kind -> (fall rate, first step metric) (just the fall rate for a task
    without step metrics); ``{}`` for the empty cell of a task without terrain."""
    return {name: tuple(float(v) for v in values.split("/"))
            for name, values in (pair.split(":", 1) for pair in text.split())}


__all__ = ["POOLED_MEANS", "kinds_cell", "kinds_from_text", "kinds_table", "most_falls_text", "reported",
           "step_metrics", "tile_kinds"]
