"""Sole-sphere contacts with the terrain heightfield, MuJoCo C against MuJoCo Warp, in identical states.

Why: a humanoid-rough policy trained on MuJoCo Warp falls more on the CPU engine (MuJoCo C) on the
tiles still in the heightfield (session 16: slope_down, stepping stones). This replays a policy on
the CPU engine on ``--kinds`` tiles, keeps every ``--every``-th state (qpos, qvel, ctrl) of every
robot, and runs ``mj_forward`` of MuJoCo C and ``mjw.forward`` of MuJoCo Warp (Warp's CPU device) on
the same model in those states. Per touching sole sphere it compares: the contact count, the
deepest contact's depth, the spread of the contact points, the normals' tilt from the deepest
one's, the contacts' solref/solimp/friction/margin, and the sphere's summed contact force
(``mj_contactForce``/``mjw.contact_force``, world frame) from each engine's own constraint solve,
and how far one physics step takes the base apart (``qacc * dt``).
The Warp side applies humanoid-rough's ``warp_hfield_contact_depth_m`` (``engine.warp_hfield``), as
its env does. ``--mujoco-hfield own`` (default) replays and compares MuJoCo C's own heightfield
contacts; ``warp``: reduced as Warp's (``engine.mujoco_hfield``, the terrain tasks' default on the
CPU engine). Ends with one ``RESULT {json}``.

    python benchmarks/hfield_contacts.py --run <run>/model_1514.pt --kinds slope_down --worlds 16
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np
import torch
from terrain_engines import geom_ids

from ambulo.engine.mujoco_hfield import reduce_hfield_contacts
from ambulo.rl import runs


def record_states(args, info, run_dir, ckpt):
    """(model, qpos (S, nq), qvel (S, nv), ctrl (S, nu)) every ``--every`` policy step of every world
    on the CPU engine."""
    env = runs.make_env_for_run(info, num_envs=args.worlds, seed=args.seed, play=True, device="cpu",
                                engine="mujoco", episode_length_s=args.steps * 0.02 + 1.0,
                                **{"terrain.kinds": tuple(args.kinds.split(",")),
                                   "mujoco_hfield_contacts_as_warp": args.mujoco_hfield == "warp"})
    runner = runs.load_runner(run_dir, env, ckpt)
    policy = runner.get_inference_policy(device="cpu")
    obs = runner.env.reset()
    qpos, qvel, ctrl = [], [], []
    e = env.engine
    with torch.inference_mode():
        for t in range(args.steps):
            obs, *_ = runner.env.step(policy(obs))
            if t % args.every == args.every - 1:
                qpos.append(e.qpos.numpy().copy())
                qvel.append(e.qvel.numpy().copy())
                ctrl.append(e.ctrl.numpy().copy())
    model = e.get_model(0)
    env.close()
    return model, np.concatenate(qpos), np.concatenate(qvel), np.concatenate(ctrl)


def mujoco_contacts(model, qpos, qvel, ctrl, terrain, soles):
    """Per state, a list of (sphere, dist, pos, normal, force_world, solref, solimp, friction0, margin)."""
    data = mujoco.MjData(model)
    out, qacc = [], []
    f6 = np.zeros(6)
    for s in range(len(qpos)):
        data.qpos[:], data.qvel[:], data.ctrl[:] = qpos[s], qvel[s], ctrl[s]
        mujoco.mj_forward(model, data)
        rows = []
        for i in range(data.ncon):
            c = data.contact[i]
            g1, g2 = int(c.geom1), int(c.geom2)
            sphere = g2 if g1 in terrain else g1 if g2 in terrain else None
            if sphere not in soles:
                continue
            mujoco.mj_contactForce(model, data, i, f6)
            frame = np.array(c.frame).reshape(3, 3)
            force = frame.T @ f6[:3]  # on geom2, world frame
            if sphere == g1:
                force = -force
            normal = frame[0] * (1.0 if g1 in terrain else -1.0)  # out of the terrain
            rows.append((sphere, float(c.dist), np.array(c.pos), normal, force, np.array(c.solref),
                         np.array(c.solimp), float(c.friction[0]), float(c.includemargin)))
        out.append(rows)
        qacc.append(data.qacc.copy())
    return out, np.array(qacc)


def warp_contacts(model, qpos, qvel, ctrl, terrain, soles, depth_m):
    import mujoco_warp as mjw
    import warp as wp

    from ambulo.engine.warp_hfield import limit_hfield_contact_depth

    wp.init()
    limit_hfield_contact_depth(depth_m)
    n = len(qpos)
    with wp.ScopedDevice("cpu"):
        m = mjw.put_model(model)
        d = mjw.put_data(model, mujoco.MjData(model), nworld=n, nconmax=64 * n, njmax=256 * n)
        d.qpos.assign(qpos.astype(np.float32))
        d.qvel.assign(qvel.astype(np.float32))
        d.ctrl.assign(ctrl.astype(np.float32))
        mjw.forward(m, d)
        nacon = int(d.nacon.numpy()[0])
        ids = wp.array(np.arange(nacon, dtype=np.int32), dtype=int)
        force = wp.zeros(nacon, dtype=wp.spatial_vector)
        mjw.contact_force(m, d, ids, True, force)
        force = force.numpy()
        geom, world = d.contact.geom.numpy()[:nacon], d.contact.worldid.numpy()[:nacon]
        dist, pos, frame = d.contact.dist.numpy()[:nacon], d.contact.pos.numpy()[:nacon], d.contact.frame.numpy()[:nacon]
        solref, solimp = d.contact.solref.numpy()[:nacon], d.contact.solimp.numpy()[:nacon]
        friction, margin = d.contact.friction.numpy()[:nacon], d.contact.includemargin.numpy()[:nacon]
        qacc = d.qacc.numpy().astype(float)
    out = [[] for _ in range(n)]
    for i in range(nacon):
        g1, g2 = (int(x) for x in geom[i])
        sphere = g2 if g1 in terrain else g1 if g2 in terrain else None
        if sphere not in soles:
            continue
        sign = 1.0 if g1 in terrain else -1.0
        # contact_force in the world frame is the force on geom 2 (MuJoCo's convention)
        f = force[i][:3]
        out[int(world[i])].append((sphere, float(dist[i]), pos[i].astype(float), frame[i][0].astype(float) * sign,
                                   f.astype(float) * sign, solref[i], solimp[i], float(friction[i][0]),
                                   float(margin[i])))
    return out, qacc


def per_sphere(contacts):
    """{(state, sphere): summary} of one engine's contacts."""
    spheres = {}
    for s, rows in enumerate(contacts):
        for row in rows:
            spheres.setdefault((s, row[0]), []).append(row)
    summary = {}
    for key, rows in spheres.items():
        dist = np.array([r[1] for r in rows])
        deepest = rows[int(dist.argmin())]
        pos = np.array([r[2] for r in rows])
        tilt = [float(np.degrees(np.arccos(np.clip(r[3] @ deepest[3], -1, 1)))) for r in rows]
        summary[key] = {"count": len(rows), "depth_m": float(-dist.min()),
                        "spread_m": float(np.linalg.norm(pos - deepest[2], axis=1).max()),
                        "max_tilt_deg": max(tilt), "normal_z": float(deepest[3][2]),
                        "force_w": np.sum([r[4] for r in rows], axis=0),
                        "params": (tuple(np.round(deepest[5], 4)), tuple(np.round(deepest[6], 4)),
                                   round(deepest[7], 4), round(deepest[8], 5))}
    return summary


