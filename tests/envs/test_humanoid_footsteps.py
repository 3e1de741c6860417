"""humanoid-footsteps: the plan sampler keeps the planner's limits, touchdowns score and advance the
targets, and the task trains and evaluates on the CPU."""

import math

import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.envs.footstep_sampler import FootstepSampler, FootstepSamplerCfg, relative_xyyaw, start_feet_xyyaw_w
from ambulo.nav.footstep_lattice import relative, steps_within_limits


def sampled_plans(num_plans=256, num_steps=60, seed=0):
    """(P, S + 2, 3) plans in the planner's layout (rows 0, 1 the start feet, row 1 the first
    stance) and (P, S + 2) sides, drawn by the sampler."""
    gen = torch.Generator().manual_seed(seed)
    sampler = FootstepSampler(FootstepSamplerCfg(), gen, torch.device("cpu"))
    base = torch.zeros(num_plans, 3)
    base[:, 2] = torch.rand(num_plans, generator=gen) * 2 * math.pi - math.pi
    feet = start_feet_xyyaw_w(base, 0.03, 0.18)
    first = torch.where(torch.rand(num_plans, generator=gen) < 0.5, 1.0, -1.0)  # side moving first
    stance = torch.where((first < 0)[:, None], feet[:, 0], feet[:, 1])
    swing = torch.where((first > 0)[:, None], feet[:, 0], feet[:, 1])
    poses, sides = [swing, stance], [first, -first]
    segments = sampler.draw_segments(num_plans)
    for _ in range(num_steps):
        new, segments = sampler.next_footstep(poses[-1], sides[-1], segments)
        poses.append(new)
        sides.append(-sides[-1])
    return torch.stack(poses, dim=1).double().numpy(), torch.stack(sides, dim=1).numpy()


def test_sampled_plans_keep_the_planner_limits_and_vary():
    plans, sides = sampled_plans()
    limits = FootstepSamplerCfg().limits
    stance, swing = plans[:, 1:-1].reshape(-1, 3), plans[:, 2:].reshape(-1, 3)
    rel = relative(stance, swing)  # the planner's own frames and limit check
    assert steps_within_limits(rel, sides[:, 1:-1].reshape(-1), limits).all()
    assert np.all(sides[:, 1:] == -sides[:, :-1])  # alternating feet
    # straight walks, turns both ways, forward, in place and backward steps, several widths
    assert (np.abs(rel[:, 2]) < 0.05).mean() > 0.3 and (rel[:, 2] > 0.2).any() and (rel[:, 2] < -0.2).any()
    assert (rel[:, 0] > 0.2).any() and (np.abs(rel[:, 0]) < 0.02).any() and (rel[:, 0] < -0.05).any()
    assert np.ptp(np.abs(rel[:, 1])) > 0.1


