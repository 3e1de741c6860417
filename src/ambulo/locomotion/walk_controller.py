"""Whole-body walking controller of the bundled humanoid: a walking pattern (CoM, feet) turned
into joint references by inverse kinematics, plus inverse-dynamics torque feed-forward and a
capture-point (DCM) stabilizer, sent through the humanoid's implicit PD drives.

Pipeline (per pattern sample k, dt = the pattern's sample time):

1. **Inverse kinematics** (``WalkIK``): Newton iterations on MuJoCo's Jacobians of the floating
   base and the 12 leg joints so that the whole-body CoM, the pelvis orientation (upright, yaw
   = the mean of the feet's yaws) and both sole frames (the ``left_sole``/``right_sole`` sites,
   position and orientation) hit the pattern. 18 equations in 18 unknowns: exact, no weights to
   tune. The torso and arms hold the robot's initial (``home``) pose. ``q_ref, qd_ref, qdd_ref`` follow by finite
   differences. (Written on MuJoCo's Jacobians rather than with ``mink``: with a square task set
   a Newton solve is exact and needs no QP solver dependency, and the whole pattern is solved
   offline in ~1 s.)
2. **Feed-forward torque**: inverse dynamics of the reference motion, ``M(q) qdd + h(q, qd)``,
   minus the contact wrenches that carry it. The floating base's 6 rows fix the sum of the foot
   wrenches; in double support they are split by where the reference ZMP lies between the soles
   (weighted least norm). The joint rows give the torques. Without this term the stiff PD drives
   would sag under the body weight (~30 N m on a stance hip roll against KP = 300 N m/rad: 0.1 rad
   of error) and the robot would not follow its pattern.
3. **Stabilizer** (online, each control step; ``WalkController``): the measured divergent
   component of motion ``xi = c + c_dot / omega`` is compared with the reference one and the
   CoP is asked to move to ``p_d = p_ref + k (xi - xi_ref)`` (DCM feedback, Englsberger et al.
   2015; k > 1 makes the error decay), clipped into the support polygon. The feet push it there:
   in double support mostly by moving vertical load from one sole to the other (hips and knees),
   the rest through the ankles (``dM = F_z (dp_y, -dp_x, 0)``). The stance hips also hold the
   pelvis upright in the world. The references are re-anchored to the measured stance foot, so
   foot placement errors and slips do not read as balance errors.
4. Drives: the joint targets ``(q_ref, qd_ref, tau_ff + tau_stabilizer)`` go to the humanoid's
   ``core.Entity.set_joint_targets``, whose implicit PD drives exert
   ``tau = KP (q_ref - q) + KD (qd_ref - qd) + effort``.

Nothing here touches the simulation except through those targets: no fixed base, no external
forces, no state resets. Arrays over the robot's joints are in its ``Entity``'s joint order
(``EntityNames.joint_ids``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..core import EntityNames
from ..robots import humanoid
from ..robots.humanoid import BASE_BODY, LEG_JOINTS, PRIM_PATH, SOLE_SITES
from ..utils.math import quat_from_yaw
from ..utils.validate import Checked, rule
from .balance import FootShape, lipm_omega, support_polygon
from .preview import WalkPattern

HUMANOID_FOOT = FootShape(length_m=humanoid.SOLE_LENGTH_M, width_m=humanoid.SOLE_WIDTH_M)
"""The bundled humanoid's sole (0.22 x 0.09 m box) in the frame of its ``*_sole`` site (the sole
centre on the ground): the foot frame of walking patterns for it."""

def walk_robot(model: mujoco.MjModel, prim_path: str = PRIM_PATH) -> EntityNames:
    """The humanoid's elements in ``model`` by name (``core.EntityNames``)."""
    robot = EntityNames(model, prim_path)
    if not robot.is_floating:
        raise ValueError(f"the walking controller needs the humanoid on a free joint; {prim_path} has none "
                         "(build the scene with scenes.walk_arena)")
    return robot


def _rot_error(target_mat: np.ndarray, current_mat: np.ndarray) -> np.ndarray:
    """World-frame rotation vector taking ``current`` to ``target`` (both (3, 3))."""
    rel = target_mat @ current_mat.T
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, rel.ravel())
    vel = np.empty(3)
    mujoco.mju_quat2Vel(vel, quat, 1.0)
    return vel


