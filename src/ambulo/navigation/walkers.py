"""Walkers: what turns a footstep plan into joint targets, behind one interface (``Walker``).

A walker is bound to a ``NavWorld``'s humanoid, takes a ``FootstepPlan`` (``set_plan``), is
stepped every physics step with the navigator's pose estimate (``step``), can be told to stand
(``stand``), reports its balance (``balance``: capture point and ZMP against the support polygon,
from ``locomotion.balance``) and refuses, *before* it is taken, a plan it cannot walk
(``refuse(plan)`` -> a one-line reason, or None).

``PolicyWalker`` (the default): the shipped walking policy (``policies.WalkingPolicy``) follows the
plan's body path, the midpoints of consecutive footsteps, with ``tracker.PathTracker``. It places
its own feet (the policy knows no footholds), so the plan gives the path and the footholds'
clearance, not exact steps. Standing (told to, at the end of a plan, arrived) it holds its pose
with ``stand_hold.PositionHold``: the policy creeps ~4 cm/s when commanded zero. Where the head
camera has not seen the floor (near the start, and where the navigator says: ``add_blind_zone``) it
walks slowly, and a foot that feels an obstacle makes it step back and refuse plans through it
(``caution``; ``felt_xy_m`` for the navigator's map).

The other walkers (``benchmark.make_walker(name)``): ``footstep_walker.FootstepPolicyWalker``
("footsteps"), the learned humanoid-footsteps policy, puts its feet on the plan's footsteps, fed
them as its training env feeds them (it stands with this module's velocity policy and position
hold); ``zmp_walker.ZmpWalker`` ("zmp") steps on them with preview control of the ZMP. Both plan
from their own feet (``start_feet``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import mujoco
import numpy as np

from ..locomotion.balance import (
    CenterOfPressure,
    FootShape,
    capture_point,
    polygon_signed_distance,
    support_polygon,
)
from ..nav import FootstepPlan, PlanStatus
from ..policies.walking import WalkingPolicy
from ..robots import humanoid
from ..utils.validate import Checked
from .caution import CautionCfg, FootTouch, floor_blind_distance_m
from .stand_hold import PositionHold, StandHoldCfg
from .tracker import PathTracker, TrackerCfg
from .world import NavWorld


def body_path(plan: FootstepPlan) -> np.ndarray:
    """(num_steps + 1, 2) the plan's body path: the midpoint of each pair of consecutive feet, m."""
    feet = plan.footsteps_xyyaw_w[:, :2]
    return 0.5 * (feet[:-1] + feet[1:])


def plan_refusal(plan: FootstepPlan, pose_xy_m: np.ndarray, max_start_offset_m: float, max_step_m: float) -> str | None:
    """Why a walker at ``pose_xy_m`` (pose estimate frame) cannot take ``plan``, in one line, or None: the
    planner failed, the plan has no step, its body path starts more than ``max_start_offset_m`` away or
    moves more than ``max_step_m`` in one step."""
    if plan.status in (PlanStatus.START_IN_COLLISION, PlanStatus.GOAL_IN_COLLISION):
        return f"the plan failed ({plan.status.value}): {plan.detail}"
    if plan.num_steps < 1:
        return "the plan has no step"
    path = body_path(plan)
    offset = float(np.linalg.norm(path[0] - pose_xy_m))
    if offset > max_start_offset_m:
        return f"the plan starts {offset:.2f} m from the robot (more than {max_start_offset_m} m)"
    jumps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    if len(jumps) and jumps.max() > max_step_m:
        return f"the plan's body moves {jumps.max():.2f} m in one step (more than {max_step_m} m)"
    return None


