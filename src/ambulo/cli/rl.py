"""``ambulo train | play | export | eval``: the RL commands (need the ``rl`` extra).

Each handler imports ``ambulo.rl`` (and so rsl-rl-lib and torch) only when it runs. Task
configs come from the task registry (``ambulo.envs.spec(task).cfg_fn()``) and PPO settings
from ``default_ppo_cfg``; ``--env-cfg`` / ``--ppo-cfg`` overrides are typed against them
(``ambulo.utils.overrides``).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import errno
import math
import os
import re
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ..utils.overrides import OverrideError, parse_overrides
from .errors import CliError
from .viewer_args import add_viewer_args, web_watch

STARTED_S = time.monotonic()
"""When the command started (this module is imported as ``ambulo`` starts): ``--eval-every``
times the first success from here, so imports, env build and kernel compile count."""

# ---------------------------------------------------------------------------------------------
# where the CLI gets tasks and their configs


def task_names() -> list[str]:
    """Registered task names."""
    from ambulo import envs

    return envs.names()


def task_description(task: str) -> str:
    """One line on what ``task`` is."""
    from ambulo import envs

    return envs.spec(task).description


def default_env_cfg(task: str) -> Any:
    """A fresh default config (a dataclass) of ``task``, from the task registry."""
    from ambulo import envs

    return envs.spec(task).cfg_fn()


def default_ppo_cfg(task: str) -> Any:
    """The default PPO settings (a ``PpoCfg`` dataclass) of ``task``.

    The one place the CLI obtains them: if PpoCfg or the per-task PPO factories move, change
    only this function."""
    from ambulo.rl.config import ppo_cfg

    return ppo_cfg(task)


def default_offpolicy_cfg(task: str, algo: str) -> Any:
    """The default settings (an ``OffPolicyCfg``) of ``ambulo train TASK --algo ALGO`` for an
    off-policy ``algo`` (fast-sac, fast-td3)."""
    from ambulo.rl.offpolicy.config import offpolicy_cfg

    return offpolicy_cfg(task, algo)


def check_task(task: str) -> None:
    """``CliError`` naming close task names if ``task`` is not registered."""
    names = task_names()
    if task not in names:
        close = difflib.get_close_matches(task, names, n=3)
        fix = (f"did you mean {' or '.join(map(repr, close))}?" if close else
               f"tasks: {', '.join(names)}")
        raise CliError(f"no task named {task!r}", fix)


def tasks_help() -> str:
    """The task list shown by ``ambulo train --help``."""
    names = task_names()
    width = max(map(len, names), default=0)
    return "tasks:\n" + "\n".join(f"  {name:<{width}}  {task_description(name)}" for name in names)


# ---------------------------------------------------------------------------------------------
# overrides

_ENV_KEYS_WITH_FLAGS = {"num_envs": "--num-envs", "device": "--device", "seed": "--seed"}
"""Task config fields that ``ambulo train`` sets from its own flags (not by --env-cfg)."""

def typed_overrides(flag: str, cfg: Any, pairs: list[str] | None,
                    reserved: dict[str, str] | None = None) -> dict[str, Any]:
    """``--flag KEY=VALUE`` pairs checked against dataclass ``cfg`` -> ``{dotted key: typed
    value}``, JSON-safe for the run's ``run.json`` and applied by ``ambulo.envs.make_cfg`` /
    ``ambulo.rl.config.ppo_cfg``. ``CliError`` on a bad pair or a key in ``reserved`` (key ->
    the flag that sets it)."""
    if not pairs:
        return {}
    try:
        values = parse_overrides(cfg, pairs)
    except OverrideError as err:
        raise CliError(f"{flag} {err.problem}", err.fix) from None
    for key in values:
        head = key.split(".")[0]
        if reserved and head in reserved:
            raise CliError(f"{flag} cannot set {head}", f"use {reserved[head]} instead")
    return values


# ---------------------------------------------------------------------------------------------
# commands


def _check_positive(args: argparse.Namespace, *names: str) -> None:
    for name in names:
        value = getattr(args, name)
        if value is not None and value <= 0:
            flag = "--" + name.replace("_", "-")
            raise CliError(f"{flag} {value} is not positive", f"give {flag} above 0")


def whole_above_zero(example: str) -> Callable[[str], int]:
    """argparse ``type`` for counts and sizes: a whole number > 0 (``1.5``, ``0`` and ``-3``
    fail at parsing, in one line naming a valid value, before anything runs)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value <= 0:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number above 0; give "
                                             f"e.g. {example}")
        return value

    return parse


