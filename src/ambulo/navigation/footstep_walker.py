"""The learned footstep walker behind the navigator's ``Walker`` interface: the shipped
humanoid-footsteps policy (``policies.FootstepPolicy``) puts its feet on the plan's footsteps.

It feeds the policy exactly what the training env feeds it, with the env's own code: the state of
one world's plan (targets, sides, timers) lives in ``_PlanState``, whose ``footstep_command``
(the next two footsteps in the base's heading frame), ``update_plan`` (touchdowns by
``footstep_gait.swing_touchdown``, placement errors, advancing on a touchdown within
``advance_radius_m``) and ``_swing_index`` *are* ``HumanoidFootstepsEnv``'s methods, run on N = 1
with the env's configuration (``humanoid_footsteps_cfg``). What the env reads from its contact
sensor (``first_contact``, ``last_air_time_s`` of each foot, once per policy step) is rebuilt
here from the simulator's contacts with the sensor's timer rule (``_FootContacts``): the
navigator's world has no contact sensor.

Frames: the plan is in the frame of the navigator's pose estimate (the map's); the command takes
the base pose from the estimate (as the velocity walker's tracker does), and the soles, measured
in the simulator, are placed relative to the true base and then at the estimate, so touchdowns
are scored in the plan's frame (in ``oracle`` mode the two frames are one).

The plan: a new plan whose start foot kept down (row 1) is the current swing target
(``start_feet``: the navigator plans from the feet at the next touchdown, as for the ZMP walker)
splices on without a break; another starts at row 2 as ``follow_plans`` does (and, as there, the
feet's last policy step before it is not read for touchdowns).

Standing (before the first plan, at a plan's end, told to ``stand``): the footstep policy cannot
stand still (trained on plans that never end; stepping in place its pelvis moves at ~0.65 m/s,
and its trailing foot lands ~0.25 m behind its foothold), so it steps in place on the last two
footholds until a touchdown on them with both feet down, then hands the robot to the velocity
policy (``policies.WalkingPolicy``) with ``stand_hold.PositionHold``, as ``PolicyWalker`` stands,
holding the base pose those footholds give (the env's stance: soles ``start_sole_x_m`` ahead);
the next plan hands it back. Both policies share joints, default pose and action scale: each
starts from the other's last action. It does not turn on the spot (no ``scan`` or ``stand_at``:
the navigator faces the route by plans alone, as with the ZMP walker).

The arms: the policy swings them wide (forearms 0.60-0.63 m to the side of the body path), so
their joint targets move only ``arm_swing_scale`` (0.4) of the way from the default pose to the
policy's (``_NarrowArmsPolicy``; 0.52 m).

Measured (``benchmarks/navigate.py --episodes 20 --modes oracle --walkers policy,footsteps
--workers 1 --ceiling-every 0``, apartments 0-19): 20 of 20 arrived, SPL 0.66, 2.9 collisions an
episode, 56 of 58 a forearm (arms as trained: 19 of 20, one fall, SPL 0.62, 6.5, 123 of 130);
``PolicyWalker``: 20 of 20, SPL 0.89, none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
import torch

from ..envs.humanoid_footsteps import HumanoidFootstepsCfg, HumanoidFootstepsEnv, humanoid_footsteps_cfg
from ..nav import FootstepPlan
from ..nav.footstep_lattice import compose, relative
from ..policies.footstep_policy import FOOTSTEP_TASK, FootstepPolicy
from ..policies.walking import WalkingPolicy
from ..robots import humanoid
from ..utils.validate import Checked, rule
from .stand_hold import PositionHold, StandHoldCfg
from .walkers import BalanceMonitor, BalanceReport, plan_refusal
from .world import NavWorld


@dataclass(kw_only=True)
class FootstepWalkerCfg(Checked):
    task: str = FOOTSTEP_TASK
    """The shipped footstep policy to run (flat ground: humanoid-footsteps)."""
    max_start_offset_m: float = 0.45
    """A plan whose start stance is farther than this from the robot is refused, m (as ``PolicyWalkerCfg``)."""
    max_step_m: float = 0.45
    """A plan whose body path jumps farther than this between footstep pairs is refused, m."""
    hold: StandHoldCfg = field(default_factory=StandHoldCfg)
    """Standing, the velocity policy holds the base pose of the last two footholds (``stand_hold``)."""
    splice_radius_m: float = 0.05
    """A new plan whose kept-down start foot (row 1) lies this close to the current swing target,
    same side, continues the step in progress, m."""
    arm_swing_scale: float = field(default=0.4, metadata=rule(minimum=0.0))
    """The arm joints' (shoulders', elbows') targets are the default pose plus this fraction of what
    the policy asks (1: as trained). Its arms swing wide: the forearms reach 0.60-0.63 m to the side
    of the body path (0.27-0.34 m for the velocity policy), so in the apartments' corridors and doors
    they met the walls 0.35-0.5 m from the pelvis (apartments 0, 8, 16), out of reach of any body
    clearance the routes through them can keep (footsteps kept 0.5/0.4 m where they could:
    6.4 collisions an episode instead of 6.5). 0.4: 0.52 m at most; placement unchanged (8 straight
    steps median 1.3 cm, the 14-step turn 1.6 cm); oracle apartments 20-59: 2.3 collisions an
    episode against 6.9, all 40 arrived either way. Held at the default pose (0) 3 of 20 fell."""


class _PlanState:
    """One world's footstep targets and timers, advanced by ``HumanoidFootstepsEnv``'s own methods
    (module docstring). Tensors as the env's, N = 1; ``on_advance`` moves the targets on."""

    num_envs = 1
    _swing_index = HumanoidFootstepsEnv._swing_index
    _swing_to_target_m = HumanoidFootstepsEnv._swing_to_target_m
    update_plan = HumanoidFootstepsEnv.update_plan
    footstep_command = HumanoidFootstepsEnv.footstep_command

    def __init__(self, cfg: HumanoidFootstepsCfg, step_dt_s: float, on_advance):
        self.cfg, self.step_dt_s, self._on_advance = cfg, step_dt_s, on_advance
        self.targets_xyyaw_w = torch.zeros(1, 2, 3)
        self.target_sides = torch.tensor([[1.0, -1.0]])
        self.base_xyyaw = torch.zeros(1, 3)
        self.since_advance_s = torch.zeros(1)
        self._swing_distance_m = torch.zeros(1)
        self.touchdown = torch.zeros(1, dtype=torch.bool)
        self.touchdown_error_m = torch.zeros(1)
        self.placement_error_m = torch.zeros(1)
        self.yaw_error_rad = torch.zeros(1)

    def _base_xyyaw_w(self) -> torch.Tensor:
        return self.base_xyyaw

    def _advance(self, rows) -> None:
        if rows is not None:
            self._on_advance()


