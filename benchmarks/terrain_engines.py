"""The CPU engine (MuJoCo C) against MuJoCo Warp on a terrain task: contacts of resting feet, and a
policy's falls, with nothing else different.

Why: a policy trained on the GPU engine is judged on the CPU engine (``ambulo eval --device cpu``,
the CPU-engine confirmation of ``--stop-at-criterion``, ``scripts/ship_policy.py``). On flat ground
(a plane) the two engines agree (``benchmarks/sim_to_sim.py``); on terrain they collide the feet
with MuJoCo's height field by different algorithms, and session 15 found a humanoid-footsteps-stairs
policy trained on MuJoCo Warp falling on the CPU engine even on flat tiles.

1. Contacts: ``--worlds`` robots of the task's play variant stand in their default pose on tiles of
   ``--kinds`` for ``--settle-s``; then, in one state, each engine's contacts between the terrain
   and each sole sphere (``scenes.terrain.soles``) are counted. ``per_touching_sphere`` is the mean
   count over spheres with at least one (1.0: one contact each; more: duplicates, each its own
   constraint row, so that sphere's contact is that many times as stiff and as frictional).
2. Falls (``--run``): the run's policy on the same tiles, same seed, on each engine (``rl.run_episodes``,
   the evaluation ``ambulo eval`` runs; fall rate includes a task's other failures, e.g. a lost plan).

``--box-kinds`` sets which tile kinds are static boxes (``terrain.box_kinds``; default the task's),
e.g. ``flat,stairs_up,stairs_down,stepping_stones`` for stepping stones as boxes.
``--mujoco-hfield own`` gives MuJoCo C its own heightfield contacts (one per prism a geom overlaps)
instead of the task's default, Warp's reduction (``engine.mujoco_hfield``); ``--engines mujoco``
skips the Warp side. ``--warp-device cpu`` runs MuJoCo Warp on Warp's CPU device (no GPU needed; its first build
compiles the kernels, minutes). Ends with one ``RESULT {json}``; ``ratio`` = MuJoCo C's contacts
per touching sphere over Warp's (1.0: the engines agree).

    python benchmarks/terrain_engines.py --task humanoid-footsteps-stairs --kinds flat
    python benchmarks/terrain_engines.py --run runs/humanoid-footsteps-stairs/<run> --kinds flat --episodes 16
    python benchmarks/terrain_engines.py --run runs/humanoid-rough/<run> --kinds stepping_stones \
        --box-kinds flat,stairs_up,stairs_down,stepping_stones --warp-device cpu
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np
import torch

from ambulo import envs
from ambulo.rl import runs
from ambulo.rl.evaluate import run_episodes
from ambulo.scenes.terrain.generator import TERRAIN_PRIM_PATH


def geom_ids(model: mujoco.MjModel) -> tuple[set[int], set[int]]:
    """(terrain geoms, sole spheres) by name: every geom under the terrain's prim path, and the
    spheres ``sphere_soles`` adds (their names end in ``sole_sphere<k>``)."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)]
    terrain = {g for g, n in enumerate(names) if n.startswith(TERRAIN_PRIM_PATH + "/")}
    soles = {g for g, n in enumerate(names) if "sole_sphere" in n.rsplit("/", 1)[-1]}
    return terrain, soles


def sphere_contact_counts(env) -> np.ndarray:
    """Contacts between the terrain and each sole sphere of every world, at the engine's current
    state: a flat array of the counts of the spheres that have at least one."""
    engine = env.engine
    model = engine.model
    terrain, soles = geom_ids(model)
    counts: dict[tuple[int, int], int] = {}
    if hasattr(engine, "wp_data"):
        engine.forward()
        d = engine.wp_data
        nacon = int(d.nacon.numpy()[0])
        geom, world = d.contact.geom.numpy()[:nacon], d.contact.worldid.numpy()[:nacon]
        pairs = [(int(w), tuple(int(x) for x in g)) for w, g in zip(world, geom, strict=True)]
    else:
        pairs = []
        for w in range(engine.num_worlds):
            data = engine.get_data(w)  # mj_forward at the world's state
            pairs += [(w, (int(c.geom1), int(c.geom2))) for c in data.contact[:data.ncon]]
    for w, (g1, g2) in pairs:
        sphere = g2 if g1 in terrain else g1 if g2 in terrain else None
        if sphere in soles:
            counts[(w, sphere)] = counts.get((w, sphere), 0) + 1
    return np.array(sorted(counts.values()), dtype=float)


def tile_overrides(args) -> dict:
    """The terrain overrides of ``--kinds``, ``--box-kinds`` and ``--mujoco-hfield``."""
    tiles = {"terrain.kinds": tuple(args.kinds.split(","))}
    if args.box_kinds is not None:
        tiles["terrain.box_kinds"] = tuple(k for k in args.box_kinds.split(",") if k)
    if args.mujoco_hfield is not None:
        tiles["mujoco_hfield_contacts_as_warp"] = args.mujoco_hfield == "warp"
    return tiles


