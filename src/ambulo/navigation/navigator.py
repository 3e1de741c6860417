"""``Navigator``: the closed loop in a ``NavWorld``.

    world = NavWorld.from_apartment(3, start_pose=(x, y, yaw))
    nav = Navigator(world, NavigatorCfg(mode="full"))
    nav.set_goal((4.0, 2.5))
    nav.run()                       # until arrived, fallen, lost, stuck or out of time
    nav.status, nav.walked_path_xy_m, nav.replans

Every physics step (5 ms) the walker steps on the pose estimate. Every ``1 / camera_hz`` s a frame
is taken (rendered only when the localizer, the mapper or an observer needs images): the
localizer updates, and a tracked pose (a VO fix) is fused into the map. In full mode the leg
odometry bridges a VO loss (``localization.LegVoLocalizer``): the robot walks on the bridged
estimate up to ``bridge_max_m`` / ``bridge_max_s`` since the last fix, and never fuses depth at it.
Untracked (no fix and no bridge within those limits), the robot stands (then scans) and waits for
relocalisation (``lost_timeout_s``): nothing is fused or steered on. Every
control period (20 ms) the map is refreshed (at its own rate), the episode's end is checked, and
the plan is renewed when:

- there is none, or ``replan_period_s`` passed since the last;
- the robot is more than ``drift_replan_m`` from the plan's body path;
- a partial plan's end (the subgoal) is near (``subgoal_renew_m`` of path left);
- the map changed and the remaining body path now runs through cells without clearance.

Modes: ``oracle`` (true pose, true map), ``mapping`` (true pose, online map), ``full`` (VO pose,
online map). Observers (``add_observer``) get a ``NavSnapshot`` per frame.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..maps import Grid2D
from ..nav import FootstepPlan, PlanStatus
from ..perception.costmap import Costmap
from ..perception.frames import RgbdFrame
from ..scenes.apartment_paths import path_length_m
from ..utils.checks import InvalidValueError, check_vector
from ..utils.validate import Checked
from .floor_level import FloorLevelCfg, level_on_floor
from .localization import (
    LegVoLocalizer,
    LegVoLocalizerCfg,
    OracleLocalizer,
    PoseEstimate,
    VoLocalizer,
    VoLocalizerCfg,
)
from .mapping import OnlineMapper, OnlineMapperCfg, OracleMapper
from .planning import (
    FootstepStage,
    PlanningCfg,
    ReplanRecord,
    Route,
    RoutePlanner,
    choose_subgoal,
    footstep_clearance,
    roomy_goal,
    route_heading,
)
from .walkers import BalanceReport, PolicyWalker, Walker, body_path
from .world import NavWorld

MODES = ("oracle", "mapping", "full")
DISPUTED_STATES = ("rejected", "unverified")
"""Estimate states after a camera fix that disagreed with it (``LegVoLocalizer``): no arrival on them
without the map's confirmation."""


