"""How much of split (b)'s clutter cost no detector could avoid: 3 of its 12 distractors were spheres within 25 %
of a ball's radius (0.147, 0.175, 0.181 m; the balls are 0.12 and 0.18 m), balls by geometry. This scores
checkpoints on the clutter-only factor split as ``detect_domain_gap.py --factors`` draws it, and on the same
split with those spheres shrunk to 1 cm (same seed, the rest of the pool and every draw unchanged): the
difference is what the ball-sized spheres cost. Since session 9 split (b) redraws them
(``ClassFreeDistractors``); this script rebuilds the old pool (plain ``Distractors``) for both its splits, so
its figures stay those of the old split.

    python benchmarks/detect_gap_ball_twins.py --width 160 --height 120 --frames 100 --out /tmp/twins \
        --checkpoint runs/a/checkpoint.pt runs/b/checkpoint.pt

RESULT: {checkpoint: {"clutter_only": mAP50, "clutter_only_no_ball_spheres": mAP50, per-class APs}}.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from detect_domain_gap import config, make

from ambulo.replicator.hard_negatives import DISTRACTOR_SHAPES, class_shapes, too_close
from ambulo.replicator.scatter import Distractors


@dataclass(kw_only=True)
class NoBallSpheres(Distractors):
    """``Distractors`` whose spheres within ``margin`` of a ball's radius are 1 cm: the same draws (so
    the same pool otherwise, and the same placements where collisions allow)."""

    margin: float = 0.25

    def build(self, spec):
        rng = np.random.default_rng(self.pool_seed)
        balls = [shape for shape in class_shapes() if shape[0] == "sphere"]
        root = self.prims.rstrip("*").rstrip("/")
        for i in range(self.pool_size):
            body = spec.worldbody.add_body(name=f"{root}/distractor_{i}", pos=[0, 0, -10.0 - 3.0 * i])
            body.add_freejoint()
            size = rng.uniform(*self.size_m, 3)  # Distractors.build's draws, in its order
            rgba = [*rng.uniform(0.1, 1.0, 3), 1.0]
            kind = DISTRACTOR_SHAPES[i % len(DISTRACTOR_SHAPES)]
            if kind == "sphere" and too_close(kind, tuple(size), balls, self.margin):
                size = np.full(3, 0.01)
            body.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=size, rgba=rgba)


def old_clutter_config(width: int, height: int, kind: type[Distractors] = Distractors, suffix: str = "_old_pool"):
    """The old split (b)'s clutter-only factor (before session 9: the pool as ``Distractors`` draws it, ball-sized
    spheres included), its distractors built by ``kind``."""
    base = config(width, height, ("clutter",))
    randomizers = [kind(**{f.name: getattr(r, f.name) for f in dataclasses.fields(kind)})
                   if r.name == "distractors" else r for r in base.randomizers]
    return dataclasses.replace(base, name=base.name + suffix, randomizers=randomizers)


def no_ball_spheres_config(width: int, height: int):
    """The old split (b)'s clutter-only factor with its ball-sized spheres shrunk (module docstring)."""
    return old_clutter_config(width, height, NoBallSpheres, "_no_ball_spheres")


def main() -> None:
    from ambulo.detection import evaluate_checkpoint

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", nargs="+", required=True)
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", default="runs/ball_twins", help="the two splits go here")
    args = parser.parse_args()
    out = Path(args.out)
    # seed 1: detect_domain_gap's split (b) and its factors
    splits = {"clutter_only": make(old_clutter_config(args.width, args.height), out / "clutter", args.frames, 1,
                                   args.workers),
              "clutter_only_no_ball_spheres": make(no_ball_spheres_config(args.width, args.height),
                                                   out / "clutter_no_ball_spheres", args.frames, 1, args.workers)}
    result = {}
    for checkpoint in args.checkpoint:
        scores = {name: evaluate_checkpoint(checkpoint, folder, device=args.device, masks=False)
                  for name, folder in splits.items()}
        result[checkpoint] = {name: {"mAP50": round(s["mAP50"], 3), "mAP": round(s["mAP"], 3),
                                     "per_class": {k: round(v, 3) for k, v in s["per_class"].items()}}
                              for name, s in scores.items()}
        cost = 100 * (scores["clutter_only_no_ball_spheres"]["mAP50"] - scores["clutter_only"]["mAP50"])
        print(f"{checkpoint}: clutter only mAP50 {scores['clutter_only']['mAP50']:.3f}, without the ball-sized "
              f"spheres {scores['clutter_only_no_ball_spheres']['mAP50']:.3f} (they cost {cost:.1f} points)")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
