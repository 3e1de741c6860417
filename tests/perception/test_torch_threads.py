"""The odometry and the TSDF run their per-frame CPU torch work on one thread (``torch_threads``):
with torch's 2 threads on a busy 2-core machine the odometry took 222 ms a frame instead of 59."""

import numpy as np
import pytest
import torch

from ambulo.perception.torch_threads import one_torch_thread


@pytest.fixture
def two_threads():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(before)


def test_one_torch_thread_pins_and_restores(two_threads):
    with one_torch_thread("cpu"):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2
    with one_torch_thread("meta"):  # another device's work is not torch's CPU pool: untouched
        assert torch.get_num_threads() == 2
    with pytest.raises(RuntimeError), one_torch_thread("cpu"):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == 2


def test_the_odometry_tracks_on_one_torch_thread(two_threads):
    pytest.importorskip("cv2", reason="the perception extra is not installed")
    from ambulo.perception.vo.odometry import RgbdOdometry

    k = np.array([[200.0, 0, 79.5], [0, 200.0, 59.5], [0, 0, 1]])
    vo = RgbdOdometry(k)
    seen = []
    detect = vo.features.detect

    def spy(rgb, depth):
        seen.append(torch.get_num_threads())
        return detect(rgb, depth)

    vo.features.detect = spy
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (120, 160, 3), dtype=np.uint8)
    for _ in range(2):
        vo.track(rgb, np.full((120, 160), 2.0, np.float32))
    assert seen == [1, 1] and torch.get_num_threads() == 2