def _yaw_mat(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class WalkIK:
    """Whole-body IK of the humanoid for walking: CoM (3), pelvis orientation (3) and both sole
    poses (6 + 6) from the floating base (6) and the leg joints (12); see the module docstring."""

    def __init__(self, model: mujoco.MjModel, prim_path: str = PRIM_PATH):
        self.model = model
        self.data = mujoco.MjData(model)
        self.robot = robot = walk_robot(model, prim_path)
        self.root = robot.root_body_id
        """Model id of the humanoid's root body: its whole-body CoM is ``subtree_com[root]``."""
        self.pelvis = robot.body_id(BASE_BODY)
        self.sites = [robot.site_id(name) for name in SOLE_SITES]
        legs = robot.joint_model_ids([f"{side}_{j}" for side in ("left", "right") for j in LEG_JOINTS])
        self.base_dofs = robot.free_dof_adr + np.arange(6)
        """The free joint's 6 velocity addresses (linear, angular)."""
        self.base_qpos = robot.free_qpos_adr + np.arange(7)
        """The free joint's 7 position addresses (position, wxyz quaternion)."""
        self.dofs = np.concatenate([self.base_dofs, model.jnt_dofadr[legs]])  # base + legs
        self._jac = np.zeros((18, model.nv))
        self._jp, self._jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        self.last_jacobian = np.zeros((18, 18))

    def _forward(self, qpos: np.ndarray) -> None:
        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)

    def residual(self, qpos, com_w, pelvis_yaw, feet_xyzyaw) -> np.ndarray:
        """(18,) task error (target - current): CoM, pelvis rotation, left sole, right sole."""
        self._forward(qpos)
        return self._error(com_w, pelvis_yaw, feet_xyzyaw)

    def _error(self, com_w, pelvis_yaw, feet_xyzyaw) -> np.ndarray:
        d = self.data
        err = np.empty(18)
        err[0:3] = com_w - d.subtree_com[self.root]
        err[3:6] = _rot_error(_yaw_mat(pelvis_yaw), d.xmat[self.pelvis].reshape(3, 3))
        for i, site in enumerate(self.sites):
            foot = feet_xyzyaw[i]
            err[6 + 6 * i: 9 + 6 * i] = foot[:3] - d.site_xpos[site]
            err[9 + 6 * i: 12 + 6 * i] = _rot_error(_yaw_mat(foot[3]), d.site_xmat[site].reshape(3, 3))
        return err

    def _jacobian(self) -> np.ndarray:
        m, d, jac = self.model, self.data, self._jac
        mujoco.mj_jacSubtreeCom(m, d, jac[0:3], self.root)
        mujoco.mj_jacBody(m, d, self._jp, jac[3:6], self.pelvis)
        for i, site in enumerate(self.sites):
            mujoco.mj_jacSite(m, d, jac[6 + 6 * i: 9 + 6 * i], jac[9 + 6 * i: 12 + 6 * i], site)
        return jac[:, self.dofs]

    def solve(self, qpos0, com_w, pelvis_yaw, feet_xyzyaw, *, iterations: int = 20,
              tol: float = 1e-7) -> tuple[np.ndarray, float]:
        """(qpos, max |error|) after Newton steps from ``qpos0``; ``feet_xyzyaw`` (2, 4) left,
        right sole poses. ``last_jacobian`` holds the (18, 18) task Jacobian at the solution."""
        qpos = np.array(qpos0, dtype=np.float64)
        dq = np.zeros(self.model.nv)
        err = np.inf
        for _ in range(iterations):
            self._forward(qpos)
            e = self._error(com_w, pelvis_yaw, feet_xyzyaw)
            err = float(np.abs(e).max())
            jac = self._jacobian()
            if err < tol:
                break
            dq[:] = 0.0
            dq[self.dofs] = np.linalg.solve(jac.T @ jac + 1e-10 * np.eye(18), jac.T @ e)
            mujoco.mj_integratePos(self.model, qpos, dq, 1.0)
        self.last_jacobian = jac.copy()
        return qpos, err


