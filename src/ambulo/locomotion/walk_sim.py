"""The bundled humanoid walking a footstep plan in MuJoCo, with the balance measured as it goes.

``plan_walk`` plans footsteps on a map for the humanoid, ``walk_pattern`` turns them into a
preview-control walking pattern (``preview``), and ``WalkSimulation`` runs the whole-body
controller (``walk_controller``) on the simulated robot: flat floor, friction 1, contacts and
friction as MuJoCo simulates them, nothing held or pushed. The physics is the core's: one
``core.Simulation`` of the walk arena (``walk_world``), whose engine steps it, with the controller's
joint targets sent through the humanoid's ``core.Entity``. Each run records:

- the measured ZMP: centre of pressure of the feet's contact forces (``CenterOfPressure``), and
  its signed distance to the support polygon of the soles that touch the floor (measured poses);
  "single support" samples are those where the pattern has one foot down;
- the capture point ``xi = c + c_dot / omega`` (measured CoM state) at every touchdown, and its
  signed distance to the support polygon right after the touchdown (both measured soles: the
  new double support) and to the new foot's sole alone;
- falls: the pelvis below ``fall_height_m``, tilted past ``fall_tilt_rad``, or a robot geom other
  than the soles touching the floor.

Runs are seeded: ``seed`` perturbs the initial state (joint angles and the base's horizontal
velocity, uniform within ``WalkSimCfg.joint_noise_rad`` / ``base_speed_noise_mps``); seed None
starts exactly in the pattern's first pose.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ..nav.footsteps import FootstepPlan, FootstepPlanner, humanoid_footstep_cfg
from ..nav.grid_map import GridMap
from ..robots.humanoid import BASE_BODY, FOOT_BODIES, SOLE_SITES, SOLE_X_M
from ..scenes.walk_arena import GROUND_GEOM
from ..utils.validate import Checked, rule
from .balance import CenterOfPressure, FootShape, lipm_omega, polygon_signed_distance, support_polygon
from .preview import WalkPattern, WalkPatternGenerator, walk_pattern_cfg
from .walk_controller import HUMANOID_FOOT, StabilizerCfg, WalkController, build_reference, walk_robot
from .walk_world import start_walk_world


def plan_walk(grid: GridMap, start_xyyaw_w, goal_xyyaw_w, cfg=None, *, time_budget_s: float | None = None
              ) -> FootstepPlan:
    """Footsteps for the humanoid from a body pose to another (x m, y m, yaw rad; the body is the
    midpoint of the soles, ``SOLE_X_M`` ahead of the pelvis)."""
    planner = FootstepPlanner(grid, cfg or humanoid_footstep_cfg())
    return planner.plan(start_xyyaw_w, goal_xyyaw_w, time_budget_s=time_budget_s)


def walk_pattern(plan, *, com_height_m: float = 0.80, step_time_s: float = 0.8,
                 double_support_ratio: float = 0.2, swing_height_m: float = 0.05,
                 foot: FootShape = HUMANOID_FOOT) -> WalkPattern:
    """Preview-control walking pattern of a plan for the humanoid (defaults: CoM 0.80 m high,
    0.8 s steps with 20 % double support, 5 cm swing apex)."""
    cfg = walk_pattern_cfg(com_height_m=com_height_m, foot=foot, step_time_s=step_time_s,
                           double_support_ratio=double_support_ratio, swing_height_m=swing_height_m)
    return WalkPatternGenerator(cfg).generate(plan)


@dataclass(kw_only=True)
class WalkSimCfg(Checked):
    """A simulated walk."""

    friction: float = 1.0
    """Sliding friction of the floor and the robot's geoms."""
    settle_s: float = field(default=1.0, metadata=rule(minimum=0.0))
    """Simulated time after the pattern ends (standing still), s."""
    joint_noise_rad: float = 0.02
    """Seeded runs: every joint starts off its reference by up to this much, rad."""
    base_speed_noise_mps: float = 0.05
    """Seeded runs: the base starts with a horizontal velocity of up to this much, m/s."""
    fall_height_m: float = 0.55
    fall_tilt_rad: float = math.radians(45.0)
    stabilizer: StabilizerCfg = field(default_factory=StabilizerCfg)


