"""Leg-inertial odometry: where the pelvis went, from the joint encoders and the head gyro alone.

    legs = LegOdometry()
    legs.reset(world)                     # starts at the world's pose now (as the VO does)
    every physics step: legs.update()     # after world.step()
    legs.xyyaw, legs.distance_m

What a humanoid bridges visual-odometry gaps with (kinematic odometry: Bloesch et al. 2013, *State
Estimation for Legged Robots*, RSS; the kinematics-only form here, no Kalman filter). Per update:

1. **attitude**: the head gyro's newest reading (``NavWorld.gyro``, with its noise model), less the
   bias estimate (``gyro_bias_rad_s``: the VO's, set by the fused localizer), turns the IMU's
   orientation, ``R_w_imu <- R_w_imu exp((w - b) dt)`` (MuJoCo's ``mju_quatIntegrate``). Roll and
   pitch come from the same integration (an AHRS's job; a VO fix re-anchors the whole attitude,
   ``anchor``). The pelvis's orientation is ``R_w_imu R_pelvis_imu^T``, the last from kinematics
   (the torso's three hinges sit between pelvis and head).
2. **kinematics**: a private ``MjData`` of the world's model holds the robot's hinge joints at the
   encoder angles and its free joint at the identity, so ``mj_kinematics`` gives the soles and the
   IMU in the pelvis frame. The free joint's state (the true base pose) is never read after ``reset``.
3. **stance**: the planted sole; the swing sole takes over when it is lower along gravity
   (``stance_switch_m``) and has stopped over the ground (``touchdown_speed_m_s``, at the pelvis
   velocity estimate), or is much lower (``forced_switch_m``).
4. **displacement**: a planted sole stays where it is in the world, so the pelvis moves by minus
   the change of the sole's position relative to it (world axes). While the stance sole itself
   slides over the ground (the policy's gait has a ~50 ms flight phase and lands sliding), the
   pelvis coasts at its low-passed velocity instead (``slip_speed_m_s``). Without the coasting
   the odometry lost 11-12 % of the distance walked; pinning the pelvis to the lower sole alone, 20 %
   (apartments 200-201, true attitude).

Drift on two recorded oracle policy walks (apartments 200 and 201, 3.6 m and 5.8 m): 2.0-2.3 % of
the distance with the true attitude, 2.4-2.5 % with the gyro's bias removed, 7-8 % and 3-6 deg/m
of yaw on the raw gyro (its turn-on bias was ~1 deg/s about yaw). The fused localizer therefore
hands the legs the VO's bias estimate and attitude at every fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..robots import humanoid
from ..utils.validate import Checked
from .world import NavWorld


@dataclass(kw_only=True)
class LegOdometryCfg(Checked):
    """The stance rules' thresholds, chosen on policy walks in apartments 200-201 (the benchmark's
    held-out seeds are 0-99): the figures in the module docstring."""

    stance_switch_m: float = 0.005
    """The swing sole must be this much lower than the stance sole (along gravity), and slow
    (``touchdown_speed_m_s``), to become the stance foot, m: the soles are within ~1 mm in double
    support, a swing lifts 3-5 cm."""
    touchdown_speed_m_s: float = 0.3
    """A landing sole slower than this over the ground (at the pelvis velocity estimate) is down:
    the policy lands at 1-2 m/s and slides 20-50 ms before it grips."""
    forced_switch_m: float = 0.02
    """A swing sole this much lower than the stance sole is the stance foot whatever its speed, m."""
    slip_speed_m_s: float = 0.3
    """A stance sole moving faster than this over the ground is slipping or in flight (the policy's
    gait has a ~50 ms flight phase): the pelvis coasts at its velocity estimate instead, m/s."""
    velocity_time_constant_s: float = 0.2
    """Low-pass time constant of the pelvis velocity estimate (about half a stride), s."""


class LegOdometry:
    """Kinematic odometry of the pelvis (module docstring). ``xyyaw``: (3,) x m, y m, yaw rad, world."""

    def __init__(self, cfg: LegOdometryCfg | None = None):
        self.cfg = cfg or LegOdometryCfg()
        self.gyro_bias_rad_s = np.zeros(3)
        """(3,) gyro bias subtracted from the readings, IMU frame, rad/s (the VO's estimate)."""

    def reset(self, world: NavWorld) -> None:
        """Start at the robot's pose now (the one read of the true state: the VO starts there too)."""
        self.world = world
        model = world.model
        robot = world.robot
        self._data = mujoco.MjData(model)
        self._enc_adr = model.jnt_qposadr[robot.names.joint_ids]
        """qpos addresses of the robot's hinge joints, in ``robot.joint_names`` order (the encoders)."""
        free = robot.names.free_qpos_adr
        self._data.qpos[free:free + 7] = [0, 0, 0, 1, 0, 0, 0]  # pelvis at the origin: FK in its frame
        prefix = humanoid.PRIM_PATH + "/"
        self._soles = [model.site(prefix + s).id for s in humanoid.SOLE_SITES]
        self._imu = model.site(world.imu.site_name).id
        self._kinematics(robot.data.joint_pos[0].cpu().numpy())
        true = world.engine.get_data(0)
        rot_w_imu = true.site_xmat[self._imu].reshape(3, 3)
        self.quat_w_imu = np.zeros(4)
        mujoco.mju_mat2Quat(self.quat_w_imu, rot_w_imu.ravel())
        pelvis = true.xpos[model.body(prefix + humanoid.BASE_BODY).id]
        self.pelvis_w_m = np.array(pelvis, float)
        """(3,) the pelvis position estimate, world frame, m."""
        self.rot_w_pelvis = self._pelvis_rotation()
        sole_w = self._sole_p @ self.rot_w_pelvis.T
        self.stance = int(np.argmin(sole_w[:, 2]))
        """0: left sole planted, 1: right."""
        self._ground_z_m = float(self.pelvis_w_m[2] + sole_w[self.stance, 2])
        self._sole_w_rel = sole_w
        """(2, 3) the soles relative to the pelvis, world axes, at the last update, m."""
        self.vel_w_m_s = np.zeros(2)
        """(2,) horizontal pelvis velocity estimate, world frame, m/s."""
        gyro = world.gyro.latest()
        self._gyro_time_s = gyro[0] if gyro is not None else world.time_s
        self._joint_time_s = world.time_s
        self._held: tuple[np.ndarray, float] | None = None
        self.distance_m = 0.0
        """Horizontal path length of the estimate since ``reset``, m (what drift is quoted against)."""
        self.switches = 0
        self.coasted_steps = 0
        """Updates on which the stance sole slid and the pelvis coasted."""

    # -- the estimate ----------------------------------------------------------------------------
    @property
    def xyyaw(self) -> np.ndarray:
        r = self.rot_w_pelvis
        return np.array([self.pelvis_w_m[0], self.pelvis_w_m[1], math.atan2(r[1, 0], r[0, 0])])

    def pose_w_imu(self) -> np.ndarray:
        """(4, 4) the IMU's (head's) pose in the world by the legs: what the VO's motion prior is
        made of."""
        out = np.eye(4)
        out[:3, :3] = self._rot_w_imu()
        out[:3, 3] = self.pelvis_w_m + self.rot_w_pelvis @ self._imu_p
        return out

    def pose_pelvis_imu(self) -> np.ndarray:
        """(4, 4) the IMU's (head's) pose in the pelvis frame at the encoders' angles: what turns a
        head pose (the VO's) into a pelvis pose through the torso's joints."""
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = self._rot_pelvis_imu, self._imu_p
        return out

    def anchor(self, rot_w_imu: np.ndarray) -> None:
        """Take the IMU's orientation from a better source (a VO fix): the attitude's drift since the
        last fix is dropped; the position goes on from where the legs have it."""
        mujoco.mju_mat2Quat(self.quat_w_imu, np.asarray(rot_w_imu, float).ravel())
        self.rot_w_pelvis = self._pelvis_rotation()
        self._sole_w_rel = self._sole_p @ self.rot_w_pelvis.T

    # -- one update ----------------------------------------------------------------------------
    def update(self) -> None:
        """Read the encoders and the gyro's newest reading, then ``step`` (call it after every
        ``world.step()``). The world samples the gyro at the start of its next step, so the newest
        reading covers the step before last: the encoders are held one update to pair with it."""
        w = self.world
        gyro = w.gyro.latest()
        held, self._held = self._held, (w.robot.data.joint_pos[0].cpu().numpy(), w.time_s)
        if held is not None:
            self.step(*held, *(gyro if gyro is not None else (None, None)))

    def step(self, joint_pos: np.ndarray, time_s: float, gyro_time_s: float | None = None,
             gyro_rad_s: np.ndarray | None = None) -> None:
        """Integrate a gyro reading (skipped when not newer than the last) and move the pelvis with
        the planted sole. ``joint_pos``: (J,) encoder angles in ``robot.joint_names`` order, rad,
        read at ``time_s``."""
        c = self.cfg
        if gyro_time_s is not None and gyro_time_s > self._gyro_time_s:
            mujoco.mju_quatIntegrate(self.quat_w_imu, np.asarray(gyro_rad_s, float) - self.gyro_bias_rad_s,
                                     gyro_time_s - self._gyro_time_s)
            mujoco.mju_normalize4(self.quat_w_imu)
            self._gyro_time_s = gyro_time_s
        dt_s = time_s - self._joint_time_s
        if dt_s <= 0:
            return
        self._joint_time_s = time_s
        self._kinematics(joint_pos)
        self.rot_w_pelvis = self._pelvis_rotation()
        sole_w = self._sole_p @ self.rot_w_pelvis.T
        moved = -(sole_w - self._sole_w_rel)[:, :2]  # (2, 2) pelvis displacement if that sole is planted
        self._sole_w_rel = sole_w
        speed = np.linalg.norm(self.vel_w_m_s - moved / dt_s, axis=1)  # each sole's ground speed, m/s
        s, o = self.stance, 1 - self.stance
        lower_by = sole_w[s, 2] - sole_w[o, 2]
        if (lower_by > c.stance_switch_m and speed[o] < c.touchdown_speed_m_s) or lower_by > c.forced_switch_m:
            self.stance, s = o, o
            self.switches += 1
        step = moved[s]
        if speed[s] > c.slip_speed_m_s:
            step = self.vel_w_m_s * dt_s
            self.coasted_steps += 1
        self.pelvis_w_m[:2] += step
        self.pelvis_w_m[2] = self._ground_z_m - sole_w[s, 2]
        self.vel_w_m_s += min(1.0, dt_s / c.velocity_time_constant_s) * (step / dt_s - self.vel_w_m_s)
        self.distance_m += float(np.hypot(*step))

    def _kinematics(self, joint_pos: np.ndarray) -> None:
        """Soles and IMU in the pelvis frame at the encoders' angles."""
        d = self._data
        d.qpos[self._enc_adr] = joint_pos
        mujoco.mj_kinematics(self.world.model, d)
        self._sole_p = d.site_xpos[self._soles].copy()
        self._imu_p = d.site_xpos[self._imu].copy()
        self._rot_pelvis_imu = d.site_xmat[self._imu].reshape(3, 3).copy()

    def _rot_w_imu(self) -> np.ndarray:
        out = np.zeros(9)
        mujoco.mju_quat2Mat(out, self.quat_w_imu)
        return out.reshape(3, 3)

    def _pelvis_rotation(self) -> np.ndarray:
        return self._rot_w_imu() @ self._rot_pelvis_imu.T


__all__ = ["LegOdometry", "LegOdometryCfg"]
