"""The policy walker walking into a low box it has not seen: how often does it fall?

    python benchmarks/walker_low_box.py [--heights 0.06,0.10,0.14] [--offsets -0.2,-0.1,0,0.1,0.2]
        [--variants off,back,caution] [--seconds 8]

An empty floor with one box (0.5 x 0.32 m, ``--heights`` tall) whose centre is 1.0 m ahead of the
robot and ``--offsets`` m to its side; the ``navigation.walkers.PolicyWalker`` follows a straight
3 m path through it on the true pose (no camera: what the walker does when the map missed the box,
the benchmark's falls). Variants (``navigation.caution``):

- ``off``: no caution (the policy at its 0.55 m/s cruise);
- ``slow``: 0.25 m/s everywhere (the blind-zone cap), no step back;
- ``back``: the step back after a foot feels the box, at the 0.55 m/s cruise (no blind zone);
- ``caution``: both, the walker's default.

Reported per variant: falls of the approaches. One ``RESULT {json}`` line at the end.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import mujoco
import numpy as np

from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.caution import CautionCfg
from ambulo.navigation.walkers import PolicyWalker, PolicyWalkerCfg


def walker_cfg(variant: str) -> PolicyWalkerCfg:
    if variant == "off":
        return PolicyWalkerCfg(caution=None)
    if variant == "slow":
        cfg = PolicyWalkerCfg(caution=None)
        cfg.tracker.cruise_speed_m_s = CautionCfg().blind_speed_m_s
        return cfg
    if variant == "back":  # no blind zone: the cap never applies
        return PolicyWalkerCfg(caution=CautionCfg(blind_speed_m_s=10.0))
    if variant == "caution":
        return PolicyWalkerCfg()
    raise SystemExit(f"unknown variant {variant!r}: use off, slow, back or caution")


def approach(variant: str, height_m: float, offset_m: float, seconds: float) -> dict:
    xml = f"""<mujoco><worldbody><geom name="floor" type="plane" size="8 8 0.1"/>
      <body name="box" pos="1.0 {offset_m} {height_m / 2}"><geom type="box" size="0.25 0.16 {height_m / 2}"/></body>
      </worldbody></mujoco>"""
    world = NavWorld.from_spec(mujoco.MjSpec.from_string(xml), (0.0, 0.0, 0.0), NavWorldCfg(record_gyro=False))
    walker = PolicyWalker(walker_cfg(variant))
    walker.bind(world)
    walker.reset()
    world.engine.forward()
    walker.tracker.set_path(np.stack([np.linspace(0.0, 3.0, 31), np.zeros(31)], 1), final=True)
    walker.resume()
    for _ in range(int(seconds / world.dt_s)):
        walker.step(world.dt_s, world.true_pose())
        world.step()
        if world.fell:
            break
    out = {"height_m": height_m, "offset_m": offset_m, "fell": bool(world.fell), "x_m": float(world.true_pose()[0]),
           "felt": int(len(getattr(walker, "felt_xy_m", ())))}
    world.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--heights", default="0.06,0.10,0.14")
    parser.add_argument("--offsets", default="-0.2,-0.1,0,0.1,0.2")
    parser.add_argument("--variants", default="off,back,caution")
    parser.add_argument("--seconds", type=float, default=8.0)
    args = parser.parse_args()
    heights = [float(v) for v in args.heights.split(",")]
    offsets = [float(v) for v in args.offsets.split(",")]
    result = {}
    for variant in args.variants.split(","):
        t0 = time.perf_counter()
        runs = [approach(variant, h, dy, args.seconds) for h, dy in itertools.product(heights, offsets)]
        falls = sum(r["fell"] for r in runs)
        by_height = {str(h): sum(r["fell"] for r in runs if r["height_m"] == h) for h in heights}
        result[variant] = {"falls": falls, "approaches": len(runs), "falls_by_height_m": by_height,
                           "wall_s": round(time.perf_counter() - t0, 1)}
        print(f"{variant}: {falls} of {len(runs)} approaches fell {by_height}", flush=True)
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