@dataclass
class WalkResult:
    """What one simulated walk measured (arrays per control sample unless said otherwise)."""

    seed: int | None
    fell: bool
    fall_time_s: float | None
    fall_reason: str
    time_s: np.ndarray
    com_w: np.ndarray
    """(N, 3) measured CoM, m."""
    cop_xy: np.ndarray
    """(N, 2) measured ZMP (CoP of the foot contacts), NaN without contact, m."""
    zmp_margin_m: np.ndarray
    """(N,) signed distance of the measured ZMP to the support polygon of the soles in contact
    (> 0 inside), NaN without contact, m."""
    single_support: np.ndarray
    """(N,) bool: the pattern has one foot on the ground."""
    touchdown_time_s: np.ndarray
    """(S,) s."""
    capture_margin_m: np.ndarray
    """(S,) signed distance of the capture point at each touchdown to the support polygon right
    after it (both soles, measured), m."""
    capture_margin_new_foot_m: np.ndarray
    """(S,) the same to the new foot's sole alone, m."""
    capture_margin_liftoff_m: np.ndarray
    """(S - 1,) signed distance of the capture point to the stance sole when the next swing
    starts (the end of each double support), m."""
    final_body_xyyaw: np.ndarray
    """(3,) midpoint of the soles and their mean yaw at the end, m and rad."""
    start_body_xyyaw: np.ndarray
    frames: int = 0

    @property
    def single_support_margins_m(self) -> np.ndarray:
        m = self.zmp_margin_m[self.single_support]
        return np.where(np.isnan(m), -np.inf, m)  # no contact in single support: outside

    @property
    def zmp_inside_fraction(self) -> float:
        """Share of single-support samples with the measured ZMP inside the support polygon."""
        m = self.single_support_margins_m
        return float(np.mean(m >= 0.0)) if len(m) else float("nan")

    def summary(self) -> dict:
        ss = self.single_support_margins_m
        finite = ss[np.isfinite(ss)]
        start, end = self.start_body_xyyaw, self.final_body_xyyaw
        return {
            "seed": self.seed, "fell": self.fell, "fall_time_s": self.fall_time_s, "fall_reason": self.fall_reason,
            "zmp_inside_single_support": self.zmp_inside_fraction,
            "zmp_margin_single_support_mm": {
                "min": float(finite.min() * 1e3) if len(finite) else None,
                "p5": float(np.percentile(finite, 5) * 1e3) if len(finite) else None,
                "median": float(np.median(finite) * 1e3) if len(finite) else None},
            "single_support_samples": int(len(ss)),
            "touchdowns": int(len(self.capture_margin_m)),
            "capture_inside_all": bool(len(self.capture_margin_m) and np.all(self.capture_margin_m >= 0.0)),
            "capture_margin_min_mm": (float(np.nanmin(self.capture_margin_m) * 1e3)
                                      if np.isfinite(self.capture_margin_m).any() else None),
            "capture_in_new_sole": int(np.sum(self.capture_margin_new_foot_m >= 0.0)),
            "capture_in_stance_sole_at_liftoff": int(np.sum(self.capture_margin_liftoff_m >= 0.0)),
            "liftoffs": int(len(self.capture_margin_liftoff_m)),
            "capture_liftoff_margin_min_mm": (float(np.nanmin(self.capture_margin_liftoff_m) * 1e3)
                                              if np.isfinite(self.capture_margin_liftoff_m).any() else None),
            "distance_m": float(np.hypot(*(end[:2] - start[:2]))),
            "turn_deg": float(math.degrees(end[2] - start[2])),
            "final_body_xyyaw": [round(float(v), 4) for v in end],
        }


def _sole_pose(data: mujoco.MjData, site: int) -> np.ndarray:
    mat = data.site_xmat[site]
    return np.array([data.site_xpos[site][0], data.site_xpos[site][1], math.atan2(mat[3], mat[0])])


