"""How a walking policy follows slow and fast commands: the forward speed it reaches at each commanded speed.

A pooled velocity error hides the way a policy fails. humanoid-rough's PPO walker after 24 minutes (session 16)
had 0.33 m/s of error on its hardest tiles, and this table showed why: it stood still under a 0.25 m/s command
on flat tiles, and at the foot of 0.15 m stairs under anything below 0.75 m/s. The flat walkers reach 0.28-0.31 m/s
at the same command.

For each commanded forward speed (``--speeds``, m/s; no lateral velocity, no yaw, no standing or heading envs) and,
on a terrain task, each tile kind (``--kinds``; every robot on the hardest level of that kind, the play variant),
``--worlds`` robots walk for ``--seconds``. The command is written every step, so a robot that falls and restarts
keeps it. Reported for each row:
  - the mean forward speed in the heading frame after ``--settle-s``;
  - the share of robots that moved less than a quarter of what was asked ("stood");
  - the falls.

    python benchmarks/command_tracking.py --shipped humanoid-walk
    python benchmarks/command_tracking.py --run runs/humanoid-rough/<run> --kinds flat,stairs_up,stepping_stones

Ends with one ``RESULT {json}``. ``ratio`` is the mean over the moving rows of speed / command (1.0: every
command reached, whatever the falls).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from ambulo.envs.observations import base_lin_vel_yaw
from ambulo.rl.vecenv import RslRlVecEnv

# the sibling script's one way to load a run's checkpoint or a shipped policy
sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness import add_policy_args, policy_maker

FORWARD_ONLY = {"commands.lin_vel_y_m_s": (0.0, 0.0), "commands.yaw_rate_rad_s": (0.0, 0.0),
                "commands.heading_fraction": 0.0, "commands.standing_fraction": 0.0}
"""Env overrides under which a velocity task draws forward commands only: no lateral, yaw, heading or
standing draws (``hold_command`` then pins the forward speed)."""


def hold_command(env, command: torch.Tensor) -> None:
    """Put ``command`` (N, 3) back as every robot's velocity command, neither heading-steered nor standing:
    call it before each step, after whatever resample the previous step did (timers, a fallen robot's reset)."""
    env.commands.command.copy_(command)
    env.commands.is_heading.zero_()
    env.commands.is_standing.zero_()


def track(env, policy, speed_m_s: float, steps: int, settle_steps: int) -> dict:
    """Mean forward speed (m/s), the share of robots below a quarter of ``speed_m_s`` and the falls of
    ``env``'s robots under the fixed command (``speed_m_s``, 0, 0), from a reset."""
    vec = RslRlVecEnv(env)
    command = torch.zeros_like(env.commands.command)
    command[:, 0] = speed_m_s
    speed_sum = torch.zeros(env.num_envs, device=env.device)
    falls = torch.zeros((), dtype=torch.long, device=env.device)
    with torch.inference_mode():
        obs = vec.reset()
        for t in range(steps):
            hold_command(env, command)
            obs, _, dones, _ = vec.step(policy(obs))
            falls += dones.sum()  # episodes have no time-out in the play variant: a done is a fall
            if t >= settle_steps:
                data = env.robot.data
                speed_sum += base_lin_vel_yaw(data.root_quat_w, data.root_lin_vel_w)[:, 0].float()
    mean = speed_sum / (steps - settle_steps)
    stood = (mean < 0.25 * speed_m_s).float().mean().item() if speed_m_s > 0 else 0.0
    return {"command_m_s": speed_m_s, "speed_m_s": round(mean.mean().item(), 3), "stood": round(stood, 3),
            "falls": int(falls.item())}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_policy_args(p)
    p.add_argument("--kinds", default=None, help="tile kinds of a terrain task, comma-separated (default: all)")
    p.add_argument("--speeds", default="0.25,0.5,0.75,1.0", help="commanded forward speeds, m/s, comma-separated")
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--seconds", type=float, default=8.0)
    p.add_argument("--settle-s", type=float, default=3.0)
    p.add_argument("--seed", type=int, default=3)
    args = p.parse_args()
    if args.device is None and not torch.cuda.is_available():
        args.device = "cpu"  # a GPU-trained run read on a machine without one: the CPU engine
    try:
        speeds = [float(s) for s in args.speeds.split(",")]
    except ValueError:
        raise SystemExit(f"command_tracking: --speeds {args.speeds!r} is not a comma-separated list of m/s; "
                         "e.g. --speeds 0.25,0.5,1.0") from None
    if not 0.0 < args.settle_s < args.seconds:
        raise SystemExit(f"command_tracking: --settle-s {args.settle_s} must lie in (0, --seconds {args.seconds})")
    task, make_env, make_policy = policy_maker(args)
    fixed = FORWARD_ONLY
    probe = make_env(1, args.seed, **fixed)
    terrain = getattr(probe.cfg, "terrain", None)
    all_kinds = tuple(terrain.kinds) if terrain is not None else (None,)
    probe.close()
    kinds = all_kinds if args.kinds is None or terrain is None else tuple(args.kinds.split(","))
    unknown = sorted(set(kinds) - set(all_kinds))
    if unknown:
        raise SystemExit(f"command_tracking: unknown tile kinds {unknown}; {task} has {list(all_kinds)}")
    rows = []
    for kind in kinds:
        overrides = dict(fixed) if kind is None else {**fixed, "terrain.kinds": (kind,)}
        env = make_env(args.worlds, args.seed, **overrides)
        policy = make_policy(env)
        steps, settle = round(args.seconds / env.step_dt_s), round(args.settle_s / env.step_dt_s)
        cells = []
        for speed in speeds:
            row = {"kind": kind or "ground", **track(env, policy, speed, steps, settle)}
            rows.append(row)
            cells.append(f"{speed:.2f} -> {row['speed_m_s']:.2f} (stood {row['stood']:.2f}, falls {row['falls']})")
        print(f"{kind or 'ground':16s}", " | ".join(cells), flush=True)
        env.close()
    moving = [r for r in rows if r["command_m_s"] > 0]
    ratio = sum(min(r["speed_m_s"] / r["command_m_s"], 2.0) for r in moving) / max(len(moving), 1)
    print("RESULT " + json.dumps({"benchmark": "command_tracking", "task": task,
                                  "policy": args.run or f"shipped {args.shipped}", "worlds": args.worlds,
                                  "seconds": args.seconds, "settle_s": args.settle_s, "rows": rows,
                                  "ratio": round(ratio, 3)}))


if __name__ == "__main__":
    main()