@dataclass
class BalanceReport:
    """The robot's balance now (world frame, m)."""

    time_s: float
    com_xyz_m: np.ndarray
    """(3,) centre of mass."""
    capture_point_xy_m: np.ndarray
    """(2,) instantaneous capture point (LIPM, the CoM's height)."""
    zmp_xy_m: np.ndarray
    """(2,) measured ZMP (centre of pressure of the feet's ground contacts); NaN in flight."""
    feet_in_contact: tuple[bool, bool]
    """(left, right) sole touching the ground."""
    support_polygon_xy_m: np.ndarray | None
    """(M, 2) counter-clockwise hull of the soles in contact; None with no foot down."""
    capture_margin_m: float
    """Signed distance of the capture point to the support polygon's edge (> 0 inside), m."""
    zmp_margin_m: float
    """The same for the ZMP, m (NaN without contact)."""


class BalanceMonitor:
    """Capture point and ZMP of the humanoid in a ``NavWorld`` (on request: one ``get_data``)."""

    def __init__(self, world: NavWorld):
        self.world = world
        model = world.model
        prefix = humanoid.PRIM_PATH + "/"
        self._root = model.body(prefix + humanoid.BASE_BODY).id
        self._soles = [model.site(prefix + s).id for s in humanoid.SOLE_SITES]
        self._foot_geoms = [np.flatnonzero(model.geom_bodyid == model.body(prefix + f).id) for f in humanoid.FOOT_BODIES]
        planes = np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)
        self.cop = CenterOfPressure(model, [prefix + f for f in humanoid.FOOT_BODIES],
                                    ground_geoms=[int(g) for g in planes] or None, ground_height_m=0.0)
        self.foot = FootShape(length_m=humanoid.SOLE_LENGTH_M, width_m=humanoid.SOLE_WIDTH_M)
        self._data: mujoco.MjData | None = None

    def report(self) -> BalanceReport:
        w = self.world
        data = self._data = w.engine.get_data(0, self._data)
        mujoco.mj_subtreeVel(w.model, data)
        com = data.subtree_com[self._root].copy()
        vel = data.subtree_linvel[self._root].copy()
        cp = capture_point(com, vel, max(float(com[2]), 0.3))
        pressure = self.cop(data)
        geom = np.asarray(data.contact.geom)[:data.ncon]
        down = []
        for ids in self._foot_geoms:
            down.append(bool(np.isin(geom, ids).any()) if data.ncon else False)
        poses = []
        for site, is_down in zip(self._soles, down, strict=True):
            if is_down:
                m = data.site_xmat[site].reshape(3, 3)
                poses.append([data.site_xpos[site, 0], data.site_xpos[site, 1], math.atan2(m[1, 0], m[0, 0])])
        poly = support_polygon(np.array(poses), self.foot) if poses else None
        zmp = pressure.cop_w[:2].copy()
        cp_margin = float(polygon_signed_distance(cp, poly)) if poly is not None else -math.inf
        zmp_margin = float(polygon_signed_distance(zmp, poly)) if poly is not None and np.isfinite(zmp).all() else math.nan
        return BalanceReport(time_s=w.time_s, com_xyz_m=com, capture_point_xy_m=np.asarray(cp), zmp_xy_m=zmp,
                             feet_in_contact=(down[0], down[1]), support_polygon_xy_m=poly,
                             capture_margin_m=cp_margin, zmp_margin_m=zmp_margin)


@runtime_checkable
class Walker(Protocol):
    """The interface every walker implements (module docstring)."""

    name: str

    def bind(self, world: NavWorld) -> None:
        """Drive ``world``'s humanoid from now on."""

    def reset(self) -> None:
        """Stand the robot in its default pose; forget any plan."""

    def refuse(self, plan: FootstepPlan) -> str | None:
        """Why this walker cannot walk ``plan`` from where it stands (one line), or None."""

    def set_plan(self, plan: FootstepPlan | None, *, final: bool) -> None:
        """Walk ``plan`` from now on (None: stand); ``final``: it ends at the goal (stop there)."""

    def stand(self) -> None:
        """Stop walking and stand still where the robot is (e.g. while localization is lost)."""

    def step(self, dt_s: float, pose_xyyaw: np.ndarray) -> None:
        """Every physics step: ``pose_xyyaw`` is the navigator's estimate of the base pose."""

    def balance(self) -> BalanceReport:
        """Capture point, ZMP and support margins now."""

    @property
    def arrived(self) -> bool:
        """At the end of a final plan, standing."""

    @property
    def remaining_m(self) -> float:
        """Length of the plan's body path still ahead, m."""