def test_touchdowns_score_advance_and_respect_the_swing_foot():
    env = envs.make("humanoid-footsteps", num_envs=3, seed=0, num_threads=1, play=True)
    targets = torch.tensor([[1.0, 0.0, 0.0], [1.2, 0.2, 0.0]])
    env.targets_xyyaw_w[:] = targets
    env.target_sides[:] = torch.tensor([-1.0, 1.0])  # the right foot swings
    env.placement_error_m.fill_(0.5)
    env.since_advance_s.fill_(1.0)  # the plan has waited 1 s: the feet below took off after it last moved
    soles = torch.tensor([[0.9, 0.2, 0.0], [1.03, 0.0, 0.1]]).expand(3, 2, 3).clone()
    # world 0: the right foot lands after 0.3 s in the air; world 1: only the left (stance) foot
    # lands; world 2: the right foot lands after 0.1 s (a shuffle, shorter than min_air_time_s)
    first_contact = torch.tensor([[False, True], [True, False], [False, True]])
    air_s = torch.tensor([[0.0, 0.3], [0.3, 0.0], [0.0, 0.1]])
    env.update_plan(soles, first_contact, air_s)
    assert env.touchdown.tolist() == [True, False, False]
    assert env.touchdown_error_m[0].item() == pytest.approx(0.03, abs=1e-6)
    assert env.touchdown_yaw_error_rad[0].item() == pytest.approx(0.1, abs=1e-6)
    assert env.placement_error_m.tolist() == pytest.approx([0.03, 0.5, 0.5], abs=1e-6)
    assert env.steps_taken.tolist() == [1, 0, 0]
    # world 0 advanced: its second target is first, a left-foot step follows it within the limits
    torch.testing.assert_close(env.targets_xyyaw_w[0, 0], targets[1])
    assert env.target_sides[0].tolist() == [1.0, -1.0]
    step = relative_xyyaw(env.targets_xyyaw_w[0, 0], env.targets_xyyaw_w[0, 1]).double().numpy()[None]
    assert steps_within_limits(step, np.array([1]), FootstepSamplerCfg().limits).all()
    torch.testing.assert_close(env.targets_xyyaw_w[1:], targets.expand(2, 2, 3))
    rewards = env._get_rewards()
    expected = math.exp(-(0.03 / env.cfg.placement_std_m) ** 2)
    assert rewards["foot_placement"].tolist() == pytest.approx([expected, 0.0, 0.0], abs=1e-6)
    assert rewards["foot_yaw"][0].item() == pytest.approx(math.exp(-(0.1 / env.cfg.yaw_std_rad) ** 2), abs=1e-6)
    # the swing foot of world 1 (right, at 0.03 m from its target) is where progress counts from
    assert env._swing_distance_m[1].item() == pytest.approx(0.03, abs=1e-6)


def test_a_missed_touchdown_is_scored_and_the_same_foot_steps_again():
    env = envs.make("humanoid-footsteps", num_envs=2, seed=0, num_threads=1, play=True)
    targets = torch.tensor([[1.0, 0.0, 0.0], [1.2, 0.2, 0.0]])
    env.targets_xyyaw_w[:] = targets
    env.target_sides[:] = torch.tensor([-1.0, 1.0])  # the right foot swings
    env.since_advance_s.fill_(1.0)
    # the right sole lands 0.15 m (world 0: within advance_radius_m) and 0.3 m (world 1) from its target
    soles = torch.tensor([[[0.9, 0.2, 0.0], [0.85, 0.0, 0.0]], [[0.9, 0.2, 0.0], [0.7, 0.0, 0.0]]])
    env.update_plan(soles, torch.tensor([[False, True]] * 2), torch.tensor([[0.0, 0.4]] * 2))
    assert env.touchdown.tolist() == [True, True]
    assert env.touchdown_error_m.tolist() == pytest.approx([0.15, 0.3], abs=1e-6)
    assert env.steps_taken.tolist() == [1, 0]
    torch.testing.assert_close(env.targets_xyyaw_w[0, 0], targets[1])  # advanced
    torch.testing.assert_close(env.targets_xyyaw_w[1], targets)  # the miss: same targets, same swing foot
    assert env.target_sides[1].tolist() == [-1.0, 1.0]


def test_shuffles_cost_and_strides_earn_whatever_the_command():
    env = envs.make("humanoid-footsteps", num_envs=2, seed=0, num_threads=1, play=True)
    threshold = env.cfg.air_time_threshold_s
    env.feet.data.first_contact[:] = torch.tensor([[False, True], [True, False]])
    env.last_support_air_s[:] = torch.tensor([[0.0, threshold + 0.2], [threshold - 0.3, 0.0]])
    env.commands.command.zero_()  # as in training: humanoid-walk's term would pay nothing at a zero command
    reward = env._get_rewards()["step_air_time"]
    assert reward.tolist() == pytest.approx([0.2, -0.3], abs=1e-6)