def seconds_above_zero(example: str) -> Callable[[str], float]:
    """argparse ``type`` for durations: a finite number of seconds > 0."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value <= 0:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds above 0; "
                                             f"give e.g. {example}")
        return value

    return parse


def _check_writable(path: str | os.PathLike | None, flag: str, *, folder: bool) -> None:
    """``CliError`` unless ``path`` (a file, or a ``folder``) can be created: it is not the
    other kind, and its nearest existing parent is a folder this user may write in. Checked
    before a command spends minutes on work it could not save."""
    if path is None:
        return
    target = Path(path).absolute()
    fix = f"give {flag} a place you can write to"
    if target.exists() and target.is_dir() != folder:
        kind = "a file" if folder else "a folder"
        raise CliError(f"{flag} {path} is {kind}", fix)
    parent = target if folder else target.parent
    existing = next(p for p in (parent, *parent.parents) if p.exists())
    if not existing.is_dir():
        raise CliError(f"cannot write {flag} {path}: {existing} is a file, not a folder", fix)
    if not os.access(existing, os.W_OK | os.X_OK):
        raise CliError(f"cannot write {flag} {path}: {existing} is not writable", fix)


_WRITE_ERRORS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT,
                 errno.EEXIST, errno.ENOTDIR, errno.EISDIR}


@contextlib.contextmanager
def _rl_errors(out_flag: str) -> Iterator[None]:
    """``ambulo.rl``'s own errors (a missing or corrupt checkpoint, a run that cannot resume)
    and failed writes, as one-line ``CliError``s."""
    from ambulo.rl import RunError

    try:
        yield
    except RunError as err:
        raise CliError(err.problem, err.fix) from None
    except OSError as err:
        if err.errno not in _WRITE_ERRORS or err.filename is None:
            raise
        raise CliError(f"cannot write {err.filename}: {err.strerror}",
                       f"give {out_flag} a place you can write to") from None


def _check_run(run: str) -> None:
    """``CliError`` unless ``run`` is a run folder, a checkpoint file or a task name (whose
    runs ``ambulo.rl`` looks up under --log-root, with its own messages)."""
    path = Path(run)
    if (path / _RUN_FILE).is_file() or (path.is_file() and _CHECKPOINT.match(path.name)):
        return
    names = task_names()
    if run in names:
        return
    if path.is_dir():
        raise CliError(f"{run} is not a run folder (it holds no {_RUN_FILE})",
                       "pass the folder `ambulo train` printed (runs/<task>/<time>)")
    if path.is_file():
        raise CliError(f"{run} is not a checkpoint (model_<iteration>.pt)",
                       "pass a run folder or a model_<iteration>.pt in one")
    close = difflib.get_close_matches(run, names, n=3)
    fix = (f"did you mean the task {' or '.join(map(repr, close))}?" if close else
           f"pass the folder `ambulo train` printed (runs/<task>/<time>), a checkpoint in it, "
           f"or a task name ({', '.join(names)}) for its latest run")
    raise CliError(f"no run folder, checkpoint or task named {run!r}", fix)


_RUN_FILE = "run.json"
"""``ambulo.rl.runs.RUN_FILE`` (not imported: it pulls in rsl-rl-lib)."""
_CHECKPOINT = re.compile(r"^model_\d+\.pt$")


def train(args: argparse.Namespace) -> int:
    if args.task is not None:
        check_task(args.task)
    resume = args.resume
    if resume is not None and resume is not True and resume in ("", "last"):
        resume = True
    env_overrides: dict[str, Any] = {}
    ppo_overrides: dict[str, Any] = {}
    sizes = {"num_envs": args.num_envs, "max_iterations": args.max_iterations}
    algo, algo_cfg = getattr(args, "algo", None), getattr(args, "algo_cfg", None)  # a namespace built by hand
    offpolicy = (algo or "ppo") != "ppo"
    init_from = getattr(args, "init_from", None)
    if init_from is not None and resume:
        raise CliError("--init-from and --resume both given (--init-from starts a new run from a checkpoint's "
                       "weights, --resume continues a run)", "give one of them")
    if resume:
        if args.env_cfg or args.ppo_cfg:
            raise CliError("--env-cfg and --ppo-cfg apply to new runs only (a resumed run keeps "
                           "the settings in its run.json)", "drop them, or start a new run")
        if resume is True and args.task is None:
            raise CliError("--resume without a run needs the task",
                           "ambulo train <task> --resume, or --resume runs/<task>/<time>")
        if resume is not True:
            _check_run(resume)
        if algo_cfg:
            raise CliError("--algo-cfg applies to new runs only (a resumed run keeps the settings in "
                           "its run.json)", "drop it, or start a new run")
    else:
        if args.task is None:
            raise CliError("no task given", f"name one: {', '.join(task_names())}")
        if args.env_cfg:
            env_overrides = typed_overrides("--env-cfg", default_env_cfg(args.task), args.env_cfg,
                                            reserved=_ENV_KEYS_WITH_FLAGS)
        if offpolicy and args.ppo_cfg:
            raise CliError(f"--ppo-cfg sets PPO's settings, not {algo}'s", "use --algo-cfg KEY=VALUE")
        if not offpolicy and algo_cfg:
            raise CliError("--algo-cfg sets the settings of --algo fast-sac or fast-td3", "use --ppo-cfg for PPO")
        if args.ppo_cfg:
            ppo_overrides = typed_overrides("--ppo-cfg", default_ppo_cfg(args.task), args.ppo_cfg)
        if algo_cfg:  # the off-policy settings, in the same dict: num_envs/max_iterations below
            ppo_overrides = typed_overrides("--algo-cfg", default_offpolicy_cfg(args.task, algo),
                                            algo_cfg, reserved={"algo": "--algo"})
        for key, value in sizes.items():  # PpoCfg fields that are also flags: one or the other
            if key in ppo_overrides:
                flag = "--" + key.replace("_", "-")
                if value is not None:
                    raise CliError(f"{flag} and --{'algo' if offpolicy else 'ppo'}-cfg {key}=... both given",
                                   "give one of them")
                sizes[key] = ppo_overrides.pop(key)
    _check_positive(argparse.Namespace(**sizes), *sizes)
    _check_writable(args.log_root, "--log-root", folder=True)
    if args.stop_at_criterion and not args.eval_every:
        raise CliError("--stop-at-criterion needs --eval-every", "add e.g. --eval-every 50")
    if args.eval_async and not args.eval_every:
        raise CliError("--eval-async needs --eval-every", "add e.g. --eval-every 50")
    if args.eval_async and args.num_gpus is not None:
        raise CliError("--eval-async evaluates beside one training process, not --num-gpus ranks",
                       "drop --eval-async (the ranks evaluate together)")
    watch = web_watch(args)
    if args.num_gpus is not None and os.environ.get("LOCAL_RANK") is None:
        return _train_on_gpus(args, watch)

    from ambulo.rl import TrainingInterrupted
    from ambulo.rl import train as run_train

    try:
        with _rl_errors("--log-root"):
            run_train(args.task, num_envs=sizes["num_envs"], max_iterations=sizes["max_iterations"],
                      seed=args.seed, device=args.device, resume=resume, log_root=args.log_root,
                      env_overrides=env_overrides, algo=algo, init_from=init_from,
                      ppo_overrides=None if offpolicy else ppo_overrides,
                      algo_overrides=ppo_overrides if offpolicy else None,
                      verbose=args.verbose, eval_every=args.eval_every,
                      stop_at_criterion=args.stop_at_criterion, started_s=STARTED_S, watch=watch,
                      eval_async=args.eval_async)
    except TrainingInterrupted as stopped:  # SIGINT/SIGTERM: says what was saved, how to resume
        print(f"ambulo train: {stopped}", file=sys.stderr)
        return stopped.exit_status
    return 0


def _train_on_gpus(args: argparse.Namespace, watch: Callable | None) -> int:
    """``ambulo train TASK --num-gpus N``: this command as N torchrun ranks (``rl.launch``)."""
    from ambulo.rl.eval_gpus import check_num_gpus
    from ambulo.rl.launch import launch_ranks, without_option

    if watch is not None:
        raise CliError("--viewer watches one process's training", "drop --viewer or --num-gpus")
    device = args.device or "cuda"
    try:
        check_num_gpus(args.num_gpus, device, what="trains")
    except ValueError as err:
        raise CliError(str(err)) from None
    if args.num_gpus == 1:
        args.num_gpus = None
        args.device = device
        return train(args)
    argv = without_option(list(args.argv), "--num-gpus")
    if args.device is None:
        argv += ["--device", device]
    return launch_ranks(argv, args.num_gpus)


def play(args: argparse.Namespace) -> int:
    _check_run(args.run)
    _check_writable(args.out, "--out", folder=False)
    watch = web_watch(args, real_time=True)
    if watch is not None and args.out:
        raise CliError("--viewer web shows the rollout live; --out films it to an MP4", "pass one of them")
    from ambulo.rl import play as run_play

    with _rl_errors("--out"):
        run_play(args.run, checkpoint=args.checkpoint, seconds=args.seconds, out=args.out,
                 width=args.width, height=args.height, log_root=args.log_root, device=args.device,
                 watch=watch)
    return 0


def export(args: argparse.Namespace) -> int:
    _check_run(args.run)
    _check_writable(args.out_dir, "--out-dir", folder=True)
    from ambulo.rl import export as run_export

    with _rl_errors("--out-dir"):
        run_export(args.run, checkpoint=args.checkpoint, out_dir=args.out_dir,
                   log_root=args.log_root)
    return 0


_EVAL_KEYS_WITH_FLAGS = {**_ENV_KEYS_WITH_FLAGS, "num_envs": "--episodes", "episode_length_s": "--episode-length-s"}
"""Task config fields that ``ambulo eval`` sets from its own flags (not by --env-cfg)."""


def _eval_env_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """``ambulo eval --env-cfg`` pairs typed against the evaluated task's config."""
    if not args.env_cfg:
        return {}
    if args.num_gpus is not None:
        raise CliError("--env-cfg is not carried to --num-gpus processes", "drop one of them")
    if args.shipped:
        task = args.run  # checked by _evaluate_shipped
        from ambulo.policies.shipped import shipped_tasks

        if task not in shipped_tasks():
            return {}
    else:
        _check_run(args.run)
        from ambulo.rl import runs

        with _rl_errors("the run folder"):
            task = runs.read_run_info(runs.resolve_run(args.run, args.log_root))["task"]
    return typed_overrides("--env-cfg", default_env_cfg(task), args.env_cfg, reserved=_EVAL_KEYS_WITH_FLAGS)


