"""The robustness table: a walking policy evaluated under transfer randomization, term by term.

Issue 30: "the flat-ground policy still meets ``walks`` with gains +-20 %, 0-20 ms latency and
CoM +-3 cm". Each row evaluates the same policy as ``ambulo eval`` does (``rl.run_episodes``: one
full episode per env of the task's play variant, deterministic actions) with one
``envs.transfer.TransferCfg`` on top: nominal, each term alone, the issue's three together, and
``transfer_cfg_wide`` (all terms). The nominal row is the ceiling the others are read against.

``--set corners`` evaluates the issue's three terms at the corners of their ranges instead of drawn
within them: every joint's kp and kd at 0.8 or 1.2, the action latency at 0 or 20 ms, the pelvis
and torso CoM at (+-3, +-3, +3) cm (z up: a raised CoM is the harder one), 16 corners, beside the
nominal row and the random draws of the three (``issue_three``).

    python benchmarks/robustness.py --shipped humanoid-walk --num-episodes 100
    python benchmarks/robustness.py --shipped humanoid-walk --set corners --num-episodes 32
    python benchmarks/robustness.py --run runs/humanoid-walk/<run> --device cuda --num-episodes 1000
    python benchmarks/robustness.py --run runs/humanoid-walk-robust/<run>/model_300.pt --set corners \
        --device cuda --num-episodes 100 --batched

``--run`` takes a run folder (its newest checkpoint) or one checkpoint in it. ``--batched``
evaluates every row in one env, side by side (``num_episodes`` worlds a row, the rows as
humanoid-walk's ``transfer_blocks``): one rollout instead of one a row, for the GPU, where a row
costs its 1,000 sequential steps whatever its width. Each row draws other random numbers than it
would alone, so its figures differ from the row-by-row ones within their sampling error.

Ends with one ``RESULT {json}``: each row's fall rate, velocity error and ``walks``; ``ratio`` is
the share of the rows where the task's criteria hold (1.0 when every row walks). humanoid-walk-robust's
own criterion (``walks_robust``, ``ambulo eval``) is ``walks`` in each of the nominal row and the 16
corners, the rows of ``--set corners --only nominal,<the corners>``.
"""

from __future__ import annotations

import argparse
import functools
import json

from ambulo import envs
from ambulo.envs.transfer import TransferCfg, transfer_cfg_wide, transfer_corners
from ambulo.rl import runs
from ambulo.rl.evaluate import eval_episode_length_s, run_episodes
from ambulo.rl.vecenv import RslRlVecEnv

CONDITIONS = {
    "nominal": TransferCfg(),
    "gains_20pct": TransferCfg(kp_scale_range=(0.8, 1.2), kd_scale_range=(0.8, 1.2)),
    "latency_0_20ms": TransferCfg(action_latency_range_s=(0.0, 0.02)),
    "com_3cm": TransferCfg(com_offset_m=0.03),
    "strength_10pct": TransferCfg(motor_strength_range=(0.9, 1.1)),
    "joint_friction_0_0.5nm": TransferCfg(joint_friction_range_n_m=(0.0, 0.5)),
    "armature_20pct": TransferCfg(armature_scale_range=(0.8, 1.2)),
    "obs_delay_0_1step": TransferCfg(observation_delay_range_steps=(0, 1)),
    "issue_three": TransferCfg(kp_scale_range=(0.8, 1.2), kd_scale_range=(0.8, 1.2),
                               action_latency_range_s=(0.0, 0.02), com_offset_m=0.03),
    "wide": transfer_cfg_wide(),
}


def corner_conditions() -> dict[str, TransferCfg]:
    """Nominal, the random draws of the issue's three terms, and their 16 corners
    (``envs.transfer.transfer_corners``: the corners humanoid-walk-robust's criterion is judged at)."""
    return {"nominal": CONDITIONS["nominal"], "issue_three": CONDITIONS["issue_three"], **transfer_corners()}


