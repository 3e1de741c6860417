"""How far the humanoid reaches while the walking policy turns on the spot: the pelvis's wander from
where the turn began and the farthest point of any robot geom but the soles from there, with the
turn open loop (the policy told (0, 0, w)) and with the position held (``PositionHold.turn_command``,
what ``PolicyWalker`` does now), in an empty world, the true pose as the estimate.

    .venv/bin/python benchmarks/turn_on_the_spot.py [--seconds 6] [--rates 0.3 0.6 0.9]

Prints one line per (rate, hold) and ``RESULT {json}``: per rate the open loop's and the held turn's
wander and reach (m), and their ratio (held / open loop; the ceiling is the arms' reach standing
still, measured in the same run: no turn can need less room than that).
"""

from __future__ import annotations

import argparse
import json
import math

import mujoco
import numpy as np

from ambulo.navigation.walkers import PolicyWalker, PolicyWalkerCfg
from ambulo.navigation.world import NavWorld
from ambulo.robots import humanoid

EMPTY = '<mujoco><worldbody><geom name="floor" type="plane" size="20 20 0.1"/></worldbody></mujoco>'


def geom_reach_m(model, data, geoms: np.ndarray, centre_xy: np.ndarray) -> float:
    """Farthest horizontal distance of the ``geoms`` (capsules, boxes, others by their bounding
    radius) from ``centre_xy``, m."""
    out = 0.0
    for g in geoms:
        p, size, rot = data.geom_xpos[g], model.geom_size[g], data.geom_xmat[g].reshape(3, 3)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            ends = np.stack([p + rot[:, 2] * size[1], p - rot[:, 2] * size[1]])
            reach = np.linalg.norm(ends[:, :2] - centre_xy, axis=1).max() + size[0]
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
            corners = p + (signs * size) @ rot.T
            reach = np.linalg.norm(corners[:, :2] - centre_xy, axis=1).max()
        else:
            reach = np.linalg.norm(p[:2] - centre_xy) + model.geom_rbound[g]
        out = max(out, float(reach))
    return out


def turn(rate_rad_s: float, hold: bool, seconds: float) -> dict:
    """Stand 1 s, then turn at ``rate_rad_s`` for ``seconds``: wander and reach from the turn's start, m."""
    world = NavWorld.from_spec(mujoco.MjSpec.from_string(EMPTY), (0.0, 0.0, 0.0))
    cfg = PolicyWalkerCfg(caution=None) if hold else PolicyWalkerCfg(caution=None, hold=None)
    walker = PolicyWalker(cfg)
    walker.bind(world)
    walker.reset()
    world.engine.forward()
    world.reset_monitors()
    model = world.model
    prefix = humanoid.PRIM_PATH + "/"
    feet = {model.body(prefix + f).id for f in humanoid.FOOT_BODIES}
    body_names = [model.body(b).name for b in range(model.nbody)]
    robot = np.array([body_names[b].startswith(prefix) and b not in feet for b in model.geom_bodyid])
    geoms = np.flatnonzero(robot)
    wander = reach = 0.0
    start = None
    turned = 0.0
    last_yaw = None
    for k in range(int((1.0 + seconds) / world.dt_s)):
        t = k * world.dt_s
        if t >= 1.0 and start is None:
            start = world.true_pose()[:2].copy()
            walker.scan(rate_rad_s)
        walker.step(world.dt_s, world.true_pose())
        world.step()
        if start is not None and k % 4 == 0:
            pose = world.true_pose()
            if last_yaw is not None:
                turned += abs(math.atan2(math.sin(pose[2] - last_yaw), math.cos(pose[2] - last_yaw)))
            last_yaw = pose[2]
            data = world.engine.get_data(0)
            wander = max(wander, float(np.linalg.norm(pose[:2] - start)))
            reach = max(reach, geom_reach_m(model, data, geoms, start))
    fell = world.fell
    world.close()
    return {"wander_m": round(wander, 3), "reach_m": round(reach, 3), "turned_rad": round(turned, 2), "fell": fell}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--rates", type=float, nargs="+", default=[0.3, 0.6, 0.9])
    args = ap.parse_args(argv)
    standing = turn(0.0, True, args.seconds)
    print(f"standing (held): {standing}")
    out = {"seconds": args.seconds, "standing_reach_m": standing["reach_m"], "rates": {}}
    for rate in args.rates:
        open_loop, held = turn(rate, False, args.seconds), turn(rate, True, args.seconds)
        print(f"{rate:.1f} rad/s: open loop {open_loop}, held {held}")
        out["rates"][f"{rate:.1f}"] = {"open_loop": open_loop, "held": held,
                                       "reach_held_over_open": round(held["reach_m"] / open_loop["reach_m"], 3),
                                       "reach_held_over_standing": round(held["reach_m"] / standing["reach_m"], 3)}
    print("RESULT " + json.dumps(out))
    return out


if __name__ == "__main__":
    main()
