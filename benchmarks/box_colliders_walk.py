"""The shipped rough walker with and without legs-only terrain boxes (``box_collider_bodies``), side by side.

Why: ``box_collider_bodies=HUMANOID_BOX_COLLIDERS`` lets only the legs touch the terrain's static
boxes (fewer candidate pairs for MuJoCo Warp's broadphase); a walker that never touches a box with
its pelvis, torso, head or arms cannot tell. Two envs of the same seed (the play variant: no
randomization, every robot on the hardest level of one box kind) step in lockstep under one forward
command, the shipped humanoid-rough policy acting on each env's own observations. On the CPU engine
(MuJoCo C) the filtered pairs only change the physics when such a geom would touch a box, so the
two trajectories stay bit-identical until that happens; each row reports the forward speed (after
``--settle-s``) and falls of both, the largest root-position gap between them, and how often a
non-leg robot geom touched a box in the default env (at each env step's last physics step, before
the resets of that step: a reset overwrites a world's state, so the terminal step is counted here).

    python benchmarks/box_colliders_walk.py --kinds flat,stairs_up,stairs_down --seeds 1,2,3,4
    python benchmarks/box_colliders_walk.py --kinds stairs_up --seeds 1 --keep-fallen  # the check's check
    python benchmarks/box_colliders_walk.py --train --kinds stairs_up,stairs_down --worlds 16 --seconds 20
    python benchmarks/box_colliders_walk.py --engine warp --device cuda --worlds 64 --seconds 20

``--train``: the training variant (randomization, pushes), first on the hardest level;
``--random-actions``: uniform actions in +-1 instead of the walker. ``--keep-fallen`` never ends an episode (no fall termination), so a fallen robot lies on the stairs:
its torso and arms then touch boxes in the default env and sink through them with the option, and
the row shows the gap and the contacts the comparison is there to catch.

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import torch

import ambulo.envs as envs
from ambulo.envs.humanoid_rough import HUMANOID_BOX_COLLIDERS
from ambulo.envs.observations import base_lin_vel_yaw
from ambulo.policies.shipped import load_policy
from ambulo.rl.vecenv import RslRlVecEnv
from ambulo.scenes.terrain import candidate_geom_pairs

# the sibling script's forward-only commands, held the same way
sys.path.insert(0, str(Path(__file__).resolve().parent))
from command_tracking import FORWARD_ONLY, hold_command

TASK = "humanoid-rough"


def non_leg_box_contacts(env) -> int:
    """Contacts of a robot geom outside ``HUMANOID_BOX_COLLIDERS`` with a terrain box, all worlds."""
    model = env.engine.model
    terrain = model.body("/World/terrain").id
    box = (model.geom_bodyid == terrain) & (model.geom_type == mujoco.mjtGeom.mjGEOM_BOX)
    legs = [model.body(f"{env.cfg.robot.prim_path}/{b}").id for b in HUMANOID_BOX_COLLIDERS]
    non_leg = (model.geom_bodyid != terrain) & ~np.isin(model.geom_bodyid, legs) & (model.geom_bodyid != 0)
    count = 0
    for world in range(env.num_envs):
        con = env.engine.get_data(world).contact
        count += int(((box[con.geom1] & non_leg[con.geom2]) | (box[con.geom2] & non_leg[con.geom1])).sum())
    return count


def twin_walk(kind: str, seed: int, worlds: int, speed_m_s: float, seconds: float, settle_s: float, policy,
              keep_fallen: bool = False, train: bool = False, device: str = "cpu", engine: str = "mujoco") -> dict:
    """One row (see the module docstring); ``policy`` None: uniform random actions in +-1, the same
    in both envs; ``engine`` "warp" (``device`` cpu or cuda) counts no contacts (None); ``train``: the training variant (transfer randomization, action latency, pushes,
    observation noise) with the robots' first level the hardest (the curriculum moves them)."""
    variant = {"min_base_height_m": 0.0, "max_tilt_rad": 4.0} if keep_fallen else {}
    variant |= {"curriculum.init_level": -1} if train else {}
    pair = {name: envs.make(TASK, num_envs=worlds, device=device, seed=seed, play=not train, engine=engine,
                            **FORWARD_ONLY, **variant, **{"terrain.kinds": (kind,)}, box_collider_bodies=colliders)
            for name, colliders in (("all", None), ("legs", HUMANOID_BOX_COLLIDERS))}
    touches = [0]
    default_terminations = pair["all"]._get_terminations

    def counted_terminations():  # after the physics of a step, before its resets
        touches[0] += non_leg_box_contacts(pair["all"])
        return default_terminations()

    if engine == "mujoco":  # MuJoCo C's contacts, world by world
        pair["all"]._get_terminations = counted_terminations
    else:
        touches[0] = None
    counts = {k: len(candidate_geom_pairs(e.engine.model)) for k, e in pair.items()}
    assert counts["legs"] < counts["all"], f"the option changed no candidate pair: {counts}"
    vecs = {k: RslRlVecEnv(e) for k, e in pair.items()}
    generator = torch.Generator().manual_seed(seed)
    env0 = pair["all"]
    steps, settle = round(seconds / env0.step_dt_s), round(settle_s / env0.step_dt_s)
    command = torch.zeros_like(env0.commands.command)
    command[:, 0] = speed_m_s
    speed = {k: torch.zeros(worlds, device=env0.device) for k in pair}
    falls = dict.fromkeys(pair, 0)
    gap_m, first_gap_step = 0.0, None
    with torch.inference_mode():
        obs = {k: v.reset() for k, v in vecs.items()}
        for t in range(steps):
            noise = (torch.rand(worlds, env0.num_actions, generator=generator) * 2 - 1).to(env0.device)
            for k, env in pair.items():
                hold_command(env, command)
                obs[k], _, dones, _ = vecs[k].step(noise if policy is None else policy(obs[k]["policy"]))
                falls[k] += int(dones.sum())  # episode ends: falls in the play variant (no time-outs); --train adds time-outs
                if t >= settle:
                    data = env.robot.data
                    speed[k] += base_lin_vel_yaw(data.root_quat_w, data.root_lin_vel_w)[:, 0].float()
            gap = float((pair["all"].robot.data.root_pos_w - pair["legs"].robot.data.root_pos_w).abs().max())
            if gap > 0.0 and first_gap_step is None:
                first_gap_step = t
            gap_m = max(gap_m, gap)
    for env in pair.values():
        env.close()
    return {"kind": kind, "seed": seed, "command_m_s": speed_m_s, "candidate_pairs": counts,
            **{f"speed_m_s_{k}": round(float(v.mean()) / (steps - settle), 3) for k, v in speed.items()},
            **{f"falls_{k}": v for k, v in falls.items()},
            "max_root_gap_m": gap_m, "first_gap_step": first_gap_step, "non_leg_box_contacts": touches[0]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kinds", default="flat,stairs_up,stairs_down", help="box tile kinds, comma-separated")
    p.add_argument("--seeds", default="1,2,3,4")
    p.add_argument("--worlds", type=int, default=8)
    p.add_argument("--speed", type=float, default=1.0, help="the forward command, m/s")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--settle-s", type=float, default=2.0)
    p.add_argument("--engine", default="mujoco", choices=("mujoco", "warp"),
                   help="warp: MuJoCo Warp, where trajectories may differ in float rounding (its contact order)")
    p.add_argument("--device", default="cpu", help="cpu, or cuda with --engine warp")
    p.add_argument("--keep-fallen", action="store_true", help="no fall termination: fallen robots lie on the boxes")
    p.add_argument("--random-actions", action="store_true", help="uniform random actions in +-1 instead of the walker")
    p.add_argument("--train", action="store_true",
                   help="the training variant (transfer randomization, latency, pushes, noise), first on the "
                        "hardest level, instead of play")
    args = p.parse_args()
    policy = None if args.random_actions else load_policy(TASK)
    rows = []
    for kind in args.kinds.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            row = twin_walk(kind, seed, args.worlds, args.speed, args.seconds, args.settle_s, policy, args.keep_fallen,
                            args.train, args.device, args.engine)
            rows.append(row)
            print(json.dumps(row), flush=True)
    print("RESULT " + json.dumps({"benchmark": "box_colliders_walk", "worlds": args.worlds, "seconds": args.seconds,
                                  "keep_fallen": args.keep_fallen, "random_actions": args.random_actions,
                                  "train": args.train, "engine": args.engine, "device": args.device, "rows": rows}))


if __name__ == "__main__":
    main()
