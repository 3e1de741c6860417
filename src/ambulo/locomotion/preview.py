"""Walking patterns by ZMP preview control (Kajita et al., *Biped walking pattern generation by
using preview control of zero-moment point*, ICRA 2003).

The CoM is a cart on a table of height z_c (the LIPM). Per horizontal axis the discrete model
with sample time T and the CoM jerk u as input is (Kajita 2003, Sec. III)::

    x(k+1) = A x(k) + B u(k),  x = (c, c_dot, c_ddot)     A = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]]
    p(k)   = C x(k)                                      B = (T^3/6, T^2/2, T),  C = (1, 0, -z_c/g)

which is exact for a jerk held constant over each sample. The preview controller (Katayama et
al. 1985, as used by Kajita) minimises ``sum Qe (p - p_ref)^2 + R du^2`` over an augmented
system of the integrated ZMP error and the state increments, whose Riccati solution gives::

    u(k) = -Gi sum_{i<=k} (p(i) - p_ref(i)) - Gx x(k) - sum_{j=1..N} Gp(j) p_ref(k + j)

with N = preview time / T, plus a tail term that treats the reference as constant beyond the
window (``PreviewGains.tail_gain``). ``WalkPatternGenerator`` turns a footstep plan into the reference
ZMP (on the stance sole during single support, moving linearly between soles during double
support), runs the controller on x and y, and adds swing-foot trajectories.

Frames and units: world frame (z up), m, s, rad. The CoM height z_c is constant.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg

from ..utils.validate import Checked
from .balance import GRAVITY_MPS2, FootShape, support_polygon


# --------------------------------------------------------------------------- configs
@dataclass(kw_only=True)
class PreviewControlCfg(Checked):
    """ZMP preview controller of a cart-table model."""

    com_height_m: float
    """z_c: height of the CoM above the ground, m (robot-specific)."""
    dt_s: float = 0.005
    """Sample time T, s (Kajita 2003: 5 ms)."""
    preview_time_s: float = 2.0
    """How far the controller looks ahead, s. Kajita 2003 uses 1.6 s; the gains decay with a time
    constant ~ 1/omega (0.29 s at z_c = 0.814 m), and the preview gain mass left beyond the window
    is 0.4 % of Gx[0] at 1.6 s, 0.1 % at 2.0 s. Measured on a 0.25 m-step walk at z_c = 0.814 m
    (tests/nav/test_preview.py): the CoM deviates from the closed-form LIPM over single support
    by 2.9 mm with 1.6 s and 0.5 mm with 2.0 s, hence 2.0 s."""
    zmp_error_weight: float = 1.0
    """Qe, weight of the squared ZMP tracking error, 1/m^2 (Kajita 2003: 1)."""
    jerk_weight: float = 1.0e-6
    """R, weight of the squared jerk increment, s^6/m^2 (Kajita 2003: 1e-6)."""
    gravity_mps2: float = GRAVITY_MPS2


@dataclass(kw_only=True)
class WalkPatternCfg(Checked):
    """Step timing and swing shape of a walking pattern, with its preview controller."""

    preview: PreviewControlCfg
    foot: FootShape
    """Sole shape (ZMP reference at its centre; support polygons)."""
    single_support_s: float
    """Duration of a swing, s."""
    double_support_s: float
    """Duration of the transfer between soles, s (the ZMP reference moves linearly)."""
    swing_height_m: float
    """Apex of the swing foot above the straight line between lift-off and touch-down, m."""
    stand_before_s: float = 2.0
    """Standing time before the first step (ZMP between the feet), s. At least the preview time,
    so the first transfer enters the preview window gradually instead of all at once at t = 0
    (which forces a ZMP jump of several cm to start the CoM moving)."""
    stand_after_s: float = 1.0
    """Standing time after the last step, ZMP back between the feet, s."""


def kajita2003_preview_cfg() -> PreviewControlCfg:
    """The parameters of Kajita et al. 2003's simulation: z_c = 0.814 m, T = 5 ms, Qe = 1,
    R = 1e-6, 1.6 s preview."""
    return PreviewControlCfg(com_height_m=0.814, dt_s=0.005, preview_time_s=1.6,
                             zmp_error_weight=1.0, jerk_weight=1.0e-6)


def walk_pattern_cfg(*, com_height_m: float, foot: FootShape, step_time_s: float = 0.8,
                     double_support_ratio: float = 0.2, swing_height_m: float = 0.05,
                     preview_time_s: float = 2.0, zmp_error_weight: float = 1.0,
                     jerk_weight: float = 1.0e-6, dt_s: float = 0.005,
                     stand_before_s: float = 2.0, stand_after_s: float = 1.0) -> WalkPatternCfg:
    """A walking pattern config from one step's total time (single + double support) and the
    share of it in double support."""
    if not 0.0 < double_support_ratio < 1.0:
        raise ValueError(f"double_support_ratio must be in (0, 1), got {double_support_ratio}")
    double = step_time_s * double_support_ratio
    preview = PreviewControlCfg(com_height_m=com_height_m, dt_s=dt_s, preview_time_s=preview_time_s,
                                zmp_error_weight=zmp_error_weight, jerk_weight=jerk_weight)
    return WalkPatternCfg(preview=preview, foot=foot, single_support_s=step_time_s - double,
                          double_support_s=double, swing_height_m=swing_height_m,
                          stand_before_s=stand_before_s, stand_after_s=stand_after_s)


# --------------------------------------------------------------------------- controller
def cart_table_model(com_height_m: float, dt_s: float,
                     gravity_mps2: float = GRAVITY_MPS2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete cart-table model (A (3, 3), B (3,), C (3,)), state (c m, c_dot m/s, c_ddot
    m/s^2), input jerk m/s^3, output ZMP m; see the module docstring."""
    t = dt_s
    a = np.array([[1.0, t, t * t / 2.0], [0.0, 1.0, t], [0.0, 0.0, 1.0]])
    b = np.array([t**3 / 6.0, t * t / 2.0, t])
    c = np.array([1.0, 0.0, -com_height_m / gravity_mps2])
    return a, b, c


