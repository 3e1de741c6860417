"""How left-right symmetric a walking policy is, over its own rollouts: |pi(M o) - M pi(o)|.

``M`` is the task's mirror map (``envs.symmetry``: the robot's sagittal plane, derived from the model
and checked against the physics). A symmetric policy answers a mirrored situation with the mirrored
action; one that is not limps, turns or drifts to one side. Training with ``--ppo-cfg
symmetry=true`` / ``--algo-cfg symmetry=true`` should drive the error toward zero; this measures it.

``--worlds`` robots run the play variant of the task for ``--seconds`` under the policy; at every step
the policy is also asked for the mirrored observation (no effect on the rollout). Reported:
  - ``mirror_error``: mean |pi(M o) - M pi(o)| over steps, worlds and actions (action units);
  - ``action_mean``: mean |pi(o)|, the scale it compares with;
  - ``worst_joints``: the joints with the largest mean error.

    python benchmarks/policy_symmetry.py --shipped humanoid-walk
    python benchmarks/policy_symmetry.py --run runs/humanoid-rough/<run> --device cpu

Ends with one ``RESULT {json}``; ``ratio`` = mirror_error / action_mean (0: perfectly symmetric).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from ambulo.envs.symmetry import TaskMirror, task_mirror
from ambulo.rl.symmetry import mirrored_obs
from ambulo.rl.vecenv import RslRlVecEnv

# the sibling script's one way to load a run's checkpoint or a shipped policy
sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness import add_policy_args, policy_maker


@torch.no_grad()
def measure(env, policy, mirror: TaskMirror, steps: int) -> dict:
    """Roll ``policy`` out for ``steps`` in ``env`` and compare it with its mirror image at every step.
    Returns the summed (A,) absolute errors and |actions|, and the count of (step, world) samples."""
    vec = RslRlVecEnv(env)
    obs = vec.get_observations()
    error = torch.zeros(env.num_actions, dtype=torch.float64)
    magnitude = torch.zeros(env.num_actions, dtype=torch.float64)
    for _ in range(steps):
        actions = policy(obs)
        reflected = policy(mirrored_obs(obs, mirror))
        error += (reflected - mirror.actions(actions)).abs().sum(dim=0).double().cpu()
        magnitude += actions.abs().sum(dim=0).double().cpu()
        obs = vec.step(actions)[0]
    return {"error": error, "magnitude": magnitude, "samples": steps * env.num_envs}


def summary(sums: dict, joint_names: list[str], worst: int = 4) -> dict:
    n = sums["samples"]
    per_joint = sums["error"] / n
    mirror_error, action_mean = float(per_joint.mean()), float((sums["magnitude"] / n).mean())
    order = torch.argsort(per_joint, descending=True)[:worst].tolist()
    return {"mirror_error": round(mirror_error, 5), "action_mean": round(action_mean, 5),
            "ratio": round(mirror_error / action_mean, 4) if action_mean > 0 else None,
            "worst_joints": {joint_names[j]: round(float(per_joint[j]), 5) for j in order}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_policy_args(p)
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--seed", type=int, default=3)
    args = p.parse_args()
    if args.device is None and not torch.cuda.is_available():
        args.device = "cpu"
    task, make_env, make_policy = policy_maker(args)
    env = make_env(args.worlds, args.seed)
    mirror = task_mirror(env)
    policy = make_policy(env)
    steps = round(args.seconds / env.step_dt_s)
    result = summary(measure(env, policy, mirror, steps), list(env.robot.joint_names))
    env.close()
    print(f"{task}: mirror error {result['mirror_error']:.4f} of mean |action| {result['action_mean']:.4f} "
          f"({100 * (result['ratio'] or 0):.1f} %); worst {result['worst_joints']}")
    print("RESULT " + json.dumps({"benchmark": "policy_symmetry", "task": task,
                                  "policy": args.run or f"shipped {args.shipped}", "worlds": args.worlds,
                                  "seconds": args.seconds, **result}))


if __name__ == "__main__":
    main()
