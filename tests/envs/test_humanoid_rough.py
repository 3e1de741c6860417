"""humanoid-rough: robots stand on their tiles, falls count against the ground under them, the
transfer randomization lags actions and observations by exactly the drawn steps, PPO runs."""

import csv

import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.humanoid_rough import HumanoidRoughEnv
from ambulo.envs.transfer import TransferCfg
from ambulo.robots import humanoid
from runaway_probe import fastest_speed_under_noise
from script_loader import ROOT, load_script

SMALL = {"terrain.num_levels": 3, "terrain.tile_size_m": 4.0, "terrain.platform_size_m": 1.0,
         "terrain.border_m": 1.0}
STAIRS_DOWN = 5  # index of "stairs_down" in the default TerrainCfg.kinds


def make(num_envs=7, transfer=None, **overrides):
    cfg = envs.make_cfg("humanoid-rough", num_envs=num_envs, seed=0, num_threads=1, push_interval_s=None, **SMALL,
                        **overrides)
    cfg.transfer = transfer or TransferCfg()
    return HumanoidRoughEnv(cfg)


@pytest.mark.parametrize("engine", ["mujoco", pytest.param("warp", marks=pytest.mark.slow)])
def test_robots_stand_on_the_hardest_stairs_summit(engine):
    """Every robot starts on its tile's platform at the hardest level; on the stairs-down tile that
    is 5 steps of 0.15 m up. Standing still for 0.5 s, its soles rest on the platform, and it is
    not "fallen" although its base is 1.6 m above z = 0 (nor in the stairs-up pit at 0.15 m).
    On MuJoCo Warp (its CPU device here: minutes of kernel compilation) the hfield holds them too."""
    env = make(engine=engine, **{"curriculum.init_level": -1, "curriculum.enabled": False})
    assert env.curriculum.levels.tolist() == [2] * 7
    assert env.curriculum.origins_w[STAIRS_DOWN, 2].item() == pytest.approx(0.75)
    for _ in range(25):
        _, _, dones, _ = env.step(torch.zeros(7, env.num_actions))
        assert not dones.any()
    sites = [env.model.site(f"{humanoid.PRIM_PATH}/{s}").id for s in humanoid.SOLE_SITES]
    soles = env.engine.site_xpos[:, sites].float()
    ground = env.ground_height_m(soles[..., :2])
    np.testing.assert_allclose(ground[STAIRS_DOWN].numpy(), [0.75, 0.75], atol=1e-6)
    np.testing.assert_allclose((soles[..., 2] - ground).numpy(), 0.0, atol=0.03 if engine == "warp" else 0.015)
    assert env.robot.data.root_pos_w[STAIRS_DOWN, 2].item() > 1.5


def test_action_latency_delays_targets_by_exactly_the_drawn_physics_steps():
    env = make(num_envs=6, transfer=TransferCfg(action_latency_range_s=(0.0, 0.02)))
    delay = env.transfer.action_delay.delay.clone()
    assert set(delay.tolist()) <= {0, 1, 2, 3, 4} and len(set(delay.tolist())) > 1
    kp = -env.engine.model_field("actuator_biasprm")[:, env.robot.actuator_idx, 1]
    seen = []
    step = env.engine.step

    def spy(n):
        seen.append(env.engine.ctrl[:, env.robot.actuator_idx].clone() / kp)  # the targets physics uses
        return step(n)

    env.engine.step = spy
    generator = torch.Generator().manual_seed(0)
    actions = [torch.rand(6, env.num_actions, generator=generator) * 0.2 for _ in range(2)]
    targets = [env.robot.default_joint_pos + a * env.cfg.action_scale for a in actions]
    for a in actions:
        env.step(a)
    assert len(seen) == 8  # one physics step at a time
    previous = [env.robot.default_joint_pos.expand(6, -1), targets[0]]
    for t in range(2):
        for s in range(4):
            expected = torch.where((s >= delay)[:, None], targets[t], previous[t])
            torch.testing.assert_close(seen[4 * t + s], expected.to(seen[0].dtype))