def evaluate(args: argparse.Namespace) -> int:
    watch = web_watch(args)
    args.env_overrides = _eval_env_overrides(args)
    if args.shipped:
        result = _evaluate_shipped(args, watch)
    elif args.num_gpus is not None:
        result = _evaluate_on_gpus(args, watch)
    else:
        _check_run(args.run)
        from ambulo.rl import evaluate as run_eval

        with _rl_errors("the run folder (eval.json goes there)"):
            result = run_eval(args.run, checkpoint=args.checkpoint, num_episodes=args.episodes,
                              episode_length_s=args.episode_length_s, seed=args.seed,
                              log_root=args.log_root, device=args.device, watch=watch,
                              env_overrides=args.env_overrides)
    if not args.require_criteria:
        return 0
    failed = [name for name in result.get("criteria", []) if not result[name]]
    return 1 if failed else 0


def _evaluate_on_gpus(args: argparse.Namespace, watch: Callable | None) -> dict:
    """``ambulo eval RUN --num-gpus N``: the episodes split over N processes, one GPU each."""
    if args.shipped or watch is not None:
        raise CliError("--num-gpus evaluates a run folder with no viewer", "drop --shipped / --viewer or --num-gpus")
    _check_run(args.run)
    from ambulo import envs
    from ambulo.rl import runs
    from ambulo.rl.eval_blocks import eval_layout
    from ambulo.rl.eval_gpus import check_num_gpus, evaluate_split

    with _rl_errors("the run folder (eval.json goes there)"):
        device = args.device or runs.read_run_info(runs.resolve_run(args.run, args.log_root))["device"]
        try:
            check_num_gpus(args.num_gpus, device)
            task = envs.spec(runs.read_run_info(runs.resolve_run(args.run, args.log_root))["task"])
            layout = eval_layout(task, args.episodes)
            per_block = layout.num_episodes // layout.blocks
            if per_block < args.num_gpus:
                raise ValueError(f"--episodes {layout.num_episodes} cannot be split over --num-gpus {args.num_gpus}"
                                 + (f" ({layout.blocks} blocks of {per_block})" if layout.names else ""))
        except ValueError as err:
            raise CliError(str(err)) from None
        return evaluate_split(args.run, processes=args.num_gpus, checkpoint=args.checkpoint,
                              num_episodes=args.episodes, episode_length_s=args.episode_length_s, seed=args.seed,
                              log_root=args.log_root)