@dataclass(frozen=True)
class PreviewGains:
    """Gains of ``u(k) = -Gi sum e - Gx x(k) - sum_j Gp(j) p_ref(k + j) - tail p_ref(k + N)``."""

    integral_gain: float
    """Gi, jerk per summed ZMP error, 1/s^3."""
    state_gain: np.ndarray
    """(3,) Gx on (c, c_dot, c_ddot)."""
    preview_gain: np.ndarray
    """(N,) Gp(j), j = 1..N, on the reference ZMP j samples ahead, 1/s^3."""
    tail_gain: float
    """``sum_{j>N} Gp(j) = -(Gx[0] + sum_{j<=N} Gp(j))``, 1/s^3: the infinite-horizon gains
    beyond the window, applied to the last previewed reference p_ref(k + N) (the reference is
    taken as constant beyond the window). Without it a truncated preview is not translation
    invariant: holding a constant ZMP at distance d from the origin would need an integral
    error ~ d (Gx[0] + sum Gp) / Gi, i.e. a transient that grows with d."""


def preview_gains(cfg: PreviewControlCfg) -> PreviewGains:
    """Optimal preview gains from the discrete algebraic Riccati equation of the augmented
    system X = (e, dx): A~ = [[1, C A], [0, A]], B~ = (C B, B), Q~ = diag(Qe, 0, 0, 0)
    (Katayama 1985). With K = (R + B~' P B~)^-1 B~' P A~ = (Gi, Gx) and Ac = A~ - B~ K:
    Gp(1) = -Gi, Gp(j) = (R + B~' P B~)^-1 B~' X(j-1), X(1) = -Ac' P (1, 0, 0, 0),
    X(j) = Ac' X(j-1)."""
    a, b, c = cart_table_model(cfg.com_height_m, cfg.dt_s, cfg.gravity_mps2)
    a_aug = np.zeros((4, 4))
    a_aug[0, 0] = 1.0
    a_aug[0, 1:] = c @ a
    a_aug[1:, 1:] = a
    b_aug = np.concatenate([[c @ b], b])[:, None]
    q_aug = np.diag([cfg.zmp_error_weight, 0.0, 0.0, 0.0])
    r = np.array([[cfg.jerk_weight]])
    p = scipy.linalg.solve_discrete_are(a_aug, b_aug, q_aug, r)
    inv = 1.0 / (cfg.jerk_weight + float(b_aug[:, 0] @ p @ b_aug[:, 0]))
    k = inv * (b_aug.T @ p @ a_aug)[0]
    a_cl = a_aug - b_aug @ k[None, :]
    horizon = max(1, round(cfg.preview_time_s / cfg.dt_s))
    gains = np.empty(horizon)
    gains[0] = -k[0]
    x = -a_cl.T @ p[:, 0]
    for j in range(1, horizon):
        gains[j] = inv * float(b_aug[:, 0] @ x)
        x = a_cl.T @ x
    tail = -(k[1] + gains.sum())  # the infinite preview sums to -Gx[0]: the equilibrium c = p needs u = 0
    return PreviewGains(integral_gain=float(k[0]), state_gain=k[1:].copy(), preview_gain=gains, tail_gain=float(tail))


