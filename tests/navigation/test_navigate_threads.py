"""``ambulo navigate`` (one episode) runs with torch and OpenCV on one thread, as each worker of
``--episodes N`` does, and gives the thread counts back afterwards."""

import argparse

import pytest
import torch

from ambulo.cli import navigate


def test_one_episode_runs_single_threaded_like_the_benchmarks_workers(monkeypatch):
    cv2 = pytest.importorskip("cv2")
    seen = {}

    def fake_run(args):
        seen["torch"], seen["cv2"] = torch.get_num_threads(), cv2.getNumThreads()
        return 0

    monkeypatch.setattr(navigate, "_run_one", fake_run)
    torch_before, cv2_before = torch.get_num_threads(), cv2.getNumThreads()
    torch.set_num_threads(2)
    cv2.setNumThreads(2)
    try:
        assert navigate.run_one(argparse.Namespace()) == 0
        assert seen == {"torch": 1, "cv2": 1}
        assert (torch.get_num_threads(), cv2.getNumThreads()) == (2, 2)
    finally:
        torch.set_num_threads(torch_before)
        cv2.setNumThreads(cv2_before)