def policy_maker(args):
    """``make(env) -> policy`` for a run's checkpoint or a shipped policy, and the task name."""
    if args.run:
        run_dir, ckpt = runs.resolve_policy(args.run, None, args.log_root)
        info = runs.read_run_info(run_dir)

        def make_env(num_envs, seed, **overrides):
            return runs.make_env_for_run(info, num_envs=num_envs, seed=seed, play=True, device=args.device,
                                         **overrides)

        def make_policy(env):
            return runs.load_runner(run_dir, env, ckpt).get_inference_policy(device=str(env.device))
        return info["task"], make_env, make_policy
    from ambulo.policies.shipped import load_policy

    shipped = load_policy(args.shipped)

    def make_env(num_envs, seed, **overrides):
        return envs.make(args.shipped, num_envs=num_envs, device=args.device or "cpu", seed=seed, play=True,
                         **overrides)
    return args.shipped, make_env, lambda env: (lambda obs: shipped(obs["policy"]))


def add_policy_args(parser: argparse.ArgumentParser) -> None:
    """The arguments ``policy_maker`` reads: ``--run`` or ``--shipped``, ``--log-root``, ``--device``."""
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--run", help="a training run folder or checkpoint")
    source.add_argument("--shipped", help="a task whose shipped policy to evaluate (humanoid-walk)")
    parser.add_argument("--log-root", default="runs")
    parser.add_argument("--device", default=None)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_policy_args(parser)
    parser.add_argument("--num-episodes", type=int, default=100)
    parser.add_argument("--episode-length-s", type=float, default=None)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--set", choices=("terms", "corners"), default="terms",
                        help="terms: each transfer term alone and together; corners: the issue's three at their corners")
    parser.add_argument("--only", default=None, help="comma-separated condition names")
    parser.add_argument("--num-threads", type=int, default=None,
                        help="CPU engine threads (default: the env's, every CPU); a shared machine wants fewer")
    parser.add_argument("--batched", action="store_true",
                        help="every row in one env, side by side (one rollout; for the GPU)")
    args = parser.parse_args()
    task, make_env, make_policy = policy_maker(args)
    spec = envs.spec(task)
    spec_criteria = [c.name for c in spec.criteria]
    conditions = CONDITIONS if args.set == "terms" else corner_conditions()
    names = args.only.split(",") if args.only else list(conditions)
    unknown = [name for name in names if name not in conditions]
    if unknown:
        parser.error(f"--only: no condition {', '.join(unknown)} in --set {args.set}; conditions: {', '.join(conditions)}")
    length_s = eval_episode_length_s(spec, args.episode_length_s)
    if args.num_threads is not None:
        make_env = functools.partial(make_env, num_threads=args.num_threads)
    rows = {}

    def report(name: str, measured: dict) -> None:
        rows[name] = {k: measured[k] for k in ("fall_rate", "mean_abs_vel_error_m_s", *measured["criteria"])
                      if k in measured}
        print(f"{name:34s} " + "  ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}"
                                         for k, v in rows[name].items()), flush=True)

    if args.batched:
        env = make_env(args.num_episodes * len(names), args.seed,
                       transfer_blocks=tuple(conditions[name] for name in names), episode_length_s=length_s)
        measured = run_episodes(env, RslRlVecEnv(env), make_policy(env), spec, quiet=True, blocks=tuple(names))
        for name, block in zip(names, measured["blocks"]):
            report(name, block)
    for name in names if not args.batched else ():
        env = make_env(args.num_episodes, args.seed, transfer=conditions[name], episode_length_s=length_s)
        report(name, run_episodes(env, RslRlVecEnv(env), make_policy(env), spec, desc=name, quiet=True))
    # a row walks where every criterion of the task holds in it (walks; humanoid-walk-robust's walks_robust)
    walks = [all(r[c] for c in spec_criteria) for r in rows.values()]
    result = {"task": task, "policy": args.run or f"shipped {args.shipped}", "device": args.device or "cpu",
              "episodes": args.num_episodes, "set": args.set, "seed": args.seed, "batched": args.batched,
              "rows": rows, "ratio": round(sum(walks) / len(walks), 3)}
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
