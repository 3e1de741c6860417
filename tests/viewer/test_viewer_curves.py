"""``WebViewer.add_scalars``: one uPlot curve per name on the page, fed from another thread without
waiting; long runs are thinned, not truncated. Read from viser's server-side GUI state (no browser)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

pytest.importorskip("viser")
import ambulo.viewer
from ambulo.sim import World
from ambulo.viewer.curves import ScalarLog
from ports import free_port

LIMIT_S = 120.0



def test_log_thins_by_half_keeping_the_ends_and_drops_non_finite():
    log = ScalarLog(max_points=10)
    for step in range(11):
        log.add(step, {"reward": step * 2.0, "bad": float("nan")})
    assert log.drain() == {"reward"}
    x, y = log.series("reward")
    np.testing.assert_array_equal(x, [0, 2, 4, 6, 8, 10])
    np.testing.assert_array_equal(y, 2.0 * x)
    assert log.names == ["reward"]


def test_add_scalars_draws_one_curve_per_name_from_another_thread(box_world):
    world = box_world((0.0, 0.0, 1.0), physics_dt=0.01)
    world.reset()
    viewer = ambulo.viewer.serve(world, port=free_port(), announce=False, process=False)
    try:
        plots = viewer.page._curves.plots

        def drawn(n: int) -> bool:
            return set(plots) == {"reward", "episode_length"} and all(len(p.data[0]) == n for p in plots.values())

        def trainer(first: int, last: int):  # what `ambulo train` does once per iteration
            for it in range(first, last):
                viewer.add_scalars(it, {"reward": 0.5 * it, "episode_length": 10 + it})

        for first, last in ((0, 10), (10, 50)):  # the curves are created, then redrawn
            thread = threading.Thread(target=trainer, args=(first, last))
            thread.start()
            thread.join(timeout=LIMIT_S)
            deadline = time.monotonic() + LIMIT_S
            while not drawn(last):
                assert time.monotonic() < deadline, f"the curves did not show {last} points"
                time.sleep(0.02)
        x, y = plots["reward"].data
        np.testing.assert_allclose(x, np.arange(50))
        np.testing.assert_allclose(y, 0.5 * np.arange(50))
        np.testing.assert_allclose(plots["episode_length"].data[1], 10 + np.arange(50))
    finally:
        viewer.close()
        World.clear_instance()