def make(args, engine: str, device: str, num_envs: int, info: dict | None):
    tiles = tile_overrides(args)
    if info is not None:
        return runs.make_env_for_run(info, num_envs=num_envs, seed=args.seed, play=True, device=device,
                                     engine=engine, episode_length_s=args.episode_length_s, **tiles)
    return envs.make(args.task, num_envs=num_envs, seed=args.seed, play=True, device=device, engine=engine, **tiles)


def contacts(args, engine: str, device: str, info: dict | None) -> dict:
    env = make(args, engine, device, args.worlds, info)
    env.reset()
    hold = torch.zeros(env.num_envs, env.num_actions, device=env.device)  # default pose under the PD drives
    for _ in range(round(args.settle_s / env.step_dt_s)):
        env.step(hold)
    counts = sphere_contact_counts(env)
    env.close()
    return {"touching_spheres": int(counts.size), "contacts": int(counts.sum()),
            "per_touching_sphere": float(counts.mean()) if counts.size else None,
            "max_per_sphere": int(counts.max()) if counts.size else 0}


def falls(args, engine: str, device: str, info: dict, run_dir, ckpt) -> dict:
    env = make(args, engine, device, args.episodes, info)
    runner = runs.load_runner(run_dir, env, ckpt)
    t0 = time.perf_counter()
    result = run_episodes(env, runner.env, runner.get_inference_policy(device=str(env.device)),
                          envs.spec(info["task"]), quiet=True)
    env.close()
    by_kind = {k: {"episodes": v["episodes"], "fall_rate": v["fall_rate"]} for k, v in result.get("by_kind", {}).items()}
    return {"episodes": args.episodes, "fall_rate": result["fall_rate"], "by_kind": by_kind,
            "mean_episode_length_s": result["mean_episode_length_s"], "seconds": round(time.perf_counter() - t0, 1)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--task", default="humanoid-footsteps-stairs", help="a terrain task (ignored with --run)")
    p.add_argument("--run", help="a run folder or checkpoint of a terrain task: also compare its falls")
    p.add_argument("--kinds", default="flat", help="tile kinds, comma-separated (the terrain's `kinds`)")
    p.add_argument("--box-kinds", help="tile kinds built as static boxes, comma-separated (the terrain's "
                   "`box_kinds`; default: the task's, flat and stairs)")
    p.add_argument("--mujoco-hfield", choices=("own", "warp"), help="MuJoCo C's heightfield contacts: its "
                   "own, or reduced as Warp's (the terrain tasks' default)")
    p.add_argument("--engines", default="mujoco,warp", help="engines to run, comma-separated")
    p.add_argument("--worlds", type=int, default=8, help="resting robots for the contact count")
    p.add_argument("--settle-s", type=float, default=0.5, help="seconds standing before the count")
    p.add_argument("--episodes", type=int, default=16, help="policy episodes per engine (--run)")
    p.add_argument("--episode-length-s", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--warp-device", default="cuda" if torch.cuda.is_available() else "cpu",
                   help="MuJoCo Warp's device: cuda[:N], or cpu (Warp's CPU device)")
    args = p.parse_args()
    info = run_dir = ckpt = None
    try:  # a wrong run, task or tile kind: one line, before anything is built
        if args.run:
            run_dir, ckpt = runs.resolve_policy(args.run)
            info = runs.read_run_info(run_dir)
            args.task = info["task"]
        if "terrain" not in envs.spec(args.task).cfg_fn().__dataclass_fields__:
            raise ValueError(f"task {args.task} has no terrain; give a terrain task "
                             "(humanoid-rough, g1-rough, humanoid-footsteps-stairs)")
        envs.make_cfg(args.task, **tile_overrides(args))
        unknown = sorted(set(args.engines.split(",")) - {"mujoco", "warp"})
        if unknown:
            raise ValueError(f"--engines {args.engines}: unknown {unknown}; give mujoco, warp or mujoco,warp")
    except (OSError, ValueError, KeyError) as err:
        message = err.args[0] if isinstance(err, KeyError) and err.args else err  # a KeyError's str quotes it
        raise SystemExit(f"terrain_engines.py: {message}") from None
    sides = {"mujoco": ("mujoco", "cpu"), "warp": ("warp", args.warp_device)}
    sides = {k: v for k, v in sides.items() if k in args.engines.split(",")}
    result = {"task": args.task, "kinds": args.kinds, "box_kinds": args.box_kinds, "seed": args.seed,
              "warp_device": args.warp_device, "mujoco_hfield": args.mujoco_hfield or "task default",
              "contacts": {k: contacts(args, *v, info) for k, v in sides.items()}}
    for name, c in result["contacts"].items():
        print(f"{name:7s} resting: {c['contacts']} contacts on {c['touching_spheres']} touching sole spheres "
              f"({c['per_touching_sphere']} a sphere, at most {c['max_per_sphere']})")
    if info is not None:
        result["falls"] = {k: falls(args, *v, info, run_dir, ckpt) for k, v in sides.items()}
        for name, f in result["falls"].items():
            print(f"{name:7s} policy: fall rate {f['fall_rate']:.3f} over {f['episodes']} episodes")
    a, b = (result["contacts"].get(k, {}).get("per_touching_sphere") for k in ("mujoco", "warp"))
    result["ratio"] = round(a / b, 3) if a and b else None
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