def test_a_flight_phase_earns_no_air_time_reward():
    """Both worlds lift the right foot for 25 policy steps (0.5 s) and land it in the 26th: world 0
    walks (the left foot stands throughout), world 1 runs (the left foot leaves for the last 10
    steps and lands after the right). The sensor's air time is 26 x 0.02 = 0.52 s in both; the
    reward counts the right foot's 26 steps in world 0 and its 15 before the flight in world 1
    (the landing step too had the left foot up), and the left foot's 2 steps after the right landed."""
    env = envs.make("humanoid-footsteps", num_envs=2, seed=0, num_threads=1, play=True)
    dt, threshold = env.step_dt_s, env.cfg.air_time_threshold_s
    assert dt == pytest.approx(0.02)
    no = torch.zeros(2, 2, dtype=torch.bool)
    for k in range(25):  # (left, right) in contact: the right foot swings; world 1's left leaves at k = 15
        env.update_support_air(torch.tensor([[True, False], [k < 15, False]]), no)
    right_lands = torch.tensor([[False, True], [False, True]])
    env.update_support_air(torch.tensor([[True, True], [False, True]]), right_lands)
    torch.testing.assert_close(env.last_support_air_s[:, 1], torch.tensor([26 * dt, 15 * dt]))
    env.feet.data.first_contact[:] = right_lands
    env.feet.data.last_air_time_s[:] = 26 * dt  # what the contact sensor measured, flight included
    reward = env._get_rewards()["step_air_time"]
    assert reward.tolist() == pytest.approx([26 * dt - threshold, 15 * dt - threshold], abs=1e-5)
    # world 1's left foot lands a step later: 2 steps in the air over a standing right foot
    env.update_support_air(torch.tensor([[True, True], [True, True]]), torch.tensor([[False, False], [True, False]]))
    assert env.last_support_air_s[1, 0].item() == pytest.approx(2 * dt, abs=1e-6)
    assert env._support_air_s.abs().max().item() == 0.0  # both feet down: the timers restart


def test_a_landing_from_before_the_advance_is_not_a_touchdown():
    """After a flight the stance foot lands just after the swing foot advanced the plan: not a
    touchdown (not scored, the plan stays), even on its new target; its next step is one."""
    env = envs.make("humanoid-footsteps", num_envs=2, seed=0, num_threads=1, play=True)
    dt = env.step_dt_s
    targets = torch.tensor([[1.0, 0.0, 0.0], [1.2, 0.2, 0.0]])
    env.targets_xyyaw_w[:] = targets
    env.target_sides[:] = torch.tensor([-1.0, 1.0])  # the right foot swings
    env.since_advance_s.fill_(1.0)
    soles = torch.tensor([[0.9, 0.2, 0.0], [1.0, 0.0, 0.0]]).expand(2, 2, 3).clone()
    right, left, none = (torch.tensor([[False, True]] * 2), torch.tensor([[True, False]] * 2),
                         torch.zeros(2, 2, dtype=torch.bool))
    env.update_plan(soles, right, torch.full((2, 2), 0.3))  # the right foot lands on its target: advance
    assert env.touchdown.tolist() == [True, True] and env.steps_taken.tolist() == [1, 1]
    soles[:, 0] = targets[1]  # the left sole on its (new) target
    # one step later world 0's left foot lands from a 0.32 s flight: it took off 0.3 s before the
    # advance; world 1's stays in the air
    env.update_plan(soles, torch.tensor([[True, False], [False, False]]), torch.tensor([[0.32, 0.0]] * 2))
    assert env.touchdown.tolist() == [False, False] and env.flight_landing.tolist() == [True, False]
    assert env.steps_taken.tolist() == [1, 1] and env.touchdown_error_m.tolist() == [0.0, 0.0]
    torch.testing.assert_close(env.targets_xyyaw_w[:, 0], targets[1].expand(2, 3))  # still its target
    for _ in range(7):
        env.update_plan(soles, none, torch.zeros(2, 2))
    # 9 steps (0.18 s) after the advance the left foot lands after 0.16 s in the air (world 0: it
    # took off after the advance, a step) or 0.2 s (world 1: in the air since before it)
    assert env.since_advance_s.tolist() == pytest.approx([8 * dt] * 2, abs=1e-6)
    env.update_plan(soles, left, torch.tensor([[0.16, 0.0], [0.2, 0.0]]))
    assert env.touchdown.tolist() == [True, False] and env.flight_landing.tolist() == [False, True]
    assert env.steps_taken.tolist() == [2, 1] and env.since_advance_s[0].item() == 0.0