@dataclass(kw_only=True)
class PolicyWalkerCfg(Checked):
    tracker: TrackerCfg = field(default_factory=TrackerCfg)
    max_start_offset_m: float = 0.45
    """A plan whose start stance is farther than this from the robot is refused (it was planned
    from somewhere else), m."""
    max_step_m: float = 0.45
    """A plan with a body path jump longer than this between consecutive footstep pairs is refused:
    the policy walks about 0.3 m a step at 0.55 m/s, and a longer jump is a plan for another walker, m."""
    hold: StandHoldCfg | None = field(default_factory=StandHoldCfg)
    """Standing, hold the pose where standing began (``stand_hold``); None: command zero (the policy
    then creeps ~4 cm/s)."""
    caution: CautionCfg | None = field(default_factory=CautionCfg)
    """Slow in the camera's blind zone at the start, step back from what the feet feel (``caution``);
    None: neither."""


class PolicyWalker:
    """The shipped walking policy following the plan's body path (module docstring)."""

    name = "policy"

    def __init__(self, cfg: PolicyWalkerCfg | None = None):
        self.cfg = cfg or PolicyWalkerCfg()
        self.policy = WalkingPolicy()
        self.tracker = PathTracker(self.cfg.tracker)
        self.hold = PositionHold(self.cfg.hold) if self.cfg.hold is not None else None
        self.world: NavWorld | None = None
        self.command = (0.0, 0.0, 0.0)
        """The last velocity command (vx m/s, vy m/s, yaw rate rad/s)."""

    def bind(self, world: NavWorld) -> None:
        self.world = world
        self.policy.bind(world.robot)
        self.monitor = BalanceMonitor(world)
        self._decimation = round(self.policy.contract["control_dt_s"] / world.dt_s)
        self._control_dt_s = self._decimation * world.dt_s
        self._pose = np.array(world.start_pose, float)
        self.touch = FootTouch(world, self.cfg.caution) if self.cfg.caution is not None else None

    def reset(self) -> None:
        self.policy.reset()
        self.tracker.set_path(None, final=False)
        self._standing = True
        self._scan_rate = 0.0
        self._count = 0
        self.command = (0.0, 0.0, 0.0)
        if self.hold is not None:
            self.hold.release()
        self.felt_xy_m = np.zeros((0, 2))
        """(K, 2) obstacles the feet felt, in the pose estimate's frame (x m, y m): cells the navigator's
        map should mark occupied (the camera may never have seen them)."""
        self.blind_zones_xy_m = np.zeros((0, 2))
        """(K, 2) centres of the blind zones (``add_blind_zone``; the start's is added at the first
        control period), pose estimate frame, m."""
        self._started = False
        self._blind_radius_m = 0.0
        self._back_off_until_s = -math.inf
        self._back_off_dir_b = np.array([-1.0, 0.0])

    def refuse(self, plan: FootstepPlan) -> str | None:
        reason = plan_refusal(plan, self._pose[:2], self.cfg.max_start_offset_m, self.cfg.max_step_m)
        if reason is not None:
            return reason
        path = body_path(plan)
        near = self._felt_distance_m(path)
        if self.cfg.caution is not None and near < self.cfg.caution.felt_clearance_m:
            return f"the plan's body passes {near:.2f} m from an obstacle the feet felt"
        return None

    def _felt_distance_m(self, path_xy: np.ndarray) -> float:
        """Distance of the polyline ``path_xy`` (K, 2) to the nearest felt obstacle, m (inf: none felt)."""
        if not len(self.felt_xy_m) or not len(path_xy):
            return math.inf
        if len(path_xy) == 1:
            return float(np.linalg.norm(self.felt_xy_m - path_xy[0], axis=1).min())
        a, ab = path_xy[:-1], np.diff(path_xy, axis=0)
        rel = self.felt_xy_m[:, None, :] - a[None]
        t = np.clip(np.einsum("fkj,kj->fk", rel, ab) / np.maximum(np.einsum("kj,kj->k", ab, ab), 1e-12), 0.0, 1.0)
        return float(np.linalg.norm(rel - t[..., None] * ab[None], axis=2).min())

    def set_plan(self, plan: FootstepPlan | None, *, final: bool) -> None:
        if plan is None:
            self.tracker.set_path(None, final=False)
            self._standing = True
            return
        end = plan.footsteps_xyyaw_w[-2:, 2]
        end_yaw = math.atan2(np.sin(end).sum(), np.cos(end).sum())
        self.tracker.set_path(body_path(plan), final=final, end_yaw_rad=None if final else end_yaw)
        self._standing = False
        self._scan_rate = 0.0

    def stand(self) -> None:
        self._standing = True
        self._scan_rate = 0.0
        self.command = (0.0, 0.0, 0.0)

    def stand_at(self, xy_m) -> None:
        """Stand, the position hold moving the pelvis to ``xy_m`` (x m, y m, the pose estimate's frame;
        a few cm: ``StandHoldCfg.max_speed_m_s``) at the heading it has now: room for the arms before a
        turn on the spot (``NavigatorCfg.arm_reach_m``). Without a hold it just stands."""
        self.stand()
        if self.hold is not None:
            self.hold.release()
            self.hold.hold_xyyaw = np.array([float(xy_m[0]), float(xy_m[1]), float(self._pose[2])])

    def scan(self, yaw_rate_rad_s: float) -> None:
        """Stand and turn on the spot at ``yaw_rate_rad_s`` (its heading open loop; the position
        held on the estimate, ``PositionHold.turn_command``): a lost camera sweeps for texture to
        relocalise against, a look turn faces the route."""
        self._standing = True
        self._scan_rate = float(yaw_rate_rad_s)

    def resume(self) -> None:
        """Walk the current plan again after ``stand``."""
        self._standing = self.tracker.path is None

    def step(self, dt_s: float, pose_xyyaw: np.ndarray) -> None:
        self._pose = pose_xyyaw
        if self._count % self._decimation == 0:
            self.command = self._command(pose_xyyaw)
        self.policy.forward(dt_s, self.command)
        self._count += 1

    def _command(self, pose_xyyaw: np.ndarray) -> tuple[float, float, float]:
        """This control period's command: the step back after a touch, the scan's turn, the
        tracker's (slowed in the blind zone), or (standing, the tracker says stop, or its path runs
        into a felt obstacle) the position hold's."""
        if self.cfg.caution is not None:
            backing = self._feel(pose_xyyaw)
            if backing is not None:
                return backing
        if self._standing and self._scan_rate:
            cmd = (0.0, 0.0, self._scan_rate)
        else:
            cmd = (0.0, 0.0, 0.0) if self._standing else self._cautious(self.tracker.command(pose_xyyaw), pose_xyyaw)
            if self.hold is not None and cmd == (0.0, 0.0, 0.0):
                return self.hold.command(pose_xyyaw, self._control_dt_s)
        if self.hold is not None:
            if cmd[0] == 0.0 and cmd[1] == 0.0:
                # a turn on the spot (a scan, a look turn, the tracker's turn at a bend) holds the
                # position where it began: open loop the policy wanders 0.14-0.23 m while it turns
                return self.hold.turn_command(pose_xyyaw, self._control_dt_s, cmd[2])
            self.hold.release()
        return cmd

    def _feel(self, pose_xyyaw: np.ndarray) -> tuple[float, float, float] | None:
        """Read the feet (``caution.FootTouch``); the step-back command while it lasts, else None."""
        c = self.cfg.caution
        now = self.world.time_s
        if not self._started:
            self._started = True
            self._blind_radius_m = floor_blind_distance_m(self.world) + c.blind_margin_m
            self.add_blind_zone(pose_xyyaw[:2])
        felt_w = self.touch.felt_xy_m()
        if len(felt_w):
            # the contact relative to the body (what the leg's kinematics give), placed at the estimate
            true = self.world.true_pose()
            cos, sin = math.cos(true[2]), math.sin(true[2])
            rel_w = felt_w - true[:2]
            rel_b = np.stack([cos * rel_w[:, 0] + sin * rel_w[:, 1], -sin * rel_w[:, 0] + cos * rel_w[:, 1]], 1)
            ce, se = math.cos(pose_xyyaw[2]), math.sin(pose_xyyaw[2])
            est = pose_xyyaw[:2] + np.stack([ce * rel_b[:, 0] - se * rel_b[:, 1], se * rel_b[:, 0] + ce * rel_b[:, 1]], 1)
            for xy in est:  # one point per obstacle cell's worth of sole: the navigator marks each
                if not len(self.felt_xy_m) or np.linalg.norm(self.felt_xy_m - xy, axis=1).min() > c.felt_spacing_m:
                    self.felt_xy_m = np.concatenate([self.felt_xy_m, xy[None]])
            if now >= self._back_off_until_s:  # a new touch: back away from where it was felt
                away = -rel_b.mean(0)
                norm = float(np.linalg.norm(away))
                self._back_off_dir_b = away / norm if norm > 1e-6 else np.array([-1.0, 0.0])
            self._back_off_until_s = now + c.back_off_s
        if now < self._back_off_until_s:
            if self.hold is not None:
                self.hold.release()
            v = c.back_off_speed_m_s * self._back_off_dir_b
            return float(v[0]), float(v[1]), 0.0
        return None

    def add_blind_zone(self, xy_m) -> None:
        """Walk slowly within the camera's blind distance of ``xy_m`` (x m, y m, the pose estimate's
        frame): where the navigator lets the robot walk on floor the camera has not seen (the start
        is one already)."""
        self.blind_zones_xy_m = np.concatenate([self.blind_zones_xy_m, np.asarray(xy_m, float).reshape(1, 2)])

    def _cautious(self, cmd: tuple[float, float, float], pose_xyyaw: np.ndarray) -> tuple[float, float, float]:
        """The tracker's command, capped in the blind zone; zero when the path ahead runs into a felt
        obstacle (the robot waits for a plan around it)."""
        c = self.cfg.caution
        if c is None or cmd == (0.0, 0.0, 0.0):
            return cmd
        if len(self.felt_xy_m) and self.tracker.path is not None:
            if self._felt_distance_m(self.tracker.path_ahead()) < c.felt_clearance_m:
                return 0.0, 0.0, 0.0
        vx, vy, yaw_rate = cmd
        if len(self.blind_zones_xy_m) and (np.linalg.norm(self.blind_zones_xy_m - pose_xyyaw[:2], axis=1)
                                           < self._blind_radius_m).any():
            vx = min(vx, c.blind_speed_m_s)
        return vx, vy, yaw_rate

    def balance(self) -> BalanceReport:
        return self.monitor.report()

    @property
    def arrived(self) -> bool:
        return self.tracker.arrived

    @property
    def remaining_m(self) -> float:
        return self.tracker.remaining_m if self.tracker.path is not None else 0.0


__all__ = ["BalanceMonitor", "BalanceReport", "PolicyWalker", "PolicyWalkerCfg", "Walker", "body_path", "plan_refusal"]