@dataclass(kw_only=True)
class NavigatorCfg(Checked):
    mode: Literal["oracle", "mapping", "full"] = "oracle"
    camera_hz: float = 10.0
    """Frames per second of simulated time (VO, mapping, observers)."""
    replan_period_s: float = 1.0
    drift_replan_m: float = 0.25
    subgoal_renew_m: float = 0.8
    """A partial plan is renewed when this much of its body path is left, m."""
    blocked_clearance_m: float = 0.18
    """After a map change, a remaining body path point with less clearance than this forces a replan, m."""
    look_radius_m: float = 0.45
    """A subgoal nearer than this (no observed free space along the route) becomes a turn on the
    spot towards the route, so the camera sees where the robot is to go, m."""
    look_ahead_m: float = 0.6
    """A look turn faces the route point this far along it; a robot already facing it walks there, m."""
    look_again_m: float = 0.3
    """A robot that turned to look (or already faced the route) within this of where it stands, and
    is not turning now, walks on down the route instead of turning to look again, m. Looking again
    from the same spot shows the same floor: the camera sees it from ~1.6 m ahead, and the route
    through unseen (optimistic) cells swings as each turn shows walls, so look turns and plans
    that turned the robot away again alternated for the whole 20 s stuck window (full mode,
    apartment 71: look, walk, look, ... 1.2 m walked; 19: 16 s turning between -1.9 and -2.8 rad
    0.87 m from the goal)."""
    look_max_s: float | None = 8.0
    """A look turn still turning this long after it began (renewed by the period and map triggers,
    each with the heading of the route as the map then has it) counts as done: the robot walks on
    as it does after a look from where it stands (``look_again_m``); None: never, s. On the device,
    full mode apartment 93 turned to look from its start for the whole 20 s stuck window (21 look
    replans, never facing within ``look_done_rad`` / 2: the heading moved with each map); on the
    100 device apartments (full and randomized) no other look turns for more than 7.7 s."""
    look_done_rad: float = 0.2
    """A look turn is renewed early (the "subgoal" trigger) only once the robot faces within this of
    its heading; the period and map triggers still renew it, rad."""
    look_turn_gain_per_s: float = 1.6
    """A walker that can turn on the spot by a yaw rate (``scan``: the policy walker) makes a look turn
    by its heading alone: yaw rate = this gain * heading error, rad/s per rad..."""
    look_turn_rate_rad_s: tuple[float, float] = (0.3, 0.9)
    """... its magnitude clipped to this range (the policy turns on the spot at 0.3-0.9 rad/s), rad/s;
    it turns until it faces within half ``look_done_rad`` (inside the footstep planner's 0.2 rad yaw
    tolerance, so the renewed plan finds it facing the route and walks on)."""
    narrow_clearance_m: float | None = 0.2
    """When no route keeps ``planning.route_clearance_m`` (0.25 m), route and footsteps keep this
    much instead, m; None: never. The online map's walls come out up to a cell thicker than they
    are (a column is occupied when any band voxel over it is), so a corridor the ground truth
    leaves 0.6 m wide can read 0.5 m: full mode apartment 43 stood 15 s with 81 "no_route"
    replans before a corridor its goal lay in (routes found at 0.20 m, none at 0.22 m)."""
    roomy_clearance_m: tuple[float, ...] = (0.35, 0.3)
    """Footsteps keep the first of these clearances the map allows (at the start, the subgoal and on
    the way between), else ``planning.route_clearance_m`` (0.25 m); (): never. The arms reach
    0.30-0.33 m from the pelvis in a turn (``benchmarks/turn_on_the_spot.py``), and a walk that
    cuts a corner keeps only the 0.25 m limit: in full mode the body passed door jambs 0.20-0.21 m
    away by the ground truth (0.25 m by the map; apartments 49, 55) and an armchair 0.11-0.16 m away
    whose near face the map placed 0.15 m short (89), a forearm on each; 16 of the 27 contacts of
    the 100-apartment run were forearms on walls and table tops. 0.35 m there was not possible
    (the subgoal or the door lacked it); 0.3 m is what ``choose_subgoal`` gives a subgoal (a cell
    more than the route's clearance) and what a 0.8 m door leaves when the map thickens its jambs
    by a cell, m."""
    roomy_start_shift_m: float | None = 0.1
    """A robot that lacks a roomy clearance where it stands plans that clearance's footsteps from the
    nearest cell centre within this that has it (the policy walker walks to a plan's start, up to
    ``PolicyWalkerCfg.max_start_offset_m``), instead of the 0.25 m plan from where it stands; None:
    never (a walker that steps from its feet never does). Not for a look turn's walk-on (a short step
    into the blind zone, where arm room moves the robot already): with it there, VM apartment 8
    shuffled between walk-ons and arm-room moves until the stuck window ended. A robot 0.21-0.25 m
    from a wall otherwise planned the 0.25 m way along it: full mode apartments 77 and 80 (device)
    walked on with the usual plan (0.25 m of room at those replans on the VM) and a forearm met the
    wall ~0.5 s later (benchmarks/results/vm-2026-11-29-s9-nav.md), m."""
    roomy_subgoal_shift_m: float | None = 0.1
    """A subgoal (not the goal: its stance is ``roomy_goal``'s; not a walk-on's) that lacks a roomy
    clearance moves to the nearest cell centre within this that has it, for that clearance's plan;
    None: never, m."""
    roomy_detour_ratio: float | None = 1.5
    """A roomy plan whose body path is longer than this times the straight distance from its start to
    its end, plus ``roomy_detour_m``, is not taken (the usual plan is planned instead); None: any
    length. A roomy plan is the usual way with more room, not another way: where the route passes a
    pinch narrower than the roomy clearance (0.28 m by a table's corner, oracle mode apartment 70),
    the 0.3 m search found a way round the furniture instead, 3.9-4.6 m of body path for a walk-on
    0.6 m long; the robot turned away down it, the next replan (the usual plan, through the pinch)
    turned it back, and it shuffled 1.1 m from its goal until the stuck window ended (oracle and
    full mode alike; VM full mode apartment 8: walk-ons of 1.8 m and 12.3 m for 0.6 m)..."""
    roomy_detour_m: float = 0.3
    """... m (a roomy plan round a bend of the route walks its corner)."""
    roomy_max_expansions: int = 60
    """Lattice expansions of each roomy plan before the next (then the usual one) is planned
    instead: most roomy plans are the straight walk along the body path (no expansion), and one
    that needs a search is in a tight spot a roomy plan is not for; so a replan costs at most
    about this much more per roomy clearance (~45 ms each on a busy 2-core VM)."""
    arm_reach_m: float | None = 0.35
    """Before a turn on the spot (a look turn; a plan the tracker starts by turning on the spot), a
    cornered walk-on (which turns at once) or a goal's first motion (apartment 50 touched a shelf 0.56 s
    in, in full and oracle mode), the robot first moves its
    pelvis, standing, to where the map's occupied cells are this far from its cell (edge to edge;
    ``planning.footstep_clearance``), or as far as it can within ``arm_shift_m`` over free cells;
    None: never. The forearms reach 0.30-0.33 m from the pelvis in a turn (0.27 m to the side when
    walking, at 0.2 and 0.55 m/s alike: slowing down would not narrow them), and the footstep planner
    tests the turned soles and the body's 0.25 m only: full mode apartment 8 turned at its start towards
    a wall it then saw, cornered, and walked on from where it stood (a forearm on the wall at 3.8 s;
    none with this); on the VM, 38 and 39 (five forearm contacts with walls, by look turns and walk-ons)
    had none with this. Not caught: a turn by an obstacle the map reads free (apartment 3 turned at 9.5 s
    and in look turns 0.26-0.28 m from a door jamb's end the camera never saw, which the body's disc,
    ``OnlineMapperCfg.body_free_radius_m``, had freed: three forearm contacts), m."""
    arm_shift_m: float = 0.15
    """The farthest the pelvis moves for ``arm_reach_m``, m (a step of the hold, not a walk)."""
    arm_back_off_s: float = 2.0
    """A move for ``arm_reach_m`` ends when the estimate is within ``arm_done_m`` of its target or after
    this long, s (then the robot replans from where it stands)..."""
    arm_done_m: float = 0.03
    """... m."""
    pose_conflict_m: float | None = 0.1
    """A leg-odometry bridge that puts the pelvis this near to a cell the map holds occupied is
    wrong (the body cannot stand inside furniture): the bridge ends there and the robot stands and
    scans until a camera fix (which the map confirms when it disagrees with the legs) relocalises
    it, instead of walking its plan on a pose it is not at (full mode apartment 74: 1.08 m of
    bridged error, every replan "start_in_collision", the old plan walked on: 10 contacts of the
    thighs with a bed); None: never, m."""
    start_snap_m: float = 0.35
    """A start stance that touches an obstacle moves to the nearest clear cell within this, m."""
    step_out_clearance_m: float = 0.2
    """A walker that steps on the footholds (``start_feet``: the ZMP walker) whose feet lack the
    planner's body clearance steps out to that clear cell on a plan with this much, m: it cannot
    walk to a plan's start as the policy does, and the benchmark's starts (0.265 m from obstacles,
    cell centre to cell) are as near as 0.23 m to them edge to edge: 7 of its 9 stuck oracle
    episodes (ZMP walker) were 77 refused plans from the start feet, "start_in_collision"."""
    goal_backoff_m: float = 0.15
    """A goal whose stance touches an obstacle is approached up to this short along the route, m."""
    goal_room_m: float = 0.35
    """The robot stands where it has this much clearance near the goal, when there is such a place
    within ``goal_shift_m`` (``planning.roomy_goal``: its arms reach 0.30-0.33 m), m..."""
    goal_shift_m: float = 0.1
    """... this far from the goal at most (the tracker stops within 0.12 m of it: 0.22 m inside the
    0.3 m success radius), m."""
    min_replan_gap_s: float = 0.25
    """Triggers other than a new goal or relocalisation wait this long after the last replan, s."""
    goal_tolerance_m: float = 0.3
    """Success radius, m (the benchmarks' 0.3 m)."""
    arrive_radius_m: float = 0.12
    """The estimated position this close to the goal stops the robot whatever its plan, m."""
    settle_s: float = 0.6
    """Standing still this long at the goal ends the episode, s."""
    standing_speed_m_s: float = 0.15
    """Below this pelvis speed the robot counts as standing, m/s."""
    lost_timeout_s: float = 15.0
    """Untracked this long ends the episode ("lost"), s."""
    scan_when_lost_after_s: float | None = 1.0
    """Untracked this long, turn on the spot open loop (``scan_rate_rad_s``; no pose is used, nothing
    is fused) so the camera sweeps for texture to relocalise against, s; None: stand and wait. A
    robot that stands facing a bare wall never sees anything else: on apartments 0-4 (full mode)
    standing and waiting arrived 0 of 5, scanning 2 of 5. A walker without ``scan`` just stands."""
    scan_rate_rad_s: float = 0.4
    stuck_window_s: float = 20.0
    stuck_progress_m: float = 0.5
    """Moving less than this in ``stuck_window_s`` ends the episode ("stuck"), m."""
    time_limit_s: float = 120.0
    planning: PlanningCfg = field(default_factory=PlanningCfg)
    mapper: OnlineMapperCfg = field(default_factory=OnlineMapperCfg)
    vo: VoLocalizerCfg = field(default_factory=VoLocalizerCfg)
    leg_odometry: bool = True
    """Full mode fuses leg-inertial odometry with the VO (``LegVoLocalizer``); False: the VO alone."""
    legs: LegVoLocalizerCfg = field(default_factory=LegVoLocalizerCfg)
    bridge_max_m: float = 3.0
    """The robot walks on the legs' bridge up to this far since the last VO fix, m (the legs drift
    2-3 % of the distance: ~8 cm at 3 m)..."""
    bridge_max_s: float = 10.0
    """... and this long, s (the gyro's yaw drifts between fixes)."""
    level_floor: FloorLevelCfg | None = field(default_factory=FloorLevelCfg)
    """Full mode: a VO fix's camera pose is levelled on the floor its frame sees before its depth is
    fused (``floor_level``: a 0.5 deg pitch error put the far floor into the occupancy band); None:
    fuse the VO's pose as it is."""
    path_log_period_s: float = 0.1
    """The walked paths are logged this often, s."""


