"""``ambulo train | play | export | eval``: the RL commands (need the ``rl`` extra).

Registered into the main parser by ``add_rl_commands(subparsers)``; each handler imports
``ambulo.rl`` (and so rsl-rl-lib and torch) only when it runs.
"""

from __future__ import annotations

import argparse
import ast
import sys


def _overrides(pairs: list[str] | None) -> dict:
    """``["episode_length_s=10", "push_interval_s=4.0"]`` -> typed dict (Python literals)."""
    result = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep:
            raise SystemExit(f"--env-cfg expects KEY=VALUE, got {pair!r}")
        try:
            result[key.strip()] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            result[key.strip()] = value
    return result


def train(args: argparse.Namespace) -> int:
    from ambulo.rl import train as run_train  # noqa: PLC0415

    resume = args.resume
    if resume is not None and resume is not True and resume in ("", "last"):
        resume = True
    run_train(args.task, num_envs=args.num_envs, max_iterations=args.max_iterations,
              seed=args.seed, device=args.device, resume=resume, log_root=args.log_root,
              env_overrides=_overrides(args.env_cfg), verbose=args.verbose)
    return 0


def play(args: argparse.Namespace) -> int:
    from ambulo.rl import play as run_play  # noqa: PLC0415

    run_play(args.run, checkpoint=args.checkpoint, seconds=args.seconds, out=args.out,
             width=args.width, height=args.height, log_root=args.log_root)
    return 0


def export(args: argparse.Namespace) -> int:
    from ambulo.rl import export as run_export  # noqa: PLC0415

    run_export(args.run, checkpoint=args.checkpoint, out_dir=args.out_dir,
               log_root=args.log_root)
    return 0


def evaluate(args: argparse.Namespace) -> int:
    from ambulo.rl import evaluate as run_eval  # noqa: PLC0415

    result = run_eval(args.run, checkpoint=args.checkpoint, num_episodes=args.episodes,
                      episode_length_s=args.episode_length_s, seed=args.seed,
                      log_root=args.log_root)
    return 0 if result.get("walks", True) or not args.require_walk else 1


def _task_names() -> list[str]:
    from ambulo.envs import names  # noqa: PLC0415

    return names()


def add_rl_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train``, ``play``, ``export`` and ``eval`` to the ``ambulo`` parser."""
    run_help = ("a run folder (runs/<task>/<time>), a checkpoint in one, or a task name "
                "(its latest run)")

    p = subparsers.add_parser("train", help="train a task with PPO (rsl-rl-lib)")
    p.add_argument("task", nargs="?", choices=_task_names(), help="task to train")
    p.add_argument("--num-envs", type=int, help="parallel envs (default: the task's)")
    p.add_argument("--max-iterations", type=int, help="PPO iterations in total")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--device", default="cpu", help="cpu or cuda[:N]")
    p.add_argument("--resume", nargs="?", const=True, metavar="RUN",
                   help="continue the task's latest run, or RUN, from its last checkpoint")
    p.add_argument("--log-root", default="runs", help="where run folders go")
    p.add_argument("--env-cfg", action="append", metavar="KEY=VALUE",
                   help="override a task config field (repeatable)")
    p.add_argument("--verbose", action="store_true", help="rsl-rl's full report per iteration")
    p.set_defaults(func=train)

    p = subparsers.add_parser("play", help="roll a trained policy out headless to an MP4")
    p.add_argument("run", help=run_help)
    p.add_argument("--checkpoint", help="model_<it>.pt to load (default: the latest)")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--out", help="MP4 path (default: <run>/videos/play.mp4)")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--log-root", default="runs")
    p.set_defaults(func=play)

    p = subparsers.add_parser("export", help="write ONNX (checked with onnxruntime) + TorchScript")
    p.add_argument("run", help=run_help)
    p.add_argument("--checkpoint")
    p.add_argument("--out-dir", help="default: <run>/exported")
    p.add_argument("--log-root", default="runs")
    p.set_defaults(func=export)

    p = subparsers.add_parser("eval", help="fall rate and velocity error over many episodes")
    p.add_argument("run", help=run_help)
    p.add_argument("--checkpoint")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--episode-length-s", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=12345)
    p.add_argument("--log-root", default="runs")
    p.add_argument("--require-walk", action="store_true",
                   help="exit 1 unless fall rate <= 5%% and velocity error <= 0.2 m/s")
    p.set_defaults(func=evaluate)


if __name__ == "__main__":  # python -m ambulo.cli_rl <command> ...
    parser = argparse.ArgumentParser(prog="ambulo")
    add_rl_commands(parser.add_subparsers(dest="command", required=True))
    arguments = parser.parse_args()
    sys.exit(int(arguments.func(arguments) or 0))