class _FootContacts:
    """The feet's ground contact and air timers, by ``sensors.ContactSensor``'s rule once per policy
    step: ``first_contact`` a landing after time in the air, ``last_air_time_s`` that flight's length
    (counting the landing's step). Ground: any geom not the robot's (the navigator's floors, rugs).

    The env's sensor reads the contacts MuJoCo found at the start of the policy step's last physics
    step (``mj_step`` collides, then integrates), so ``read`` is called just before that step and
    ``update`` at the next control period."""

    def __init__(self, model: mujoco.MjModel):
        prefix = humanoid.PRIM_PATH + "/"
        robot = np.array([model.body(b).name.startswith(prefix) for b in range(model.nbody)])
        self._robot_geom = robot[model.geom_bodyid]
        self._foot_geom = [np.flatnonzero(model.geom_bodyid == model.body(prefix + f).id) for f in humanoid.FOOT_BODIES]
        self.touching = torch.zeros(1, 2, dtype=torch.bool)
        """(1, 2) left, right sole on the ground at the last ``read``."""
        self.air_s = torch.zeros(1, 2)
        self.last_air_time_s = torch.zeros(1, 2)
        self.first_contact = torch.zeros(1, 2, dtype=torch.bool)

    def read(self, data: mujoco.MjData) -> None:
        """Which feet touch the ground in ``data`` (its contacts current)."""
        geom = np.asarray(data.contact.geom)[:data.ncon]
        self.touching = torch.zeros(1, 2, dtype=torch.bool)
        if len(geom):
            a, b = geom[:, 0], geom[:, 1]
            for i, ids in enumerate(self._foot_geom):
                on_ground = (np.isin(a, ids) & ~self._robot_geom[b]) | (np.isin(b, ids) & ~self._robot_geom[a])
                self.touching[0, i] = bool(on_ground.any())

    def update(self, dt_s: float) -> None:
        """Advance the timers by one policy step ``dt_s`` with the last ``read`` (the sensor's ``update``)."""
        was_in_air = self.air_s > 0.0
        self.air_s = self.air_s + dt_s
        self.first_contact = self.touching & was_in_air
        self.last_air_time_s = torch.where(self.first_contact, self.air_s, self.last_air_time_s)
        self.air_s = self.air_s.masked_fill(self.touching, 0.0)


