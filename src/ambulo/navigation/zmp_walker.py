"""The ZMP walker behind the navigator's ``Walker`` interface: a thin adapter over
``locomotion.step_walker.ZmpStepWalker`` (preview control of the ZMP, the whole-body controller
and its capture-point stabilizer), which steps *on* the planned footholds.

What the adapter adds: binding to a ``NavWorld``; ``start_feet()`` so the navigator plans from the
feet the walker will stand on at its next touchdown (``next_stance_feet_xyyaw_w`` and
``stance_side``: a new plan splices onto the steps in progress exactly); ``arrived`` when a final
plan is walked and the robot settled; the balance in the navigator's ``BalanceReport``.

The ZMP walker's controller measures the robot's state in the simulator (its feet, its CoM), so
the pose estimate of the navigator only chooses where to go: in ``full`` mode the footholds come
from the VO's map frame while the steps are placed in the simulator's; use it in ``oracle`` mode
(the benchmark's "ZMP walker in oracle mode").

Its steps take 0.6 s (``zmp_walker_cfg``), not the step walker's 0.8 s default: on the navigate
benchmark's apartments 200-209 (oracle, episode seed 0) 0.6 s arrived in 9 of 10 (SPL 0.71, one
stuck, no fall, no collision) against 9 of 10 at 0.8 s (SPL 0.67, one fall, 0.4 collisions an
episode), 14-29 % sooner on each of the 9 apartments both reached (``zmp_walker_cfg`` has the command).
"""

from __future__ import annotations

import math

import numpy as np

from ..locomotion.step_walker import StepWalkerCfg, ZmpStepWalker, step_walker_cfg
from ..nav import FootstepPlan
from .walkers import BalanceReport, body_path
from .world import NavWorld


def zmp_walker_cfg(**overrides) -> StepWalkerCfg:
    """The navigator's step walker: 0.6 s steps (module docstring). Measured with
    ``benchmarks/navigate.py --episodes 10 --first-seed 200 --modes oracle --walkers zmp --workers 1``
    run once with each step time (patched in) on the busy 2-core machine; ``benchmarks/zmp_step_walker.py --episodes 5 --seed 3 --min-m 3 --max-m 5``: 5 of 5 at
    both, mean speed 0.137 against 0.107 m/s."""
    return step_walker_cfg(**{"step_time_s": 0.6, **overrides})


class ZmpWalker:
    """``walkers.Walker`` over ``ZmpStepWalker`` (module docstring)."""

    name = "zmp"

    def __init__(self, cfg: StepWalkerCfg | None = None):
        self.inner = ZmpStepWalker(cfg or zmp_walker_cfg())
        self.world: NavWorld | None = None
        self.command = None
        self._final = False
        self._step_m = 0.2

    def bind(self, world: NavWorld) -> None:
        self.world = world
        self.inner.bind(world.sim, world.robot)

    def reset(self) -> None:
        self.inner.reset()
        self._final = False

    def refuse(self, plan: FootstepPlan) -> str | None:
        return self.inner.refuse(plan)

    def start_feet(self) -> tuple[np.ndarray, int]:
        """((2, 3) left and right feet at the next touchdown, the foot to keep down first)."""
        return self.inner.next_stance_feet_xyyaw_w(), self.inner.stance_side

    def set_plan(self, plan: FootstepPlan | None, *, final: bool) -> None:
        reason = self.inner.set_plan(plan)
        self._final = bool(final and plan is not None and reason is None)
        if plan is not None and plan.num_steps:
            jumps = np.linalg.norm(np.diff(body_path(plan), axis=0), axis=1)
            self._step_m = float(jumps.mean()) if len(jumps) else self._step_m

    def stand(self) -> None:
        """Stop after the step in the air (a swing foot always lands where it was going)."""
        self.inner.set_plan(None)
        self._final = False

    def step(self, dt_s: float, pose_xyyaw: np.ndarray) -> None:
        self.inner.step(dt_s)

    def balance(self) -> BalanceReport:
        b = self.inner.balance()
        data = self.inner.data
        root = self.inner.root
        return BalanceReport(time_s=self.world.time_s, com_xyz_m=data.subtree_com[root].copy(),
                             capture_point_xy_m=np.asarray(b.capture_point_xy), zmp_xy_m=np.asarray(b.zmp_xy),
                             feet_in_contact=(True, True) if b.support_polygon_xy is None else
                             tuple(bool(v) for v in self._contacts()),
                             support_polygon_xy_m=b.support_polygon_xy, capture_margin_m=b.capture_margin_m,
                             zmp_margin_m=b.zmp_margin_m)

    def _contacts(self) -> tuple[bool, bool]:
        target = self.inner.swing_target_w
        if target is None:
            return True, True
        side = self.inner.stance_side  # the foot in the air lands on this side
        return (side != 1, side != -1)

    @property
    def arrived(self) -> bool:
        return self._final and self.inner.done

    @property
    def remaining_m(self) -> float:
        return self.inner.remaining_steps * self._step_m if not math.isnan(self._step_m) else 0.0


__all__ = ["ZmpWalker", "zmp_walker_cfg"]
