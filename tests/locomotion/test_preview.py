"""ZMP preview control (Kajita 2003) and the walking pattern generator: the discrete cart-table
model and the generated CoM against the closed-form LIPM, the ZMP tracking error against a
bound, and the swing-foot trajectories."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg

from ambulo.locomotion.balance import FootShape, cart_table_zmp, polygon_signed_distance
from ambulo.locomotion.preview import (
    PreviewControlCfg,
    PreviewController,
    WalkPatternGenerator,
    cart_table_model,
    footsteps_array,
    kajita2003_preview_cfg,
    preview_gains,
    walk_pattern_cfg,
)

G = 9.81
Z_C = 0.814  # Kajita 2003
OMEGA = math.sqrt(G / Z_C)
DT = 0.005
FOOT = FootShape(length_m=0.22, width_m=0.09)  # the bundled humanoid's sole (assets/data/humanoid.xml)
LEFT_FOOT, RIGHT_FOOT = 0, 1  # the foot axis of the pattern's arrays; sides are +1 left, -1 right


def straight_plan(num_steps=8, length=0.25, width=0.2):
    """Start stance (left, right) at x = 0, then ``num_steps`` alternating steps forward."""
    plan = [(0.0, width / 2, 0.0, "left"), (0.0, -width / 2, 0.0, "right")]
    for i in range(num_steps):
        side = "left" if i % 2 == 0 else "right"
        plan.append((length * (i + 1), width / 2 if side == "left" else -width / 2, 0.0, side))
    return plan


def lipm_closed_form(t, c0, v0, p):
    """c(t) = p + (c0 - p) cosh(w t) + c0_dot / w sinh(w t) for a constant ZMP p."""
    t = np.asarray(t)[:, None]
    return p + (c0 - p) * np.cosh(OMEGA * t) + v0 / OMEGA * np.sinh(OMEGA * t)


# --------------------------------------------------------------------------- the model
def test_cart_table_model_is_the_exact_discretization():
    # A = expm(F T) and B = int_0^T expm(F s) ds e3 for the triple integrator c''' = u
    a, b, c = cart_table_model(Z_C, DT)
    f = np.diag([1.0, 1.0], k=1)
    big = scipy.linalg.expm(np.block([[f, np.eye(3)[:, 2:]], [np.zeros((1, 4))]]) * DT)
    np.testing.assert_allclose(a, big[:3, :3], atol=1e-15)
    np.testing.assert_allclose(b, big[:3, 3], atol=1e-15)
    np.testing.assert_allclose(c, [1.0, 0.0, -Z_C / G])


def test_discrete_model_holding_a_constant_zmp_follows_the_closed_form_lipm():
    # choose each jerk so the ZMP at the next sample is p (u = (p - C A x) / (C B)); over a
    # single support of 0.8 s from a state far from equilibrium the CoM is the closed-form LIPM
    a, b, c = cart_table_model(Z_C, DT)
    p = np.array([0.25, -0.1])
    c0, v0 = np.array([0.18, -0.02]), np.array([0.35, -0.25])
    x = np.stack([c0, v0, OMEGA**2 * (c0 - p)])  # (3, 2): start on the LIPM (ZMP = p)
    com = []
    for _ in range(161):
        com.append(x[0].copy())
        u = (p - c @ a @ x) / (c @ b)
        x = a @ x + np.outer(b, u)
    expected = lipm_closed_form(np.arange(161) * DT, c0, v0, p)
    error = np.abs(np.array(com) - expected).max()
    assert error < 1e-4, f"discrete cart-table vs closed-form LIPM: {error * 1e3:.3f} mm"
    assert np.abs(expected - c0).max() > 0.2  # a meaningful excursion, not a state at rest


# --------------------------------------------------------------------------- the controller
def test_infinite_preview_gains_balance_the_state_gain():
    # at rest over a constant reference p the jerk must vanish: Gx[0] p + sum_j Gp(j) p = 0,
    # a property of the Riccati solution the truncated sum reaches as the window grows
    gains = preview_gains(PreviewControlCfg(com_height_m=Z_C, preview_time_s=8.0))
    assert np.all(gains.preview_gain < 0)
    assert abs(gains.state_gain[0] + gains.preview_gain.sum()) < 1e-6 * gains.state_gain[0]
    kajita = preview_gains(kajita2003_preview_cfg())
    assert kajita.preview_gain[0] == -kajita.integral_gain
    assert abs(kajita.preview_gain[-1] / kajita.preview_gain[0]) < 0.01  # decayed within 1.6 s


@pytest.mark.parametrize("cfg", [kajita2003_preview_cfg(), PreviewControlCfg(com_height_m=Z_C)])
def test_constant_zmp_from_equilibrium_is_the_closed_form_lipm(cfg):
    # closed form from c0 = p, c0_dot = 0 is c(t) = p; far from the origin, where a truncated
    # preview without the tail term would drift by metres
    p = np.array([10.0, -3.0])
    traj = PreviewController(cfg).simulate(np.repeat(p[None], 1000, 0))
    expected = lipm_closed_form(np.arange(1000) * cfg.dt_s, p, np.zeros(2), p)
    assert np.abs(traj.com_pos - expected).max() < 1e-3
    assert np.abs(traj.zmp - p).max() < 1e-3


def generate(preview_time_s=2.0, plan=None, stand_before_s=4.0):
    cfg = walk_pattern_cfg(com_height_m=Z_C, foot=FOOT, step_time_s=0.8, double_support_ratio=0.2,
                           swing_height_m=0.06, preview_time_s=preview_time_s, stand_before_s=stand_before_s)
    return cfg, WalkPatternGenerator(cfg).generate(plan or straight_plan())


def single_support_windows(cfg, pattern):
    num = round(cfg.single_support_s / cfg.preview.dt_s)
    return [(k1 - num, k1) for k1 in pattern.touchdown_index]


def test_walking_com_follows_the_closed_form_lipm_in_single_support():
    # over each single support the reference ZMP is the stance sole's centre: the pattern's CoM
    # must be the LIPM about it, from the pattern's own state at lift-off
    cfg, pattern = generate()
    worst = 0.0
    for k0, k1 in single_support_windows(cfg, pattern):
        p = pattern.zmp_ref_xy[k0]
        np.testing.assert_allclose(pattern.zmp_ref_xy[k0:k1 + 1], np.repeat(p[None], k1 + 1 - k0, 0), atol=1e-12)
        expected = lipm_closed_form(pattern.time_s[k0:k1 + 1] - pattern.time_s[k0],
                                    pattern.com_pos_w[k0, :2], pattern.com_vel_w[k0, :2], p)
        worst = max(worst, np.abs(pattern.com_pos_w[k0:k1 + 1, :2] - expected).max())
    assert worst < 1e-3, f"CoM vs closed-form LIPM over single support: {worst * 1e3:.2f} mm"


def closed_loop_impulse_response(controller, num):
    """ZMP response h(k) of the preview controller's closed loop (integral + state feedback)
    to a unit jerk added at k = 0, with a zero reference."""
    g, a, b, c = controller.gains, controller.a, controller.b, controller.c
    x, error_sum, out = np.zeros(3), 0.0, np.empty(num)
    for k in range(num):
        error_sum += c @ x
        out[k] = c @ x
        x = a @ x + b * (-g.integral_gain * error_sum - g.state_gain @ x + (k == 0))
    return out


def test_walking_zmp_error_within_the_truncated_preview_bound():
    """Bound: ``max|e_N| <= max|e_ideal| + ||h||_1 max_k |d_N(k)|``, per axis.

    e_ideal is the tracking error of the same LQ controller with an ideal (4 s) preview, whose
    neglected gain mass is 1e-6 of Gx[0]: the error that the Qe/R trade-off alone leaves. The
    1.6-2.0 s controller differs from it only through the jerk it does not see,
    ``d_N(k) = sum_{j>N} Gp(j) (p_ref(k+j) - p_ref(k+N))`` (the tail term assumes the reference
    constant beyond the window), which passes through the closed loop, so
    ``e_N - e_ideal = h * d_N`` and Young's inequality gives the bound (h: the closed-loop
    impulse response from jerk to ZMP). The test also checks the decomposition itself, and that
    the error converges to e_ideal as the window grows.
    """
    plan = straight_plan()
    cfg_ideal, ideal = generate(4.0, plan)
    e_ideal = ideal.zmp_xy - ideal.zmp_ref_xy
    ref = ideal.zmp_ref_xy
    gains_ideal = preview_gains(cfg_ideal.preview)
    gp_ideal = gains_ideal.preview_gain
    gaps = []
    for window in (1.2, 1.6, 2.0, 2.4):
        cfg, pattern = generate(window, plan)
        controller = WalkPatternGenerator(cfg).controller
        e = pattern.zmp_xy - pattern.zmp_ref_xy
        n, m = controller.horizon, len(gp_ideal)
        padded = np.concatenate([ref, np.repeat(ref[-1:], m, 0)])
        beyond = np.lib.stride_tricks.sliding_window_view(padded[n + 1:], m - n, axis=0)[: len(ref)]
        at_n = padded[n:n + len(ref)]
        d = (beyond - at_n[..., None]) @ gp_ideal[n:] + gains_ideal.tail_gain * (beyond[..., -1] - at_n)
        h = closed_loop_impulse_response(controller, 2000)
        predicted = np.stack([np.convolve(h, d[:, i])[: len(ref)] for i in range(2)], -1)
        np.testing.assert_allclose(e - e_ideal, predicted, atol=1e-6)
        bound = np.abs(e_ideal).max(0) + np.abs(h).sum() * np.abs(d).max(0)
        assert np.all(np.abs(e).max(0) <= bound), (window, np.abs(e).max(0), bound)
        gaps.append(np.abs(e - e_ideal).max())
    assert gaps == sorted(gaps, reverse=True) and gaps[-1] < 1e-3, gaps
    assert np.abs(e_ideal).max() < 5e-3  # Qe/R = 1e6 tracks a walk to a few mm


def test_pattern_is_consistent_and_keeps_the_zmp_inside_the_support_polygon():
    cfg, pattern = generate(stand_before_s=2.0)
    # the pattern's ZMP is the cart-table ZMP of its CoM motion (balance.py's formula)
    np.testing.assert_allclose(cart_table_zmp(pattern.com_pos_w, pattern.com_acc_w), pattern.zmp_xy, atol=1e-12)
    # margins with shapely as the independent judge: >= 2 cm everywhere (research goal 5)
    shapely = pytest.importorskip("shapely")
    margins = []
    for k in range(0, len(pattern.time_s), 5):
        poly = shapely.Polygon(pattern.support_polygon(k))
        point = shapely.Point(pattern.zmp_xy[k])
        margins.append(poly.exterior.distance(point) * (1 if poly.contains(point) else -1))
        assert margins[-1] == pytest.approx(polygon_signed_distance(pattern.zmp_xy[k], pattern.support_polygon(k)))
    assert min(margins) >= 0.02, min(margins)


# --------------------------------------------------------------------------- feet
def test_swing_feet_lift_and_land_at_rest_on_their_steps():
    cfg, pattern = generate(plan=straight_plan(4))
    dt = cfg.preview.dt_s
    feet = pattern.foot_pose_w
    vel = np.gradient(feet, dt, axis=0)
    for (k0, k1), step, step_side in zip(single_support_windows(cfg, pattern), pattern.steps, pattern.step_sides):
        side = LEFT_FOOT if step_side == 1 else RIGHT_FOOT
        stance = 1 - side
        assert not pattern.foot_contact[k0:k1, side].any() and pattern.foot_contact[k0:k1, stance].all()
        assert np.ptp(feet[k0:k1 + 1, stance], axis=0).max() == 0.0  # the stance foot stays put
        np.testing.assert_allclose(feet[k1, side, :3], step[:3], atol=1e-12)  # lands on its step
        assert math.remainder(feet[k1, side, 3] - step[3], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
        # zero velocity at lift-off and touchdown (the first and last samples of the swing)
        assert np.abs(vel[[k0, k1], side]).max() < 0.02
        apex = feet[k0:k1, side, 2].max()
        assert apex == pytest.approx(cfg.swing_height_m, abs=1e-4)
        assert np.argmax(feet[k0:k1, side, 2]) == pytest.approx((k1 - k0) / 2, abs=1)
    # both feet end where the plan put them
    np.testing.assert_allclose(feet[-1, LEFT_FOOT, :3], pattern.steps[pattern.step_sides == 1][-1, :3])
    np.testing.assert_allclose(feet[-1, RIGHT_FOOT, :3], pattern.steps[pattern.step_sides == -1][-1, :3])


def test_turning_steps_turn_the_short_way():
    plan = [(0.0, 0.1, 3.0, "left"), (0.0, -0.1, 3.0, "right"), (0.2, 0.1, -3.0, "left")]
    cfg, pattern = generate(plan=plan)
    yaw = pattern.foot_pose_w[:, LEFT_FOOT, 3]
    assert np.diff(yaw).min() >= 0.0 and yaw[-1] == pytest.approx(2 * math.pi - 3.0)


def test_footstep_formats():
    step = SimpleNamespace(x=0.3, y=-0.1, yaw=0.2, side=-1)
    poses, sides = footsteps_array([{"x": 0.0, "y": 0.1, "yaw": 0.0, "side": "L", "z": 0.05},
                                    (0.1, -0.1, 0.0, "right"), step, (0.4, 0.1, 0.0, 1)])
    np.testing.assert_allclose(poses, [[0, 0.1, 0.05, 0], [0.1, -0.1, 0, 0], [0.3, -0.1, 0, 0.2], [0.4, 0.1, 0, 0]])
    assert sides.tolist() == [1, -1, -1, 1]
    # the planner's FootstepPlan layout: (S, 3) poses, (S,) int8 sides, (S,) heights
    plan = SimpleNamespace(footsteps_xyyaw_w=poses[:, [0, 1, 3]], foot_sides=sides, foot_z_m=poses[:, 2])
    again, again_sides = footsteps_array(plan)
    np.testing.assert_allclose(again, poses)
    assert again_sides.tolist() == sides.tolist()
    with pytest.raises(ValueError, match="side 0"):
        footsteps_array([(0.0, 0.0, 0.0, 0)])
    with pytest.raises(ValueError, match="missing \\['yaw'\\]"):
        footsteps_array([{"x": 0.0, "y": 0.0, "side": "left"}])
    with pytest.raises(ValueError, match="one left and one right"):
        WalkPatternGenerator(generate()[0]).generate([(0, 0.1, 0, "left"), (0, 0.3, 0, "left")])
