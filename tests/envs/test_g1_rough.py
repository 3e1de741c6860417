"""g1-rough: the G1 on humanoid-rough's terrain. Its observations are g1-walk's plus the scan, the
scan reads the terrain under the robot, robots start on their tiles at the G1's height and stand
there on their sole spheres without sinking, the curriculum promotes a robot that walked out of
its tile, and play puts every robot on the hardest level with no transfer randomization."""

import mujoco
import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.g1_rough import G1RoughEnv  # importable without the URDF: it is read when built
from ambulo.envs.transfer import TransferCfg
from runaway_probe import fastest_speed_under_noise

pytest.importorskip("cmeel")  # the robots extra (example-robot-data) brings the G1 URDF

SMALL = {"terrain.num_levels": 3, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
         "terrain.border_m": 1.0}
KINDS = ("flat", "rough", "slope_up", "slope_down", "stairs_up", "stairs_down", "stepping_stones")
STAIRS_DOWN = KINDS.index("stairs_down")
SCAN_POINTS = 17 * 11
G1_PELVIS_M = 0.76  # g1-walk's start height over the ground


def make(num_envs=7, engine="mujoco", **overrides):
    cfg = envs.make_cfg("g1-rough", num_envs=num_envs, seed=0, num_threads=1, push_interval_s=None, engine=engine,
                        **{**SMALL, **overrides})
    cfg.transfer = TransferCfg()  # the randomized gains and delays are humanoid-rough's tests'
    return G1RoughEnv(cfg)


def sole_spheres(env) -> list[int]:
    model = env.engine.model
    return [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
            and (model.geom_contype[g] or model.geom_conaffinity[g])]


def test_observations_are_g1_walks_and_the_scan():
    """Actor: g1-walk's 96 values (29 joints) + the 17 x 11 scan; critic: g1-walk's, the scan and
    the two feet's heights over the ground. Only the feet's 8 spheres and the terrain collide."""
    walk = envs.make("g1-walk", num_envs=1, seed=0, num_threads=1)
    env = make(num_envs=2, observation_noise={})
    assert walk.num_obs == 3 + 3 + 29 * 3 + 3
    assert env.num_obs == walk.num_obs + SCAN_POINTS and env.num_actions == 29
    assert env.num_privileged_obs == walk.num_privileged_obs + SCAN_POINTS + 2
    model = env.engine.model
    colliding = [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]
    terrain = model.body(env.feet.cfg.against_body).id  # the terrain body: its hfield and box tiles
    assert len(set(colliding) - set(np.flatnonzero(model.geom_bodyid == terrain))) == 8
    assert set(colliding) - set(sole_spheres(env)) == set(np.flatnonzero(model.geom_bodyid == terrain))


def test_sole_spheres_grow_keeping_their_lowest_points():
    """The URDF's 5 mm spheres 3 cm below the ankle become 2 cm ones 1.5 cm below it; the feet's
    mass stays."""
    env = make(num_envs=1)
    walk = envs.make("g1-walk", num_envs=1, seed=0, num_threads=1)
    spheres, urdf = sole_spheres(env), sole_spheres(walk)
    m, w = env.engine.model, walk.engine.model
    assert (m.geom_size[spheres, 0] == pytest.approx(0.02)) and (w.geom_size[urdf, 0] == pytest.approx(0.005))
    lowest = m.geom_pos[spheres, 2] - m.geom_size[spheres, 0]
    assert lowest.tolist() == pytest.approx((w.geom_pos[urdf, 2] - w.geom_size[urdf, 0]).tolist())
    assert lowest.tolist() == pytest.approx([-0.035] * 8)
    foot = "/World/robot/left_ankle_roll_link"
    assert m.body(foot).mass[0] == pytest.approx(w.body(foot).mass[0]) and w.body(foot).mass[0] > 0.5