def divergence(qacc_mj: np.ndarray, qacc_wp: np.ndarray, dt_s: float) -> dict:
    """How far one physics step from the same state takes the engines apart: the base's linear
    and angular velocity change (qacc * dt) differing, m/s and rad/s, median and p95 over states."""
    lin = np.linalg.norm(qacc_mj[:, :3] - qacc_wp[:, :3], axis=1) * dt_s
    ang = np.linalg.norm(qacc_mj[:, 3:6] - qacc_wp[:, 3:6], axis=1) * dt_s
    return {"base_dv_m_s": [float(np.median(lin)), float(np.percentile(lin, 95))],
            "base_dw_rad_s": [float(np.median(ang)), float(np.percentile(ang, 95))]}


def compare(c_mj, c_wp) -> dict:
    a, b = per_sphere(c_mj), per_sphere(c_wp)
    both = sorted(set(a) & set(b))
    count_a = np.array([a[k]["count"] for k in both])
    count_b = np.array([b[k]["count"] for k in both])
    fz_a = np.array([a[k]["force_w"][2] for k in both])
    fz_b = np.array([b[k]["force_w"][2] for k in both])
    fxy_a = np.array([np.linalg.norm(a[k]["force_w"][:2]) for k in both])
    fxy_b = np.array([np.linalg.norm(b[k]["force_w"][:2]) for k in both])
    depth_a = np.array([a[k]["depth_m"] for k in both])
    depth_b = np.array([b[k]["depth_m"] for k in both])

    def hist(c):
        values, counts = np.unique(c, return_counts=True)
        return {int(v): int(n) for v, n in zip(values, counts, strict=True)}

    total_force = (float(np.sum(fz_a)), float(np.sum(fz_b)))
    return {
        "touching_spheres": {"mujoco": len(a), "warp": len(b), "both": len(both)},
        "contacts_per_sphere": {"mujoco": hist(count_a), "warp": hist(count_b)},
        "mean_count": {"mujoco": float(count_a.mean()), "warp": float(count_b.mean())},
        "depth_mm_median": {"mujoco": float(np.median(depth_a) * 1e3), "warp": float(np.median(depth_b) * 1e3)},
        "depth_mm_p95": {"mujoco": float(np.percentile(depth_a, 95) * 1e3),
                         "warp": float(np.percentile(depth_b, 95) * 1e3)},
        "depth_diff_mm_p95": float(np.percentile(np.abs(depth_a - depth_b), 95) * 1e3),
        "spread_mm_p95": {"mujoco": float(np.percentile([a[k]["spread_m"] for k in both], 95) * 1e3),
                          "warp": float(np.percentile([b[k]["spread_m"] for k in both], 95) * 1e3)},
        "max_tilt_deg_p95": {"mujoco": float(np.percentile([a[k]["max_tilt_deg"] for k in both], 95)),
                             "warp": float(np.percentile([b[k]["max_tilt_deg"] for k in both], 95))},
        "normal_z_min": {"mujoco": float(min(a[k]["normal_z"] for k in both)),
                         "warp": float(min(b[k]["normal_z"] for k in both))},
        "sum_force_z_N": {"mujoco": total_force[0], "warp": total_force[1]},
        "force_z_ratio_median": float(np.median(fz_a / np.maximum(fz_b, 1e-6))),
        "force_xy_over_z": {"mujoco": float(np.sum(fxy_a) / max(np.sum(fz_a), 1e-9)),
                            "warp": float(np.sum(fxy_b) / max(np.sum(fz_b), 1e-9))},
        "force_z_N_by_count_mujoco": {int(c): [float(np.median(fz_a[count_a == c])), float(np.median(fz_b[count_a == c]))]
                                      for c in np.unique(count_a)},
        "params": {"mujoco": sorted({str(a[k]["params"]) for k in both}),
                   "warp": sorted({str(b[k]["params"]) for k in both})},
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--run", required=True, help="a humanoid-rough run folder or checkpoint")
    p.add_argument("--kinds", default="slope_down", help="tile kinds, comma-separated")
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--steps", type=int, default=200, help="policy steps replayed on the CPU engine")
    p.add_argument("--every", type=int, default=10, help="keep every n-th state")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--mujoco-hfield", choices=("own", "warp"), default="own",
                   help="MuJoCo C's heightfield contacts: its own, or reduced as Warp's")
    p.add_argument("--warp-depth-m", type=float, default=0.02, help="Warp's hfield depth limit (0: off)")
    args = p.parse_args()
    run_dir, ckpt = runs.resolve_policy(args.run)
    info = runs.read_run_info(run_dir)
    t0 = time.perf_counter()
    model, qpos, qvel, ctrl = record_states(args, info, run_dir, ckpt)
    terrain, soles = geom_ids(model)
    reduce_hfield_contacts(args.warp_depth_m or None, enabled=args.mujoco_hfield == "warp")
    c_mj, qacc_mj = mujoco_contacts(model, qpos, qvel, ctrl, terrain, soles)
    c_wp, qacc_wp = warp_contacts(model, qpos, qvel, ctrl, terrain, soles, args.warp_depth_m or None)
    result = {"run": str(ckpt), "kinds": args.kinds, "mujoco_hfield": args.mujoco_hfield, "states": len(qpos),
              **compare(c_mj, c_wp), "one_step_divergence": divergence(qacc_mj, qacc_wp, model.opt.timestep),
              "seconds": round(time.perf_counter() - t0, 1)}
    for k, v in result.items():
        print(f"{k}: {v}")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