@dataclass(frozen=True)
class CartTableTrajectory:
    """Samples k = 0..K-1 at t = k T of the cart-table state under preview control."""

    com_pos: np.ndarray
    """(K, D) CoM position along each axis, m."""
    com_vel: np.ndarray
    """(K, D) m/s."""
    com_acc: np.ndarray
    """(K, D) m/s^2."""
    zmp: np.ndarray
    """(K, D) cart-table ZMP C x(k), m."""
    jerk: np.ndarray
    """(K, D) the jerk applied over [k T, (k+1) T), m/s^3."""


class PreviewController:
    """Kajita's ZMP preview controller on independent axes (the gains are shared)."""

    def __init__(self, cfg: PreviewControlCfg):
        self.cfg = cfg
        self.a, self.b, self.c = cart_table_model(cfg.com_height_m, cfg.dt_s, cfg.gravity_mps2)
        self.gains = preview_gains(cfg)

    @property
    def horizon(self) -> int:
        """N, preview samples."""
        return len(self.gains.preview_gain)

    def preview_term(self, zmp_ref) -> np.ndarray:
        """(K, D) ``sum_{j<=N} Gp(j) p_ref(k + j) + tail_gain p_ref(k + N)`` for every k of a
        (K, D) reference, the reference held at its last value beyond its end."""
        ref = np.asarray(zmp_ref, dtype=np.float64)
        n = self.horizon
        padded = np.concatenate([ref, np.repeat(ref[-1:], n, axis=0)], axis=0)
        windows = np.lib.stride_tricks.sliding_window_view(padded[1:], n, axis=0)[: len(ref)]  # (K, D, N)
        return windows @ self.gains.preview_gain + self.gains.tail_gain * windows[..., -1]

    def simulate(self, zmp_ref, com_state0=None) -> CartTableTrajectory:
        """Track a reference ZMP.

        Args:
          zmp_ref: (K, D) reference ZMP per sample and axis (or (K,)), m.
          com_state0: (3, D) initial (c, c_dot, c_ddot); default rest over the first reference
            point, the equilibrium of a constant reference.
        """
        ref = np.asarray(zmp_ref, dtype=np.float64)
        squeeze = ref.ndim == 1
        ref = ref[:, None] if squeeze else ref
        if ref.ndim != 2 or len(ref) == 0 or not np.all(np.isfinite(ref)):
            raise ValueError(f"zmp_ref must be a finite (K, D) array, got shape {ref.shape}")
        x = np.zeros((3, ref.shape[1]))
        if com_state0 is None:
            x[0] = ref[0]
        else:
            x[:] = np.asarray(com_state0, dtype=np.float64).reshape(3, -1)
        feedforward = self.preview_term(ref)
        gi, gx = self.gains.integral_gain, self.gains.state_gain
        states, jerks = np.empty((len(ref), 3, ref.shape[1])), np.empty_like(ref)
        error_sum = np.zeros(ref.shape[1])
        for k in range(len(ref)):
            states[k] = x
            error_sum += self.c @ x - ref[k]
            u = -gi * error_sum - gx @ x - feedforward[k]
            jerks[k] = u
            x = self.a @ x + np.outer(self.b, u)
        zmp = np.einsum("i,kid->kd", self.c, states)
        out = [states[:, 0], states[:, 1], states[:, 2], zmp, jerks]
        if squeeze:
            out = [o[:, 0] for o in out]
        return CartTableTrajectory(*out)


# --------------------------------------------------------------------------- footsteps
# Sides are +1 (left) and -1 (right), as in ``footstep_lattice``; the foot axis of the pattern's
# (K, 2, ...) arrays is [left, right], so side s is at index (1 - s) // 2.
def _side(value: Any) -> int:
    raw = value
    for attr in ("name", "value"):  # enums
        if not isinstance(value, (str, int, np.integer)) and hasattr(value, attr):
            value = getattr(value, attr)
    if isinstance(value, str) and value[:1].lower() in ("l", "r"):
        return 1 if value[:1].lower() == "l" else -1
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value in (1, -1):
        return int(value)
    raise ValueError(f"footstep side {raw!r} is neither 'left'/'right' nor +1 (left) / -1 (right)")


