"""``viewer.frames.copy_world``: the drawn worlds' rows, copied without a device sync."""

import pytest
import torch

from ambulo.viewer.frames import copy_world

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("worlds", [[3], [5, 6, 7], [6, 7, 0, 1]], ids=["one", "consecutive", "wrapping"])
def test_a_frame_holds_the_drawn_worlds_rows_watched_first(device, worlds):
    n, nbody = 8, 4
    xpos = torch.arange(n * nbody * 3, dtype=torch.float32, device=device).reshape(n, nbody, 3)
    xquat = torch.arange(n * nbody * 4, dtype=torch.float32, device=device).reshape(n, nbody, 4)
    time_s = torch.arange(n, dtype=torch.float64, device=device) * 0.5
    frame = copy_world(worlds, time_s, xpos, xquat, {"command": torch.tensor([0.4, 0.0, 0.1], device=device)})
    t, xpos_w, xquat_w, extras = frame.numpy()
    assert t == 0.5 * worlds[0] and frame.world == worlds[0]
    assert xpos_w.shape == (len(worlds), nbody, 3)
    for k, w in enumerate(worlds):  # row k is world w: its first x is w * nbody * 3
        assert xpos_w[k, 0, 0] == w * nbody * 3 and xquat_w[k, 0, 0] == w * nbody * 4
    assert extras["command"].tolist() == pytest.approx([0.4, 0.0, 0.1])


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
@pytest.mark.parametrize("worlds", [[5, 6, 7], [6, 7, 0, 1]], ids=["consecutive", "wrapping"])
def test_copying_a_frame_off_the_gpu_syncs_nowhere(worlds):
    xpos, xquat = torch.zeros(8, 4, 3, device="cuda"), torch.zeros(8, 4, 4, device="cuda")
    time_s = torch.zeros(8, device="cuda")
    copy_world(worlds, time_s, xpos, xquat, {})  # the first frame of a set of worlds may make its index
    torch.cuda.synchronize()
    previous = torch.cuda.get_sync_debug_mode()
    torch.cuda.set_sync_debug_mode("error")
    try:
        frame = copy_world(worlds, time_s, xpos, xquat, {})
    finally:
        torch.cuda.set_sync_debug_mode(previous)
    assert frame.numpy()[1].shape == (len(worlds), 4, 3)
