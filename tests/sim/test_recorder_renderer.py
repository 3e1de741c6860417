"""``Recorder(renderer=...)``, under ``ambulo view --video`` and ``ambulo demo``: Filament draws the
frames for 'pbr', the path tier is refused, and ``view --renderer`` needs ``--video``."""

import argparse

import numpy as np
import pytest

from ambulo.cli.errors import CliError
from ambulo.cli.view import run as view_run
from ambulo.render import pbr
from ambulo.sim import World
from ambulo.sim.recorder import Recorder


def _frames(path) -> np.ndarray:
    import imageio.v3 as iio

    return np.stack(list(iio.imiter(path, plugin="FFMPEG")))


@pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}")
def test_a_pbr_recording_shows_the_scene_drawn_by_filament(tmp_path):
    world = World()
    world.scene.add_default_ground_plane()
    world.reset()
    videos = {}
    for renderer in ("raster", "pbr"):
        videos[renderer] = tmp_path / f"{renderer}.mp4"
        with Recorder(world, videos[renderer], width=96, height=64, fps=10, renderer=renderer) as rec:
            for _ in range(3):
                world.step()
                rec.capture()
        assert rec.num_frames >= 1
    raster, lit = _frames(videos["raster"]), _frames(videos["pbr"])
    assert raster.shape == lit.shape and lit.std() > 3  # a picture, not a blank frame
    assert np.abs(raster.astype(int) - lit).mean() > 3  # another renderer drew it


def test_the_path_tier_is_refused_for_a_viewport_recording(tmp_path):
    world = World()
    world.reset()
    with pytest.raises(ValueError, match="renders a model camera"):
        Recorder(world, tmp_path / "x.mp4", renderer="path")


def test_view_renderer_without_video_is_one_line():
    args = argparse.Namespace(target="demo", video=None, seconds=1.0, renderer="pbr")
    with pytest.raises(CliError, match="--renderer pbr draws --video frames"):
        view_run(args)
