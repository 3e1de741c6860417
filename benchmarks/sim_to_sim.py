"""Sim-to-sim: how the GPU engine (MuJoCo Warp) and the CPU engine (MuJoCo C) differ on humanoid-walk.

1. States: a policy (the shipped one, or ``--run``'s checkpoint) walks ``--worlds`` humanoids of
   the play variant on the CPU engine; the state (qpos, qvel, solver warm start) before every
   policy step and the controls it wrote are recorded. Every ``--stride``-th policy step of every
   world that did not fall in the next ``--horizon`` physics steps is a sample.
2. Open loop: each sample is loaded into both engines, which then replay the recorded controls
   for ``--horizon`` physics steps; per step k the divergence from the CPU engine is reported
   (median and 90th percentile over samples of max |qpos diff| and max |qvel diff|, and of the
   base's planar velocity difference, m/s, the quantity `walks` judges), with the mean signed
   planar velocity difference in the base's heading frame (a systematic drag shows there).
   Reference variants on the CPU engine separate the causes: ``mujoco_f32_state`` starts from
   the float32-rounded state (what float32 storage alone does to a contact-rich trajectory: the
   floor any float32 engine has), ``mujoco_tol`` runs at MuJoCo Warp's solver tolerance.
3. At the sampled states (one ``forward`` on each engine): ground contacts per foot (count,
   normal force, centroid), solver iterations and |qacc diff|, and the option values each
   engine actually runs with (``mujoco_warp.put_model`` may change them).
4. Closed loop (``--closed-loop-s``): the policy walks both engines from identical initial states
   under identical commands (held for the episode: no resampling, so both engines see the same
   ones) and the mean planar velocity error per engine, paired per world, is reported.

    python benchmarks/sim_to_sim.py --device cpu --worlds 16 --horizon 40      # Warp's CPU device
    python benchmarks/sim_to_sim.py --device cuda --worlds 128 --closed-loop-s 20

Ends with one ``RESULT {json}`` line.
"""

from __future__ import annotations

import argparse
import datetime
import json
import time

import mujoco
import numpy as np
import torch

import ambulo.envs as envs
from ambulo.engine import CpuEngine, make_engine
from ambulo.engine.gpu import stack_versions

TASK = "humanoid-walk"
FEET = ("left_foot", "right_foot")
OPTIONS = ("timestep", "integrator", "solver", "iterations", "ls_iterations", "tolerance", "ls_tolerance",
           "cone", "impratio", "noslip_iterations", "ccd_iterations", "disableflags", "enableflags")


def load_policy(run: str | None, checkpoint: str | None, env):
    """(obs (N, 72) on env.device) -> actions: the shipped policy, or a run's checkpoint."""
    if run is None:
        from ambulo.policies.shipped import load_policy as shipped

        return shipped(TASK), "shipped"
    from ambulo.rl import runs

    run_dir, ckpt = runs.resolve_policy(run, checkpoint)
    runner = runs.load_runner(run_dir, env, ckpt)
    act = runner.get_inference_policy(device=str(env.device))
    return (lambda obs: act({"policy": obs})), f"{run_dir.name}/{ckpt.name}"


def record(args) -> dict:
    """Walk the play variant on the CPU engine; the state before each policy step and its ctrl."""
    env = envs.make(TASK, num_envs=args.worlds, seed=args.seed, play=True, device="cpu", engine="mujoco")
    policy, name = load_policy(args.run, args.checkpoint, env)
    obs, eng = env.get_observations(), env.engine
    steps = args.warmup + args.record
    qpos, qvel, warm, ctrl, done = [], [], [], [], []
    for t in range(steps):
        keep = t >= args.warmup
        if keep:
            qpos.append(eng.qpos.clone()), qvel.append(eng.qvel.clone())
            warm.append(eng.field("qacc_warmstart").clone())
        with torch.inference_mode():
            actions = policy(obs)
        obs, _, dones, _ = env.step(actions)
        if keep:
            ctrl.append(eng.ctrl.clone()), done.append(dones.clone())
    stack = {k: torch.stack(v, 1).numpy() for k, v in dict(qpos=qpos, qvel=qvel, warm=warm, ctrl=ctrl,
                                                           done=done).items()}
    stack["model"], stack["policy"], stack["decimation"] = env.model, name, env.cfg.decimation
    return stack