@dataclass
class NavSnapshot:
    """What an observer sees at a frame (arrays are the navigator's: copy what you keep)."""

    time_s: float
    true_pose: np.ndarray
    """(3,) x m, y m, yaw rad."""
    estimate: PoseEstimate
    frame: RgbdFrame | None
    """The camera frame (None when nothing needed images)."""
    goal_xy_m: np.ndarray | None
    route_xy_m: np.ndarray | None
    footsteps: FootstepPlan | None
    occupancy: Grid2D
    walked_xy_m: np.ndarray
    """(K, 2) true positions so far."""
    command: tuple[float, float, float] | None
    status: str


class Navigator:
    """The navigator (module docstring). ``walker``, ``localizer`` and ``mapper`` default to the
    mode's; pass your own to swap a part (a walker must follow ``walkers.Walker``)."""

    def __init__(self, world: NavWorld, cfg: NavigatorCfg | None = None, *, walker: Walker | None = None,
                 localizer=None, mapper=None):
        self.cfg = cfg = cfg or NavigatorCfg()
        if cfg.mode not in MODES:
            raise InvalidValueError("NavigatorCfg.mode", cfg.mode, "unknown mode", f"use one of {MODES}")
        self.world = world
        self.localizer = localizer or self._default_localizer()
        self.mapper = mapper or (OracleMapper() if cfg.mode == "oracle" else OnlineMapper(cfg.mapper))
        self.walker = walker or PolicyWalker()
        self.routes = RoutePlanner(cfg.planning)
        self.footsteps_stage = FootstepStage(cfg.planning)
        self._narrow_routes = self._narrow_stage = None  # NavigatorCfg.narrow_clearance_m
        if cfg.narrow_clearance_m is not None:
            narrow = dataclasses.replace(cfg.planning, route_clearance_m=cfg.narrow_clearance_m)
            self._narrow_routes = RoutePlanner(narrow)
            self._narrow_stage = FootstepStage(narrow, body_clearance_m=cfg.narrow_clearance_m)
        self._step_out_stage = FootstepStage(cfg.planning, body_clearance_m=cfg.step_out_clearance_m)
        roomy = dataclasses.replace(cfg.planning, footstep_max_expansions=cfg.roomy_max_expansions)
        self._roomy_stages = [FootstepStage(roomy, body_clearance_m=r) for r in cfg.roomy_clearance_m]
        self._observers: list[tuple[Callable[[NavSnapshot], None], bool]] = []
        self.walker.bind(world)
        if hasattr(self.localizer, "bind_map") and self.mapper.needs_images:
            # the map built so far is what a lost or slipped VO is relocalised against (relocalize)
            self.localizer.bind_map(lambda: self.mapper.grid)
        self.reset()

    def _default_localizer(self):
        c = self.cfg
        if c.mode != "full":
            return OracleLocalizer()
        if c.leg_odometry:
            return LegVoLocalizer(c.legs, c.vo, bridge_max_m=c.bridge_max_m, bridge_max_s=c.bridge_max_s)
        return VoLocalizer(c.vo)

    # -- public API ---------------------------------------------------------------------------
    def reset(self) -> None:
        """Stand the robot in the walker's default pose where it is now (it is not moved back to the
        start); forget goal, map and plans. The estimate restarts at the true pose."""
        w = self.world
        self.walker.reset()
        w.engine.forward()
        w.reset_monitors()
        self.localizer.reset(w)
        self.mapper.reset(w)
        self._felt_marked = 0
        """How many of the walker's felt points (``felt_xy_m``) the map has been given."""
        self.goal_xy_m: np.ndarray | None = None
        self.goal_yaw_rad: float | None = None
        self.estimate = PoseEstimate(w.true_pose(), True, w.time_s, source="oracle" if self.cfg.mode != "full" else "vo")
        self._localizer_step = getattr(self.localizer, "on_step", None)
        self.route: Route | None = None
        self.plan: FootstepPlan | None = None
        self.plan_final = False
        self._stepping_out = False
        """The last footstep plan steps a footholds walker out to room (``step_out_clearance_m``)."""
        self._look_yaw_rad: float | None = None
        """The heading the current plan turns the robot to on the spot (a look turn), else None."""
        self._look_by_heading = False
        """The look turn is steered by the heading (``_steer_look``), the walker standing and turning."""
        self._looked_xy_m: np.ndarray | None = None
        """Where the robot last turned to look or faced the route already (``look_again_m``), estimate frame."""
        self._look_since_s = -math.inf
        """When the look turn under way began (``look_max_s``), s."""
        self.replans: list[ReplanRecord] = []
        self.status = "idle"
        """idle | walking | lost (waiting) | arrived | fell | lost_timeout | stuck | timeout | no_route"""
        self.done = False
        self._steps = 0
        self._frame_every = max(1, round(1.0 / (self.cfg.camera_hz * w.dt_s)))
        self._decimation = max(1, round(0.02 / w.dt_s))
        self._path_every = max(1, round(self.cfg.path_log_period_s / w.dt_s))
        self._last_plan_s = -math.inf
        self._replan_reason: str | None = None
        self._lost_since: float | None = None
        self._arm_back_off: tuple[np.ndarray, float] | None = None
        """(target xy m, start time s) of the move to arm room under way (``arm_reach_m``), or None."""
        self._arm_backed_from_xy: np.ndarray | None = None
        """Where the last move to arm room started: not again from within ``arm_done_m`` of it."""
        self._roomy: FootstepPlan | None = None
        """This replan's plan that keeps ``roomy_clearance_m``, if any (its reason says so)."""
        self._bridge_refuted = False
        """The map refuted the legs' bridge (``_pose_conflict``): no bridge until the next fix."""
        self._settled_since: float | None = None
        self._start_time_s = w.time_s
        self.times_s: list[float] = []
        self.walked_path_xy_m: list[np.ndarray] = []
        """True base positions every ``path_log_period_s``."""
        self.estimated_path_xy_m: list[np.ndarray] = []
        self.frame_errors_m: list[float] = []
        """Per tracked frame: |estimated - true| base position, m (the ATE's samples)."""
        self.frames = 0
        self.frames_by_source: dict[str, int] = {}
        """Frames per estimate source: "vo", "oracle", "legs" (bridged), "none" (untracked)."""
        self.bridged_errors_m: list[float] = []
        """Per bridged frame: |estimated - true| base position, m."""
        self.untracked_frames = 0
        self.fused_while_untracked = 0
        """Frames fused into the map while untracked: 0 by construction (checked by the tests)."""
        self.frame_wall_s: list[float] = []
        self.floor_tilts_rad: list[float] = []
        """Per fused estimated frame: the tilt its levelling on the floor corrected, rad (NaN: the
        frame showed too little floor to level it)."""
        self._mark_body()

    def set_goal(self, goal_xy_m, yaw_rad: float | None = None) -> None:
        """Navigate to ``goal_xy_m`` (x m, y m), arriving with ``yaw_rad`` if given."""
        self.goal_xy_m = np.array(check_vector("goal_xy_m", goal_xy_m, 2, "pass (x m, y m)"), float)
        self._stance_xy_m = self.goal_xy_m.copy()
        """Where the robot stands for the goal (``planning.roomy_goal``, renewed with the map at each
        final plan)."""
        self.goal_yaw_rad = None if yaw_rad is None else float(yaw_rad)
        # the last goal's arrival must not end this one at once (a second goal on /goal_pose, an
        # object search's next leg): its plan, with the walker's "arrived" latch, and the settle
        # timer go; the first replan plans for this goal
        self.walker.set_plan(None, final=False)
        self.plan, self.plan_final = None, False
        self._settled_since = None
        self.done = False
        self.status = "walking"
        self._replan_reason = "new goal"
        self._looked_xy_m = None
        self._arm_back_off = None
        self._start_time_s = self.world.time_s
        self._progress_mark = (self.world.time_s, self.world.true_pose()[:2])

    def add_observer(self, fn: Callable[[NavSnapshot], None], *, images: bool = True) -> None:
        """Call ``fn(snapshot)`` at every frame; ``images``: render the camera for it."""
        self._observers.append((fn, images))

    @property
    def occupancy(self) -> Grid2D:
        """The map the navigator plans on (``maps.Grid2D``)."""
        return self.mapper.grid

    def costmap(self) -> Costmap:
        """The humanoid costmap of ``occupancy`` (computed on request)."""
        return self.mapper.costmap()

    @property
    def tracked(self) -> bool:
        return self.estimate.tracked

    def true_pose(self) -> np.ndarray:
        return self.world.true_pose()

    def balance(self) -> BalanceReport:
        return self.walker.balance()

    def run(self, until: Callable[[Navigator], bool] | None = None, max_time_s: float | None = None) -> str:
        """Step until the episode ends (or ``until(self)`` holds, or ``max_time_s`` of simulated
        time passed); returns ``status``."""
        t_end = math.inf if max_time_s is None else self.world.time_s + max_time_s
        while not self.done and self.world.time_s < t_end and not (until is not None and until(self)):
            self.step()
        return self.status

    def step(self) -> None:
        """One physics step of the loop (module docstring)."""
        if self._steps % self._frame_every == 0:
            self._on_frame()
        if self._steps % self._decimation == 0 and not self.done:
            self._control_tick()
        if self._steps % self._path_every == 0:
            self.times_s.append(self.world.time_s)
            self.walked_path_xy_m.append(self.world.true_pose()[:2])
            self.estimated_path_xy_m.append(self.estimate.xyyaw[:2].copy())
        self.walker.step(self.world.dt_s, self.estimate.xyyaw)
        self.world.step()
        if self._localizer_step is not None:
            self._localizer_step()
        self._steps += 1

    # -- the loop -----------------------------------------------------------------------------
    def _needs_images(self) -> bool:
        return (self.localizer.needs_images or self.mapper.needs_images
                or any(images for _, images in self._observers))

    def _on_frame(self) -> None:
        t0 = time.perf_counter()
        w = self.world
        frame = w.capture() if self._needs_images() else None
        if self.localizer.needs_images:
            est = self.localizer.on_frame(frame)
        else:
            est = PoseEstimate(self.localizer.pose(), True, w.time_s, None if frame is None else frame.pose_wc.numpy())
        self.frames += 1
        if est.tracked:
            self._bridge_refuted = False  # a fix: the next bridge starts from it
        usable = est.tracked or self._bridges(est)
        source = est.source if usable else "none"
        self.frames_by_source[source] = self.frames_by_source.get(source, 0) + 1
        if usable:
            self.estimate = est
            error_m = float(np.linalg.norm(est.xyyaw[:2] - w.true_pose()[:2]))
            if est.tracked:
                self.frame_errors_m.append(error_m)
            else:
                self.bridged_errors_m.append(error_m)
            # depth is fused at VO fixes (and the oracle's pose) only, never at a bridged pose
            if est.tracked and frame is not None and self.mapper.needs_images and est.pose_wc is not None:
                self.mapper.fuse(frame, self._levelled(frame, est.pose_wc))
            if self._lost_since is not None:
                self._lost_since = None
                if self.status == "lost":
                    self.status = "walking"
                self._replan_reason = "relocalised"
        else:
            self.untracked_frames += 1
            self.estimate = PoseEstimate(self.estimate.xyyaw, False, w.time_s, None, est.state, "none",
                                         est.since_fix_m, est.since_fix_s)
            if self._lost_since is None:
                self._lost_since = w.time_s
            self.walker.stand()
            if not self.done and self.status == "walking":
                self.status = "lost"
        self.frame_wall_s.append(time.perf_counter() - t0)
        if self._observers:
            snap = NavSnapshot(w.time_s, w.true_pose(), self.estimate, frame, self.goal_xy_m,
                               None if self.route is None else self.route.path_xy_m, self.plan, self.occupancy,
                               np.array(self.walked_path_xy_m).reshape(-1, 2), getattr(self.walker, "command", None),
                               self.status)
            for fn, _ in self._observers:
                fn(snap)

    def _levelled(self, frame: RgbdFrame, pose_wc: np.ndarray) -> np.ndarray:
        """The pose to fuse ``frame`` at: an estimated (VO) pose levelled on the floor the frame sees
        (``NavigatorCfg.level_floor``); the oracle's as it is."""
        if self.cfg.level_floor is None or not self.localizer.needs_images:
            return pose_wc
        fit = level_on_floor(frame.depth_m.numpy(), frame.intrinsics.numpy(), pose_wc, self.cfg.level_floor)
        if fit is None:
            self.floor_tilts_rad.append(math.nan)
            return pose_wc
        self.floor_tilts_rad.append(fit.tilt_rad)
        return fit.pose_wc

    def _bridges(self, est: PoseEstimate) -> bool:
        """Whether an untracked estimate is a leg-odometry bridge within the limits (module docstring)."""
        c = self.cfg
        return (est.source == "legs" and not self._bridge_refuted and est.since_fix_m <= c.bridge_max_m
                and est.since_fix_s <= c.bridge_max_s)

    @property
    def localized(self) -> bool:
        """Whether the navigator has a pose to act on: a VO fix (or the oracle) or a bridge within limits."""
        return self.estimate.tracked or self._bridges(self.estimate)

    def _mark_body(self) -> None:
        self.mapper.mark_body(self.estimate.xyyaw[:2])

    def _finish(self, status: str) -> None:
        self.status, self.done = status, True
        self.walker.stand()

    def _blind_zone(self, est) -> None:
        """A plan that counts unseen floor free: the walker goes slowly from here (``caution``),
        so low clutter the camera never saw is felt, not tripped over."""
        add = getattr(self.walker, "add_blind_zone", None)
        if add is not None:
            add(est[:2])

    def _control_tick(self) -> None:
        w, c = self.world, self.cfg
        now = w.time_s
        if not self.localizer.needs_images:  # the oracle pose is there every step
            self.estimate = PoseEstimate(self.localizer.pose(), True, now, source="oracle")
        elif self._localizer_step is not None and self.localized:  # the legs move the estimate every tick
            since_m, since_s = self.localizer.since_fix()
            self.estimate = PoseEstimate(self.localizer.pose(), self.estimate.tracked, now, None, self.estimate.state,
                                         self.estimate.source, since_m, since_s)
            if not self.localized:  # the bridge ran out between frames
                self._end_bridge(now, "bridge ended")
        if self.estimate.tracked and self.estimate.source != "legs":
            self._mark_body()
        felt = getattr(self.walker, "felt_xy_m", ())
        if len(felt) > self._felt_marked:  # the feet touched what the camera never showed: map it
            for xy in felt[self._felt_marked:]:
                self.mapper.mark_obstacle(xy)
            self._felt_marked = len(felt)
            self._replan_reason = "felt obstacle"
        map_changed = self.mapper.refresh(now, self.estimate.xyyaw[:2])
        if w.fell:
            return self._finish("fell")
        if self.goal_xy_m is None:
            return
        if now - self._start_time_s > c.time_limit_s:
            return self._finish("timeout")
        t_mark, xy_mark = self._progress_mark
        if np.linalg.norm(w.true_pose()[:2] - xy_mark) >= c.stuck_progress_m:
            self._progress_mark = (now, w.true_pose()[:2])
        elif now - t_mark > c.stuck_window_s:
            return self._finish("stuck")
        if not self.localized:
            if now - self._lost_since > c.lost_timeout_s:
                return self._finish("lost_timeout")
            if (c.scan_when_lost_after_s is not None and now - self._lost_since > c.scan_when_lost_after_s
                    and hasattr(self.walker, "scan")):
                self.walker.scan(c.scan_rate_rad_s)
            return
        est = self.estimate.xyyaw
        at_goal = float(np.linalg.norm(est[:2] - self._stance_xy_m)) < c.arrive_radius_m
        if at_goal and not self.walker.arrived:
            self.walker.stand()  # close enough whatever the plan says (a goal stance that touched something)
        if (self.walker.arrived and self.plan_final) or at_goal:
            if w.base_speed_m_s() < c.standing_speed_m_s:
                self._settled_since = now if self._settled_since is None else self._settled_since
                if now - self._settled_since >= c.settle_s:
                    verify = getattr(self.localizer, "verify", None)
                    answer = verify() if verify is not None else None
                    if answer is False:
                        # the map puts the robot elsewhere (the estimate has moved there): not there yet
                        self._settled_since = None
                        self._replan_reason = "relocalised"
                        return
                    if answer is None and self.estimate.state in DISPUTED_STATES:
                        # the camera's last fix disagreed with the estimate (the legs' bridge) and the map
                        # cannot tell which is right (a bare or ambiguous view: apartment 80's goal read
                        # "ambiguous" at every check): wait; the localizer settles it (a later fix that
                        # agrees, the map told apart, or the bridge's end and a scan). The benchmark's
                        # apartment 80 (226 refused VO fixes) "arrived" 4.9 m from its goal.
                        self._settled_since = None
                        return
                    return self._finish("arrived")
            else:
                self._settled_since = None
            return
        self._settled_since = None
        if self._arm_back_off is not None:
            target, since = self._arm_back_off
            if np.linalg.norm(est[:2] - target) > c.arm_done_m and now - since < c.arm_back_off_s:
                return  # standing, the hold moves the pelvis there; no replan meanwhile
            self._arm_back_off = None
            self._replan_reason = "arm room"
        if self._look_by_heading:
            self._steer_look(est)
        reason = self._replan_reason or self._replan_trigger(now, est, map_changed)
        if reason is not None:
            if self._pose_conflict(est):
                return self._end_bridge(now, "pose conflict")
            self._replan(now, est, reason)

    def _pose_conflict(self, est: np.ndarray) -> bool:
        """Whether the estimate is a leg-odometry bridge that puts the pelvis within
        ``pose_conflict_m`` of a cell the map holds occupied (``NavigatorCfg.pose_conflict_m``). A
        camera fix's pose is not tested: the cells under the body are marked free at each fix."""
        c = self.cfg
        if c.pose_conflict_m is None or self.estimate.tracked or self.estimate.source != "legs":
            return False
        grid = self.mapper.grid
        iy, ix = grid.cell_of(est[:2])
        ny, nx = grid.shape
        return bool(0 <= iy < ny and 0 <= ix < nx
                    and footstep_clearance(grid, optimistic=True)[iy, ix] < c.pose_conflict_m)

    def _end_bridge(self, now: float, why: str) -> None:
        """Stop walking on the legs' bridge (it ran out, or ``_pose_conflict``): untracked from here,
        the robot stands (then scans) until a fix; a refuted bridge no longer gates the camera's
        fixes either (``LegVoLocalizer.refute_bridge``)."""
        if why != "bridge ended":
            self._bridge_refuted = True
            refute = getattr(self.localizer, "refute_bridge", None)
            if refute is not None:
                refute()
        self._lost_since = now
        e = self.estimate
        self.estimate = PoseEstimate(e.xyyaw, False, now, None, why, "none", e.since_fix_m, e.since_fix_s)
        self.walker.stand()
        if not self.done and self.status == "walking":
            self.status = "lost"

    def _replan_trigger(self, now: float, est: np.ndarray, map_changed: bool) -> str | None:
        c = self.cfg
        if now - self._last_plan_s < c.min_replan_gap_s:
            return None
        if self.plan is None:
            return "no plan"
        if now - self._last_plan_s >= c.replan_period_s:
            return "period"
        if self._drift_m(est) > c.drift_replan_m:
            return "drift"
        if not self.plan_final and self.walker.remaining_m < c.subgoal_renew_m and not self._turning(est):
            return "subgoal"
        if map_changed and self._plan_blocked():
            return "map changed"
        return None

    def _clear_start(self, grid, optimistic: bool, est: np.ndarray):
        """The nearest pose (the robot's heading) within ``start_snap_m`` whose cell has the route's
        clearance and one cell more, or None: where a plan starts when the robot brushed close to
        something (the policy walker walks to a plan's start within its start offset)."""
        clr = footstep_clearance(grid, optimistic)
        need = self.cfg.planning.route_clearance_m + grid.resolution_m
        iy, ix = grid.cell_of(est[:2])
        k = int(math.ceil(self.cfg.start_snap_m / grid.resolution_m))
        ny, nx = grid.shape
        y0, y1, x0, x1 = max(0, iy - k), min(ny, iy + k + 1), max(0, ix - k), min(nx, ix + k + 1)
        if y0 >= y1 or x0 >= x1:
            return None
        yy, xx = np.nonzero(clr[y0:y1, x0:x1] >= need)
        if not len(yy):
            return None
        cx, cy = grid.cell_center_xy_m(yy + y0, xx + x0)
        d = np.hypot(cx - est[0], cy - est[1])
        j = int(np.argmin(d))
        if d[j] > self.cfg.start_snap_m:
            return None
        return (float(cx[j]), float(cy[j]), float(est[2]))

    def _turning(self, est: np.ndarray) -> bool:
        """Whether a look turn is still turning (``look_done_rad`` from its heading): its plan is
        all "subgoal" (no path left), and renewing it every ``min_replan_gap_s`` restarted the
        tracker on the turn's zig-zag body path, which then never reached the end where it turns to
        the heading: 16 s for a 135 deg turn at the start of apartment 3 (mapping mode)."""
        if self._look_yaw_rad is None:
            return False
        err = est[2] - self._look_yaw_rad
        return abs(math.atan2(math.sin(err), math.cos(err))) > self.cfg.look_done_rad

    def _steer_look(self, est: np.ndarray) -> None:
        """One control period of a look turn by the heading: turn on the spot towards the look
        heading; facing it (within half ``look_done_rad``), stand and replan at once (the plan then
        walks on down the route)."""
        c = self.cfg
        err = self._look_yaw_rad - est[2]
        err = math.atan2(math.sin(err), math.cos(err))
        if abs(err) > 0.5 * c.look_done_rad:
            lo, hi = c.look_turn_rate_rad_s
            self.walker.scan(math.copysign(min(max(c.look_turn_gain_per_s * abs(err), lo), hi), err))
            return
        self.walker.stand()
        self._look_by_heading = False
        self._look_yaw_rad = None
        self._replan_reason = "faced"

    def _drift_m(self, est: np.ndarray) -> float:
        """Distance from the estimated position to the plan's body path, m."""
        path = body_path(self.plan)
        if len(path) == 1:
            return float(np.linalg.norm(path[0] - est[:2]))
        a, b = path[:-1], path[1:]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", est[:2] - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
        return float(np.linalg.norm(a + t[:, None] * ab - est[:2], axis=1).min())

    def _plan_blocked(self) -> bool:
        grid = self.mapper.grid
        path = body_path(self.plan)
        iy, ix = grid.cells_of(path)
        ny, nx = grid.shape
        inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
        clr = footstep_clearance(grid, optimistic=True)
        return bool((clr[iy[inside], ix[inside]] < self.cfg.blocked_clearance_m).any())

    def _replan(self, now: float, est: np.ndarray, reason: str) -> None:
        t0 = time.perf_counter()
        first = reason == "new goal"  # the goal's first motion (``arm_reach_m``)
        self._replan_reason = None
        self._last_plan_s = now
        grid, version, optimistic = self.mapper.grid, self.mapper.version, self.mapper.optimistic
        route = self.routes.route(grid, version, est[:2], self.goal_xy_m)
        planning, stage = self.cfg.planning, self.footsteps_stage
        if not route.found and self._narrow_routes is not None:
            narrow = self._narrow_routes.route(grid, version, est[:2], self.goal_xy_m)
            if narrow.found:
                route, reason = narrow, reason + " (narrow)"
                # subgoals inside the passage: choose_subgoal asks a cell more than the route's
                # clearance, which the passage's cells (the route's minimum) lack; route points are
                # cell centres, which the narrow footstep stage tests as they are
                stage = self._narrow_stage
                planning = dataclasses.replace(stage.cfg, route_clearance_m=stage.cfg.route_clearance_m - grid.resolution_m)
        status, steps, final, refused = "no_route", 0, False, None
        if route.found:
            self.route = route
            clearance = footstep_clearance(grid, optimistic)
            k, final = choose_subgoal(route, clearance, grid, planning)
            path = route.path_xy_m
            if final:
                self._stance_xy_m = goal_xy = roomy_goal(grid, clearance, self.goal_xy_m, self.cfg.goal_room_m,
                                                         self.cfg.goal_shift_m)
                yaw = self.goal_yaw_rad if self.goal_yaw_rad is not None else route_heading(path, k)
            else:
                goal_xy, yaw = path[k], route_heading(path, k)
            look = not final and np.linalg.norm(goal_xy - est[:2]) < self.cfg.look_radius_m
            looked = False
            if look:
                # nothing observed along the route ahead: turn on the spot to look down it
                s = np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))
                j = min(len(path) - 1, int(np.searchsorted(s, self.cfg.look_ahead_m)) + 1)
                d = path[j] - est[:2]
                goal_xy, yaw = est[:2].copy(), float(math.atan2(d[1], d[0]))
                reason = reason + " (look)"
                # looked here already: a turn that ended, or one that has turned for ``look_max_s``
                here = (self._looked_xy_m is not None
                        and np.linalg.norm(est[:2] - self._looked_xy_m) < self.cfg.look_again_m)
                long_turn = (self._look_yaw_rad is not None and self.cfg.look_max_s is not None
                             and now - self._look_since_s > self.cfg.look_max_s)
                looked = here and (self._look_yaw_rad is None or long_turn)
                if looked and self._look_yaw_rad is not None:
                    reason = reason + " (long look)"
            plan = self._plan_footsteps(stage, grid, version, optimistic, est, route, k, final, goal_xy, yaw,
                                        roomy=not look)
            if look and plan.status == PlanStatus.GOAL_IN_COLLISION and not optimistic:
                # the body's cells (yaw-free) are clear, the turned soles touch cells never seen
                # beside it: turning on the spot there is what the robot's own cells allow
                # (apartment 200: 82 refused look turns, stuck)
                plan = self._plan_footsteps(stage, grid, version, True, est, route, k, final, goal_xy, yaw, roomy=False)
                reason = reason + " (unseen free)"
                self._blind_zone(est)
            facing = look and plan.status == PlanStatus.SUCCESS and plan.num_steps < 1
            faced = facing or (look and plan.status == PlanStatus.SUCCESS and looked)
            cornered = look and plan.status == PlanStatus.GOAL_IN_COLLISION
            if facing:  # facing the route already: as good as a look turn here
                self._looked_xy_m = est[:2].copy()
            if faced or cornered:
                # already facing down the route: the camera cannot see the floor this near (it sees
                # from ~1.6 m), so turning shows nothing new; walk on along the route instead (a
                # well-localised robot stood here for the whole 20 s stuck window, apartments 200-209)
                # up to the goal itself when it is that near, with the goal's recoveries (a goal
                # stance by a wall: apartment 201 stood 0.28 m from it, refused 72 times).
                # Cornered: the turned stance touches a *seen* obstacle (the robot stands by a wall or
                # furniture), so it cannot turn on the spot here; walking on turns while it walks,
                # away from it (apartments 40, 50 full mode stood through 65-74 refused look turns)
                final = j == len(path) - 1
                if final:
                    self._stance_xy_m = walk_xy = roomy_goal(grid, clearance, self.goal_xy_m, self.cfg.goal_room_m,
                                                             self.cfg.goal_shift_m)
                    walk_yaw = self.goal_yaw_rad if self.goal_yaw_rad is not None else route_heading(path, j)
                else:
                    # facing where it looked: the route's heading at a bend there turned the robot
                    # away from it while it walked (apartment 19), and the next replan looked back
                    walk_xy, walk_yaw = path[j], yaw
                plan = self._plan_footsteps(stage, grid, version, optimistic, est, route, j, final, walk_xy, walk_yaw,
                                            shift=False)
                reason = reason + (" (faced: walk on)" if facing else " (looked: walk on)" if faced
                                   else " (cornered: walk on)")
                if plan.status == PlanStatus.GOAL_IN_COLLISION and not optimistic:
                    # the walk-on stance touches cells the camera never saw: a door jamb's shadow
                    # beside the route just past a door, which the head camera (floor in view from
                    # ~1.6 m) cannot see from here whichever way it turns; the robot turned and
                    # stood until the stuck window ended (apartments 2, 3: 20 s of look turns and
                    # refused walk-ons). So this short step (``look_ahead_m``, inside the blind
                    # zone) counts unseen cells free; seen obstacles still block it, and the cells
                    # the body crosses are marked free (``mark_body``).
                    plan = self._plan_footsteps(stage, grid, version, True, est, route, j, final, walk_xy, walk_yaw,
                                                shift=False)
                    reason = reason + " (unseen free)"
                    self._blind_zone(est)
            if plan is self._roomy:
                reason = reason + " (roomy)"
            self._roomy = None
            status, steps = plan.status.value, plan.num_steps
            usable = plan.status == PlanStatus.SUCCESS or (plan.num_steps >= 2 and plan.status in (
                PlanStatus.BUDGET_EXHAUSTED, PlanStatus.GOAL_UNREACHABLE))
            final = final and plan.status == PlanStatus.SUCCESS and not self._stepping_out
            arm_xy = None
            # a turn on the spot (a look turn, a plan the tracker starts by turning on the spot), a walk-on
            # that turns at once, or the goal's first motion
            if usable and ((look and not faced) or first or self._starts_turning(plan, est)):
                arm_xy = self._arm_room_xy(grid, est)
            if arm_xy is not None:
                # stand and move to arm room first (``arm_reach_m``); the replan after it plans the turn
                reason = reason + " (arm room)"
                self._arm_backed_from_xy = est[:2].copy()
                self._arm_back_off = (arm_xy, now)
                self.plan, self.plan_final = None, False
                self._look_yaw_rad, self._look_by_heading = None, False
                self.walker.set_plan(None, final=False)
                self.walker.stand_at(arm_xy)
            elif usable:
                refused = self.walker.refuse(plan)
                if refused is None:
                    self.plan, self.plan_final = plan, final
                    turn = look and not (faced or cornered)
                    if turn and self._look_yaw_rad is None:
                        self._looked_xy_m = est[:2].copy()  # a new look turn starts here
                        self._look_since_s = now
                    self._look_yaw_rad = yaw if turn else None
                    self._look_by_heading = turn and hasattr(self.walker, "scan")
                    if self._look_by_heading:
                        # the turn goes by the heading alone (``_steer_look``), not along the plan's
                        # body path: that path zig-zags a few cm about the robot, and the tracker's
                        # pure pursuit turned towards its points (the wrong way as often as not); with
                        # pushes and randomized friction the robot turned back and forth for the whole
                        # 20 s stuck window (apartments 9, 60, 67 randomized)
                        self.walker.set_plan(None, final=False)
                        self._steer_look(est)
                    else:
                        self.walker.set_plan(plan, final=final)
        self.replans.append(ReplanRecord(now, time.perf_counter() - t0, reason, route.found, status, steps, final,
                                         refused))

    def _starts_turning(self, plan: FootstepPlan, est: np.ndarray) -> bool:
        """Whether the walker's path tracker turns on the spot before it walks ``plan``'s body path
        (``PathTracker.starts_turning``)."""
        tracker = getattr(self.walker, "tracker", None)
        if tracker is None or plan.num_steps < 1:
            return False
        return tracker.starts_turning(body_path(plan), est)

    def _arm_room_xy(self, grid: Grid2D, est: np.ndarray) -> np.ndarray | None:
        """(2,) where to stand before turning on the spot (``NavigatorCfg.arm_reach_m``): the free cell
        centre within ``arm_shift_m`` with the most clearance from occupied cells (capped at
        ``arm_reach_m``; the nearest among equals), the cell halfway to it free too, no nearer to unseen
        cells than the route's clearance or than the robot's own cell is; None when the
        robot's own cell has that reach, nothing nearby has more, the walker cannot stand at a
        point, or it moved for arm room from here already."""
        c = self.cfg
        if c.arm_reach_m is None or not hasattr(self.walker, "stand_at"):
            return None
        if self._arm_backed_from_xy is not None and np.linalg.norm(est[:2] - self._arm_backed_from_xy) < c.arm_done_m:
            return None
        clr = footstep_clearance(grid, optimistic=True)
        iy, ix = grid.cell_of(est[:2])
        ny, nx = grid.shape
        if not (0 <= iy < ny and 0 <= ix < nx) or clr[iy, ix] >= c.arm_reach_m:
            return None
        yy, xx, cx, cy, d = _cells_near(grid, est, c.arm_shift_m)
        free = grid.free()
        my, mx = grid.cells_of(np.stack([(cx + est[0]) / 2, (cy + est[1]) / 2], -1))
        ok = (d <= c.arm_shift_m) & free[yy, xx] & free[np.clip(my, 0, ny - 1), np.clip(mx, 0, nx - 1)]
        # not nearer to unseen cells than the footsteps' body clearance (or than it stands now): a wall the
        # camera has not seen (beside or behind the robot at its start) may be there
        seen = footstep_clearance(grid, self.mapper.optimistic)
        ok &= seen[yy, xx] >= min(float(seen[iy, ix]), self.cfg.planning.route_clearance_m)
        if not ok.any():
            return None
        room = np.minimum(clr[yy, xx], c.arm_reach_m)[ok]
        best = np.lexsort((d[ok], -room))[0]
        if room[best] <= clr[iy, ix]:
            return None
        return np.array([cx[ok][best], cy[ok][best]])

    def _plan_footsteps(self, stage: FootstepStage, grid, version, optimistic, est, route, k, final, goal_xy,
                        yaw, roomy: bool = True, shift: bool = True) -> FootstepPlan:
        """Footsteps from the robot to route point ``k``: first with ``roomy_clearance_m`` where the
        map allows it (``roomy``, the usual stage; ``_roomy_plan``), else as follows. Two
        recoveries: a goal stance that touches an obstacle at the route's heading is tried at three
        other headings and then moved back along the route (up to ``goal_backoff_m``, inside the
        success radius); a start stance that touches one (the robot brushed close to something)
        starts from the nearest route point ahead whose stance is clear, within the walker's start
        offset. ``stage``: the footstep stage of this replan (the narrow one after a narrow route)."""
        self._stepping_out = False
        feet = self.walker.start_feet() if hasattr(self.walker, "start_feet") else None
        if roomy and stage is self.footsteps_stage:
            plan = self._roomy_plan(grid, version, optimistic, est, goal_xy, yaw, feet, final, shift)
            if plan is not None:
                return plan
        if feet is not None:  # a walker that steps on the footholds: plan from its feet
            plan = stage.plan(grid, version, optimistic, est, (goal_xy[0], goal_xy[1], yaw),
                              start_feet=feet[0], stance_side=feet[1])
            if plan.status == PlanStatus.START_IN_COLLISION:  # step out to room first (step_out_clearance_m)
                start = self._clear_start(grid, optimistic, est)
                if start is not None:
                    out = self._step_out_stage.plan(grid, version, optimistic, est, start, start_feet=feet[0],
                                                    stance_side=feet[1])
                    if out.status == PlanStatus.SUCCESS and out.num_steps >= 1:
                        self._stepping_out = True  # not the goal's plan, whatever the route said
                        return out
            return plan
        plan = stage.plan(grid, version, optimistic, est, (goal_xy[0], goal_xy[1], yaw))
        path = route.path_xy_m
        if plan.status == PlanStatus.START_IN_COLLISION:
            start = self._clear_start(grid, optimistic, est)
            if start is not None:
                retry = stage.plan(grid, version, optimistic, start, (goal_xy[0], goal_xy[1], yaw))
                if retry.status != PlanStatus.START_IN_COLLISION:
                    return retry
        if plan.status == PlanStatus.GOAL_IN_COLLISION and final:
            for turn in (math.pi / 2, -math.pi / 2, math.pi):
                retry = stage.plan(grid, version, optimistic, est, (goal_xy[0], goal_xy[1], yaw + turn))
                if retry.status != PlanStatus.GOAL_IN_COLLISION:
                    return retry
            s_end = np.cumsum(np.linalg.norm(np.diff(path[::-1], axis=0), axis=1))
            for j in range(len(s_end)):
                if s_end[j] > self.cfg.goal_backoff_m:
                    break
                p = path[len(path) - 2 - j]
                retry = stage.plan(grid, version, optimistic, est, (p[0], p[1], route_heading(path, len(path) - 2 - j)))
                if retry.status != PlanStatus.GOAL_IN_COLLISION:
                    return retry
        return plan

    def _roomy_plan(self, grid, version, optimistic, est, goal_xy, yaw, feet, final: bool = True,
                    shift: bool = True) -> FootstepPlan | None:
        """A plan that keeps the first of ``roomy_clearance_m`` it can all the way, or None (the
        robot or the goal lacks each on the map within ``roomy_start_shift_m`` (a subgoal, not
        ``final``: within ``roomy_subgoal_shift_m``): no search then, or each search did not end at
        the goal within ``roomy_max_expansions``)."""
        if not self._roomy_stages:
            return None
        clr = footstep_clearance(grid, optimistic)
        iy, ix = grid.cells_of(np.array([est[:2], goal_xy[:2]], float))
        ny, nx = grid.shape
        if not ((iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)).all():
            return None
        start_room, goal_room = float(clr[iy[0], ix[0]]), float(clr[iy[1], ix[1]])
        start = {} if feet is None else {"start_feet": feet[0], "stance_side": feet[1]}
        for stage in self._roomy_stages:
            need = stage.footstep_cfg.body_clearance_m
            goal = (goal_xy[0], goal_xy[1], yaw)
            if goal_room < need:
                near = None if final or not shift else self._room_near(grid, clr, goal_xy, need,
                                                                         self.cfg.roomy_subgoal_shift_m)
                if near is None:
                    continue
                goal = (near[0], near[1], yaw)
            from_xyyaw = est
            if start_room < need:
                near = None if feet is not None or not shift else self._room_near(grid, clr, est, need,
                                                                                  self.cfg.roomy_start_shift_m)
                from_xyyaw = None if near is None else np.array([near[0], near[1], est[2]])
                if from_xyyaw is None:
                    continue
            plan = stage.plan(grid, version, optimistic, from_xyyaw, goal, **start)
            if plan.status == PlanStatus.SUCCESS and not self._detour(plan):
                self._roomy = plan
                return plan
        return None

    def _detour(self, plan: FootstepPlan) -> bool:
        """Whether ``plan``'s body path is longer than ``roomy_detour_ratio`` times the straight
        distance between its ends plus ``roomy_detour_m`` (a roomy plan that goes another way)."""
        c = self.cfg
        if c.roomy_detour_ratio is None:
            return False
        path = body_path(plan)  # (K, 2) x m, y m
        length_m = path_length_m(path)
        straight_m = float(np.linalg.norm(path[-1] - path[0]))
        return length_m > c.roomy_detour_ratio * straight_m + c.roomy_detour_m

    @staticmethod
    def _room_near(grid: Grid2D, clr: np.ndarray, xy, need_m: float, shift_m: float | None) -> np.ndarray | None:
        """(2,) the nearest cell centre within ``shift_m`` of ``xy`` whose clearance ``clr`` is at least
        ``need_m`` (x m, y m); None: none, or ``shift_m`` None."""
        if shift_m is None:
            return None
        yy, xx, cx, cy, d = _cells_near(grid, xy, shift_m)
        ok = (d <= shift_m) & (clr[yy, xx] >= need_m)
        if not ok.any():
            return None
        j = int(np.argmin(np.where(ok, d, np.inf)))
        return np.array([cx[j], cy[j]])



def _cells_near(grid: Grid2D, xy, radius_m: float):
    """The cells of the square window of ``radius_m`` around ``xy``'s cell, clipped to the grid:
    (yy, xx) flat cell indices, (cx, cy) their centres (m) and d their centres' distances to ``xy`` (m).
    The caller keeps those with d <= its radius."""
    iy, ix = grid.cell_of(xy[:2])
    k = int(math.ceil(radius_m / grid.resolution_m))
    ny, nx = grid.shape
    y0, y1, x0, x1 = max(0, iy - k), min(ny, iy + k + 1), max(0, ix - k), min(nx, ix + k + 1)
    yy, xx = (a.ravel() for a in np.mgrid[y0:y1, x0:x1])
    cx, cy = grid.cell_center_xy_m(yy, xx)
    return yy, xx, cx, cy, np.hypot(cx - xy[0], cy - xy[1])

__all__ = ["MODES", "NavSnapshot", "Navigator", "NavigatorCfg"]
