"""Shared set-up of the VO tests: kinematic head-camera walks rendered once per walk (size and
``WalkCfg``) for the whole package and replayed to every test that runs that walk, and odometry runs
made once per arguments for the tests that check different things of the same run."""

import pytest

from ambulo.perception.sources.head_camera_walk import HeadCameraWalk, WalkCfg

from .rendered_once import RenderedOnce


@pytest.fixture(scope="package")
def rendered_walk():
    """``rendered_walk(width, height, walk_cfg=None)``: the ``RenderedOnce`` kinematic walk of the
    default indoor scene, shared by the package's tests (e.g. the 320x240 default walk: 1,195 frames
    rendered by 8 tests before, 200 now)."""
    from ambulo.scenes.indoor import build_indoor_scene

    walks: dict[tuple, RenderedOnce] = {}
    scene = []

    def get(width: int, height: int, walk_cfg: WalkCfg | None = None) -> RenderedOnce:
        walk_cfg = walk_cfg or WalkCfg()
        key = (width, height, repr(walk_cfg))
        if key not in walks:
            if not scene:
                scene.append(build_indoor_scene())
            walks[key] = RenderedOnce(HeadCameraWalk(scene[0], walk_cfg, width=width, height=height))
        return walks[key]

    yield get
    for walk in walks.values():
        walk.release()


@pytest.fixture(scope="package")
def walk_vo_run(rendered_walk):
    """``walk_vo_run(width, height, walk_cfg, num_frames, **run_walk_vo_kwargs)``: ``run_walk_vo`` of the
    rendered walk, run once per arguments for the package (the run is a function of them: the walk's
    frames are replayed exactly and the odometry is seeded). E.g. the turn too fast to track, 102
    frames: test_odometry checks its recovery, test_imu compares it with the gyro-aided run.
    Callers read the ``VoRun``; none writes into it."""
    from ambulo.perception.vo.eval import run_walk_vo

    runs = {}

    def get(width: int, height: int, walk_cfg: WalkCfg | None, num_frames: int, **kwargs):
        key = (width, height, repr(walk_cfg or WalkCfg()), num_frames, repr(sorted(kwargs.items())))
        if key not in runs:
            runs[key] = run_walk_vo(rendered_walk(width, height, walk_cfg), num_frames, **kwargs)
        return runs[key]

    return get