def samples(rec: dict, horizon: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """(world, policy step) of each sample whose next ``horizon`` physics steps have no reset."""
    span = -(-horizon // rec["decimation"])
    worlds, steps = rec["done"].shape
    picks = [(w, t) for t in range(0, steps - span + 1, stride) for w in range(worlds)
             if not rec["done"][w, t:t + span].any()]
    picks = np.array(picks)
    return picks[:, 0], picks[:, 1]


def load(engine, state: dict[str, np.ndarray], f32: bool = False) -> None:
    """Give the engine's worlds the sampled states (qpos, qvel, warm start, ctrl: (S, n))."""
    for name, key in (("qpos", "qpos"), ("qvel", "qvel"), ("ctrl", "ctrl"), ("qacc_warmstart", "warm")):
        value = torch.from_numpy(state[key].astype(np.float32) if f32 else state[key])
        engine.field(name)[:] = value.to(engine.field(name).dtype).to(engine.device)
    engine.field("time").zero_()


def rollout(engine, ctrl: np.ndarray, decimation: int, horizon: int) -> dict[str, np.ndarray]:
    """Replay ``ctrl`` (S, policy steps, nu) for ``horizon`` physics steps; qpos, qvel (S, horizon, n)."""
    out = {"qpos": [], "qvel": []}
    for k in range(horizon):
        engine.ctrl[:] = torch.from_numpy(ctrl[:, k // decimation]).to(engine.ctrl)
        engine.step()
        out["qpos"].append(engine.qpos.detach().cpu().double().clone())
        out["qvel"].append(engine.qvel.detach().cpu().double().clone())
    return {k: torch.stack(v, 1).numpy() for k, v in out.items()}


def planar_velocity_heading(qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """(..., 2) base linear velocity in the heading frame (yaw of the base quaternion), m/s."""
    w, x, y, z = (qpos[..., 3 + i] for i in range(4))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    c, s = np.cos(yaw), np.sin(yaw)
    vx, vy = qvel[..., 0], qvel[..., 1]
    return np.stack([c * vx + s * vy, -s * vx + c * vy], -1)


def divergence(ref: dict, other: dict, at: list[int]) -> dict:
    dq = np.abs(other["qpos"] - ref["qpos"]).max(-1)
    dv = np.abs(other["qvel"] - ref["qvel"]).max(-1)
    dvel = planar_velocity_heading(other["qpos"], other["qvel"]) - planar_velocity_heading(ref["qpos"], ref["qvel"])
    out = {}
    for k in at:
        i = k - 1
        d = dvel[:, i]
        out[f"step_{k}"] = {
            "qpos_max_abs_median": float(np.median(dq[:, i])), "qpos_max_abs_p90": float(np.percentile(dq[:, i], 90)),
            "qvel_max_abs_median": float(np.median(dv[:, i])), "qvel_max_abs_p90": float(np.percentile(dv[:, i], 90)),
            "planar_vel_diff_median_m_s": float(np.median(np.linalg.norm(d, axis=-1))),
            "planar_vel_diff_p90_m_s": float(np.percentile(np.linalg.norm(d, axis=-1), 90)),
            "heading_vel_bias_m_s": [float(v) for v in d.mean(0)],
            "heading_vel_bias_stderr_m_s": [float(v) for v in d.std(0) / np.sqrt(len(d))],
        }
    return out


def foot_contacts_mujoco(model, engine: CpuEngine, feet: list[int], ground: int) -> dict[str, np.ndarray]:
    """Per sample and foot: ground contacts, normal force N, contact centroid; solver iterations, qacc."""
    n = engine.num_worlds
    count, force, centroid = np.zeros((n, 2)), np.zeros((n, 2)), np.full((n, 2, 3), np.nan)
    niter, qacc = np.zeros(n), np.zeros((n, model.nv))
    f6 = np.zeros(6)
    for s in range(n):
        data = engine.get_data(s)  # mj_forward at the state
        niter[s] = data.solver_niter[:max(1, data.nisland)].max()
        qacc[s] = data.qacc
        pos = [[], []]
        for c in range(data.ncon):
            con = data.contact[c]
            g = set(con.geom.tolist())
            for j, foot in enumerate(feet):
                if g == {foot, ground} and con.efc_address >= 0:
                    mujoco.mj_contactForce(model, data, c, f6)
                    count[s, j] += 1
                    force[s, j] += f6[0]
                    pos[j].append(con.pos.copy())
        for j in range(2):
            if pos[j]:
                centroid[s, j] = np.mean(pos[j], 0)
    return {"count": count, "force": force, "centroid": centroid, "niter": niter, "qacc": qacc}


def foot_contacts_warp(model, engine, feet: list[int], ground: int) -> dict[str, np.ndarray]:
    """As ``foot_contacts_mujoco``, from MuJoCo Warp's contact and constraint arrays."""
    import mujoco_warp as mjw

    engine.forward()
    d = engine.wp_data
    n = engine.num_worlds
    nacon = int(d.nacon.numpy()[0])
    geom, world = d.contact.geom.numpy()[:nacon], d.contact.worldid.numpy()[:nacon]
    ctype, adr = d.contact.type.numpy()[:nacon], d.contact.efc_address.numpy()[:nacon]
    dim, pos = d.contact.dim.numpy()[:nacon], d.contact.pos.numpy()[:nacon]
    efc_force = d.efc.force.numpy()
    pyramidal = model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    count, force, centroid = np.zeros((n, 2)), np.zeros((n, 2)), np.full((n, 2, 3), np.nan)
    pts = [[[] for _ in range(2)] for _ in range(n)]
    for c in range(nacon):
        if not ctype[c] & int(mjw._src.types.ContactType.CONSTRAINT) or adr[c, 0] < 0:
            continue
        for j, foot in enumerate(feet):
            if set(geom[c].tolist()) == {foot, ground}:
                rows = 2 * (dim[c] - 1) if pyramidal and dim[c] > 1 else 1
                w = world[c]
                count[w, j] += 1
                force[w, j] += efc_force[w, adr[c, 0]:adr[c, 0] + rows].sum() if pyramidal else efc_force[w, adr[c, 0]]
                pts[w][j].append(pos[c])
    for w in range(n):
        for j in range(2):
            if pts[w][j]:
                centroid[w, j] = np.mean(pts[w][j], 0)
    return {"count": count, "force": force, "centroid": centroid,
            "niter": d.solver_niter.numpy().astype(float), "qacc": engine.qacc.detach().cpu().double().numpy()}


def contact_report(c: dict, w: dict) -> dict:
    both = (c["count"] > 0) & (w["count"] > 0)
    loaded = c["force"] > 1.0
    rel = np.abs(w["force"] - c["force"])[loaded] / c["force"][loaded]
    return {
        "feet": int(c["count"].size),
        "contacts_per_foot_mean": {"mujoco": float(c["count"].mean()), "warp": float(w["count"].mean())},
        "feet_with_different_contact_count": float((c["count"] != w["count"]).mean()),
        "contact_count_hist": {"mujoco": np.bincount(c["count"].astype(int).ravel(), minlength=5).tolist(),
                               "warp": np.bincount(w["count"].astype(int).ravel(), minlength=5).tolist()},
        "normal_force_per_foot_mean_N": {"mujoco": float(c["force"].mean()), "warp": float(w["force"].mean())},
        "normal_force_rel_diff_median": float(np.median(rel)) if rel.size else None,
        "normal_force_rel_diff_p90": float(np.percentile(rel, 90)) if rel.size else None,
        "centroid_diff_median_m": float(np.median(np.linalg.norm(c["centroid"][both] - w["centroid"][both], axis=-1)))
        if both.any() else None,
        "solver_iterations_mean": {"mujoco": float(c["niter"].mean()), "warp": float(w["niter"].mean())},
        "qacc_max_abs_diff_median": float(np.median(np.abs(c["qacc"] - w["qacc"]).max(-1))),
        "qacc_max_abs_median": float(np.median(np.abs(c["qacc"]).max(-1))),
    }


def engine_options(model, warp_engine) -> dict:
    """Option values as each engine runs them (MuJoCo Warp's after ``put_model``)."""
    opt = warp_engine.wp_model.opt

    def warp_value(name):
        v = getattr(opt, name, None)
        if v is None:
            return None
        return float(v.numpy().ravel()[0] if hasattr(v, "numpy") else v)

    out = {name: {"mujoco": float(getattr(model.opt, name)), "warp": warp_value(name)} for name in OPTIONS}
    out["impratio"]["warp"] = warp_value("impratio_invsqrt") ** -2
    return out


def closed_loop(args, policy_args) -> dict:
    """The policy on both engines from identical states under identical (held) commands."""
    seconds = args.closed_loop_s
    hold = {"commands.resampling_time_s": (1.0e6, 2.0e6), "episode_length_s": seconds}
    n = args.closed_loop_worlds
    cpu = envs.make(TASK, num_envs=n, seed=args.seed + 1, play=True, device="cpu", engine="mujoco", **hold)
    gpu = envs.make(TASK, num_envs=n, seed=args.seed + 1, play=True, device=args.device, engine="warp", **hold)
    policy_cpu, _ = load_policy(*policy_args, cpu)
    policy_gpu, _ = load_policy(*policy_args, gpu)
    # identical initial states and commands: the CPU env's, copied into the Warp env
    for name in ("qpos", "qvel", "qacc_warmstart"):
        gpu.engine.field(name)[:] = cpu.engine.field(name).to(gpu.engine.field(name))
    gpu.engine.forward()
    for name in ("command", "heading_target", "is_heading", "is_standing", "time_left_s"):
        getattr(gpu.commands, name).copy_(getattr(cpu.commands, name).to(gpu.device))
    gpu.obs_buf = gpu._compute_observations()
    out = {}
    for tag, env, policy in (("mujoco", cpu, policy_cpu), ("warp", gpu, policy_gpu)):
        obs, running = env.get_observations(), torch.ones(n, dtype=torch.bool, device=env.device)
        err, steps = torch.zeros(n, dtype=torch.float64, device=env.device), torch.zeros_like(running, dtype=torch.float64)
        began = time.perf_counter()
        for _ in range(env.max_episode_length):
            with torch.inference_mode():
                actions = policy(obs)
            lin, _ = env.velocity_tracking_error()
            err += lin.double() * running
            steps += running.double()
            obs, _, dones, extras = env.step(actions)
            running &= ~(dones.bool() & extras["terminated"])
        out[tag] = {"per_world": (err / steps.clamp(min=1)).cpu().numpy(), "fell": (~running).cpu().numpy(),
                    "s": time.perf_counter() - began}
    paired = out["warp"]["per_world"] - out["mujoco"]["per_world"]
    return {
        "worlds": n, "seconds": seconds,
        "mean_abs_vel_error_m_s": {k: float(v["per_world"].mean()) for k, v in out.items()},
        "falls": {k: int(v["fell"].sum()) for k, v in out.items()},
        "paired_diff_warp_minus_mujoco_m_s": float(paired.mean()),
        "paired_diff_stderr_m_s": float(paired.std() / np.sqrt(n)),
        "wall_s": {k: round(v["s"], 1) for k, v in out.items()},
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="cuda", help="the Warp engine's device: cuda[:N] or cpu")
    p.add_argument("--worlds", type=int, default=64, help="humanoids walking while states are recorded")
    p.add_argument("--warmup", type=int, default=50, help="policy steps before recording (1 s)")
    p.add_argument("--record", type=int, default=60, help="policy steps recorded")
    p.add_argument("--stride", type=int, default=20, help="policy steps between samples of one world")
    p.add_argument("--horizon", type=int, default=100, help="physics steps replayed open loop")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--run", help="a run folder (default: the shipped policy)")
    p.add_argument("--checkpoint")
    p.add_argument("--closed-loop-s", type=float, default=0.0, help="seconds of closed-loop walking (0: skip)")
    p.add_argument("--closed-loop-worlds", type=int, default=100)
    p.add_argument("--max-samples", type=int, default=256)
    args = p.parse_args()

    began = time.perf_counter()
    rec = record(args)
    model = rec["model"]
    ws, ts = samples(rec, args.horizon, args.stride)
    ws, ts = ws[:args.max_samples], ts[:args.max_samples]
    m = len(ws)
    feet = [model.geom(f"/World/robot/{f}").id for f in FEET]
    ground = model.geom("/World/defaultGroundPlane/geom").id
    tol_model = model.__copy__()
    tol_model.opt.tolerance = max(model.opt.tolerance, 1e-6)  # what mujoco_warp.put_model runs with

    state = {k: rec[k][ws, ts] for k in ("qpos", "qvel", "warm", "ctrl")}
    span = -(-args.horizon // rec["decimation"])
    ctrl = np.stack([rec["ctrl"][ws, ts + k] for k in range(span)], 1)
    variants = {"mujoco": (model, "mujoco", False), "warp": (model, "warp", False),
                "mujoco_f32_state": (model, "mujoco", True), "mujoco_tol": (tol_model, "mujoco", False)}
    engines = {tag: make_engine(mdl, m, device=args.device if kind == "warp" else "cpu", engine=kind)
               for tag, (mdl, kind, _) in variants.items()}
    for tag, eng in engines.items():
        load(eng, state, variants[tag][2])
        eng.forward()
    # contacts, forces and solver iterations at the sampled states (before any step)
    warp_at_state = foot_contacts_warp(model, engines["warp"], feet, ground)
    at_state = contact_report(foot_contacts_mujoco(model, engines["mujoco"], feet, ground), warp_at_state)
    at_state_tol = contact_report(foot_contacts_mujoco(tol_model, engines["mujoco_tol"], feet, ground),
                                  warp_at_state)
    trajectories = {}
    for tag, eng in engines.items():
        load(eng, state, variants[tag][2])
        trajectories[tag] = rollout(eng, ctrl, rec["decimation"], args.horizon)
    at = sorted({1, rec["decimation"], min(20, args.horizon), args.horizon})
    result = {
        "benchmark": "sim_to_sim", "task": TASK, "device": args.device, "date": datetime.date.today().isoformat(),
        "policy": rec["policy"], "samples": m, "horizon_steps": args.horizon,
        "timestep_s": float(model.opt.timestep), "versions": stack_versions(),
        "options": engine_options(model, engines["warp"]),
        "at_state": at_state, "at_state_vs_mujoco_at_warp_tolerance": at_state_tol,
        "divergence_from_mujoco": {tag: divergence(trajectories["mujoco"], trajectories[tag], at)
                                   for tag in ("warp", "mujoco_f32_state", "mujoco_tol")},
        "warp_vs_mujoco_tol": divergence(trajectories["mujoco_tol"], trajectories["warp"], at),
    }
    if args.device.startswith("cuda"):
        result["gpu"] = torch.cuda.get_device_name(0)
    if args.closed_loop_s > 0:
        result["closed_loop"] = closed_loop(args, (args.run, args.checkpoint))
    result["wall_s"] = round(time.perf_counter() - began, 1)
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