def test_action_latency_leaves_the_feet_sensor_as_one_policy_step():
    """The latency steps physics one step at a time; the contact sensor still sees each policy
    step once: with every drawn latency 0 the feet's touchdowns, air and contact times equal
    the plain batched step's (updated per physics step, a touchdown in the first three physics
    steps was lost to first_contact, which feet_air_time pays on)."""
    latency = TransferCfg(action_latency_range_s=(0.0, 0.02))
    lagged, plain = make(num_envs=12, transfer=latency), make(num_envs=12, transfer=latency)
    lagged.transfer.action_delay.delay.zero_()
    plain.transfer.action_delay = None  # the batched path
    generator = torch.Generator().manual_seed(0)
    touchdowns = 0
    for _ in range(15):
        actions = torch.rand(12, lagged.num_actions, generator=generator) * 2 - 1
        _, _, dones_lagged, _ = lagged.step(actions)
        _, _, dones_plain, _ = plain.step(actions)
        assert not dones_lagged.any() and not dones_plain.any()  # no reset draws a latency
        a, b = lagged.feet.data, plain.feet.data
        touchdowns += int(b.first_contact.sum())
        for name in ("first_contact", "in_contact", "current_air_time_s", "last_air_time_s",
                     "current_contact_time_s"):
            torch.testing.assert_close(getattr(a, name), getattr(b, name), msg=name)
    assert touchdowns >= 10


@pytest.mark.parametrize("final_obs", [False, True])
def test_observation_delay_shows_the_actor_last_steps_clean_observations(final_obs):
    """Also when each step computes observations twice (``final_obs``, as ``GymVectorEnv`` asks)."""
    env = make(num_envs=4, transfer=TransferCfg(observation_delay_range_steps=(1, 1)), observation_noise={})
    env.return_final_obs = final_obs
    critic = [env.get_privileged_observations()[:, :env.num_obs].clone()]
    generator = torch.Generator().manual_seed(0)
    for _ in range(3):
        obs, _, dones, _ = env.step(torch.rand(4, env.num_actions, generator=generator) * 0.2)
        assert not dones.any()
        torch.testing.assert_close(obs, critic[-1])
        critic.append(env.get_privileged_observations()[:, :env.num_obs].clone())
    assert not torch.equal(critic[-1], critic[-2])


def test_startup_randomization_reaches_each_worlds_model():
    env = make(num_envs=4, transfer=TransferCfg(joint_friction_range_n_m=(0.1, 0.5), armature_scale_range=(0.8, 1.2),
                                                com_offset_m=0.03))
    dofs = env.robot.dof_idx
    nominal_arm = env.model.dof_armature[dofs]
    for w in range(4):
        model = env.engine.get_model(w)
        friction = model.dof_frictionloss[dofs] - env.model.dof_frictionloss[dofs]
        assert ((friction >= 0.1) & (friction < 0.5)).all()
        ratio = model.dof_armature[dofs] / nominal_arm
        assert ((ratio >= 0.8) & (ratio < 1.2)).all()
        pelvis = env.model.body(f"{humanoid.PRIM_PATH}/pelvis").id
        offset = model.body_ipos[pelvis] - env.model.body_ipos[pelvis]
        assert (np.abs(offset) <= 0.03).all() and np.abs(offset).max() > 0
    frictions = env.engine.model_field("dof_frictionloss")[:, dofs]
    assert not torch.equal(frictions[0], frictions[1])


def test_height_scan_is_in_the_actor_observation():
    env = make(num_envs=2, observation_noise={})
    points = env.scanner.num_points
    assert points == 17 * 11 and env.num_obs == 72 + points
    scan = env.get_observations()[:, -points:]
    # on the platform at the start: every point that lies on it reads the standing height
    torch.testing.assert_close(scan, env._height_scan())
    blind = make(num_envs=2, scan_in_actor=False, observation_noise={})
    assert blind.num_obs == 72 and blind.num_privileged_obs == env.num_privileged_obs


