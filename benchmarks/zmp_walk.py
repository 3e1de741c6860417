"""The bundled humanoid walking issue 14's acceptance path in MuJoCo, over seeded runs.

    python benchmarks/zmp_walk.py [--seeds 10] [--distance 3] [--turn-deg 90]
        [--joint-noise 0.02] [--speed-noise 0.05] [--png docs/images/zmp_walk.png]

The footstep planner plans ``--distance`` m straight ahead and a ``--turn-deg`` turn on the spot
(empty floor), ZMP preview control makes the walking pattern, and the whole-body controller of
``ambulo.locomotion.walk_controller`` walks it on the simulated humanoid (flat floor, friction 1; one
``core.Simulation`` world of ``scenes.walk_arena``, its joint targets through the humanoid's ``Entity``). Run s
(s = 0..seeds-1) starts from the pattern's first pose with every joint off by up to
``--joint-noise`` rad and the base moving at up to ``--speed-noise`` m/s (uniform, seed s).

Per run and over all runs: falls; the measured ZMP (centre of pressure of the foot contact forces)
inside the support polygon of the soles in contact, as a share of single-support samples, and its
margin (min / p5 / median); the capture point at every touchdown against the support polygon
right after it (both soles) and against the new sole alone; the capture point at every lift-off
against the stance sole; distance walked and heading change. One ``RESULT {json}`` line at the
end. Acceptance (issue 14): >= 95 % of single-support samples inside, the capture point inside
at every touchdown, no fall.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from ambulo.locomotion.walk_sim import WalkSimCfg, acceptance_walk, straight_and_turn_goal


class Snapshots:
    """Renders the robot at a few moments of the walk (a fixed camera from the side and above)
    and saves them side by side."""

    def __init__(self, model, pattern, track_body: int, times_s=None, size=(360, 480)):
        import mujoco

        from ambulo.render import OffscreenRenderer

        end = pattern.time_s[-1]
        self.times = list(times_s or np.linspace(2.0, end - 0.5, 6))
        self.keys = {int(round(t / pattern.dt_s)) for t in self.times}
        self.renderer = OffscreenRenderer(model, size[0], size[1])
        self.model, self.images = model, []
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self.camera.trackbodyid = track_body
        self.camera.distance, self.camera.elevation, self.camera.azimuth = 2.6, -15.0, 100.0

    def __call__(self, k, data):
        if k in self.keys:
            self.renderer.update_view(self.model, data, self.camera)
            self.images.append((k, np.array(self.renderer.render_rgb())))

    def save(self, path):
        import imageio.v2 as imageio

        self.renderer.close()
        if self.images:
            imageio.imwrite(path, np.concatenate([img for _, img in sorted(self.images)], axis=1))


def _mm(value) -> str:
    return "n/a" if value is None else f"{value:.1f}"


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--distance", type=float, default=3.0)
    parser.add_argument("--turn-deg", type=float, default=90.0)
    parser.add_argument("--joint-noise", type=float, default=0.02, help="rad")
    parser.add_argument("--speed-noise", type=float, default=0.05, help="m/s")
    parser.add_argument("--png", default=None, help="picture of the first run")
    parser.add_argument("--video", default=None, help="MP4 of the first run")
    parser.add_argument("--frames", default=None, help="PNG strip of snapshots of the first run")
    args = parser.parse_args(argv)

    t0 = time.perf_counter()
    cfg = WalkSimCfg(joint_noise_rad=args.joint_noise, base_speed_noise_mps=args.speed_noise)
    plan, sim = acceptance_walk(args.distance, math.radians(args.turn_deg), cfg=cfg)
    setup_s = time.perf_counter() - t0
    runs, margins, results = [], [], []
    for seed in range(args.seeds):
        t1 = time.perf_counter()
        snapshots = Snapshots(sim.model, sim.pattern, sim.pelvis) if seed == 0 and args.frames else None
        result = sim.run(seed, video=args.video if seed == 0 else None, on_step=snapshots)
        if snapshots is not None:
            snapshots.save(args.frames)
        s = result.summary()
        s["wall_s"] = round(time.perf_counter() - t1, 2)
        runs.append(s)
        results.append(result)
        margins.append(result.single_support_margins_m)
        m = s["zmp_margin_single_support_mm"]
        print(f"seed {seed}: {'FELL ' + s['fall_reason'] if s['fell'] else 'no fall'}; ZMP inside "
              f"{100 * s['zmp_inside_single_support']:.1f} % of single support (min {_mm(m['min'])} mm, p5 "
              f"{_mm(m['p5'])} mm); capture point inside at {int((result.capture_margin_m >= 0).sum())}/"
              f"{s['touchdowns']} touchdowns (min {_mm(s['capture_margin_min_mm'])} mm), in the stance sole at "
              f"{s['capture_in_stance_sole_at_liftoff']}/{s['liftoffs']} lift-offs; {s['distance_m']:.3f} m, "
              f"{s['turn_deg']:.1f} deg")
    all_margins = np.concatenate(margins)
    finite = all_margins[np.isfinite(all_margins)]
    summary = {
        "seeds": args.seeds, "steps": int(plan.num_steps), "plan_status": plan.status.value,
        "falls": int(sum(r["fell"] for r in runs)),
        "zmp_inside_single_support": float(np.mean(all_margins >= 0.0)),
        "zmp_inside_single_support_worst_run": float(np.nanmin([r["zmp_inside_single_support"] for r in runs])),
        "zmp_margin_mm": {"min": float(finite.min() * 1e3), "p5": float(np.percentile(finite, 5) * 1e3),
                          "median": float(np.median(finite) * 1e3), "max": float(finite.max() * 1e3)},
        "capture_inside_every_touchdown": all(r["capture_inside_all"] for r in runs),
        "capture_margin_min_mm": min((r["capture_margin_min_mm"] for r in runs if r["capture_margin_min_mm"] is not None),
                                     default=None),
        "capture_in_new_sole_at_touchdown": int(sum(r["capture_in_new_sole"] for r in runs)),
        "capture_in_stance_sole_at_liftoff": int(sum(r["capture_in_stance_sole_at_liftoff"] for r in runs)),
        "liftoffs": int(sum(r["liftoffs"] for r in runs)),
        "capture_liftoff_margin_min_mm": min((r["capture_liftoff_margin_min_mm"] for r in runs
                                              if r["capture_liftoff_margin_min_mm"] is not None), default=None),
        "touchdowns": int(sum(r["touchdowns"] for r in runs)),
        "distance_m": [round(r["distance_m"], 3) for r in runs],
        "turn_deg": [round(r["turn_deg"], 2) for r in runs],
        "joint_noise_rad": args.joint_noise, "speed_noise_mps": args.speed_noise,
        "setup_s": round(setup_s, 2), "wall_s": round(time.perf_counter() - t0, 2),
    }
    if args.png:
        from ambulo.locomotion.walk_plot import plot_walk
        from ambulo.nav import GridMap

        size = args.distance + 3.0
        grid = GridMap.empty((size, size), resolution_m=0.05, origin_xy_m=(-1.5, -size / 2))
        _, goal = straight_and_turn_goal(args.distance, math.radians(args.turn_deg))
        plot_walk(grid, plan, args.png, pattern=sim.pattern, result=results[0], goal_xyyaw_w=goal,
                  title=f"seed 0 of {args.seeds}: {plan.num_steps} steps, {args.distance:g} m and a "
                        f"{args.turn_deg:g} deg turn (MuJoCo)")
    print(f"{summary['falls']} falls in {args.seeds} runs; measured ZMP inside the support polygon in "
          f"{100 * summary['zmp_inside_single_support']:.2f} % of single-support samples (margin min "
          f"{summary['zmp_margin_mm']['min']:.1f} mm, p5 {summary['zmp_margin_mm']['p5']:.1f} mm); capture point "
          f"inside at every touchdown: {summary['capture_inside_every_touchdown']}")
    print("RESULT " + json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
