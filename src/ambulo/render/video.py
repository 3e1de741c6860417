"""The one MP4 writer: RGB frames in, an H.264 MP4 out (imageio-ffmpeg's ffmpeg), written atomically.

Every video ambulo writes goes through ``VideoWriter`` (``sim.Recorder``, ``ambulo play``, the walk
simulation's film). The file is encoded into a hidden temporary beside ``path``
(``utils.atomic.temporary_name``) and renamed onto ``path`` by ``close()``: an interrupted run
never leaves a truncated MP4 under the final name, and a failed one deletes the temporary.
``close()`` also checks that ffmpeg wrote something, since it can fail without raising.

Frame sizes: H.264 in yuv420p needs even sizes and players want multiples of 8, so frames whose
width or height is not a multiple of ``MACRO_BLOCK`` are scaled up to the next one by ffmpeg (with
imageio-ffmpeg's warning); 640 x 480 and the other usual sizes pass unchanged.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

from ..utils.atomic import temporary_name

MACRO_BLOCK = 8
"""Frame width and height are rounded up to a multiple of this (H.264 macroblocks)."""


class VideoError(RuntimeError):
    """No video can be written: ``problem`` says why, ``fix`` what to do (the CLI prints one line)."""

    def __init__(self, problem: str, fix: str = ""):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}" if fix else problem)


def _ffmpeg(path: Path):
    """imageio-ffmpeg, after checking that it finds an ffmpeg executable."""
    try:
        import imageio_ffmpeg  # loaded only when a video is written

        exe = imageio_ffmpeg.get_ffmpeg_exe()  # IMAGEIO_FFMPEG_EXE is returned unchecked
        if not (os.path.isfile(exe) or shutil.which(exe)):
            raise RuntimeError(f"{exe} does not exist")
    except (ImportError, RuntimeError) as err:
        raise VideoError(f"cannot write the video {path}: no ffmpeg found ({' '.join(str(err).split())})",
                         "pip install imageio-ffmpeg (it ships ffmpeg), or set IMAGEIO_FFMPEG_EXE "
                         "to an ffmpeg executable") from None
    return imageio_ffmpeg


class VideoWriter:
    """Append ``(H, W, 3)`` uint8 RGB frames to the MP4 ``path`` at ``fps`` frames per second.

    ``quality`` is imageio's 1-10 scale (libx264 CRF ``int((1 - quality / 10) * 51)``). The
    folder of ``path`` is created. Use as a context manager, or call ``close()`` (keeps the
    video) or ``abort()`` (deletes it); leaving the ``with`` block by an exception aborts.
    """

    def __init__(self, path: str | os.PathLike, *, fps: float, quality: float = 7, codec: str = "libx264"):
        if not fps > 0:
            raise ValueError(f"fps must be above 0, got {fps}")
        self.path = Path(path)
        self.fps, self.quality, self.codec = fps, quality, codec
        self._ffmpeg = _ffmpeg(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(temporary_name(self.path.name))
        self._gen = None  # ffmpeg starts at the first frame, which gives the size
        self._size: tuple[int, int] | None = None
        self._closed = False
        self.num_frames = 0

    def append(self, frame: np.ndarray) -> None:
        """Encode one ``(H, W, 3)`` uint8 RGB frame; every frame has the first one's size."""
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(f"a video frame is (H, W, 3) uint8 RGB, got {frame.shape} {frame.dtype}")
        if self._closed:
            raise RuntimeError(f"the video {self.path} is already closed")
        size = (int(frame.shape[1]), int(frame.shape[0]))
        if self._gen is None:
            self._size = size
            self._gen = self._ffmpeg.write_frames(
                os.fspath(self._tmp), size, fps=self.fps, codec=self.codec, quality=self.quality,
                macro_block_size=MACRO_BLOCK, output_params=["-f", "mp4"])  # the temporary has no .mp4
            self._gen.send(None)  # starts ffmpeg
        elif size != self._size:
            raise ValueError(f"video frames must keep one size: {self._size[0]}x{self._size[1]} so far, "
                             f"got {size[0]}x{size[1]}")
        self._gen.send(np.ascontiguousarray(frame))
        self.num_frames += 1

    def close(self) -> Path:
        """Finish the MP4 and move it to ``path`` (returned); ``VideoError`` if nothing was written."""
        if self._closed:
            return self.path
        self._closed = True
        try:
            if self._gen is not None:
                self._gen.close()  # waits for ffmpeg to finish the file
            if self.num_frames == 0:
                raise VideoError(f"no video was written to {self.path}: no frames were given",
                                 "run for longer, or check why nothing was captured")
            if not self._tmp.is_file() or self._tmp.stat().st_size == 0:
                raise VideoError(f"no video was written to {self.path}",
                                 "check that ffmpeg runs and the folder is writable")
            os.replace(self._tmp, self.path)
        finally:
            self._tmp.unlink(missing_ok=True)
        return self.path

    def abort(self) -> None:
        """Stop ffmpeg and delete the unfinished video (``path`` is left as it was)."""
        self._closed = True
        try:
            if self._gen is not None:
                self._gen.close()
        finally:
            self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


__all__ = ["MACRO_BLOCK", "VideoError", "VideoWriter"]