@pytest.mark.slow  # ~65 s on a shared 2-core machine
def test_ppo_smoke_run(tmp_path):
    from ambulo.rl import train

    run = train("humanoid-rough", num_envs=8, max_iterations=2, seed=0, log_root=tmp_path, env_overrides=SMALL,
                ppo_overrides={"num_steps_per_env": 8})
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    assert [int(r["iteration"]) for r in rows] == [0, 1]
    assert all(np.isfinite(float(r["mean_reward"])) for r in rows if r.get("mean_reward"))


def test_training_logs_the_mean_terrain_level():
    env = make(num_envs=3, stats_interval_steps=1, episode_length_s=0.04)  # time-outs after 2 steps
    extras = [env.step(torch.zeros(3, env.num_actions))[3] for _ in range(2)]
    level = extras[-1]["episode"]["Curriculum/terrain_level"]
    assert level.item() == pytest.approx(env.curriculum.levels.float().mean().item())


@pytest.mark.parametrize("engine", ["mujoco", pytest.param("warp", marks=pytest.mark.slow)])
def test_robots_in_the_default_pose_stand_on_the_training_terrain(engine):
    """humanoid-rough as trained (the full terrain, first levels 0-4, wide transfer): 16 robots
    sending zero actions stand 1.5 s, calmly, with finite rewards. On MuJoCo Warp (its CPU device
    here) the foot boxes' heightfield contacts pointed down: joint speeds of 30-80 rad/s at the
    first step and 4 of 16 robots fell within 2 s (the first after 3 steps); the sole spheres
    (``sole_sphere_radius_m``) fixed it."""
    cfg = envs.make_cfg("humanoid-rough", num_envs=16, seed=0, num_threads=1, engine=engine, push_interval_s=None)
    env = HumanoidRoughEnv(cfg)
    for _ in range(75):
        _, rewards, dones, _ = env.step(torch.zeros(16, env.num_actions))
        assert not dones.any()
        assert torch.isfinite(rewards).all()
        assert env.engine.field("qvel").abs().max().item() < 10.0


@pytest.mark.slow  # ~20 s on a shared 2-core machine
def test_no_world_runs_away_under_ppo_first_exploration_on_warp():
    """16 robots as trained, PPO's first actions (unit Gaussian noise) for 100 steps on MuJoCo Warp's
    CPU device: no joint or base speed past 100 rad/s (the runaway guard is off here, so a runaway
    would show). Without the terrain contacts' depth limit (``warp_hfield_contact_depth_m=None``)
    one reached 152 rad/s (3 of 16 with another noise, 104-247 rad/s): a sole sphere sunk past its radius got a metres-deep contact."""
    cfg = envs.make_cfg("humanoid-rough", num_envs=16, seed=0, num_threads=1, engine="warp",
                        diverged_speed_bound=None)
    assert fastest_speed_under_noise(HumanoidRoughEnv(cfg), steps=100) < 100.0