@dataclass
class WalkReference:
    """Joint-space references of a walking pattern, K samples at ``dt_s``."""

    dt_s: float
    qpos: np.ndarray
    """(K, nq) reference configuration (floating base included)."""
    qvel: np.ndarray
    """(K, nv)."""
    qacc: np.ndarray
    """(K, nv)."""
    tau_ff: np.ndarray
    """(K, J) feed-forward joint torque (inverse dynamics minus contact wrenches), N m, in the
    robot's joint order."""
    com_to_q: np.ndarray
    """(K, 18, 3) joint change (base + legs) per unit CoM shift at each sample (IK Jacobian)."""
    ik_error: np.ndarray
    """(K,) largest task error left by the IK, m or rad."""
    contact_wrench: np.ndarray
    """(K, 2, 6) the foot wrenches (force, moment at the sole site) of the reference motion."""
    zmp_multibody: np.ndarray
    """(K, 2) ZMP of the reference motion's contact wrenches (the multi-body ZMP), m."""


def build_reference(model: mujoco.MjModel, pattern: WalkPattern, home_qpos: np.ndarray, *, ik_iterations: int = 20,
                    prim_path: str = PRIM_PATH) -> WalkReference:
    """IK of every pattern sample, finite-difference velocities and accelerations, and the
    inverse-dynamics feed-forward (module docstring, steps 1-2) of the humanoid at ``prim_path``.
    ``home_qpos`` (nq,): the robot's initial configuration (``walk_world.WalkWorld.home_qpos``), the
    IK's first guess and the pose the torso and arms hold."""
    ik = WalkIK(model, prim_path)
    num = len(pattern.time_s)
    qpos = np.empty((num, model.nq))
    com_to_q = np.empty((num, 18, 3))
    ik_err = np.empty(num)
    q = np.array(home_qpos, dtype=np.float64)
    q[ik.base_qpos[0:2]] = pattern.com_pos_w[0, :2]
    q[ik.base_qpos[3:7]] = quat_from_yaw(float(pattern.foot_pose_w[0, :, 3].mean()))
    for k in range(num):
        feet = pattern.foot_pose_w[k]
        q, ik_err[k] = ik.solve(q, pattern.com_pos_w[k], float(feet[:, 3].mean()), feet,
                                iterations=ik_iterations)
        qpos[k] = q
        com_to_q[k] = np.linalg.solve(ik.last_jacobian, np.eye(18)[:, :3])
    dt = pattern.dt_s
    qvel = np.zeros((num, model.nv))
    for k in range(num - 1):
        mujoco.mj_differentiatePos(model, qvel[k], dt, qpos[k], qpos[k + 1])
    # central differences: velocity at k from (k-1, k+1)
    vel_mid = qvel.copy()  # forward differences, i.e. velocity at k + 1/2
    qvel[1:-1] = 0.5 * (vel_mid[:-2] + vel_mid[1:-1])
    qvel[0] = qvel[-1] = 0.0
    qacc = np.zeros_like(qvel)
    qacc[1:-1] = (vel_mid[1:-1] - vel_mid[:-2]) / dt

    data = mujoco.MjData(model)
    sites = ik.sites
    joint_dofs = model.jnt_dofadr[ik.robot.joint_ids]
    tau_ff = np.zeros((num, len(joint_dofs)))
    wrench = np.zeros((num, 2, 6))
    zmp = np.full((num, 2), np.nan)
    jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    rne = np.zeros(model.nv)
    for k in range(num):
        data.qpos[:], data.qvel[:], data.qacc[:] = qpos[k], qvel[k], qacc[k]
        mujoco.mj_fwdPosition(model, data)
        mujoco.mj_fwdVelocity(model, data)
        mujoco.mj_rne(model, data, 1, rne)
        feet = np.flatnonzero(pattern.foot_contact[k])
        jacs, weights = [], []
        for i in feet:
            mujoco.mj_jacSite(model, data, jp, jr, sites[i])
            jacs.append(np.vstack([jp, jr]).copy())
            weights.append(_load_share(pattern, k, i) if len(feet) == 2 else 1.0)
        jc = np.vstack(jacs)  # (6 n, nv)
        a = jc[:, ik.base_dofs].T  # base rows of J^T: (6, 6 n)
        w_inv = np.repeat(np.maximum(np.asarray(weights), 1e-3), 6)
        f = w_inv * (a.T @ np.linalg.solve((a * w_inv) @ a.T, rne[ik.base_dofs]))
        tau = rne - jc.T @ f
        tau_ff[k] = tau[joint_dofs]
        for j, i in enumerate(feet):
            wrench[k, i] = f[6 * j: 6 * j + 6]
        # multi-body ZMP: CoP of the contact wrenches on the ground z = 0
        force, moment = np.zeros(3), np.zeros(3)
        for j, i in enumerate(feet):
            fj, mj = f[6 * j: 6 * j + 3], f[6 * j + 3: 6 * j + 6]
            force += fj
            moment += np.cross(data.site_xpos[sites[i]], fj) + mj
        if force[2] > 1e-6:
            zmp[k] = (-moment[1] / force[2], moment[0] / force[2])
    return WalkReference(dt_s=dt, qpos=qpos, qvel=qvel, qacc=qacc, tau_ff=tau_ff, com_to_q=com_to_q,
                         ik_error=ik_err, contact_wrench=wrench, zmp_multibody=zmp)


