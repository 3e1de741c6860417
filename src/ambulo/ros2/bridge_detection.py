"""``DetectionWorker``: a bridge's detector off the physics thread, one "latest wins" slot per camera.

A detector costs ~4 ms a 640x480 frame on a GPU and 5-40 ms on CPU threads; run in the camera path it
stalled the simulation for that long at every camera frame. Isaac ROS runs detection as its own node;
here it runs on one thread of the bridge's process (the detector is a Python object, often holding a
GPU context: a thread shares it, a process would not). The physics thread hands each camera frame to
``submit`` and goes on; the worker runs the detector and publishes the result stamped with the time of
the frame it was computed on. When the detector is slower than the camera, a frame arriving while it
works replaces that camera's pending frame (the detections describe the newest frame, not a queue
growing without end): the replaced ones are counted in ``dropped``.

``threaded=False`` runs the detector inside ``submit``, on the physics thread, as before: every frame
detected, deterministic (tests, offline evaluation).

A detector's exception is kept and raised (``DetectorFailed``, one line naming the camera, the frame's
time and the error) on the next physics step or at ``close``; the worker stops at the first one.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

CLOSE_WAIT_S = 60.0
"""How long ``close`` waits for the detector to finish the pending frames before leaving them."""


class DetectorFailed(RuntimeError):
    """The bridge's detector raised on a frame (the message says which, when and what)."""


@dataclass
class DetectionJob:
    """One camera frame for the detector: ``camera`` index, ``rgb`` (H, W, 3) uint8, ``depth_m`` (H, W) m or
    None, ``camera_info`` (the capture's ``camera`` dict: intrinsics, extrinsics_cw; for the height above the
    floor) or None, the frame's simulated time ``time_s`` / ``stamp_ns`` and its ``frame_id``."""

    camera: int
    rgb: np.ndarray
    depth_m: np.ndarray | None
    camera_info: dict | None
    time_s: float
    stamp_ns: int
    frame_id: str


def owned(array: np.ndarray | None) -> np.ndarray | None:
    """``array`` itself when it owns its memory (a camera's capture returns fresh arrays: the next capture
    cannot overwrite it), else a copy (a view into a buffer that may be reused)."""
    if array is None or array.flags.owndata:
        return array
    return array.copy()


class DetectionWorker:
    """Runs ``run(job)`` (detect and publish one ``DetectionJob``) for ``num_cameras`` cameras, on its own
    thread (``threaded``) or inside ``submit``.

    Attributes: ``dropped`` (frames replaced in their slot before the detector took them), ``detected``
    (frames the detector ran on), ``error`` (the ``DetectorFailed`` not raised yet, or None).
    """

    def __init__(self, run: Callable[[DetectionJob], None], num_cameras: int, threaded: bool = True):
        self._run, self.threaded = run, threaded
        self._slots: list[DetectionJob | None] = [None] * num_cameras
        self._next = 0
        """The camera whose slot the worker looks at first (round robin: one busy camera cannot starve another)."""
        self._cond = threading.Condition()
        self._stopping = self._abandoned = False
        self.dropped = self.detected = 0
        self.error: DetectorFailed | None = None
        self._thread = None
        if threaded:
            self._thread = threading.Thread(target=self._loop, name="ros2-bridge-detector", daemon=True)
            self._thread.start()

    # -- the physics thread -----------------------------------------------------------------------
    def submit(self, job: DetectionJob) -> None:
        """Hand over a frame: detect it now (inline) or put it in its camera's slot (threaded)."""
        if not self.threaded:
            self._detect(job)
            self.check()
            return
        with self._cond:
            if self._slots[job.camera] is not None:
                self.dropped += 1
            self._slots[job.camera] = job
            self._cond.notify()

    def check(self) -> None:
        """Raise the detector's exception, once (the next physics step, or ``close``)."""
        error = self.error
        if error is not None:
            self.error = None
            raise error

    def close(self) -> None:
        """Detect and publish the pending frames (waiting at most ``CLOSE_WAIT_S``), stop the thread, then
        raise the detector's exception if it was not raised yet."""
        if self._thread is not None:
            with self._cond:
                self._stopping = True
                self._cond.notify()
            self._thread.join(CLOSE_WAIT_S)
            if self._thread.is_alive():  # a detector stuck in a call: leave it (a daemon thread), publish nothing more
                with self._cond:
                    self._abandoned = True
                log.warning("the detector did not finish within %.0f s; closing without its last detections",
                            CLOSE_WAIT_S)
            self._thread = None
        self.check()

    # -- the worker thread ------------------------------------------------------------------------
    def _take(self) -> DetectionJob | None:
        """The next pending frame (waiting for one), or None once stopping with nothing pending."""
        with self._cond:
            while True:
                n = len(self._slots)
                for k in range(n):
                    i = (self._next + k) % n
                    job = self._slots[i]
                    if job is not None:
                        self._slots[i], self._next = None, (i + 1) % n
                        return job
                if self._stopping:
                    return None
                self._cond.wait()

    def _loop(self) -> None:
        while self.error is None:
            job = self._take()
            if job is None or self._abandoned:
                return
            self._detect(job)

    def _detect(self, job: DetectionJob) -> None:
        if self._abandoned:
            return
        try:
            self._run(job)
        except Exception as err:  # kept for the physics thread: an exception here would only kill this thread
            self.error = DetectorFailed(
                f"the detector failed on camera {job.camera}'s frame at t={job.time_s:.3f} s: "
                f"{type(err).__name__}: {err}")
            self.error.__cause__ = err
            return
        self.detected += 1


__all__ = ["CLOSE_WAIT_S", "DetectionJob", "DetectionWorker", "DetectorFailed", "owned"]