def test_swing_touchdown_counts_a_take_off_after_the_advance():
    from ambulo.envs.footstep_gait import swing_touchdown

    dt = 0.02
    since = torch.tensor([0.2, 0.2, 0.2, 0.2, 0.1])  # s since the plan advanced (10 steps; 5 in the last)
    air = torch.tensor([0.2, 0.22, 0.16, 0.14, 0.1])  # the landing foot's flight, s
    landed = torch.tensor([True, True, True, True, False])
    touchdown, flight = swing_touchdown(landed, air, since, 0.15, dt)
    # lifted in the step after the advance (counted); one step before it (not); a short shuffle; no landing
    assert touchdown.tolist() == [True, False, True, False, False]
    assert flight.tolist() == [False, True, False, False, False]


def test_command_is_the_two_targets_in_the_heading_frame():
    env = envs.make("humanoid-footsteps", num_envs=2, seed=1, num_threads=1, play=True)
    base = env._base_xyyaw_w()
    cmd = env.footstep_command().reshape(2, 2, 5)
    back = torch.cat([cmd[..., :2], torch.atan2(cmd[..., 3], cmd[..., 2])[..., None]], dim=-1)
    from ambulo.envs.footstep_sampler import compose_xyyaw

    torch.testing.assert_close(compose_xyyaw(base[:, None].expand(-1, 2, -1), back), env.targets_xyyaw_w,
                               atol=1e-5, rtol=0)
    torch.testing.assert_close(cmd[..., 4], env.target_sides)
    # the first target is the first swing foot's first step: within reach of the start stance
    assert (torch.linalg.vector_norm(cmd[:, 0, :2], dim=-1) < 0.45).all()


def test_trains_and_evaluates_on_the_cpu(tmp_path):
    from ambulo.rl import evaluate, train

    run = train("humanoid-footsteps", num_envs=8, max_iterations=2, seed=0, log_root=tmp_path,
                ppo_overrides={"num_steps_per_env": 8})
    result = evaluate(run, num_episodes=4, episode_length_s=1.0, quiet=True)
    assert result["criteria"] == ["places_feet"] and isinstance(result["places_feet"], bool)
    assert math.isfinite(result["mean_placement_error_m"]) and result["mean_placement_error_m"] > 0
    assert 0.0 <= result["mean_placement_miss_5cm"] <= 1.0 and "mean_touchdowns_per_s" in result


def test_places_feet_is_the_median_of_the_held_errors():
    from ambulo.envs.humanoid_footsteps import PLACES_FEET

    walks = {"fall_rate": 0.0, "mean_touchdowns_per_s": 1.8}
    assert PLACES_FEET.holds({**walks, "mean_placement_miss_5cm": 0.4})  # most steps within 5 cm
    assert not PLACES_FEET.holds({**walks, "mean_placement_miss_5cm": 0.6})
    assert not PLACES_FEET.holds({**walks, "mean_placement_miss_5cm": 0.0, "fall_rate": 0.1})
    assert not PLACES_FEET.holds({**walks, "mean_placement_miss_5cm": 0.0, "mean_touchdowns_per_s": 0.2})
    env = envs.make("humanoid-footsteps", num_envs=3, seed=0, num_threads=1, play=True)
    env.placement_error_m[:] = torch.tensor([0.01, 0.049, 0.06])
    miss = envs.spec("humanoid-footsteps").step_metrics(env)["placement_miss_5cm"]
    assert miss.tolist() == [0.0, 0.0, 1.0]