def _load_share(pattern: WalkPattern, k: int, foot: int) -> float:
    """Share of the weight on ``foot`` in double support: where the reference ZMP lies on the
    segment between the two soles (1 on this sole, 0 on the other)."""
    here, other = pattern.foot_pose_w[k, foot, :2], pattern.foot_pose_w[k, 1 - foot, :2]
    seg = here - other
    t = float(np.dot(pattern.zmp_ref_xy[k] - other, seg) / max(np.dot(seg, seg), 1e-12))
    return min(max(t, 0.0), 1.0)


@dataclass(kw_only=True)
class StabilizerCfg(Checked):
    """Capture-point (DCM) feedback through the stance feet's moments (module docstring, step 3)."""

    zmp_gain: float = 2.0
    """k in ``p_d = p_ref + k (xi - xi_ref)``; > 1 makes the capture-point error decay at
    ``omega (k - 1)``."""
    cop_margin_m: float = 0.015
    """The commanded CoP stays this far inside the support polygon, m."""
    attitude_kp: float = 150.0
    """Pelvis roll/pitch feedback through the stance hips, N m/rad (world-frame attitude)."""
    attitude_kd: float = 15.0
    """N m s/rad."""
    load_transfer: bool = True
    """In double support, shift the CoP across the feet by moving vertical load between them."""
    min_sole_load_n: float = 30.0
    """... leaving each sole at least this much of its reference load, N."""
    reanchor: bool = True
    """Express the reference in the frame of the measured stance foot (see ``WalkController``)."""
    reanchor_time_s: float = field(default=0.05, metadata=rule(minimum=0.0))
    """Time constant with which the reference frame follows the stance foot, s."""
    enabled: bool = True


