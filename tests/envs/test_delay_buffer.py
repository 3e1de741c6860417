"""DelayBuffer: each world reads exactly what was pushed ``delay`` pushes ago; a fill erases the past."""

import torch

from ambulo.envs.delay import DelayBuffer


def test_each_world_lags_by_exactly_its_delay():
    buf = DelayBuffer(3, 4, (2,), device="cpu")
    buf.delay[:] = torch.tensor([0, 1, 2, 3])
    buf.fill(None, torch.full((4, 2), -1.0))
    for t in range(10):
        buf.push(torch.full((4, 2), float(t)))
        got = buf.read()[:, 0]
        expected = torch.tensor([t - k if t - k >= 0 else -1.0 for k in range(4)])
        assert torch.equal(got, expected), (t, got)


def test_a_fill_gives_selected_worlds_no_past():
    buf = DelayBuffer(2, 3, (), device="cpu")
    buf.delay[:] = 2
    for t in range(5):
        buf.push(torch.full((3,), float(t)))
    buf.fill(torch.tensor([1]), torch.tensor([9.0]))
    assert buf.read().tolist() == [2.0, 9.0, 2.0]
    buf.fill(torch.tensor([False, False, True]), torch.full((3,), 7.0))  # a GPU-style mask
    assert buf.read().tolist() == [2.0, 9.0, 7.0]
