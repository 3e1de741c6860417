"""The bridge's detector thread without ROS: ``DetectionWorker``'s latest-wins slots, draining, inline mode and
errors, and ``PhysicsPublisher._publish_frame`` from two threads (the frame ring's slot order)."""

from __future__ import annotations

import os
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from ambulo.ros2.bridge_detection import DetectionJob, DetectionWorker, DetectorFailed


def _job(camera: int, k: int) -> DetectionJob:
    return DetectionJob(camera, np.full((2, 3, 3), k, np.uint8), None, None, k * 0.1, k * 100_000_000, "cam")


def test_a_busy_worker_keeps_only_each_cameras_newest_frame_and_drains_it_at_close():
    hold, started, done = threading.Event(), threading.Event(), []

    def run(job: DetectionJob) -> None:
        started.set()
        if not done:
            assert hold.wait(30.0)
        done.append((job.camera, int(job.rgb[0, 0, 0]), job.stamp_ns, threading.current_thread().name))

    worker = DetectionWorker(run, num_cameras=2)
    worker.submit(_job(0, 0))
    assert started.wait(30.0)  # the worker holds camera 0's frame 0
    for k in range(1, 6):  # submit returns at once while the detector is busy
        worker.submit(_job(0, k))
    worker.submit(_job(1, 7))
    assert worker.dropped == 4 and done == []
    hold.set()
    worker.close()
    assert sorted(d[:3] for d in done) == [(0, 0, 0), (0, 5, 500_000_000), (1, 7, 700_000_000)]
    assert {d[3] for d in done} == {"ros2-bridge-detector"} and worker.detected == 3


def test_inline_worker_detects_every_frame_on_the_callers_thread():
    done = []
    worker = DetectionWorker(lambda job: done.append((int(job.rgb[0, 0, 0]), threading.current_thread())), 1,
                             threaded=False)
    for k in range(4):
        worker.submit(_job(0, k))
        assert done[-1] == (k, threading.current_thread())  # before submit returned
    assert worker.dropped == 0 and len(done) == 4


@pytest.mark.parametrize("threaded", [True, False])
def test_a_detectors_exception_is_raised_once_in_one_line(threaded):
    def run(job: DetectionJob) -> None:
        raise KeyError("weights")

    worker = DetectionWorker(run, 1, threaded=threaded)
    with pytest.raises(DetectorFailed) as raised:
        worker.submit(_job(0, 3))
        worker.close()  # threaded: the worker has stopped on it; close raises it
    assert str(raised.value) == "the detector failed on camera 0's frame at t=0.300 s: KeyError: 'weights'"
    assert isinstance(raised.value.__cause__, KeyError)
    worker.check()
    worker.close()  # raised once: nothing more


def test_frames_published_from_two_threads_reach_the_publisher_in_slot_order():
    """The publisher takes frame slots in the order their numbers arrive: each message must name the slot
    written for it, with the other thread publishing at the same time (a slow ``on_publish`` widens the gap
    between writing a slot and sending its number; the lock keeps the two together)."""
    from ambulo.ros2 import cdr
    from ambulo.ros2.bridge_publishing import PhysicsPublisher
    from ambulo.ros2.frame_ring import FrameRing

    ring, fd = FrameRing.create(64, 4096)
    sent = []
    fake = SimpleNamespace(
        _frames=ring, cfg=SimpleNamespace(drop_when_behind=False), _proc=SimpleNamespace(poll=lambda: None),
        on_publish=lambda topic, ns: time.sleep(0.0005), _topic={"rgb0": "/rgb", "seg0": "/seg"},
        process=SimpleNamespace(send=sent.append), _header=[0] * 8, _out_lock=threading.Lock(), dropped_frames=0)

    def publish(key: str, value: int) -> None:
        for k in range(25):
            PhysicsPublisher._publish_frame(fake, key, value * 1000 + k, "cam", "mono8", np.full((4, 8), value, np.uint8))

    threads = [threading.Thread(target=publish, args=(key, value)) for key, value in (("rgb0", 1), ("seg0", 2))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(sent) == 50
    for _, key, nbytes, ns, _ in sent:
        value = 1 if key == "rgb0" else 2
        expected = cdr.image_prefix(ns, "cam", 4, 8, "mono8", 8, 32) + bytes([value]) * 32
        assert ring.take(nbytes) == expected, key
    ring.close()
    os.close(fd)