def _evaluate_shipped(args: argparse.Namespace, watch: Callable | None) -> dict:
    """``ambulo eval TASK --shipped``: the policy in ambulo's assets, no run folder."""
    from ambulo.policies.shipped import shipped_tasks

    shipped = shipped_tasks()
    if args.run not in shipped:
        raise CliError(f"no shipped policy for {args.run!r}",
                       f"--shipped takes a task with one: {', '.join(shipped) or 'none'}")
    if args.checkpoint:
        raise CliError("--checkpoint does not apply to --shipped", "drop one of them")
    from ambulo.rl.evaluate import evaluate_shipped

    return evaluate_shipped(args.run, num_episodes=args.episodes, episode_length_s=args.episode_length_s,
                            seed=args.seed, device=args.device or "cpu", watch=watch,
                            env_overrides=args.env_overrides)


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``train``, ``play``, ``export`` and ``eval`` to the ``ambulo`` parser."""
    run_help = ("a run folder (runs/<task>/<time>), a checkpoint in one, or a task name "
                "(its latest run)")
    checkpoint_help = ("model_<it>.pt or <it> in the run folder, or a path (default: the newest "
                       "readable)")

    p = subparsers.add_parser(
        "train", help="train a task with PPO (rsl-rl-lib) or fast-sac / fast-td3, on N GPUs with --num-gpus",
        description="Train a task with PPO (rsl-rl-lib), or the parallel off-policy fast-sac / fast-td3 "
                    "(--algo); --num-gpus N trains data-parallel on N GPUs. Checkpoints and TensorBoard logs "
                    "go to <log-root>/<task>/<time>/. --env-cfg, --ppo-cfg and --algo-cfg values are read as the "
                    "field's type: 10, 0.5, true, cuda:0, 0.1,0.2 or (0.1, 0.2) for tuples, "
                    "{'alive': 1.0} for dicts, none; dotted keys reach nested fields "
                    "(physics.solver_iterations=50) and dict entries (reward_weights.alive=2).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.lazy_epilog = tasks_help
    p.add_argument("task", nargs="?", metavar="TASK", help="task to train (listed below)")
    p.add_argument("--num-envs", type=whole_above_zero("--num-envs 64"),
                   help="parallel envs (default: the task's)")
    p.add_argument("--max-iterations", type=whole_above_zero("--max-iterations 100"),
                   help="PPO iterations in total")
    p.add_argument("--seed", type=int, help="default 0; a resumed run keeps its own")
    p.add_argument("--device", help="cpu (default) or cuda[:N]; a resumed run keeps its own")
    p.add_argument("--resume", nargs="?", const=True, metavar="RUN",
                   help="continue the task's latest run, or RUN, from its newest readable "
                        "checkpoint (SIGINT/SIGTERM during training save one)")
    p.add_argument("--init-from", metavar="CHECKPOINT_OR_RUN",
                   help="fine-tune: a new run (its own folder and settings, iteration 0, a fresh optimizer) "
                        "whose networks start from a model_<it>.pt, or a run folder's newest readable one; "
                        "the networks must have the task's sizes (run.json records the checkpoint)")
    p.add_argument("--log-root", default="runs", help="where run folders go")
    p.add_argument("--env-cfg", action="append", metavar="KEY=VALUE",
                   help="set a field of the task's config, e.g. episode_length_s=10 (repeatable)")
    p.add_argument("--ppo-cfg", action="append", metavar="KEY=VALUE",
                   help="set a PPO setting (PpoCfg), e.g. learning_rate=3e-4 (repeatable)")
    p.add_argument("--algo", choices=("ppo", "fast-sac", "fast-td3"),
                   help="ppo (default: rsl-rl-lib), or the parallel off-policy fast-sac / fast-td3 "
                        "(ambulo.rl.offpolicy); a resumed run keeps its own")
    p.add_argument("--algo-cfg", action="append", metavar="KEY=VALUE",
                   help="with --algo fast-sac/fast-td3: set one of its settings (OffPolicyCfg), e.g. "
                        "batch_size=4096 (repeatable)")
    p.add_argument("--verbose", action="store_true", help="rsl-rl's full report per iteration")
    p.add_argument("--eval-every", type=whole_above_zero("--eval-every 50"), metavar="K",
                   help="every K iterations evaluate the policy as `ambulo eval` does (evals.csv) "
                        "and print the time from start to the first that meets the task's criteria")
    p.add_argument("--stop-at-criterion", action="store_true",
                   help="with --eval-every: end training at the first evaluation that meets them "
                        "(on a GPU: that also meets them on the CPU engine, evaluated then)")
    p.add_argument("--eval-async", action="store_true",
                   help="with --eval-every: evaluate in a worker process while training goes on (the "
                        "verdict a few iterations later; its log: <run>/eval_worker.log)")
    p.add_argument("--num-gpus", type=whole_above_zero("--num-gpus 2"), default=None, metavar="N",
                   help="train on GPUs 0..N-1 as N data-parallel ranks (torchrun's, started for you; "
                        "--num-envs per GPU)")
    add_viewer_args(p)  # one env of the batch, with the training curves beside it
    p.set_defaults(func=train)

    p = subparsers.add_parser("play", help="roll a trained policy out headless to an MP4")
    p.add_argument("run", help=run_help)
    p.add_argument("--checkpoint", help=checkpoint_help)
    p.add_argument("--seconds", type=seconds_above_zero("--seconds 10"), default=10.0)
    p.add_argument("--out", help="MP4 path (default: <run>/videos/play.mp4)")
    p.add_argument("--width", type=whole_above_zero("--width 640"), default=640)
    p.add_argument("--height", type=whole_above_zero("--height 480"), default=480)
    p.add_argument("--device", help="cpu or cuda[:N] (default: the run's)")
    p.add_argument("--log-root", default="runs")
    add_viewer_args(p)  # the rollout live at real time instead of an MP4
    p.set_defaults(func=play)

    p = subparsers.add_parser("export", help="write ONNX (checked with onnxruntime) + TorchScript")
    p.add_argument("run", help=run_help)
    p.add_argument("--checkpoint", help=checkpoint_help)
    p.add_argument("--out-dir", help="default: <run>/exported")
    p.add_argument("--log-root", default="runs")
    p.set_defaults(func=export)

    p = subparsers.add_parser("eval", help="fall rate and velocity error over many episodes")
    p.add_argument("run", help=run_help + "; with --shipped, a task with a policy in ambulo's assets")
    p.add_argument("--shipped", action="store_true",
                   help="evaluate the policy that ships with ambulo for the task RUN names "
                        "(e.g. `ambulo eval humanoid-walk --shipped --device cpu`)")
    p.add_argument("--checkpoint", help=checkpoint_help)
    p.add_argument("--episodes", type=whole_above_zero("--episodes 100"), default=None,
                   help="episodes in all (default 100; a task judged in blocks: 20 a block, e.g. "
                        "humanoid-walk-robust's 17 blocks: nominal + 16 transfer corners, 340)")
    p.add_argument("--episode-length-s", type=seconds_above_zero("--episode-length-s 20"),
                   default=None,
                   help="seconds per episode (default: the task's training episode length)")
    p.add_argument("--seed", type=int, default=12345)
    p.add_argument("--device", help="cpu or cuda[:N] (default: the run's); cpu after GPU training "
                   "is a sim-to-sim check")
    p.add_argument("--log-root", default="runs")
    p.add_argument("--num-gpus", type=whole_above_zero("--num-gpus 2"), default=None,
                   help="split the episodes over N processes, one GPU each (cuda:0..N-1), merged into one "
                        "result (other episodes than one process runs for the seed: each share has its own)")
    p.add_argument("--env-cfg", action="append", metavar="KEY=VALUE",
                   help="evaluate under a changed task config, on top of the run's, e.g. "
                        "friction_range=0.3,0.3 (repeatable; the result names the changes)")
    p.add_argument("--require-criteria", "--require-walk", dest="require_criteria", action="store_true",
                   help="exit 1 unless every success criterion of the task holds (humanoid-walk's "
                        "'walks': fall rate <= 5%% and velocity error <= 0.2 m/s)")
    add_viewer_args(p)  # the episodes as they run, one env of --episodes at a time
    p.set_defaults(func=evaluate)
