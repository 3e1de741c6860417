"""Evaluations laid out in blocks: a task's criteria judged under each of several conditions.

A task whose ``TaskSpec.eval_blocks`` names blocks (humanoid-walk-robust: nominal and the 16
corners of gains, latency and CoM) is evaluated in one env whose worlds split into that many
contiguous equal blocks, block b under condition b (the play variant with the layout's
``env_overrides``). Every evaluation that judges a criterion builds its env through
``eval_layout`` (``ambulo eval``, ``--eval-every`` and its CPU-engine confirmation, the shares of
``--num-gpus`` and of a data-parallel run), so the criterion judged is the same everywhere.

``run_episodes`` summarizes each block on its own (``result["blocks"]``, each with its ``name``)
beside the whole; a criterion of the whole holds when it holds in every block (the pooled means
of the whole are reported, never judged: a mean over conditions hides the one that fails), and
``worst_block`` names the block nearest to failing (``Criterion.load``), ``blocks_failed`` those
that fail. A task without blocks evaluates as before: one block, no ``blocks`` key.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ambulo import envs
from ambulo.utils.checks import InvalidValueError

DEFAULT_EPISODES = 100
"""Episodes of an evaluation of a task without blocks (``ambulo eval``'s default)."""


@dataclass(frozen=True)
class EvalLayout:
    """How one evaluation of a task lays out its episodes."""

    num_episodes: int
    """Episodes in all (one world each), over every block and process."""
    names: tuple[str, ...] = ()
    """The blocks' names in world order; empty: no blocks."""
    env_overrides: dict[str, Any] = field(default_factory=dict)
    """Play-variant overrides that lay the worlds out in the blocks."""

    @property
    def blocks(self) -> int:
        """Blocks of the layout (1 without blocks)."""
        return len(self.names) or 1

    @property
    def run_blocks(self) -> tuple[str, ...] | int:
        """``run_episodes``' ``blocks`` argument."""
        return self.names or 1


def eval_layout(task: envs.TaskSpec, num_episodes: int | None = None) -> EvalLayout:
    """``task``'s evaluation of ``num_episodes`` (None: its default: ``episodes_per_block`` a
    block, or ``DEFAULT_EPISODES``); ``InvalidValueError`` (a ValueError) in one line when they do not split into its blocks."""
    layout = task.eval_blocks()
    if layout is None:
        return EvalLayout(DEFAULT_EPISODES if num_episodes is None else num_episodes)
    count = len(layout.names)
    default = count * layout.episodes_per_block
    if num_episodes is None:
        num_episodes = default
    if num_episodes < count or num_episodes % count:
        raise InvalidValueError(f"{task.name}'s evaluation episode count", num_episodes,
                                f"it must split into its {count} equal blocks ({layout.names[0]} and "
                                f"{count - 1} more, one condition each)",
                                f"pass a multiple of {count} (default {default}: {layout.episodes_per_block} a block)")
    return EvalLayout(num_episodes, tuple(layout.names), dict(layout.env_overrides))


def judge_blocks(result: dict[str, Any], blocks: list[dict[str, Any]], task: envs.TaskSpec) -> None:
    """Set ``result``'s criteria from its ``blocks`` (each holds where it holds in every block),
    and its ``blocks``, ``worst_block`` and ``blocks_failed``, in place."""
    result["blocks"] = blocks
    for criterion in task.criteria:
        result[criterion.name] = all(block[criterion.name] for block in blocks)
    if task.criteria:
        worst = max(blocks, key=lambda block: max(c.load(block) for c in task.criteria))
        result["worst_block"] = worst["name"]
    result["blocks_failed"] = [block["name"] for block in blocks
                               if not all(block[c.name] for c in task.criteria)]


def blocks_table(result: dict[str, Any]) -> str:
    """The per-block lines of a blocked evaluation's ``result`` (fall rate, step metrics, the
    criteria), the worst block marked, and a closing line on the criteria."""
    blocks = result["blocks"]
    metrics = [k for k in blocks[0] if k == "fall_rate" or k.startswith("mean_abs")]
    criteria = result["criteria"]
    width = max(len(block["name"]) for block in blocks)
    lines = [f"  {'block':{width}s}  " + "  ".join(f"{k:>{max(len(k), 6)}s}" for k in (*metrics, *criteria))]
    for block in blocks:
        mark = "*" if block["name"] == result.get("worst_block") else " "
        cells = [f"{block[k]:>{max(len(k), 6)}.3f}" for k in metrics]
        cells += [f"{'yes' if block[c] else 'NO':>{max(len(c), 6)}s}" for c in criteria]
        lines.append(f"{mark} {block['name']:{width}s}  " + "  ".join(cells))
    failed = result["blocks_failed"]
    verdict = ", ".join(f"{c} {'holds' if result[c] else 'fails'}" for c in criteria)
    lines.append(f"{verdict}: {len(blocks) - len(failed)} of {len(blocks)} blocks pass; "
                 f"worst (*): {result.get('worst_block')}")
    return "\n".join(lines)


def worst_block(result: dict[str, Any]) -> dict[str, Any] | None:
    """The block of a blocked evaluation's ``result`` its criteria are nearest to failing in
    (``judge_blocks``' ``worst_block``); None without blocks."""
    if "blocks" not in result:
        return None
    return next(block for block in result["blocks"] if block["name"] == result.get("worst_block"))


def worst_block_text(result: dict[str, Any]) -> str:
    """``worst NAME (fall rate x, metric y, ...), k of n blocks fail`` for a blocked result; ''
    without blocks (one line of the training console and ``evals.csv``)."""
    worst = worst_block(result)
    if worst is None:
        return ""
    metrics = ", ".join(f"{k[len('mean_'):]} {worst[k]:.3f}" for k in worst if k.startswith("mean_abs"))
    return (f"worst block {worst['name']} (fall rate {worst['fall_rate']:.2f}, {metrics}), "
            f"{len(result['blocks_failed'])} of {len(result['blocks'])} blocks fail")


__all__ = ["DEFAULT_EPISODES", "EvalLayout", "blocks_table", "eval_layout", "judge_blocks", "worst_block",
           "worst_block_text"]