def footsteps_array(plan: Any) -> tuple[np.ndarray, np.ndarray]:
    """Normalise a footstep plan to ((S, 4) poses x, y, z, yaw in m/rad, (S,) int8 sides, +1 left
    and -1 right).

    ``plan`` is a ``footsteps.FootstepPlan`` (its ``footsteps_xyyaw_w``, ``foot_sides`` and
    ``foot_z_m``) or a sequence of steps, each a dict with keys ``x, y, yaw, side`` (and
    optionally ``z``), an object with those attributes, or a tuple ``(x, y, yaw, side)``; side is
    'left'/'right' (or 'l'/'r'), or +1 (left) / -1 (right).
    """
    if hasattr(plan, "footsteps_xyyaw_w") and hasattr(plan, "foot_sides"):
        xyyaw = np.asarray(plan.footsteps_xyyaw_w, dtype=np.float64).reshape(-1, 3)
        z = np.asarray(getattr(plan, "foot_z_m", np.zeros(len(xyyaw))), dtype=np.float64)
        poses = np.stack([xyyaw[:, 0], xyyaw[:, 1], z, xyyaw[:, 2]], axis=-1)
        return poses, np.array([_side(int(s)) for s in plan.foot_sides], dtype=np.int8)
    poses, sides = [], []
    for i, step in enumerate(plan):
        if isinstance(step, dict):
            get = step.get
        elif isinstance(step, (tuple, list)):
            if len(step) != 4:
                raise ValueError(f"footstep {i}: a tuple must be (x, y, yaw, side), got {step!r}")
            get = dict(zip(("x", "y", "yaw", "side"), step)).get
        else:
            def get(key, default=None, _step=step):
                return getattr(_step, key, default)
        missing = [key for key in ("x", "y", "yaw", "side") if get(key) is None]
        if missing:
            raise ValueError(f"footstep {i}: missing {missing} in {step!r}")
        poses.append([float(get("x")), float(get("y")), float(get("z", 0.0) or 0.0), float(get("yaw"))])
        sides.append(_side(get("side")))
    return np.asarray(poses, dtype=np.float64).reshape(-1, 4), np.asarray(sides, dtype=np.int8)


# --------------------------------------------------------------------------- pattern
@dataclass(frozen=True)
class WalkPattern:
    """A walking pattern sampled every ``dt_s``: K samples, S steps. World frame."""

    dt_s: float
    time_s: np.ndarray
    """(K,) s."""
    zmp_ref_xy: np.ndarray
    """(K, 2) reference ZMP, m."""
    zmp_xy: np.ndarray
    """(K, 2) ZMP of the generated CoM motion (cart-table), m."""
    com_pos_w: np.ndarray
    """(K, 3) CoM position, m (z = z_c)."""
    com_vel_w: np.ndarray
    """(K, 3) m/s."""
    com_acc_w: np.ndarray
    """(K, 3) m/s^2."""
    foot_pose_w: np.ndarray
    """(K, 2, 4) (x, y, z, yaw) of the left ([:, 0]) and right ([:, 1]) foot frames, m and rad.
    The yaw is continuous in time (unwrapped): the step's yaw modulo 2 pi."""
    foot_contact: np.ndarray
    """(K, 2) bool: the left / right foot is on the ground."""
    steps: np.ndarray
    """(S, 4) (x, y, z, yaw) of the steps taken (the start stance excluded), m and rad."""
    step_sides: np.ndarray
    """(S,) int8 foot of each step: +1 left, -1 right."""
    touchdown_index: np.ndarray
    """(S,) sample at which each step's foot lands (its single support ends)."""
    foot: FootShape = field(repr=False)

    def support_polygon(self, k: int) -> np.ndarray:
        """(M, 2) support polygon at sample k (the feet in contact), m."""
        feet = self.foot_pose_w[k][self.foot_contact[k]]
        return support_polygon(feet[:, [0, 1, 3]], self.foot)


