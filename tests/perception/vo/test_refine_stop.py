"""The refinement's early exit on the CPU (``VoCfg.refine_stop_step``): it stops once a step is
below the threshold, a few iterations sooner, at the pose the full count reaches to within the size
of the steps it skipped."""

import numpy as np

import ambulo.perception.vo.refine as refine
from ambulo.perception.vo.config import VoCfg


def _problem(seed: int):
    rng = np.random.default_rng(seed)
    k = np.array([[262.0, 0, 159.5], [0, 262.0, 119.5], [0, 0, 1]])
    points_w = rng.uniform([-1.5, -1, 1.5], [1.5, 1, 4.0], (300, 3))
    pixels = points_w[:, :2] / points_w[:, 2:] * 262.0 + [159.5, 119.5] + rng.normal(0, 0.5, (300, 2))
    points_c = points_w + rng.normal(0, 0.004, (300, 3))  # true pose: identity
    angle = 0.03
    r0 = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    return r0, np.array([0.03, -0.02, 0.05]), points_w, pixels, points_c, np.ones(300, bool), k


def test_the_early_exit_stops_sooner_at_the_same_pose(monkeypatch):
    steps = []
    exp = refine.so3_exp
    monkeypatch.setattr(refine, "so3_exp", lambda w: steps.append(float(w.abs().max())) or exp(w))
    for seed in range(3):
        problem = _problem(seed)
        steps.clear()
        r_full, t_full = refine.refine_pose(*problem, VoCfg(refine_iterations=8))
        full = list(steps)
        steps.clear()
        r_stop, t_stop = refine.refine_pose(*problem, VoCfg(refine_iterations=8, refine_stop_step=1e-5))
        assert len(full) == 8 and 2 <= len(steps) < 8
        assert steps == full[:len(steps)] and steps[-1] < 1e-5  # (the rotation part of each step)
        np.testing.assert_allclose(t_stop, t_full, atol=1e-5)
        np.testing.assert_allclose(r_stop, r_full, atol=1e-5)
        np.testing.assert_allclose(t_stop, 0, atol=3e-3)