class WalkSimulation:
    """The humanoid, its controller and a pattern; ``run`` simulates one walk. The arena is
    started once (``walk_world``: one world on the CPU engine) and the reference (IK, inverse
    dynamics) built once; every run resets the world and starts from the pattern's first pose."""

    def __init__(self, pattern: WalkPattern, cfg: WalkSimCfg | None = None, grid: GridMap | None = None,
                 obstacle_height_m: float = 0.4):
        """``grid``: its occupied cells become boxes ``obstacle_height_m`` high in the scene."""
        self.cfg = cfg = cfg or WalkSimCfg()
        self.pattern = pattern
        obstacles = [] if grid is None else grid_obstacles(grid, obstacle_height_m)
        self.world = start_walk_world(friction=cfg.friction, timestep_s=pattern.dt_s, obstacles=obstacles)
        """The started arena: ``world.sim`` steps the physics, ``world.robot`` is the humanoid's ``Entity``."""
        self.model = m = self.world.model
        self.reference = build_reference(m, pattern, self.world.home_qpos)
        self.robot = robot = walk_robot(m)
        """The humanoid's elements by name (``core.EntityNames``)."""
        self.root = robot.root_body_id
        self.base_qpos = robot.free_qpos_adr + np.arange(7)
        self.base_dofs = robot.free_dof_adr + np.arange(6)
        self.joint_qpos = m.jnt_qposadr[robot.joint_ids]
        self.joint_dofs = m.jnt_dofadr[robot.joint_ids]
        self.sites = [robot.site_id(name) for name in SOLE_SITES]
        self.foot_bodies = [robot.body_id(b) for b in FOOT_BODIES]
        self.foot_geoms = [set(robot.geom_ids(b).tolist()) for b in FOOT_BODIES]
        self.floor = m.geom(GROUND_GEOM).id
        self.pelvis = robot.body_id(BASE_BODY)
        self.omega = lipm_omega(float(pattern.com_pos_w[0, 2]))

    def start_state(self, seed: int | None) -> tuple[np.ndarray, np.ndarray]:
        """(qpos (nq,), qvel (nv,)) a run starts from: the pattern's first pose, perturbed by ``seed``
        (joints, the base's horizontal velocity) and then lowered onto the floor."""
        m, cfg = self.model, self.cfg
        qpos, qvel = self.reference.qpos[0].copy(), np.zeros(m.nv)
        if seed is not None:
            rng = np.random.default_rng(seed)
            qpos[self.joint_qpos] += rng.uniform(-cfg.joint_noise_rad, cfg.joint_noise_rad, len(self.joint_qpos))
            angle, speed = rng.uniform(0, 2 * math.pi), cfg.base_speed_noise_mps * math.sqrt(rng.uniform())
            qvel[self.base_dofs[0:2]] = speed * math.cos(angle), speed * math.sin(angle)
            data = mujoco.MjData(m)  # kinematics only, to find the soles
            data.qpos[:] = qpos
            mujoco.mj_kinematics(m, data)
            # put the lowest sole corner on the floor
            lowest = min(float(data.geom_xpos[g][2] - np.abs(data.geom_xmat[g].reshape(3, 3)[2])
                                @ m.geom_size[g]) for feet in self.foot_geoms for g in feet)
            qpos[self.base_qpos[2]] -= lowest
        return qpos, qvel

    def _start(self, seed: int | None) -> None:
        """Reset the world (the robot's initial state) and write the run's start through the Entity."""
        sim, robot = self.world.sim, self.world.robot
        qpos, qvel = self.start_state(seed)
        sim.reset(forward=False)
        rows = torch.as_tensor(qpos[None], dtype=sim.engine.dtype, device=robot.device)
        vel = torch.as_tensor(qvel[None], dtype=sim.engine.dtype, device=robot.device)
        robot.write_root_pose(pos_w=rows[:, self.base_qpos[0:3]], quat_w=rows[:, self.base_qpos[3:7]])
        robot.write_joint_state(pos=rows[:, self.joint_qpos], vel=vel[:, self.joint_dofs])
        robot.write_root_velocity(lin_vel_w=vel[:, self.base_dofs[0:3]])  # the reset left it not turning
        sim.engine.forward()

    def run(self, seed: int | None = None, *, video: str | os.PathLike | None = None, width: int = 640,
            height: int = 480, fps: int = 30, on_step=None) -> WalkResult:
        """One walk from the pattern's first pose (perturbed by ``seed``), until the pattern ends
        plus ``settle_s`` or a fall. ``video``: an MP4 to write; ``on_step(k, data)`` is called
        before each physics step (e.g. to render snapshots).

        Each control step reads the world into an ``MjData`` (``engine.get_data``: the state with
        every derived field current), asks the controller for joint targets, sends them through
        the robot's ``Entity``, measures, and lets the engine step."""
        m, cfg, pat = self.model, self.cfg, self.pattern
        sim, robot = self.world.sim, self.world.robot
        self._start(seed)
        data = sim.engine.get_data(0)
        ctl = WalkController(m, pat, self.reference, cfg.stabilizer)
        cop = CenterOfPressure(m, self.foot_bodies, ground_geoms=[self.floor])
        num_pat = len(pat.time_s)
        num = num_pat + int(round(cfg.settle_s / pat.dt_s))
        com = np.full((num, 3), np.nan)
        cop_xy = np.full((num, 2), np.nan)
        margin = np.full(num, np.nan)
        single = np.zeros(num, bool)
        touch = {int(k): i for i, k in enumerate(pat.touchdown_index)}
        cap = np.full(len(pat.touchdown_index), np.nan)
        cap_new = np.full(len(pat.touchdown_index), np.nan)
        # the swing of step i >= 1 starts when the double support after step i - 1 ends
        single_pat = pat.foot_contact.sum(axis=1) == 1
        liftoff = {}
        for i in range(1, len(pat.touchdown_index)):
            later = np.flatnonzero(single_pat[pat.touchdown_index[i - 1]:])
            if len(later):
                liftoff[int(pat.touchdown_index[i - 1] + later[0])] = i
        cap_lift = np.full(max(len(pat.touchdown_index) - 1, 0), np.nan)
        start = self._body_pose(data)
        fell, fall_time, reason = False, None, ""
        writer = _WalkFilm(m, video, width, height, fps, pat.dt_s, self.pelvis) if video else None
        steps_done, failed = 0, True
        try:
            for k in range(num):
                kk = min(k, num_pat - 1)
                data = sim.engine.get_data(0, data)  # mj_forward at the current state: data is current below
                pos, vel, effort = ctl.targets(data, k)
                robot.set_joint_targets(torch.from_numpy(pos)[None], torch.from_numpy(vel)[None],
                                        torch.from_numpy(effort)[None])
                mujoco.mj_subtreeVel(m, data)
                steps_done = k + 1
                com[k] = data.subtree_com[self.root]
                single[k] = k < num_pat and int(pat.foot_contact[kk].sum()) == 1
                touching = self._feet_touching(data)
                if touching.any():
                    pc = cop(data)
                    cop_xy[k] = pc.cop_w[:2]
                    if np.isfinite(pc.cop_w[0]):
                        poly = support_polygon([_sole_pose(data, self.sites[i]) for i in np.flatnonzero(touching)],
                                               pat.foot)
                        margin[k] = polygon_signed_distance(pc.cop_w[:2], poly)
                if k in touch:
                    i = touch[k]
                    xi = data.subtree_com[self.root, :2] + data.subtree_linvel[self.root, :2] / self.omega
                    feet = [_sole_pose(data, s) for s in self.sites]
                    cap[i] = polygon_signed_distance(xi, support_polygon(feet, pat.foot))
                    new = int((1 - pat.step_sides[i]) // 2)
                    cap_new[i] = polygon_signed_distance(xi, support_polygon(feet[new], pat.foot))
                if k in liftoff:
                    i = liftoff[k]
                    xi = data.subtree_com[self.root, :2] + data.subtree_linvel[self.root, :2] / self.omega
                    stance = int((1 - pat.step_sides[i - 1]) // 2)
                    cap_lift[i - 1] = polygon_signed_distance(
                        xi, support_polygon(_sole_pose(data, self.sites[stance]), pat.foot))
                reason = self._fallen(data)
                if reason:
                    fell, fall_time = True, k * pat.dt_s
                    break
                if writer is not None:
                    writer.capture(data, k)
                if on_step is not None:
                    on_step(k, data)
                if bool(sim.step()[0]):  # the engine found the world diverged and reset it
                    fell, fall_time, reason = True, (k + 1) * pat.dt_s, "the simulation diverged"
                    break
            failed = False
        finally:
            frames = writer.close(failed) if writer is not None else 0
        n = steps_done
        return WalkResult(seed=seed, fell=fell, fall_time_s=fall_time, fall_reason=reason,
                          time_s=np.arange(n) * pat.dt_s, com_w=com[:n], cop_xy=cop_xy[:n], zmp_margin_m=margin[:n],
                          single_support=single[:n], touchdown_time_s=pat.touchdown_index * pat.dt_s,
                          capture_margin_m=cap, capture_margin_new_foot_m=cap_new, capture_margin_liftoff_m=cap_lift,
                          final_body_xyyaw=self._body_pose(data), start_body_xyyaw=start, frames=frames)

    def _body_pose(self, data: mujoco.MjData) -> np.ndarray:
        left, right = (_sole_pose(data, s) for s in self.sites)
        yaw = right[2] + math.remainder(left[2] - right[2], 2 * math.pi) / 2
        return np.array([(left[0] + right[0]) / 2, (left[1] + right[1]) / 2, yaw])

    def _feet_touching(self, data: mujoco.MjData) -> np.ndarray:
        out = np.zeros(2, bool)
        for c in data.contact[: data.ncon] if data.ncon else ():
            g1, g2 = int(c.geom1), int(c.geom2)
            other = g2 if g1 == self.floor else g1 if g2 == self.floor else None
            if other is None:
                continue
            for i in (0, 1):
                if other in self.foot_geoms[i]:
                    out[i] = True
        return out

    def _fallen(self, data: mujoco.MjData) -> str:
        cfg = self.cfg
        height = data.qpos[self.base_qpos[2]]
        if height < cfg.fall_height_m:
            return f"pelvis at {height:.2f} m"
        up = data.xmat[self.pelvis][8]
        if up < math.cos(cfg.fall_tilt_rad):
            return f"pelvis tilted {math.degrees(math.acos(min(1.0, up))):.0f} deg"
        feet = self.foot_geoms[0] | self.foot_geoms[1]
        for c in data.contact[: data.ncon] if data.ncon else ():
            g1, g2 = int(c.geom1), int(c.geom2)
            if self.floor in (g1, g2):
                other = g2 if g1 == self.floor else g1
                if other not in feet:
                    return f"{self.model.geom(other).name} touched the floor"
        return ""


class _WalkFilm:
    """MP4 of the walk (``render.video``): a camera following the pelvis from the side and behind."""

    def __init__(self, model, path, width, height, fps, dt_s, track_body: int):
        from ..render import OffscreenRenderer
        from ..render.video import VideoWriter

        self.every = max(1, round(1.0 / (fps * dt_s)))
        self.writer = VideoWriter(path, fps=round(1.0 / (self.every * dt_s)), quality=7)
        self.renderer = OffscreenRenderer(model, width, height)
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        self.camera.trackbodyid = track_body
        self.camera.distance, self.camera.elevation, self.camera.azimuth = 3.5, -28.0, 120.0
        self.model = model

    def capture(self, data, k: int) -> None:
        if k % self.every:
            return
        self.renderer.update_view(self.model, data, self.camera)
        self.writer.append(self.renderer.render_rgb())

    def close(self, failed: bool = False) -> int:
        """Frames written; the video is kept unless the walk ``failed`` (raised) or filmed nothing."""
        self.renderer.close()
        if failed or not self.writer.num_frames:
            self.writer.abort()
        else:
            self.writer.close()
        return self.writer.num_frames


def grid_obstacles(grid: GridMap, height_m: float) -> list[tuple[float, float, float, float, float]]:
    """Boxes ``(cx, cy, sx, sy, height)`` covering the occupied cells of a map: one per run of
    occupied cells along x in each row, merged with the identical runs of the rows above."""
    r = grid.resolution_m
    (ox, oy) = grid.origin_xy_m
    boxes: dict[tuple[int, int], list[int]] = {}  # (start, end) column run -> [first row, last row] open
    done = []
    for row in range(grid.shape[0]):
        occ = np.concatenate([[False], grid.occupied[row], [False]])
        edges = np.flatnonzero(occ[1:] != occ[:-1])
        runs = set(zip(edges[0::2].tolist(), edges[1::2].tolist()))
        for run in list(boxes):
            if run not in runs:
                done.append((run, boxes.pop(run)))
        for run in runs:
            boxes.setdefault(run, [row, row])[1] = row
    done += list(boxes.items())
    out = []
    for (c0, c1), (r0, r1) in done:
        out.append((ox + (c0 + c1) * r / 2, oy + (r0 + r1 + 1) * r / 2, (c1 - c0) * r, (r1 - r0 + 1) * r, height_m))
    return out


def straight_and_turn_goal(distance_m: float = 3.0, turn_rad: float = math.pi / 2,
                           start_xyyaw=(SOLE_X_M, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(start, goal) body poses of the acceptance walk: ``distance_m`` straight ahead, then a
    turn of ``turn_rad`` on the spot."""
    start = np.asarray(start_xyyaw, dtype=np.float64)
    goal = start + np.array([distance_m * math.cos(start[2]), distance_m * math.sin(start[2]), turn_rad])
    return start, goal


def acceptance_walk(distance_m: float = 3.0, turn_rad: float = math.pi / 2, *, cfg: WalkSimCfg | None = None,
                    **pattern_kw) -> tuple[FootstepPlan, WalkSimulation]:
    """The plan (empty floor, ``plan_walk``) and simulation of the walk of issue 14's acceptance."""
    start, goal = straight_and_turn_goal(distance_m, turn_rad)
    size = distance_m + 3.0
    grid = GridMap.empty((size, size), resolution_m=0.05, origin_xy_m=(-1.5, -size / 2))
    plan = plan_walk(grid, start, goal, humanoid_footstep_cfg(goal_tolerance_m=0.05, goal_tolerance_yaw_rad=0.05),
                     time_budget_s=1.0)
    return plan, WalkSimulation(walk_pattern(plan, **pattern_kw), cfg)


__all__ = ["grid_obstacles", "plan_walk", "walk_pattern", "WalkSimCfg",
           "WalkResult", "WalkSimulation", "straight_and_turn_goal", "acceptance_walk"]