def _quintic(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk time scaling 10 t^3 - 15 t^4 + 6 t^5: zero velocity and acceleration at
    both ends."""
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


class WalkPatternGenerator:
    """Footstep plan -> reference ZMP, CoM (preview control) and swing-foot trajectories."""

    def __init__(self, cfg: WalkPatternCfg):
        self.cfg = cfg
        self.controller = PreviewController(cfg.preview)

    def _sole_center(self, pose_xyzyaw: np.ndarray) -> np.ndarray:
        ox, oy = self.cfg.foot.center_offset_m
        cos, sin = math.cos(pose_xyzyaw[3]), math.sin(pose_xyzyaw[3])
        return pose_xyzyaw[:2] + np.array([cos * ox - sin * oy, sin * ox + cos * oy])

    def generate(self, plan: Sequence[Any], start_feet: Sequence[Any] | None = None) -> WalkPattern:
        """The walking pattern of a footstep plan.

        Args:
          plan: footsteps (see ``footsteps_array``; a ``FootstepPlan`` as the planner returns it),
            in the order they are taken.
          start_feet: the two standing feet (one left, one right) before the first step, in the
            same formats; None takes them from the first two entries of ``plan`` (the
            planner's rows 0 and 1).
        """
        cfg, dt = self.cfg, self.cfg.preview.dt_s
        poses, sides = footsteps_array(plan)
        if start_feet is None:
            start_poses, start_sides, poses, sides = poses[:2], sides[:2], poses[2:], sides[2:]
        else:
            start_poses, start_sides = footsteps_array(start_feet)
        if sorted(start_sides.tolist()) != [-1, 1]:
            raise ValueError("the start stance needs one left and one right foot (the first two "
                             "plan entries, or start_feet)")
        feet = np.empty((2, 4))  # [left, right]
        feet[(1 - start_sides) // 2] = start_poses
        ss, ds = cfg.single_support_s, cfg.double_support_s

        # ZMP knots: stand between the feet, then per step: transfer to the stance sole (ds),
        # hold while the other foot swings (ss); finally transfer back between the feet
        knots_t, knots_p = [0.0, cfg.stand_before_s], [0.5 * (self._sole_center(feet[0]) + self._sole_center(feet[1]))] * 2
        swings = []  # (foot index, goal pose, lift-off time s)
        t = cfg.stand_before_s
        for pose, foot_idx in zip(poses, (1 - sides) // 2):
            stance = self._sole_center(feet[1 - foot_idx])
            knots_t += [t + ds, t + ds + ss]
            knots_p += [stance, stance]
            swings.append((foot_idx, pose, t + ds))
            feet[foot_idx] = pose
            t += ds + ss
        end = 0.5 * (self._sole_center(feet[0]) + self._sole_center(feet[1]))
        knots_t += [t + ds, t + ds + cfg.stand_after_s]
        knots_p += [end, end]
        num = int(round(knots_t[-1] / dt)) + 1
        time = np.arange(num) * dt
        knots_p = np.asarray(knots_p)
        zmp_ref = np.stack([np.interp(time, knots_t, knots_p[:, i]) for i in range(2)], axis=-1)

        traj = self.controller.simulate(zmp_ref)
        z_c = cfg.preview.com_height_m
        com_pos = np.concatenate([traj.com_pos, np.full((num, 1), z_c)], axis=1)
        com_vel = np.concatenate([traj.com_vel, np.zeros((num, 1))], axis=1)
        com_acc = np.concatenate([traj.com_acc, np.zeros((num, 1))], axis=1)

        foot_pose = np.empty((num, 2, 4))
        foot_pose[:, (1 - start_sides) // 2] = start_poses
        contact = np.ones((num, 2), dtype=bool)
        touchdown = []
        for foot_idx, goal, t0 in swings:
            k0 = int(round(t0 / dt))
            k1 = int(round((t0 + ss) / dt))
            tau = (np.arange(k0, k1) - k0) / max(k1 - k0, 1)
            s = _quintic(tau)[:, None]
            start = foot_pose[k0, foot_idx]  # its yaw unwrapped by earlier swings
            delta = goal - start
            delta[3] = (delta[3] + math.pi) % (2.0 * math.pi) - math.pi  # turn the short way
            swing = start + s * delta
            swing[:, 2] += cfg.swing_height_m * np.sin(math.pi * tau) ** 2  # zero vertical speed at ends
            foot_pose[k0:k1, foot_idx] = swing
            foot_pose[k1:, foot_idx] = start + delta
            contact[k0:k1, foot_idx] = False
            touchdown.append(k1)
        return WalkPattern(dt_s=dt, time_s=time, zmp_ref_xy=zmp_ref, zmp_xy=traj.zmp, com_pos_w=com_pos,
                           com_vel_w=com_vel, com_acc_w=com_acc, foot_pose_w=foot_pose, foot_contact=contact,
                           steps=poses, step_sides=sides, touchdown_index=np.asarray(touchdown, dtype=np.int64),
                           foot=cfg.foot)


__all__ = [
    "PreviewControlCfg", "WalkPatternCfg", "kajita2003_preview_cfg", "walk_pattern_cfg", "cart_table_model",
    "PreviewGains", "preview_gains", "CartTableTrajectory", "PreviewController", "footsteps_array", "WalkPattern", "WalkPatternGenerator",
]