def test_height_scan_reads_the_terrain_under_the_robot():
    """A G1 held 0.1 m above its standing height over the hardest stairs-down summit (0.75 m: five
    0.15 m risers, 0.30 m treads from the 1 m platform's edge), heading +x: the scan (x ahead in
    +-0.8 m, y across in +-0.5 m) reads 0.1 m over the platform (|x|, |y| < 0.5 m) and 0.25 m over
    the first tread (0.60 m high, 0.5 < |x| <= 0.8 m). Points on the edges are left out."""
    env = make(observation_noise={}, **{"curriculum.init_level": -1, "curriculum.enabled": False})
    origin = env.curriculum.origins_w[STAIRS_DOWN]
    assert origin[2].item() == pytest.approx(0.75)
    pos = torch.tensor([[origin[0].item(), origin[1].item(), 0.75 + G1_PELVIS_M + 0.1]])
    env.robot.write_root_pose(pos_w=pos.to(env.engine.dtype), quat_w=torch.tensor([[1.0, 0, 0, 0]], dtype=env.engine.dtype),
                              env_ids=torch.tensor([STAIRS_DOWN]))
    env.engine.forward()
    scan = env._compute_observations()[STAIRS_DOWN, -SCAN_POINTS:].reshape(17, 11)  # x (forward) by y (left)
    x = torch.linspace(-0.8, 0.8, 17).abs()
    platform, tread = x < 0.45, (x > 0.55) & (x < 0.75)
    assert platform.sum() == 9 and tread.sum() == 4
    inner = scan[:, 1:10]  # |y| <= 0.4 m
    torch.testing.assert_close(inner[platform], torch.full((9, 9), 0.1), atol=1e-4, rtol=0)
    torch.testing.assert_close(inner[tread], torch.full((4, 9), 0.25), atol=1e-4, rtol=0)


def test_robots_start_on_their_tiles_at_the_g1s_height():
    env = make(num_envs=14, **{"curriculum.init_level": 1, "curriculum.enabled": False})
    root = env.robot.data.root_pos_w.float()
    origins = env.curriculum.origins_w
    assert (env.curriculum.levels == 1).all()
    assert ((root[:, :2] - origins[:, :2]).abs() <= env.cfg.spawn_radius_m + 1e-6).all()
    # every robot on a different spot of its tile than its twin on the same tile (spawn jitter)
    assert not torch.allclose(root[:7, :2] - origins[:7, :2], root[7:, :2] - origins[7:, :2])
    torch.testing.assert_close(root[:, 2] - env.ground_height_m(root[:, :2]), torch.full((14,), G1_PELVIS_M),
                               atol=1e-4, rtol=0)
    assert root[STAIRS_DOWN, 2].item() == pytest.approx(0.5 + G1_PELVIS_M, abs=1e-4)  # 5 risers of 0.10 m


@pytest.mark.parametrize("engine", ["mujoco", pytest.param("warp", marks=pytest.mark.slow)])
def test_g1_stands_on_flat_rough_and_stair_tiles_without_sinking(engine):
    """Zero actions for 2 s on the 0.10 m level: tiles with a 1 m platform (stairs up and down, the
    robot up to 0.3 m off the centre, near a step edge) and, with a 0.3 m platform, flat and rough
    ground under the feet. From 0.1 s on no sole sphere's lowest point gets 1 cm below the ground
    (3.7 mm at most on the CPU engine, 4.3 mm on Warp's CPU device; off the platform a robot starts
    at its base's ground height, so on rough ground a sole starts up to ~1 cm in or above it, pushed
    out within 0.1 s), and no robot falls in the first 0.8 s. (Under zero actions the G1 topples after ~1.3 s on g1-walk's
    plane too: its URDF ankle gains, 2 x 70 N m/rad, are below m g h ~ 240 N m/rad, so its default
    pose is not statically stable; the policy balances it.)"""
    for kinds, platform in ((("flat", "rough"), 0.3), (("stairs_up", "stairs_down"), 1.0)):
        env = make(num_envs=4, engine=engine, **{"terrain.kinds": kinds, "terrain.platform_size_m": platform,
                                                 "curriculum.init_level": 1, "curriculum.enabled": False})
        spheres = sole_spheres(env)
        radius = torch.as_tensor(env.engine.model.geom_size[spheres, 0]).float()
        deepest = 0.0
        for step in range(100):
            _, _, dones, _ = env.step(torch.zeros(4, env.num_actions))
            assert step >= 40 or not dones.any(), (kinds, step)
            centres = env.engine.field("geom_xpos")[:, spheres].float()
            sink = env.ground_height_m(centres[..., :2]) - (centres[..., 2] - radius)
            if step >= 5:
                deepest = max(deepest, sink.max().item())
        assert deepest < 0.01, (kinds, deepest)
        if "rough" in kinds:  # the feet stood on uneven ground, not on a platform
            feet = env.robot.data.body_pos_w[1, env.feet_body_ids, :2].float()
            assert env.ground_height_m(feet).std().item() > 0.0