def test_the_curriculum_compares_the_distance_walked_with_the_commanded_displacement():
    """The commands are in each robot's heading frame: the env integrates them turned into the world
    by the robot's heading. Hand values, 10 steps of 0.02 s: (vx, vy) = (1, 0) at yaw 0 asks 0.2 m
    along +x, at yaw 90 degrees 0.2 m along +y; (0, 0.5) at yaw 0 asks 0.1 m along +y, at 90 degrees
    0.1 m along -x."""
    env = make(num_envs=4, **{"curriculum.enabled": False})
    yaw = torch.tensor([0.0, 0.5 * np.pi, 0.0, 0.5 * np.pi])
    env.robot.write_root_pose(quat_w=torch.stack([torch.cos(yaw / 2), 0 * yaw, 0 * yaw, torch.sin(yaw / 2)], 1))
    env.engine.forward()
    cmd = env.commands
    cmd.cfg.heading_fraction, cmd.cfg.standing_fraction = 0.0, 0.0
    cmd.time_left_s.fill_(100.0)  # no resample inside the test
    cmd.is_heading.fill_(False), cmd.is_standing.fill_(False)
    cmd.command.copy_(torch.tensor([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.5, 0.0]]))
    env.command_displacement_w.zero_()
    headings = []
    for _ in range(10):
        _, _, dones, _ = env.step(torch.zeros(4, env.num_actions))
        assert not dones.any()
        headings.append(env.robot.data.heading_w.clone())
    # the robots stand (their yaw drifts by little): what the commands asked, to the heading's drift
    expected = torch.tensor([[0.2, 0.0], [0.0, 0.2], [0.0, 0.1], [-0.1, 0.0]])
    assert torch.allclose(env.command_displacement_w, expected, atol=5e-3)
    # exactly: each step's command turned by that step's heading, by hand
    v = cmd.command[:, :2]
    exact = sum(torch.stack([torch.cos(h) * v[:, 0] - torch.sin(h) * v[:, 1],
                             torch.sin(h) * v[:, 0] + torch.cos(h) * v[:, 1]], 1) * env.step_dt_s for h in headings)
    torch.testing.assert_close(env.command_displacement_w, exact.float(), atol=1e-6, rtol=0)


def test_a_robot_that_follows_turning_commands_exactly_is_never_moved_down():
    """20,000 simulated 20 s episodes of the task's commands (start-of-training ranges, yaw rates,
    headings, standing envs, resampling), each robot moving exactly as commanded
    (benchmarks/curriculum_demotions.py): none may move down a level. By the path length (|v|
    integrated), the rule until session 12, 13 % would under the forward commands (48 % under the
    omnidirectional ones the task had until session 18; the curriculum then drains to its easiest tiles)."""
    bench = load_script(ROOT / "benchmarks" / "curriculum_demotions.py")
    env = make(num_envs=1)
    result = bench.shares(env, bench.perfect_tracker(env, 20000, env.cfg.curriculum_start_scale, seed=0))
    assert result["down"] == 0.0
    assert result["down_by_path_length"] > 0.1


@pytest.mark.parametrize("play", [False, True])
def test_commands_ask_for_forward_walking_only(play):
    """The rough tasks command forward walking (Isaac Lab's rough humanoid ranges): over many
    resamples, training's and evaluation's envs never ask to walk backward or sideways, while the
    forward speeds and yaw rates still span their ranges (evaluation: the full ranges)."""
    env = make(num_envs=64, **({"curriculum_start_scale": None} if play else {}))
    cmd = []
    for _ in range(40):
        env.commands.resample(None)
        cmd.append(env.commands.command.clone())
    cmd = torch.cat(cmd)
    assert (cmd[:, 0] >= 0.0).all() and (cmd[:, 1] == 0.0).all()
    top = 1.0 if play else 0.4  # training starts from 0.4 of each range (the command curriculum)
    assert cmd[:, 0].max().item() > 0.9 * top and cmd[:, 2].min().item() < -0.9 * top


def test_the_evaluation_reports_each_robots_distance_from_its_start():
    """``distance_from_start_m``, reported by tile kind: a walker that stays on its start platform shows
    a small one beside flat ground's. Here: each robot teleported by a hand-chosen offset from where its
    episode started reads that offset's length after one step (a standing robot moves by mm)."""
    env = make(num_envs=3, **{"curriculum.enabled": False})
    env.reset()
    start = env.robot.data.root_pos_w[:, :2].float().clone()
    offset = torch.tensor([[0.3, 0.4], [0.0, -1.2], [0.0, 0.0]])
    env.robot.write_root_pose(pos_w=torch.cat([start + offset, env.robot.data.root_pos_w[:, 2:].float()], 1))
    env.engine.forward()
    env.step(torch.zeros(3, env.num_actions))
    distance = envs.spec("humanoid-rough").step_metrics(env)["distance_from_start_m"]
    torch.testing.assert_close(distance, torch.tensor([0.5, 1.2, 0.0]), atol=0.02, rtol=0)