class WalkController:
    """Drives the humanoid along a ``WalkReference``: ``targets(data, k)`` each control step.

    The stabilizer asks for the CoP ``p_d = p_ref + k (xi - xi_ref)`` (xi measured from the
    simulated CoM state, as an ideal state estimator would give it; p_ref the reference motion's
    multi-body ZMP), clipped into the support polygon, and makes the feet push it there: the
    ground moment that moves the CoP by ``dp`` under the vertical load ``F_z`` is
    ``dM = F_z (dp_y, -dp_x, 0)``, and the stance legs' joints get ``-J_sole^T (0, dM)`` (the
    torques that transmit that moment from the ground to the body with the legs held still),
    split between the feet by their load share in double support.

    Re-anchoring: feet land a few mm or a fraction of a degree off their plan and may slip, so
    over a walk the robot drifts from the pattern's world frame. The joint references do not
    care (the pattern is invariant under a horizontal rigid motion), but the stabilizer's
    world-frame references do: a 2 cm drift would read as a 2 cm CoM error and push the CoP to
    the edge of the sole. So in single support the planar transform (rotation about z, shift)
    taking the stance foot's planned pose to its measured pose is followed (time constant
    ``reanchor_time_s``) and held through double support, and the CoM, capture-point, ZMP and
    attitude references are taken through it; the support polygon is that of the measured soles.
    """

    def __init__(self, model: mujoco.MjModel, pattern: WalkPattern, reference: WalkReference,
                 stabilizer: StabilizerCfg | None = None, prim_path: str = PRIM_PATH):
        self.model, self.pattern, self.ref = model, pattern, reference
        self.robot = robot = walk_robot(model, prim_path)
        self.root = robot.root_body_id
        self.base_qpos = robot.free_qpos_adr + np.arange(7)
        self.base_dofs = robot.free_dof_adr + np.arange(6)
        self.cfg = stabilizer or StabilizerCfg()
        self.omega = lipm_omega(float(pattern.com_pos_w[0, 2] - pattern.foot_pose_w[0, :, 2].mean()))
        joints = robot.joint_ids  # the Entity's joint order: the order of every target
        self.joint_qpos = model.jnt_qposadr[joints]
        self.joint_dofs = model.jnt_dofadr[joints]
        self.dof_joint = np.full(model.nv, -1)
        """Velocity address -> index into the robot's joints (-1: not a joint of it)."""
        self.dof_joint[self.joint_dofs] = np.arange(len(joints))
        self.sites = [robot.site_id(name) for name in SOLE_SITES]
        self.pelvis = robot.body_id(BASE_BODY)
        sides = ("left", "right")
        self.ankle_joints = [robot.joint_model_ids([f"{s}_ankle_{a}" for a in ("pitch", "roll")]).tolist()
                             for s in sides]
        self.hip_joints = [robot.joint_model_ids([f"{s}_hip_{a}" for a in ("roll", "pitch")]).tolist() for s in sides]
        self.joint_index = {int(j): i for i, j in enumerate(joints)}
        """Model joint id -> index into the robot's joints."""
        self.leg_dofs = [model.jnt_dofadr[robot.joint_model_ids([f"{s}_{j}" for j in LEG_JOINTS])] for s in sides]
        self._jp, self._jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        self.cop_cmd = np.zeros(2)
        self.cop_shift = np.zeros(2)
        self.anchor = np.zeros(3)
        """(yaw rad, x m, y m) of the planar transform from the pattern's frame to the measured one."""

    def _anchor_rot(self) -> np.ndarray:
        c, s = math.cos(self.anchor[0]), math.sin(self.anchor[0])
        return np.array([[c, -s], [s, c]])

    def to_measured(self, xy: np.ndarray) -> np.ndarray:
        """Pattern-frame points (..., 2) in the re-anchored (measured) frame."""
        return xy @ self._anchor_rot().T + self.anchor[1:]

    def _sole(self, data: mujoco.MjData, i: int) -> np.ndarray:
        mat = data.site_xmat[self.sites[i]]
        return np.array([data.site_xpos[self.sites[i]][0], data.site_xpos[self.sites[i]][1], math.atan2(mat[3], mat[0])])

    def _update_anchor(self, data: mujoco.MjData, k: int) -> None:
        feet = np.flatnonzero(self.pattern.foot_contact[k])
        if not self.cfg.reanchor or len(feet) != 1:
            return
        planned = self.pattern.foot_pose_w[k, feet[0]][[0, 1, 3]]
        measured = self._sole(data, int(feet[0]))
        yaw = math.remainder(measured[2] - planned[2], 2 * math.pi)
        c, s = math.cos(yaw), math.sin(yaw)
        shift = measured[:2] - np.array([[c, -s], [s, c]]) @ planned[:2]
        target = np.array([yaw, shift[0], shift[1]])
        self.anchor += min(1.0, self.ref.dt_s / max(self.cfg.reanchor_time_s, 1e-9)) * (target - self.anchor)

    def dcm_error(self, data: mujoco.MjData, k: int) -> np.ndarray:
        """(2,) measured minus reference capture point (reference re-anchored), m (needs
        ``mj_subtreeVel`` on ``data``)."""
        p = self.pattern
        e_c = data.subtree_com[self.root, :2] - self.to_measured(p.com_pos_w[k, :2])
        e_v = data.subtree_linvel[self.root, :2] - self._anchor_rot() @ p.com_vel_w[k, :2]
        return e_c + e_v / self.omega

    def targets(self, data: mujoco.MjData, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint targets for sample ``k`` (clamped to the pattern's length): position (rad),
        velocity (rad/s) and effort (N m), each (J,) in the robot's joint order, for
        ``Entity.set_joint_targets``. ``data``'s derived fields must describe its state (after
        ``mj_forward``, as ``engine.get_data`` gives it); runs ``mj_subtreeVel`` on it."""
        k = min(k, len(self.ref.qpos) - 1)
        ref, cfg, pat = self.ref, self.cfg, self.pattern
        pos, vel, effort = ref.qpos[k][self.joint_qpos], ref.qvel[k][self.joint_dofs], ref.tau_ff[k].copy()
        m = self.model
        if not cfg.enabled:
            return pos, vel, effort
        mujoco.mj_subtreeVel(m, data)
        self._update_anchor(data, k)
        p_ref = self.to_measured(ref.zmp_multibody[k])
        p_d = p_ref + cfg.zmp_gain * self.dcm_error(data, k)
        feet = np.flatnonzero(pat.foot_contact[k])
        poly = support_polygon([self._sole(data, int(i)) for i in feet], pat.foot)
        p_d = _clip_into(p_d, poly, cfg.cop_margin_m)
        self.cop_cmd, self.cop_shift = p_d, p_d - p_ref
        f_z = float(ref.contact_wrench[k, :, 2].sum())
        d_moment = f_z * np.array([self.cop_shift[1], -self.cop_shift[0], 0.0])
        share = ref.contact_wrench[k, feet, 2] / max(f_z, 1e-9)
        # pelvis attitude error (world frame rotation vector) and angular velocity
        rot_ref = np.empty(9)
        mujoco.mju_quat2Mat(rot_ref, ref.qpos[k][self.base_qpos[3:7]])
        rot_ref = (_yaw_mat(float(self.anchor[0])) @ rot_ref.reshape(3, 3)).ravel()
        att_err = _rot_error(rot_ref.reshape(3, 3), data.xmat[self.pelvis].reshape(3, 3))
        omega_w = data.xmat[self.pelvis].reshape(3, 3) @ data.qvel[self.base_dofs[3:6]]
        omega_ref_w = rot_ref.reshape(3, 3) @ ref.qvel[k][self.base_dofs[3:6]]
        moment_pelvis = cfg.attitude_kp * att_err + cfg.attitude_kd * (omega_ref_w - omega_w)
        moment_pelvis[2] = 0.0  # yaw stays with the hip-yaw PD
        if len(feet) == 2 and cfg.load_transfer:
            d_moment = self._transfer_load(data, effort, d_moment, ref.contact_wrench[k, :, 2])
        for i, w in zip(feet, share):
            for j in self.ankle_joints[i]:  # the ankle pushes the foot against the ground: -dM on it
                effort[self.joint_index[j]] -= float(data.xaxis[j] @ (w * d_moment))
            for j in self.hip_joints[i]:  # the hip turns the pelvis: -tau on the parent
                effort[self.joint_index[j]] -= float(data.xaxis[j] @ (w * moment_pelvis))
        return pos, vel, effort

    def _transfer_load(self, data: mujoco.MjData, effort: np.ndarray, d_moment: np.ndarray,
                       loads_n: np.ndarray) -> np.ndarray:
        """Double support: realize the part of ``d_moment`` about the axis across the feet by
        moving vertical load from one sole to the other (``+dF`` on the left, ``-dF`` on the right
        give ``dF (d_y, -d_x, 0)`` with d = left - right), through the legs' joint torques
        ``-J_sole^T f``; return the rest, for the ankles. A sole's own CoP can move only half the
        sole's width, so across the feet the ankles alone cannot shift the CoP far."""
        m = self.model
        d = data.site_xpos[self.sites[0]][:2] - data.site_xpos[self.sites[1]][:2]
        lever = np.array([d[1], -d[0], 0.0])
        d_force = float(d_moment @ lever) / max(float(lever @ lever), 1e-9)
        keep = self.cfg.min_sole_load_n
        d_force = min(max(d_force, -(loads_n[0] - keep)), loads_n[1] - keep) if loads_n.min() > keep else 0.0
        for i, f in ((0, d_force), (1, -d_force)):
            mujoco.mj_jacSite(m, data, self._jp, self._jr, self.sites[i])
            gen = self._jp[2] * f  # generalized force of a vertical ground force f on sole i
            dofs = self.leg_dofs[i]
            effort[self.dof_joint[dofs]] -= gen[dofs]
        return d_moment - d_force * lever


def _clip_into(point: np.ndarray, polygon: np.ndarray, margin_m: float) -> np.ndarray:
    """The point, or if it lies less than ``margin_m`` inside the convex polygon, the nearest
    point of the polygon shrunk by the margin (approximately: pulled towards the centroid)."""
    from .balance import polygon_signed_distance

    if polygon_signed_distance(point, polygon) >= margin_m:
        return point
    center = polygon.mean(axis=0)
    lo, hi = 0.0, 1.0  # bisection on the segment centre -> point
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        if polygon_signed_distance(center + mid * (point - center), polygon) >= margin_m:
            lo = mid
        else:
            hi = mid
    return center + lo * (point - center)


__all__ = ["HUMANOID_FOOT", "walk_robot", "WalkIK", "WalkReference", "build_reference", "StabilizerCfg",
           "WalkController"]