def test_curriculum_promotes_a_robot_moved_out_of_its_tile():
    """Robot 0 carried 2.5 m (more than half of a 4 m tile) from its start: at its episode's end it
    moves up a level and starts on its new tile; robots that stayed keep level 0."""
    env = make(num_envs=3, episode_length_s=0.1, **{"curriculum.init_level": 0})
    assert env.curriculum.levels.tolist() == [0, 0, 0]
    env.step(torch.zeros(3, env.num_actions))
    moved = env.robot.data.root_pos_w[:1].clone()
    moved[0, 0] += 2.5
    moved[0, 2] = env.ground_height_m(moved[:, :2].float())[0] + G1_PELVIS_M
    env.robot.write_root_pose(pos_w=moved, env_ids=torch.tensor([0]))
    for _ in range(5):
        _, _, dones, _ = env.step(torch.zeros(3, env.num_actions))
        if dones[0]:
            break
    assert dones[0]
    assert env.curriculum.levels.tolist()[0] == 1 and env.curriculum.levels.tolist()[1:] == [0, 0]
    start = env.robot.data.root_pos_w[0, :2].float()
    assert ((start - env.curriculum.origins_w[0, :2]).abs() <= env.cfg.spawn_radius_m + 1e-6).all()


def test_play_puts_every_robot_on_the_hardest_level_without_transfer():
    cfg = envs.spec("g1-rough").play_cfg_fn()
    assert cfg.transfer == TransferCfg() and not cfg.curriculum.enabled
    train = envs.make_cfg("g1-rough")
    assert train.transfer.com_bodies == ("pelvis", "torso_link") and train.transfer.kp_scale_range == (0.8, 1.2)
    env = envs.make("g1-rough", num_envs=4, seed=0, num_threads=1, play=True, **SMALL)
    assert env.curriculum.levels.tolist() == [2, 2, 2, 2]
    env.step(torch.zeros(4, env.num_actions))
    assert env.curriculum.levels.tolist() == [2, 2, 2, 2]


@pytest.mark.slow  # ~30 s on a shared 2-core machine, once Warp's kernels are compiled (minutes before)
def test_no_world_runs_away_under_ppo_first_exploration_on_warp():
    """16 G1s as trained (full terrain, levels 0-4, wide transfer), unit Gaussian actions for 150
    steps on MuJoCo Warp's CPU device, runaway guard off: no joint or base speed past 100 rad/s
    (59.5 here; the CPU engine 68.7). Without the terrain contacts' depth limit one world reached
    234 rad/s, and with the URDF's 5 mm sole spheres as well 6e7 rad/s (135 terminations, not 44)."""
    cfg = envs.make_cfg("g1-rough", num_envs=16, seed=0, num_threads=1, engine="warp", diverged_speed_bound=None)
    assert fastest_speed_under_noise(G1RoughEnv(cfg), steps=150) < 100.0
