"""The navigator's closed loop: an oracle episode in an apartment arrives; a user's MJCF world
works; a pose the VO did not track is never fused nor steered on."""

import numpy as np
import pytest

from ambulo.navigation import (
    EpisodeCfg,
    Navigator,
    NavigatorCfg,
    NavWorld,
    NavWorldCfg,
    VoLocalizer,
    result_of,
    run_episode,
)
from ambulo.perception.vo.config import TrackState
from ambulo.perception.vo.odometry import VoResult

pytest.importorskip("onnxruntime")


def test_oracle_episode_in_an_apartment_reaches_the_goal():
    """Apartment 1000, episode 0: a 3-4 m geodesic (3.9 m); the robot stops within 0.3 m,
    standing, touching nothing, and its path is not much longer than the geodesic."""
    result = run_episode(1000, 0, EpisodeCfg(min_geodesic_m=3.0, max_geodesic_m=4.0))
    assert 3.0 <= result.geodesic_m <= 4.0
    assert result.success, result.to_json()
    assert result.status == "arrived" and not result.fell and result.collisions == 0
    assert result.distance_to_goal_m <= 0.3
    assert 0.6 < result.spl <= 1.0
    assert result.num_replans >= 3 and len(result.replan_wall_s) == result.num_replans
    assert result.ate_m == 0.0 and result.untracked_frames == 0


def test_a_user_mjcf_world_is_navigated(room):
    """The test room (a strip between two walls, a crate and a post): 4 m east past them."""
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.3), cfg=NavWorldCfg(record_gyro=False))
    nav = Navigator(world, NavigatorCfg(mode="oracle", time_limit_s=40.0))
    nav.set_goal((3.0, 0.2))
    assert nav.run() == "arrived"
    result = result_of(nav, geodesic_m=4.0, wall_s=1.0)
    assert result.success and result.collisions == 0 and not result.fell
    walked = np.array(nav.walked_path_xy_m)
    # it went past the crate's and the post's x, between them
    between = walked[(walked[:, 0] > 1.3) & (walked[:, 0] < 1.7)]
    assert len(between) and (between[:, 1] < 0.7 - 0.2).all() and (between[:, 1] > -0.9 + 0.2).all()
    world.close()


class _LosingOdometry:
    """A stand-in for ``RgbdOdometry`` that reads the true camera pose, except on frames
    ``lost`` where it reports LOST with a coasted pose 1 m off (what the real VO emits)."""

    def __init__(self, world, lost):
        self.world, self.lost, self.index = world, set(lost), -1

    def track(self, rgb, depth, gyro=None):
        self.index += 1
        pose = self.world.camera_pose_wc()
        if self.index in self.lost:
            coasted = pose.copy()
            coasted[0, 3] += 1.0
            return VoResult(pose_wc=coasted, state=TrackState.LOST, inliers=0, num_keyframes=1,
                            tracked=False)
        return VoResult(pose_wc=pose, state=TrackState.TRACKING, inliers=200, num_keyframes=1,
                        tracked=True)


def test_an_untracked_pose_is_never_fused_nor_steered_on(room):
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0),
                               cfg=NavWorldCfg(camera_width=96, camera_height=72, record_gyro=False))
    lost = range(5, 12)
    odometry = _LosingOdometry(world, lost)
    nav = Navigator(world, NavigatorCfg(mode="full", camera_hz=10.0),
                    localizer=VoLocalizer(odometry=odometry))
    fused = []
    real_fuse = nav.mapper.fuse
    nav.mapper.fuse = lambda frame, pose_wc: (fused.append(np.array(pose_wc)), real_fuse(frame, pose_wc))
    seen = []
    nav.add_observer(lambda s: seen.append((odometry.index, s.estimate.tracked, s.estimate.xyyaw.copy(),
                                            s.true_pose.copy(), s.command, s.status)), images=False)
    nav.set_goal((2.5, 0.0))
    nav.run(max_time_s=2.0)
    assert nav.untracked_frames == len(lost)
    assert len(fused) == nav.frames - len(lost) and nav.mapper.frames_fused == len(fused)
    # no fused pose is a coasted one (they are 1 m off the truth in x)
    for pose in fused:
        assert abs(pose[0, 3] - world.camera_pose_wc()[0, 3]) < 1.5  # sanity
    by_index = {i: (tracked, est, true, cmd, status) for i, tracked, est, true, cmd, status in seen}
    for i in lost:
        tracked, est, true, cmd, status = by_index[i]
        assert not tracked and status == "lost"
        assert abs(est[0] - true[0]) < 0.3  # the estimate held, not the coasted pose
    # while lost the walker was commanded to stand (the command of the next control step is zero)
    assert all(by_index[i][3] == (0.0, 0.0, 0.0) for i in list(lost)[1:])
    # tracked again: walking resumes
    assert by_index[max(lost) + 3][0] and by_index[max(lost) + 3][4] == "walking"
    world.close()



class _LatchingWalker:
    """The policy walker as ``walkers.Walker`` allows it to be: ``arrived`` (at the end of a final plan)
    stays True until a new plan is set (``latch()``: it has just arrived)."""

    def __init__(self):
        from ambulo.navigation.walkers import PolicyWalker
        self.inner, self.latched = PolicyWalker(), False

    def __getattr__(self, name):
        return getattr(self.inner, name)

    @property
    def arrived(self) -> bool:
        return self.latched or self.inner.arrived

    def set_plan(self, plan, *, final: bool) -> None:
        self.latched = False
        self.inner.set_plan(plan, final=final)

    def latch(self) -> None:
        self.latched = True


def test_a_second_goal_after_an_arrival_is_walked_to(room):
    """A new goal after an arrival (a second goal on /goal_pose, an object search's next leg) is
    walked to: the last goal's arrival (a walker still "arrived" on its old plan, the settle timer)
    does not end it at once where the robot stands."""
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    walker = _LatchingWalker()
    nav = Navigator(world, NavigatorCfg(mode="oracle", time_limit_s=30.0), walker=walker)
    nav.set_goal((-0.3, 0.0))
    assert nav.run() == "arrived"
    walker.latch()
    nav.set_goal((0.7, 0.0))
    assert nav.run() == "arrived"
    assert np.hypot(*(world.true_pose()[:2] - (0.7, 0.0))) <= nav.cfg.goal_tolerance_m
    world.close()