def test_follows_given_plans_then_the_sampler():
    env = envs.make("humanoid-footsteps", num_envs=2, seed=2, num_threads=1, play=True)
    feet = env.soles_xyyaw_w()  # rows 0, 1 of the plan: where the robot stands, left first to move
    rows = [feet[:, 0], feet[:, 1]]
    for k in range(4):  # 4 steps of 0.1 m straight ahead, left, right, left, right
        rows.append(relative_to_world(rows[-1], torch.tensor([0.1, 0.18 if k % 2 == 0 else -0.18, 0.0])))
    plans = torch.stack(rows, dim=1)
    sides = torch.tensor([1.0, -1.0, 1.0, -1.0, 1.0, -1.0]).expand(2, 6)
    with pytest.raises(ValueError, match="alternate"):
        env.follow_plans(plans, torch.ones(2, 6), torch.tensor([4, 4]))
    obs = env.follow_plans(plans, sides, torch.tensor([4, 3]))
    assert torch.equal(obs, env.obs_buf) and env.steps_taken.tolist() == [0, 0]
    torch.testing.assert_close(env.targets_xyyaw_w, plans[:, 2:4])
    assert env.target_sides.tolist() == [[1.0, -1.0]] * 2
    never = torch.zeros(2, 2, dtype=torch.bool)
    for k in range(3):  # the swing foot lands exactly on its target each time
        soles = env.soles_xyyaw_w().clone()
        swing = env._swing_index()
        soles[torch.arange(2), swing] = env.targets_xyyaw_w[:, 0]
        first_contact = never.clone()
        first_contact[torch.arange(2), swing] = True
        env.since_advance_s.fill_(0.5)  # it took off after the last advance
        env.update_plan(soles, first_contact, torch.full((2, 2), 0.4))
        assert env.touchdown_error_m.tolist() == pytest.approx([0.0, 0.0], abs=1e-5)
        if k == 0:
            torch.testing.assert_close(env.targets_xyyaw_w, plans[:, 3:5])
        if k == 1:  # world 1's plan has 3 steps: on its last (row 4), the sampler draws the next
            torch.testing.assert_close(env.targets_xyyaw_w[:, 0], plans[:, 4])
            torch.testing.assert_close(env.targets_xyyaw_w[0, 1], plans[0, 5])
            assert not torch.allclose(env.targets_xyyaw_w[1, 1], plans[1, 5])
    # world 0's plan has 4 steps: after 3 touchdowns it is on step 4 (row 5)
    torch.testing.assert_close(env.targets_xyyaw_w[0, 0], plans[0, 5])
    assert env.steps_taken.tolist() == [3, 3]
    # a reset ends the plan: the sampler draws the new episode's targets
    env.reset(torch.tensor([0]))
    assert env._plan_rows.tolist() == [0, 5]


def relative_to_world(pose, rel):
    from ambulo.envs.footstep_sampler import compose_xyyaw

    return compose_xyyaw(pose, rel.expand_as(pose))


def test_advance_by_mask_as_by_indices():
    """A GPU selects the touchdown worlds with a mask (``core.rows``), the CPU with indices: the
    targets move alike (the drawn footsteps differ only by how many rows were drawn)."""
    pair = [envs.make("humanoid-footsteps", num_envs=3, seed=4, num_threads=1, play=True) for _ in range(2)]
    feet = pair[0].soles_xyyaw_w()
    rows = [feet[:, 0], feet[:, 1]]
    for k in range(3):
        rows.append(relative_to_world(rows[-1], torch.tensor([0.15, 0.18 if k % 2 == 0 else -0.18, 0.1])))
    plans, sides = torch.stack(rows, dim=1), torch.tensor([1.0, -1.0, 1.0, -1.0, 1.0]).expand(3, 5)
    for env in pair:
        env.follow_plans(plans, sides, torch.tensor([3, 3, 3]))
    before = pair[0].targets_xyyaw_w.clone()
    pair[0]._advance(torch.tensor([0, 2]))
    pair[1]._advance(torch.tensor([True, False, True]))
    for env in pair:
        torch.testing.assert_close(env.targets_xyyaw_w[[0, 2]], plans[[0, 2], 3:5])  # the plan's next row
        torch.testing.assert_close(env.targets_xyyaw_w[1], before[1])  # untouched
        assert env.steps_taken.tolist() == [1, 0, 1] and env._plan_next.tolist() == [5, 4, 5]
        assert env.target_sides.tolist() == [[-1.0, 1.0], [1.0, -1.0], [-1.0, 1.0]]
