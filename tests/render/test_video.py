"""The one MP4 writer (``ambulo.render.video``): frames in, a readable MP4 out, written atomically,
and one-line errors when ffmpeg is missing or writes nothing."""

from __future__ import annotations

import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np
import pytest

from ambulo.render.video import VideoError, VideoWriter
from one_line import raises_one_line


def frames(num: int, height: int = 48, width: int = 64) -> list[np.ndarray]:
    return [np.full((height, width, 3), 20 * i, np.uint8) for i in range(num)]


def test_frames_become_an_mp4_of_that_many_frames_at_that_fps_with_no_temporary(tmp_path):
    path = tmp_path / "sub" / "clip.mp4"  # the folder is created
    with VideoWriter(path, fps=25) as video:
        for frame in frames(10):
            video.append(frame)
    assert video.num_frames == 10
    assert [p.name for p in path.parent.iterdir()] == ["clip.mp4"]
    reader = imageio.get_reader(path)
    assert reader.count_frames() == 10
    meta = reader.get_meta_data()
    assert meta["fps"] == 25 and tuple(meta["size"]) == (64, 48)
    # pixel values survive the encoding (flat grey frames; H.264 is lossy, by a few levels)
    assert abs(float(reader.get_data(5).mean()) - 100.0) < 4.0


def test_odd_sizes_are_rounded_up_to_a_macroblock(tmp_path):
    path = tmp_path / "odd.mp4"
    with VideoWriter(path, fps=10) as video:
        for frame in frames(3, height=45, width=61):
            video.append(frame)
    assert tuple(imageio.get_reader(path).get_meta_data()["size"]) == (64, 48)


def test_an_exception_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "clip.mp4"
    path.write_bytes(b"the old video")
    with pytest.raises(KeyError), VideoWriter(path, fps=10) as video:
        video.append(frames(1)[0])
        raise KeyError("interrupted")
    assert path.read_bytes() == b"the old video"
    assert [p.name for p in tmp_path.iterdir()] == ["clip.mp4"]


def test_bad_frames_are_refused(tmp_path):
    video = VideoWriter(tmp_path / "clip.mp4", fps=10)
    with pytest.raises(ValueError, match="uint8"):
        video.append(np.zeros((48, 64, 3), np.float32))
    video.append(frames(1)[0])
    with pytest.raises(ValueError, match="one size: 64x48 so far, got 32x48"):
        video.append(frames(1, width=32)[0])
    video.abort()
    assert not list(tmp_path.iterdir())


def test_ffmpeg_writing_nothing_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    def writes_nothing(*args, **kwargs):  # ffmpeg failing without an exception
        while True:
            yield

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", writes_nothing)
    video = VideoWriter(tmp_path / "clip.mp4", fps=10)
    video.append(frames(1)[0])
    raises_one_line(video.close, f"no video was written to {tmp_path / 'clip.mp4'}", "check that ffmpeg runs",
                    kind=VideoError)
    assert not list(tmp_path.iterdir())


def test_no_ffmpeg_is_one_line_naming_the_fix(tmp_path, monkeypatch):
    def no_exe():
        raise RuntimeError("No ffmpeg exe could be found.\nInstall ffmpeg on your system.")

    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", no_exe)
    raises_one_line(lambda: VideoWriter(tmp_path / "clip.mp4", fps=10), "cannot write the video",
                    "no ffmpeg found", "pip install imageio-ffmpeg", kind=VideoError)
    assert not list(tmp_path.iterdir())


def test_an_ffmpeg_path_that_does_not_exist_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", str(tmp_path / "no" / "ffmpeg"))
    raises_one_line(lambda: VideoWriter(tmp_path / "clip.mp4", fps=10), "no ffmpeg found", "does not exist",
                    "IMAGEIO_FFMPEG_EXE", kind=VideoError)
