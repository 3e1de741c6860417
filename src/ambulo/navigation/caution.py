"""Walking where the head camera has not seen the floor: the blind zone at the start and what the
feet feel.

The head camera (pitched down ``NavWorldCfg.camera_pitch_deg``) sees the floor only from
``floor_blind_distance_m`` ahead (~1.6 m), so clutter of 5-15 cm (a pile of books, a low box)
within that of the start is never seen before the robot walks into it, and the online map reads
its cells free (rays passed over them). The walking policy, trained on flat ground, falls when a
foot lands on it. The 100-apartment benchmark's falls (nominal apartments 4, 12, 43, 85, 88;
randomized also 21, 37, 75, 87): 12 and 43 rerun were a foot on a 10-11 cm box or pile 0.5-0.8 m
from the start; 4, 85, 88, 21, 75 and 87 have such clutter (7-13 cm) 0.4-1.4 m from theirs, 37 one
0.6 m from its goal (touched before the fall). In an empty world (``benchmarks/walker_low_box.py``: a box 1 m ahead, 0-0.2 m to the side of
the path) the policy at its 0.55 m/s cruise fell on 12 of 15 approaches (every one at 10 and 14 cm,
2 of 5 at 6 cm).

Two measures, what a robot without a view of its feet does:

- **slow in the blind zone**: within ``floor_blind_distance_m`` of the start (the floor there was
  never in view) the forward speed is capped at ``blind_speed_m_s``;
- **feel with the feet, then step back**: a contact point of a foot or shin higher than
  ``touch_height_m`` above the floor (what foot force sensors, joint torques and the leg's
  kinematics measure) is an obstacle felt; the walker walks away from it for ``back_off_s`` and
  remembers where (``felt_xy_m``) so the navigator can put it in its map and plans through it are
  refused.

Together (0.25 m/s, 0.3 m/s back for 1 s) the policy fell on none of the 15 approaches, against 9
of 15 at 0.25 m/s without the step back and 8 of 15 with the step back at 0.55 m/s: the slow
walk leaves the foot on the box's edge long enough for the step back to work. In the benchmark's
episodes that fell (episode seed 0, on a busy 2-core machine): full mode, apartments 4 and 85
arrived (SPL 0.83, 0.91), 88 and 12 too with ``felt_xy_m`` marked occupied in the online map (0.72,
0.85; a navigator and mapper change not made yet), 43 no longer fell (then stuck: no route, far from
the box); mapping mode, 12 fell without caution and arrived with it (0.87). Dev apartments with
clutter near the start, mapping mode: 203 and 215 arrived either way (SPL 0.96 and 0.95 without,
0.92 and 0.95 with; the slow start cost 203 4 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..robots import humanoid
from ..utils.validate import Checked
from .world import NavWorld


def floor_blind_distance_m(world: NavWorld) -> float:
    """Horizontal distance from the head camera to the nearest floor point in its view now, m
    (the image's bottom edge on the floor plane z = 0; inf when the bottom edge looks above it)."""
    pose_wc = world.camera_pose_wc()
    k = world.camera.get_intrinsics_matrix()
    height_px = world.cfg.camera_height
    # the ray through the bottom-centre pixel, OpenCV camera axes (x right, y down, z forward)
    ray_c = np.array([0.0, (height_px - k[1, 2]) / k[1, 1], 1.0])
    ray_w = pose_wc[:3, :3] @ ray_c
    cam_w = pose_wc[:3, 3]
    if ray_w[2] >= -1e-9:
        return math.inf
    t = -cam_w[2] / ray_w[2]
    return float(math.hypot(t * ray_w[0], t * ray_w[1]))


@dataclass(kw_only=True)
class CautionCfg(Checked):
    touch_height_m: float = 0.03
    """A foot contact point higher than this above the floor is an obstacle, m (the apartments'
    walk-over height: a 2 cm rug base is floor)."""
    blind_speed_m_s: float = 0.25
    """Forward speed at most within the blind zone, m/s (module docstring)."""
    blind_margin_m: float = 0.0
    """The blind zone is ``floor_blind_distance_m`` plus this around the start, m."""
    back_off_speed_m_s: float = 0.3
    """Backward speed after a touch, m/s."""
    back_off_s: float = 1.0
    """How long to walk backwards after a touch, s."""
    felt_spacing_m: float = 0.05
    """A contact point within this of one already felt adds nothing, m (the online map's cell)."""
    felt_clearance_m: float = 0.2
    """A plan whose body path passes within this of a felt obstacle is refused, m (the policy's
    feet land up to ~0.15 m beside its body path; a sole is 0.22 m long)."""


class FootTouch:
    """Contact points of the humanoid's feet and shins on anything but the floor and the robot
    (module docstring)."""

    def __init__(self, world: NavWorld, cfg: CautionCfg):
        model = world.model
        prefix = humanoid.PRIM_PATH + "/"
        feet = [model.body(prefix + f).id for f in humanoid.FOOT_BODIES]
        # the feet and the bodies they hang from (the shanks): a shin that meets a low box trips too
        self._foot = np.isin(model.geom_bodyid, feet + [int(model.body_parentid[f]) for f in feet])
        robot = np.array([model.body(b).name.startswith(prefix) for b in range(model.nbody)])
        self._robot = robot[model.geom_bodyid]
        self.world = world
        self.cfg = cfg
        self._data: mujoco.MjData | None = None

    def felt_xy_m(self) -> np.ndarray:
        """(K, 2) world xy of the feet's and shins' contact points higher than ``touch_height_m`` now, m."""
        data = self._data = self.world.engine.get_data(0, self._data)
        if not data.ncon:
            return np.zeros((0, 2))
        geom = np.asarray(data.contact.geom)[:data.ncon]
        pos = np.asarray(data.contact.pos)[:data.ncon]
        a, b = geom[:, 0], geom[:, 1]
        foot_on_world = (self._foot[a] & ~self._robot[b]) | (self._foot[b] & ~self._robot[a])
        high = pos[:, 2] > self.cfg.touch_height_m
        return pos[foot_on_world & high, :2].copy()


__all__ = ["CautionCfg", "FootTouch", "floor_blind_distance_m"]