class _NarrowArmsPolicy(FootstepPolicy):
    """``FootstepPolicy`` whose arm joint targets move ``arm_swing_scale`` of the way from the default
    pose to the policy's (``FootstepWalkerCfg.arm_swing_scale``); its actions (fed back in the
    observation) are the policy's own."""

    def __init__(self, task: str, arm_swing_scale: float):
        super().__init__(task=task)
        self.arm_swing_scale = arm_swing_scale
        self._arm = torch.tensor([("shoulder" in n or "elbow" in n) for n in self.contract["joint_names"]])
        """(J,) bool: the arm joints."""

    def joint_targets(self) -> torch.Tensor:
        targets = super().joint_targets()
        narrow = self.default_joint_pos + self.arm_swing_scale * (targets - self.default_joint_pos)
        return torch.where(self._arm.to(targets.device), narrow, targets)


class FootstepPolicyWalker:
    """``walkers.Walker`` over the shipped footstep policy (module docstring)."""

    name = "footsteps"

    def __init__(self, cfg: FootstepWalkerCfg | None = None):
        self.cfg = cfg or FootstepWalkerCfg()
        self.policy = _NarrowArmsPolicy(self.cfg.task, self.cfg.arm_swing_scale)
        self.stand_policy = WalkingPolicy()
        self.hold = PositionHold(self.cfg.hold)
        self.env_cfg = humanoid_footsteps_cfg()
        self.world: NavWorld | None = None
        self.command = torch.zeros(1, 10)
        """(1, 10) the last footstep command (``HumanoidFootstepsEnv.footstep_command``)."""

    def bind(self, world: NavWorld) -> None:
        self.world = world
        self.policy.bind(world.robot)
        self.stand_policy.bind(world.robot)
        self.monitor = BalanceMonitor(world)
        model = world.model
        prefix = humanoid.PRIM_PATH + "/"
        self._soles = [model.site(prefix + s).id for s in humanoid.SOLE_SITES]
        self._feet = [model.body(prefix + f).id for f in humanoid.FOOT_BODIES]
        self._decimation = round(self.policy.contract["control_dt_s"] / world.dt_s)
        self._control_dt_s = self._decimation * world.dt_s
        self._pose = np.array(world.start_pose, float)
        self._data: mujoco.MjData | None = None

    def reset(self) -> None:
        self.policy.reset()
        self.stand_policy.actions.zero_()
        self.state = _PlanState(self.env_cfg, self._control_dt_s, self._advanced)
        self.contacts = _FootContacts(self.world.model)
        self._read_feet()
        self._count = 0
        self._final = False
        self._fresh = False
        self._plan_rows = 0
        """Rows of the plan being walked (0: none: in place on held footholds, or standing)."""
        self.touchdowns: list[tuple[float, int, float]] = []
        """(time s, side +1 left / -1 right, distance of the sole to its target m) of each touchdown."""
        soles = self.soles_xyyaw()
        self._hold(soles[1], -1.0, soles[0])
        self.standing = True
        """The velocity policy holds the pose (``stand_hold``); else the footstep policy steps."""
        self.hold.release()
        self._active = self.stand_policy

    # -- plan rows -------------------------------------------------------------------------------
    def _row(self, j: int) -> int:
        """Row of the plan's footstep j; past the end the last two footholds alternate (in place)."""
        n = len(self._rows)
        return j if j < n else n - 2 + (j - n) % 2

    def _set_targets(self) -> None:
        rows = [self._row(self._k), self._row(self._k + 1)]
        self.state.targets_xyyaw_w = torch.as_tensor(self._rows[rows], dtype=torch.float32)[None].clone()
        self.state.target_sides = torch.as_tensor(self._sides[rows], dtype=torch.float32)[None].clone()

    def _advanced(self) -> None:
        self._k += 1
        self._set_targets()

    def _hold(self, first_xyyaw, first_side: float, second_xyyaw) -> None:
        """Step in place: ``second_xyyaw``'s foot (side ``-first_side``) next, then the other's."""
        self._rows = np.array([first_xyyaw, second_xyyaw], float)
        self._sides = np.array([first_side, -first_side])
        self._k = 1
        self._plan_rows = 0
        self._settle_after_k = 1  # stand after a touchdown on the held footholds: the feet come down there
        self._set_targets()

    @property
    def walking(self) -> bool:
        """A plan's footsteps are ahead (not yet all touched down)."""
        return self._plan_rows > 0 and self._k < self._plan_rows

    # -- the Walker interface ---------------------------------------------------------------------
    def refuse(self, plan: FootstepPlan) -> str | None:
        return plan_refusal(plan, self._pose[:2], self.cfg.max_start_offset_m, self.cfg.max_step_m)

    def start_feet(self) -> tuple[np.ndarray, int]:
        """((2, 3) left and right soles at the next touchdown, the pose estimate's frame; the foot kept
        down first). Stepping: the swing foot on its target, the other where it is, the swing foot
        kept down (a plan from these splices on, ``set_plan``). Standing: the soles where they are."""
        feet = self.soles_xyyaw()
        if self.standing:
            return feet, int(self.state.target_sides[0, 1])
        swing_side = float(self.state.target_sides[0, 0])
        feet[0 if swing_side > 0 else 1] = self.state.targets_xyyaw_w[0, 0].double().numpy()
        return feet, int(swing_side)

    def set_plan(self, plan: FootstepPlan | None, *, final: bool) -> None:
        if plan is None:
            self.stand()
            return
        rows = np.asarray(plan.footsteps_xyyaw_w, float).copy()
        sides = np.asarray(plan.foot_sides, float)
        target = self.state.targets_xyyaw_w[0, 0].double().numpy()
        splice = (not self.standing and sides[1] == float(self.state.target_sides[0, 0])
                  and np.linalg.norm(rows[1, :2] - target[:2]) <= self.cfg.splice_radius_m)
        self._rows, self._sides = rows, sides
        self._plan_rows = len(rows)
        self._settle_after_k = 0  # stand once the plan is walked (its last touchdown made)
        self._final = bool(final)
        if splice:  # the foot in the air lands where it was going, then the plan goes on
            self._rows[1] = target
            self._k = 1
        else:  # as ``follow_plans``: rows 2 and 3; a foot in the air is not stepping to them
            self._k = 2
            self.state.since_advance_s.zero_()
            self._fresh = True
        self._set_targets()

    def stand(self) -> None:
        """Stop: step in place on the swing target and where the other foot is, until both feet are
        down; then the velocity policy holds the pose."""
        if not self.walking:
            return  # standing, or about to
        swing_side = float(self.state.target_sides[0, 0])
        stance = self.soles_xyyaw()[1 if swing_side > 0 else 0]
        self._hold(stance, -swing_side, self.state.targets_xyyaw_w[0, 0].double().numpy())
        self._final = False

    def step(self, dt_s: float, pose_xyyaw: np.ndarray) -> None:
        self._pose = np.asarray(pose_xyyaw, float)
        phase = self._count % self._decimation
        if phase == 0:
            self._control()
        if phase == self._decimation - 1:
            self._read_feet()
        self._active.forward(dt_s, self._stand_command if self.standing else self.command)
        self._count += 1

    def _read_feet(self) -> None:
        """Read what the env reads after this policy step, just before its last physics step: its
        contact sensor's data and the sole sites are MuJoCo's from before that step (``mj_step``
        collides, then integrates; the engine does not refresh kinematics after it)."""
        data = self._get_data()
        self.contacts.read(data)
        self._soles_read_w = self._soles_w(data)

    def _get_data(self) -> mujoco.MjData:
        """The world's state as an ``MjData`` (contacts and kinematics current), reusing one buffer."""
        self._data = self.world.engine.get_data(0, self._data)
        return self._data

    def _control(self) -> None:
        """One policy step's bookkeeping, in the env's order: the feet after the last step's physics
        (touchdowns, the plan advanced), then the command for the next; and the switches between
        stepping (a plan ahead) and standing (none, once both feet are down)."""
        s = self.state
        self.contacts.update(self._control_dt_s)
        if self.standing and self.walking:
            self._switch(standing=False)
        elif (not self.standing and not self.walking and self._k > self._settle_after_k
              and bool(self.contacts.touching.all())):
            self._switch(standing=True)
        if self.standing:
            self._stand_command = self.hold.command(self._pose, self._control_dt_s)
            return
        k = self._k
        if self._fresh:
            # the env's first ``update_plan`` after ``follow_plans`` reads the step after it: the
            # feet's last period here predates the plan
            self._fresh = False
        else:
            s.update_plan(torch.as_tensor(self._to_plan(self._soles_read_w), dtype=torch.float32)[None],
                          self.contacts.first_contact, self.contacts.last_air_time_s)
            if bool(s.touchdown[0]):
                side = float(self._sides[self._row(k)])
                self.touchdowns.append((self.world.time_s, int(side), float(s.touchdown_error_m[0])))
        s.base_xyyaw = torch.as_tensor(self._pose, dtype=torch.float32)[None]
        self.command = s.footstep_command()

    def _switch(self, *, standing: bool) -> None:
        """Hand the robot to the other policy at a control period, its last action carried over (the
        two share joints, default pose and action scale)."""
        new = self.stand_policy if standing else self.policy
        new.actions = self._active.actions.clone()
        new._count = 0  # it acts at this physics step, the start of a control period
        self._active = new
        self.standing = standing
        if standing:
            # on the last two footholds (the plan's end, or where ``stand`` stopped): the trailing foot
            # lands ~0.25 m behind its foothold (the policy's gait) and the body still moves, so the
            # hold takes the pelvis to where the footholds put it, not where the switch happened
            self.hold.release()
            self.hold.hold_xyyaw = self._end_body_xyyaw()
        else:
            self.state.since_advance_s.zero_()  # as ``follow_plans``: the plan starts now

    def _end_body_xyyaw(self) -> np.ndarray:
        """(3,) the base pose standing on the last two footholds (a plan's, or the held ones; the
        env's start stance: soles ``start_sole_x_m`` ahead of the base), the pose estimate's frame."""
        last = self._plan_rows or len(self._rows)
        feet = self._rows[last - 2:last]
        yaw = math.atan2(np.sin(feet[:, 2]).sum(), np.cos(feet[:, 2]).sum())
        mid = feet[:, :2].mean(axis=0) - self.env_cfg.start_sole_x_m * np.array([math.cos(yaw), math.sin(yaw)])
        return np.array([mid[0], mid[1], yaw])

    def soles_xyyaw(self) -> np.ndarray:
        """(2, 3) left and right sole centres x, y m and yaw rad now, in the pose estimate's frame."""
        return self._to_plan(self._soles_w(self._get_data()))

    def _soles_w(self, data: mujoco.MjData) -> np.ndarray:
        """(2, 3) the soles as the env's ``soles_xyyaw_w`` has them (the sole site's centre, the foot
        body's yaw), simulator world frame."""
        out = np.zeros((2, 3))
        for i, (site, foot) in enumerate(zip(self._soles, self._feet, strict=True)):
            m = data.xmat[foot].reshape(3, 3)
            out[i] = data.site_xpos[site, 0], data.site_xpos[site, 1], math.atan2(m[1, 0], m[0, 0])
        return out

    def _to_plan(self, xyyaw_w: np.ndarray) -> np.ndarray:
        """(K, 3) simulator-world poses in the pose estimate's frame: relative to the true base,
        placed at the estimate (module docstring; the identity when the estimate is the truth)."""
        return compose(self._pose, relative(self.world.true_pose(), xyyaw_w))

    def balance(self) -> BalanceReport:
        return self.monitor.report()

    @property
    def arrived(self) -> bool:
        """At the end of a final plan, standing (``stand_policy``)."""
        return self._final and self.standing and self._plan_rows > 0

    @property
    def remaining_m(self) -> float:
        if not self.walking:
            return 0.0
        feet = self._rows[max(self._k - 1, 0):self._plan_rows, :2]
        path = 0.5 * (feet[:-1] + feet[1:])
        return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0


__all__ = ["FootstepPolicyWalker", "FootstepWalkerCfg"]
