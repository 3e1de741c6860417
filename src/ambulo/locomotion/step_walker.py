"""The ZMP whole-body walker, online: it steps on a footstep plan inside any simulation that holds
the bundled humanoid, and takes a new plan at any time (replanning).

``WalkSimulation`` walks one complete plan, planned offline from start to end, in the dedicated
arena. ``ZmpStepWalker`` is the same pattern generator and controller run as a receding horizon
inside the caller's simulation (an apartment, a user's world): the caller steps the physics, and
calls ``walker.step(dt_s)`` before each physics step.

How (one *chunk* per step, made when the previous one ends, i.e. at each touchdown):

1. The walker keeps the pattern's state between chunks: the cart-table CoM state and integral of
   Kajita's preview controller (``preview``), the landed feet, and the queue of next footsteps.
2. A chunk is one step: the double support (the reference ZMP moves to the stance sole) and the
   swing of the next footstep, or, with no footstep queued, standing (the ZMP between the feet).
   Its CoM comes from the preview controller looking ``preview_time_s`` ahead over the *queued*
   footsteps (the ZMP reference of the rest of the plan, then standing), so the pattern is
   Kajita's for the whole plan as it is known at that touchdown.
3. The chunk's joint references (whole-body IK and inverse-dynamics feed-forward,
   ``walk_controller.build_reference``) are solved on a private model of the humanoid alone (the
   world's other geoms do not matter to them) and mapped to the simulation's model, where a
   ``WalkController`` (the capture-point stabilizer, re-anchored on the measured stance foot)
   sends them through the robot's ``Entity`` drives. The re-anchoring transform carries over from
   chunk to chunk: the pattern frame is the world frame at ``reset``, corrected by it.
4. ``set_plan`` only stores the plan; it replaces the queue at the next chunk, so a swing in the
   air always lands where it was going. The plan is re-anchored there on the feet as they are:
   where its rows match the landed feet (``splice_tolerance_m``), it continues after the last
   match; otherwise the real feet stay and its steps are taken from its first step on.

Measured (``benchmarks/zmp_step_walker.py``, apartments 3 and 7, 10 random plans of 2-4 m of
geodesic each, every one replanned after 4 steps): 20 of 20 walked to ``done`` without a fall,
the soles' midpoint 1-3 mm from the plan's last stance; 0.12-0.13 m/s straight-line speed (start
1.8 s, stop 1.2 s and the turns included); 0.69-0.77 s of CPU per simulated second, physics
included (half of it the stabilizer's support-polygon clipping, a fifth the chunks' IK).
Replanned at every step from the 2nd on (apartment 5, ``--replan-every 1``): 10 of 10, the last
stance within 3.1 cm of the last plan's.

Units: m, s, rad; poses (x, y, yaw) or (x, y, z, yaw) in the world frame unless said otherwise;
arrays over the two feet are [left, right]; sides are +1 left, -1 right (``nav``'s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np
import torch

from ..core import Entity, RobotCfg, add_robot, new_scene
from ..robots import humanoid
from ..robots.humanoid import FOOT_BODIES, SOLE_SITES
from ..scenes.walk_arena import walk_model
from ..utils.checks import InvalidValueError
from ..utils.math import quat_from_yaw
from ..utils.validate import Checked, rule
from .balance import CenterOfPressure, lipm_omega, polygon_signed_distance, support_polygon
from .preview import PreviewController, WalkPattern, footsteps_array, walk_pattern_cfg
from .walk_controller import (
    HUMANOID_FOOT,
    StabilizerCfg,
    WalkController,
    WalkIK,
    WalkReference,
    build_reference,
    walk_robot,
)

HOME_KEYFRAME = "home"


@dataclass(kw_only=True)
class StepWalkerCfg(Checked):
    """The online walker: pattern timing, limits it refuses beyond, and balance monitoring."""

    com_height_m: float = field(default=0.80, metadata=rule(minimum=0.3))
    """z_c of the cart-table model (the walk controller's tuned 0.80 m)."""
    step_time_s: float = field(default=0.8, metadata=rule(minimum=0.2))
    """One step: double support + swing, s."""
    double_support_ratio: float = 0.2
    swing_height_m: float = 0.05
    preview_time_s: float = field(default=1.6, metadata=rule(minimum=0.2))
    """Preview window, s (Kajita 2003: 1.6 s)."""
    start_transfer_s: float = field(default=1.0, metadata=rule(minimum=0.1))
    """Double support of the first step from standing, s: the CoM starts moving only when a plan
    arrives, so the ZMP moves to the first stance sole slowly instead of in one double support."""
    start_delay_s: float = field(default=0.8, metadata=rule(minimum=0.0))
    """... and only after this long: the preview controller reacts to a change of the reference
    ZMP ahead of it in proportion to its gains there, which decay as exp(-omega t) (0.29 s at
    0.80 m). Starting the transfer at once kicks the CoM with a jerk that makes the feet slide
    (1 cm measured); 0.8 s leaves 6 % of it."""
    stand_chunk_s: float = field(default=0.2, metadata=rule(minimum=0.01))
    """Standing is walked in chunks this long: the most a new plan waits while standing, s."""
    settle_s: float = field(default=1.0, metadata=rule(minimum=0.0))
    """After the last step: standing before ``done``, s (the CoM comes over the feet)."""
    splice_tolerance_m: float = 0.04
    """A plan's foot matches a landed foot within this distance ..."""
    splice_tolerance_yaw_rad: float = 0.15
    """... and this yaw."""
    step_length_range_m: tuple[float, float] = humanoid.WALK_STEP_LENGTH_RANGE_M
    step_width_range_m: tuple[float, float] = humanoid.WALK_STEP_WIDTH_RANGE_M
    max_step_yaw_rad: float = humanoid.WALK_MAX_STEP_YAW_RAD
    max_step_up_m: float = 0.02
    """The pattern keeps the CoM at a constant height: it walks (nearly) flat floors only, m."""
    max_step_down_m: float = 0.02
    limit_slack_m: float = 0.005
    """Steps up to this much beyond a length/width limit are accepted (planner round-off), m."""
    limit_slack_rad: float = 0.01
    falling_margin_m: float = 0.05
    """``falling`` when the capture point is this far outside the support polygon, m."""
    fall_height_m: float = 0.55
    """The pelvis below this height is a fall, m."""
    monitor_every_samples: int = field(default=5, metadata=rule(minimum=1))
    """``step`` checks ``balance().falling`` (for ``fell``) every this many samples."""
    stabilizer: StabilizerCfg = field(default_factory=StabilizerCfg)


def step_walker_cfg(**overrides) -> StepWalkerCfg:
    """The walker's defaults (the walk controller's tuned pattern, ``robots.humanoid`` limits)."""
    return StepWalkerCfg(**overrides)


@dataclass
class WalkerBalance:
    """Balance of the robot now (measured state)."""

    capture_point_xy: np.ndarray
    """(2,) xi = c + c_dot / omega, m."""
    zmp_xy: np.ndarray
    """(2,) measured ZMP (CoP of the feet's contacts), NaN without contact, m."""
    support_polygon_xy: np.ndarray
    """(M, 2) support polygon of the soles the pattern has on the ground (measured poses), m."""
    capture_margin_m: float
    """Signed distance of the capture point to the support polygon (> 0 inside), m."""
    zmp_margin_m: float
    """Signed distance of the ZMP to it, NaN without contact, m."""
    capture_region_margin_m: float
    """Signed distance of the capture point to the region the robot can still stop in: the hull of
    the soles on the ground and, during a swing, the sole where the swing foot lands, m. (In a
    walk the capture point leaves the stance sole towards the next footstep every step.)"""
    falling: bool
    """The capture point is more than ``falling_margin_m`` outside the capture region, or the
    pelvis is below ``fall_height_m``."""


@dataclass
class _Chunk:
    """One step (or a stretch of standing) of the pattern, with its controller."""

    kind: str
    """"step", "stop" (last transfer back between the feet) or "stand"."""
    pattern: WalkPattern
    controller: WalkController
    swing_goal: np.ndarray | None
    """(4,) where the swing foot lands (pattern frame), None without a swing."""
    swing_side: int
    k: int = 0

    @property
    def length(self) -> int:
        return len(self.pattern.time_s)


def _wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _quintic(tau: np.ndarray) -> np.ndarray:
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def _home_keyframe():
    """The humanoid file's ``home`` keyframe (``core.KeyPose``), as ``add_robot`` reads it."""
    cfg = RobotCfg(file=humanoid.ASSET, prim_path=humanoid.PRIM_PATH)
    return add_robot(new_scene("keyframe"), cfg).keyframes[HOME_KEYFRAME]


class ZmpStepWalker:
    """Walks footstep plans online with ZMP preview control and the whole-body controller.

    Use::

        walker = ZmpStepWalker()
        walker.bind(sim, core.Entity(sim.engine, robots.humanoid.PRIM_PATH))
        walker.reset()                      # home pose where the robot is, standing
        walker.set_plan(plan)               # any time; refused plans return the reason
        while ...:
            walker.step(sim.physics.timestep_s)
            sim.step()
    """

    def __init__(self, cfg: StepWalkerCfg | None = None):
        self.cfg = cfg = cfg or StepWalkerCfg()
        self.pattern_cfg = walk_pattern_cfg(com_height_m=cfg.com_height_m, foot=HUMANOID_FOOT,
                                            step_time_s=cfg.step_time_s,
                                            double_support_ratio=cfg.double_support_ratio,
                                            swing_height_m=cfg.swing_height_m, preview_time_s=cfg.preview_time_s)
        self.dt_s = self.pattern_cfg.preview.dt_s
        self.preview = PreviewController(self.pattern_cfg.preview)
        self.omega = lipm_omega(cfg.com_height_m)
        self.engine = None
        self.robot: Entity | None = None
        self.last_refusal: str | None = None
        """Why the last plan given to ``set_plan`` (or its splice onto the feet) was refused."""
        self.steps_taken = 0
        self.plans_taken = 0

    # ------------------------------------------------------------------ binding and reset
    def bind(self, sim_or_engine, robot: Entity) -> ZmpStepWalker:
        """Attach to a started simulation (``core.Simulation`` or its engine) and the humanoid's
        ``Entity`` in it (world 0 is walked)."""
        engine = getattr(sim_or_engine, "engine", None) or sim_or_engine
        if not hasattr(engine, "get_data"):
            raise InvalidValueError("sim_or_engine", type(sim_or_engine).__name__, "expected a started "
                                    "core.Simulation or its engine", "call sim.start() first")
        self.engine, self.robot = engine, robot
        self._chunk = None
        m = self.model = engine.model
        names = walk_robot(m, robot.prim_path if hasattr(robot, "prim_path") else humanoid.PRIM_PATH)
        self.names = names
        self.sites = [names.site_id(s) for s in SOLE_SITES]
        self.pelvis = names.body_id(humanoid.BASE_BODY)
        self.root = names.root_body_id
        # the private model the references are solved on, and the address maps to the sim's model
        self.ref_model = walk_model(timestep_s=self.dt_s)
        ref_names = walk_robot(self.ref_model)
        self._qpos_src = np.concatenate([ref_names.free_qpos_adr + np.arange(7),
                                         self.ref_model.jnt_qposadr[ref_names.joint_ids]])
        self._qpos_dst = np.concatenate([names.free_qpos_adr + np.arange(7), m.jnt_qposadr[names.joint_ids]])
        self._dof_src = np.concatenate([ref_names.free_dof_adr + np.arange(6),
                                        self.ref_model.jnt_dofadr[ref_names.joint_ids]])
        self._dof_dst = np.concatenate([names.free_dof_adr + np.arange(6), m.jnt_dofadr[names.joint_ids]])
        self._ref_joint_qpos = self.ref_model.jnt_qposadr[ref_names.joint_ids]
        self._ref_names = ref_names
        # the ground: every geom that is not the robot's (floors, furniture, a user's world)
        world_geoms = np.flatnonzero(~np.isin(m.geom_bodyid, names.body_ids))
        self.cop = CenterOfPressure(m, [names.body_id(b) for b in FOOT_BODIES], ground_geoms=world_geoms.tolist(),
                                    ground_height_m=0.0)
        self.data = mujoco.MjData(m)
        return self

    def _require_bound(self, reset: bool = True) -> None:
        if self.engine is None:
            raise InvalidValueError("walker", "unbound", "bind it to a simulation first",
                                    "call walker.bind(sim, core.Entity(sim.engine, robots.humanoid.PRIM_PATH))")
        if reset and getattr(self, "_chunk", None) is None:
            raise InvalidValueError("walker", "not reset", "it has no pattern yet", "call walker.reset() after bind")

    def reset(self, floor_z_m: float = 0.0) -> None:
        """Put the robot in the ``home`` keyframe at its current x, y and yaw, soles on the floor
        at ``floor_z_m``, legs set by the IK so that the CoM stands at the pattern's height over
        the middle of the soles, at rest; the walker stands with no plan."""
        self._require_bound(reset=False)
        data = self.engine.get_data(0, self.data)
        pos = data.xpos[self.pelvis].copy()
        mat = data.xmat[self.pelvis]
        yaw = math.atan2(mat[3], mat[0])
        rm = self.ref_model
        key = _home_keyframe()
        q = rm.qpos0.copy()
        rn = self._ref_names
        for j in rn.joint_ids:  # keyframe joints by their names relative to the prim path
            name = rm.joint(j).name.removeprefix(humanoid.PRIM_PATH + "/")
            if name in key.joint_pos:
                q[rm.jnt_qposadr[j]] = key.joint_pos[name]
        base = rn.free_qpos_adr + np.arange(7)
        q[base[0:3]] = [pos[0], pos[1], key.root_pos_m[2]]
        q[base[3:7]] = quat_from_yaw(yaw)
        # feet where the keyframe puts them, on the floor
        d = mujoco.MjData(rm)
        d.qpos[:] = q
        mujoco.mj_kinematics(rm, d)
        ik = WalkIK(rm)
        feet = np.empty((2, 4))
        for i, s in enumerate(ik.sites):
            feet[i] = [d.site_xpos[s][0], d.site_xpos[s][1], floor_z_m, math.atan2(d.site_xmat[s][3], d.site_xmat[s][0])]
        mid = 0.5 * (self._sole_center(feet[0]) + self._sole_center(feet[1]))
        com = np.array([mid[0], mid[1], floor_z_m + self.cfg.com_height_m])
        q, err = ik.solve(q, com, float(feet[:, 3].mean()), feet, iterations=50)
        if err > 1e-4:
            raise RuntimeError(f"the standing pose did not solve (IK error {err:.2g}); the keyframe or "
                               "com_height_m does not fit the humanoid")
        self._write_state(q)
        self._feet = feet
        self._floor_z = floor_z_m
        self._x = np.zeros((3, 2))
        self._x[0] = mid
        self._err_sum = np.zeros(2)
        self._zmp_last = mid.copy()
        self._last_ref_qpos = q.copy()
        self._prev = dict(com=self._x.copy(), feet=feet.copy(), contact=np.ones(2, bool), zmp=mid.copy())
        self._queue: list[tuple[np.ndarray, int]] = []
        self._pending = None
        self._has_pending = False
        self._anchor = np.zeros(3)
        self._standing = True
        self.steps_taken = 0
        self.plans_taken = 0
        self.last_refusal = None
        self._fell = False
        self._last_side = 0
        """The foot that landed last (+1 left, -1 right; 0 none since ``reset``)."""
        self._since_check = 0
        self._chunk = self._make_chunk()

    def _write_state(self, q_ref: np.ndarray) -> None:
        robot, engine = self.robot, self.engine
        rn = self._ref_names
        base = rn.free_qpos_adr + np.arange(7)
        dtype = getattr(engine, "dtype", torch.float64)
        device = getattr(robot, "device", "cpu")
        pos = torch.as_tensor(q_ref[base[0:3]][None], dtype=dtype, device=device)
        quat = torch.as_tensor(q_ref[base[3:7]][None], dtype=dtype, device=device)
        robot.write_root_pose(pos_w=pos, quat_w=quat)
        robot.write_root_velocity(lin_vel_w=torch.zeros((1, 3), dtype=dtype, device=device),
                                  ang_vel_w=torch.zeros((1, 3), dtype=dtype, device=device))
        joints = torch.as_tensor(q_ref[self._ref_joint_qpos][None], dtype=dtype, device=device)
        robot.write_joint_state(pos=joints, vel=torch.zeros_like(joints))
        engine.forward()

    # ------------------------------------------------------------------ plans
    def refuse(self, plan) -> str | None:
        """Why the walker cannot walk ``plan`` (one line), or None: a step beyond the length,
        width, turn or height limits (``StepWalkerCfg``, ``robots.humanoid``'s ``WALK_*``), two
        steps in a row with one foot, or start feet that are not one left and one right."""
        try:
            poses, sides = footsteps_array(plan)
        except ValueError as err:
            return f"not a footstep plan: {err}"
        if len(poses) < 2:
            return f"a plan has the two start feet first; this one has {len(poses)} rows"
        if not np.all(np.isfinite(poses)):
            return "the plan has non-finite poses"
        if sorted(sides[:2].tolist()) != [-1, 1]:
            return "the start feet (rows 0, 1) are not one left and one right foot"
        for i in range(2, len(poses)):
            reason = self._step_problem(poses[i - 1], int(sides[i - 1]), poses[i], int(sides[i]))
            if reason:
                return f"step {i - 1} (row {i}): {reason}"
        return None

    def _step_problem(self, stance: np.ndarray, stance_side: int, swing: np.ndarray, side: int) -> str | None:
        cfg = self.cfg
        if side == stance_side:
            return "two steps in a row with the same foot"
        c, s = math.cos(stance[3]), math.sin(stance[3])
        dx, dy = swing[0] - stance[0], swing[1] - stance[1]
        length, lateral = c * dx + s * dy, -s * dx + c * dy
        width = -stance_side * lateral  # > 0: the swing foot on its own side
        turn = float(_wrap(swing[3] - stance[3]))
        rise = swing[2] - stance[2]
        lo, hi = cfg.step_length_range_m
        if not lo - cfg.limit_slack_m <= length <= hi + cfg.limit_slack_m:
            return f"length {length:.3f} m is outside the walker's [{lo:g}, {hi:g}] m"
        lo, hi = cfg.step_width_range_m
        if not lo - cfg.limit_slack_m <= width <= hi + cfg.limit_slack_m:
            return f"width {width:.3f} m is outside the walker's [{lo:g}, {hi:g}] m"
        if abs(turn) > cfg.max_step_yaw_rad + cfg.limit_slack_rad:
            return f"turn {math.degrees(turn):.1f} deg is beyond the walker's {math.degrees(cfg.max_step_yaw_rad):.1f} deg"
        if rise > cfg.max_step_up_m + 1e-9:
            return f"step up {rise:.3f} m is beyond the walker's {cfg.max_step_up_m:g} m"
        if -rise > cfg.max_step_down_m + 1e-9:
            return f"step down {-rise:.3f} m is beyond the walker's {cfg.max_step_down_m:g} m"
        return None

    def set_plan(self, plan) -> str | None:
        """Walk ``plan`` (a ``nav.FootstepPlan``: rows 0, 1 the start feet, row 1 the first stance;
        or None / a plan without steps: stop). Takes effect at the next touchdown (or within
        ``stand_chunk_s`` when standing); the swing in the air is not changed. Returns None when
        accepted, else the refusal (``refuse``): the plan is not taken and the walker stops after
        the step in progress."""
        self._require_bound()
        reason = None if plan is None else self.refuse(plan)
        self.last_refusal = reason
        self._pending = None if reason else plan
        self._has_pending = True
        return reason

    def _apply_pending(self) -> None:
        plan, self._pending, self._has_pending = self._pending, None, False
        self._queue = []
        if plan is None:
            return
        poses_w, sides = footsteps_array(plan)
        poses = self._to_pattern(poses_w)
        feet = self._feet
        start, spliced = None, False
        for r in range(len(poses) - 1, 0, -1):
            if sides[r] != sides[r - 1] and self._matches(poses[r], int(sides[r])) \
                    and self._matches(poses[r - 1], int(sides[r - 1])):
                start = r + 1
                break
        if start is None:
            # no match: the real feet stay, the plan's steps follow from its first; but a first
            # step of the foot that has just landed was planned from where that foot was before
            # (the plan's start feet are stale): moving it again at once would make the CoM
            # turn back onto the foot it is leaving, so the steps start with the other foot
            start, spliced = 2, True
            while start < len(poses) and not self._standing and sides[start] == self._last_side:
                start += 1
        steps = [(poses[i].copy(), int(sides[i])) for i in range(start, len(poses))]
        # a plan that matches the feet had its steps checked from its own rows (``refuse``); the
        # few mm and mrad the feet differ from them are the walker's to absorb (a recheck against
        # the landed feet refused a 0.3 rad planner step as 18.0 deg > 17.2 deg)
        if steps and spliced:
            pose, side = steps[0]
            stance = feet[(1 + side) // 2]  # the other foot's landed pose
            reason = self._step_problem(stance, -side, pose, side)
            if reason:
                self.last_refusal = f"spliced onto the feet as they are, the first step is refused: {reason}"
                return
        # kept in the world frame: each chunk maps them through the re-anchoring of its time, so
        # footsteps land where the plan says in the world rather than where the drift of the
        # steps before would carry them
        self._queue = [(poses_w[i].copy(), int(sides[i])) for i in range(start, len(poses))]
        self.plans_taken += 1

    def _matches(self, pose: np.ndarray, side: int) -> bool:
        foot = self._feet[(1 - side) // 2]
        return (math.hypot(pose[0] - foot[0], pose[1] - foot[1]) <= self.cfg.splice_tolerance_m
                and abs(float(_wrap(pose[3] - foot[3]))) <= self.cfg.splice_tolerance_yaw_rad)

    def _to_pattern(self, poses_w: np.ndarray) -> np.ndarray:
        """(S, 4) world poses in the pattern frame (the inverse of the re-anchoring transform)."""
        a, t = self._anchor[0], self._anchor[1:]
        out = poses_w.copy()
        out[:, :2] = (poses_w[:, :2] - t) @ _rot(a)  # R(a)^T (p - t), row-wise
        out[:, 3] = poses_w[:, 3] - a
        return out

    # ------------------------------------------------------------------ the pattern, chunk by chunk
    def _sole_center(self, pose: np.ndarray) -> np.ndarray:
        ox, oy = HUMANOID_FOOT.center_offset_m
        c, s = math.cos(pose[3]), math.sin(pose[3])
        return pose[:2] + np.array([c * ox - s * oy, s * ox + c * oy])

    def _make_chunk(self) -> _Chunk:
        cfg, pcfg, dt = self.cfg, self.pattern_cfg, self.dt_s
        if self._has_pending:
            self._apply_pending()
        ss, ds = pcfg.single_support_s, pcfg.double_support_s
        feet = self._feet.copy()
        knots_t, knots_p = [0.0], [self._zmp_last.copy()]
        swing = None
        queue = []
        if self._queue:
            poses = self._to_pattern(np.array([pose for pose, _ in self._queue]))
            queue = [(pose, side) for pose, (_, side) in zip(poses, self._queue)]
        if queue:
            kind = "step"
            goal, side = queue.pop(0)
            self._queue.pop(0)
            idx = (1 - side) // 2
            first_ds = cfg.start_delay_s + cfg.start_transfer_s if self._standing else ds
            goal = goal.copy()
            goal[3] = feet[idx, 3] + float(_wrap(goal[3] - feet[idx, 3]))  # yaw continuous, the short way
            stance = self._sole_center(feet[1 - idx])
            if self._standing:
                # from rest the CoM has seen no preview of this transfer: a minimum-jerk ZMP ramp
                # (zero slope at its start) instead of a linear one, whose slope at t = 0 the CoM
                # could only meet by a jerk that slides the feet
                u = np.linspace(0.0, 1.0, 21)[1:-1]
                delay = cfg.start_delay_s
                knots_t += [delay] + (delay + u * (first_ds - delay)).tolist()
                knots_p += [knots_p[0]] + [knots_p[0] + q * (stance - knots_p[0]) for q in _quintic(u)]
            knots_t += [first_ds, first_ds + ss]
            knots_p += [stance, stance]
            swing = (idx, first_ds, goal)
            length = first_ds + ss
            after = feet.copy()
            after[idx] = goal
            # the rest of the queue, as far as the preview looks, then standing
            t, f = length, after.copy()
            for pose, s2 in queue:
                if t > length + cfg.preview_time_s + dt:
                    break
                i2 = (1 - s2) // 2
                c2 = self._sole_center(f[1 - i2])
                knots_t += [t + ds, t + ds + ss]
                knots_p += [c2, c2]
                f[i2] = pose
                t += ds + ss
            else:
                end = 0.5 * (self._sole_center(f[0]) + self._sole_center(f[1]))
                knots_t += [t + ds]
                knots_p += [end]
        else:
            after = feet
            mid = 0.5 * (self._sole_center(feet[0]) + self._sole_center(feet[1]))
            if self._standing:
                kind, length = "stand", cfg.stand_chunk_s
                knots_t += [min(ds, length)]
            else:
                kind, length = "stop", ds + cfg.settle_s
                knots_t += [ds]
            knots_p += [mid]
        num = int(round(length / dt))
        n_prev = self.preview.horizon
        time = np.arange(num + n_prev + 2) * dt
        kp = np.asarray(knots_p)
        zmp_ref = np.stack([np.interp(time, knots_t, kp[:, i]) for i in range(2)], axis=-1)
        # preview control over this chunk (and one sample more, the next chunk's first)
        feedforward = self.preview.preview_term(zmp_ref)
        a, b, c = self.preview.a, self.preview.b, self.preview.c
        gi, gx = self.preview.gains.integral_gain, self.preview.gains.state_gain
        states = np.empty((num + 1, 3, 2))
        x, err = self._x.copy(), self._err_sum.copy()
        for k in range(num):
            states[k] = x
            err += c @ x - zmp_ref[k]
            u = -gi * err - gx @ x - feedforward[k]
            x = a @ x + np.outer(b, u)
        states[num] = x
        self._x, self._err_sum = x, err
        # the pattern of samples -1 (the last of the previous chunk) .. num (the next chunk's first)
        total = num + 2
        com = np.empty((total, 3, 2))
        com[0], com[1:] = self._prev["com"], states
        foot_pose = np.empty((total, 2, 4))
        foot_pose[0] = self._prev["feet"]
        foot_pose[1:] = feet
        contact = np.ones((total, 2), bool)
        contact[0] = self._prev["contact"]
        zref = np.empty((total, 2))
        zref[0], zref[1:] = self._prev["zmp"], zmp_ref[: num + 1]
        if swing is not None:
            idx, t0, goal = swing
            k0 = int(round(t0 / dt))
            tau = (np.arange(k0, num) - k0) / max(num - k0, 1)
            s = _quintic(tau)[:, None]
            start = feet[idx]
            path = start + s * (goal - start)
            path[:, 2] += cfg.swing_height_m * np.sin(math.pi * tau) ** 2
            foot_pose[1 + k0: 1 + num, idx] = path
            foot_pose[1 + num, idx] = goal
            contact[1 + k0: 1 + num, idx] = False
        z_c = self._floor_z + cfg.com_height_m
        pattern = WalkPattern(
            dt_s=dt, time_s=np.arange(total) * dt, zmp_ref_xy=zref, zmp_xy=np.einsum("i,kid->kd", c, com),
            com_pos_w=np.concatenate([com[:, 0], np.full((total, 1), z_c)], axis=1),
            com_vel_w=np.concatenate([com[:, 1], np.zeros((total, 1))], axis=1),
            com_acc_w=np.concatenate([com[:, 2], np.zeros((total, 1))], axis=1),
            foot_pose_w=foot_pose, foot_contact=contact,
            steps=np.zeros((0, 4)) if swing is None else swing[2][None],
            step_sides=np.zeros(0, np.int8) if swing is None else np.array([1 - 2 * swing[0]], np.int8),
            touchdown_index=np.zeros(0, np.int64) if swing is None else np.array([num + 1]), foot=HUMANOID_FOOT)
        ref = build_reference(self.ref_model, pattern, self._last_ref_qpos)
        self._last_ref_qpos = ref.qpos[num].copy()
        inner = slice(1, num + 1)
        pat_chunk = replace(pattern, time_s=pattern.time_s[inner] - dt, zmp_ref_xy=zref[inner],
                            zmp_xy=pattern.zmp_xy[inner], com_pos_w=pattern.com_pos_w[inner],
                            com_vel_w=pattern.com_vel_w[inner], com_acc_w=pattern.com_acc_w[inner],
                            foot_pose_w=foot_pose[inner], foot_contact=contact[inner],
                            touchdown_index=pattern.touchdown_index - 1)
        ref_chunk = self._to_sim_reference(ref, inner)
        ctl = WalkController(self.model, pat_chunk, ref_chunk, cfg.stabilizer, self.names.prim_path)
        ctl.anchor = self._anchor  # shared: the re-anchoring carries over from chunk to chunk
        # state for the next chunk
        self._prev = dict(com=states[num - 1].copy(), feet=foot_pose[num].copy(), contact=contact[num].copy(),
                          zmp=zmp_ref[num - 1].copy())
        self._zmp_last = zmp_ref[num].copy()
        self._feet = after.copy()
        self._standing = kind != "step"
        side = 0 if swing is None else 1 - 2 * swing[0]
        return _Chunk(kind=kind, pattern=pat_chunk, controller=ctl,
                      swing_goal=None if swing is None else swing[2].copy(), swing_side=side)

    def _to_sim_reference(self, ref: WalkReference, rows: slice) -> WalkReference:
        m = self.model
        n = len(ref.qpos[rows])
        qpos, qvel, qacc = np.zeros((n, m.nq)), np.zeros((n, m.nv)), np.zeros((n, m.nv))
        qpos[:] = m.qpos0
        qpos[:, self._qpos_dst] = ref.qpos[rows][:, self._qpos_src]
        qvel[:, self._dof_dst] = ref.qvel[rows][:, self._dof_src]
        qacc[:, self._dof_dst] = ref.qacc[rows][:, self._dof_src]
        return WalkReference(dt_s=ref.dt_s, qpos=qpos, qvel=qvel, qacc=qacc, tau_ff=ref.tau_ff[rows],
                             com_to_q=ref.com_to_q[rows], ik_error=ref.ik_error[rows],
                             contact_wrench=ref.contact_wrench[rows], zmp_multibody=ref.zmp_multibody[rows])

    # ------------------------------------------------------------------ control
    def step(self, dt_s: float | None = None) -> None:
        """Send the joint targets of the next ``dt_s`` (default: one pattern sample, the physics
        step) through the robot's drives. Call it before each physics step; ``dt_s`` must be a
        whole number of pattern samples (``dt_s`` of the walker, 5 ms)."""
        self._require_bound()
        samples = 1 if dt_s is None else int(round(dt_s / self.dt_s))
        if samples < 1 or abs(samples * self.dt_s - (dt_s or self.dt_s)) > 1e-9:
            raise InvalidValueError("dt_s", dt_s, f"the walker's pattern advances in samples of {self.dt_s} s",
                                    f"step the physics at {self.dt_s} s or a multiple of it")
        data = self.data = self.engine.get_data(0, self.data)
        chunk = self._chunk
        pos, vel, effort = chunk.controller.targets(data, chunk.k)
        self.robot.set_joint_targets(torch.from_numpy(pos)[None], torch.from_numpy(vel)[None],
                                     torch.from_numpy(effort)[None])
        chunk.k += samples
        while chunk.k >= chunk.length:
            extra = chunk.k - chunk.length
            if chunk.kind == "step":
                self.steps_taken += 1
                self._last_side = chunk.swing_side
            chunk = self._chunk = self._make_chunk()
            chunk.k = extra
        self._since_check += samples
        if self._since_check >= self.cfg.monitor_every_samples:  # the hulls cost more than the control
            self._since_check = 0
            self._fell |= self._balance(self.data).falling

    # ------------------------------------------------------------------ state
    def _current(self) -> mujoco.MjData:
        """The simulation's state now (the physics has stepped since ``step`` read it)."""
        self.data = self.engine.get_data(0, self.data)
        return self.data

    def feet_xyyaw_w(self) -> np.ndarray:
        """(2, 3) the soles now (left, right; x m, y m, yaw rad), measured: the planner's start feet."""
        self._require_bound(reset=False)
        return self._soles(self._current())

    def _soles(self, d: mujoco.MjData) -> np.ndarray:
        return np.array([[d.site_xpos[s][0], d.site_xpos[s][1], math.atan2(d.site_xmat[s][3], d.site_xmat[s][0])]
                         for s in self.sites])

    def next_stance_feet_xyyaw_w(self) -> np.ndarray:
        """(2, 3) the feet a new plan starts from (left, right): the soles now, except that a foot
        in the air is where it will land (``swing_target_w``). With ``stance_side`` as the plan's
        first stance, the new plan's start rows match the feet at the next touchdown exactly."""
        feet = self.feet_xyyaw_w()
        target = self.swing_target_w
        if target is not None:
            feet[(1 - self._chunk.swing_side) // 2] = target
        return feet

    @property
    def stance_side(self) -> int:
        """The foot a new plan should keep down first (+1 left, -1 right): the one that landed
        last (or, in a swing, the foot that will land), so the other moves next."""
        chunk = self._chunk
        if chunk.swing_goal is not None:
            return chunk.swing_side
        return self._last_side or 1

    @property
    def swing_target_w(self) -> np.ndarray | None:
        """(3,) where the foot now in the air will land (x, y, yaw; world frame through the current
        re-anchoring), None in double support or standing."""
        chunk = self._chunk
        if chunk.swing_goal is None:
            return None
        g = chunk.swing_goal
        xy = _rot(self._anchor[0]) @ g[:2] + self._anchor[1:]
        return np.array([xy[0], xy[1], float(_wrap(g[3] + self._anchor[0]))])

    @property
    def is_standing(self) -> bool:
        """No step queued or in progress, the pattern standing, the robot not fallen."""
        return self._chunk.kind in ("stand", "stop") and not self._queue and not self._fell

    @property
    def done(self) -> bool:
        """The plan is walked (or there was none, or it was refused) and the robot has settled:
        standing with the CoM over the support."""
        return self._chunk.kind == "stand" and not self._queue and not self._has_pending and not self._fell

    @property
    def fell(self) -> bool:
        """``falling`` was seen at some step since ``reset``."""
        return self._fell

    @property
    def remaining_steps(self) -> int:
        return len(self._queue) + (1 if self._chunk.swing_goal is not None else 0)

    def balance(self) -> WalkerBalance:
        """Capture point, ZMP and their margins to the support polygon now (``balance``)."""
        self._require_bound()
        return self._balance(self._current())

    def _balance(self, d: mujoco.MjData) -> WalkerBalance:
        m = self.model
        mujoco.mj_subtreeVel(m, d)
        xi = d.subtree_com[self.root, :2] + d.subtree_linvel[self.root, :2] / self.omega
        chunk = self._chunk
        k = min(chunk.k, chunk.length - 1)
        feet = [i for i in (0, 1) if chunk.pattern.foot_contact[k, i]]
        soles = self._soles(d)
        poly = support_polygon([soles[i] for i in feet], HUMANOID_FOOT)
        margin = float(polygon_signed_distance(xi, poly))
        pc = self.cop(d)
        zmp = pc.cop_w[:2].copy()
        zmp_margin = float(polygon_signed_distance(zmp, poly)) if np.all(np.isfinite(zmp)) else float("nan")
        target = self.swing_target_w
        region = poly if target is None else support_polygon([soles[i] for i in feet] + [target], HUMANOID_FOOT)
        region_margin = float(polygon_signed_distance(xi, region))
        low = float(d.xpos[self.pelvis][2]) < self._floor_z + self.cfg.fall_height_m
        return WalkerBalance(capture_point_xy=np.asarray(xi), zmp_xy=zmp, support_polygon_xy=poly,
                             capture_margin_m=margin, zmp_margin_m=zmp_margin,
                             capture_region_margin_m=region_margin,
                             falling=bool(region_margin < -self.cfg.falling_margin_m or low))


__all__ = ["StepWalkerCfg", "WalkerBalance", "ZmpStepWalker", "step_walker_cfg"]
