"""Episode metrics on hand-built trajectories: SPL, the stuck rule, the success rule."""

import math

import numpy as np
import pytest

from ambulo.navigation.metrics import is_stuck, p95, path_length_m, spl, succeeded


def test_path_length_and_spl_by_hand():
    # an L of 3 m + 4 m walked where the geodesic is the 5 m diagonal
    walked = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]])
    assert path_length_m(walked) == pytest.approx(7.0)
    assert spl(True, 5.0, 7.0) == pytest.approx(5.0 / 7.0)
    # a path shorter than the geodesic (grid rounding) counts as the geodesic: SPL 1, not more
    assert spl(True, 5.0, 4.9) == pytest.approx(1.0)
    assert spl(False, 5.0, 5.0) == 0.0
    assert spl(True, math.inf, 5.0) == 0.0


def test_stuck_needs_a_whole_window_without_half_a_metre_of_progress():
    t = np.arange(0.0, 30.0, 0.1)
    # 10 s of walking at 0.5 m/s, then 20 s of shuffling within 0.2 m: stuck
    x = np.where(t < 10.0, 0.5 * t, 5.0 + 0.2 * np.sin(t))
    xy = np.stack([x, np.zeros_like(x)], -1)
    assert is_stuck(t, xy)
    # the same shuffle for 19 s only: not stuck
    short = t < 29.0
    assert not is_stuck(t[short], xy[short])
    # slow but steady (0.03 m/s: 0.6 m in 20 s): not stuck
    steady = np.stack([0.03 * t, np.zeros_like(t)], -1)
    assert not is_stuck(t, steady)
    # an oscillation of 0.4 m amplitude that never gets 0.5 m from where a window began: stuck
    osc = np.stack([0.2 * np.sin(t), np.zeros_like(t)], -1)
    assert is_stuck(t, osc)


def test_success_rule():
    goal = (1.0, 2.0)
    assert succeeded("arrived", (1.2, 2.2), goal, fell=False)  # 0.283 m away
    assert not succeeded("arrived", (1.25, 2.2), goal, fell=False)  # 0.32 m away
    assert not succeeded("arrived", (1.0, 2.0), goal, fell=True)
    assert not succeeded("timeout", (1.0, 2.0), goal, fell=False)  # there, but never stopped
    assert not succeeded("stuck", (1.0, 2.0), goal, fell=False)


def test_p95():
    assert p95([]) == 0.0
    assert p95(list(range(101))) == pytest.approx(95.0)
