"""RLEnv's runaway guard (``EnvCfg.diverged_speed_bound``): a world whose speeds leave a physical
bound after a step, though finite and below the engine's own divergence check (mjMAXVAL, 1e10),
is terminated as diverged and earns nothing for that step. MuJoCo Warp's humanoid-rough worlds
ran away so (280 rad/s base spins) and their squared-velocity rewards reached -1e10."""

import pytest
import torch

import ambulo.envs as envs

SPIN_RAD_S = 300.0
"""A base spin no humanoid reaches (its bound is 100 rad/s), far below mjMAXVAL."""


def _spin_world_after_physics(env, world: int) -> None:
    """Make ``world`` run away inside the next physics step: its base spins about x and y."""
    simulate = env._simulate

    def runaway_simulate():
        diverged = simulate()
        env.engine.field("qvel")[world, 3:5] = SPIN_RAD_S  # the free joint's angular velocity
        return diverged

    env._simulate = runaway_simulate


def _humanoid(bound: float | None, engine: str = "mujoco"):
    return envs.make("humanoid-walk", num_envs=2, seed=0, num_threads=1, push_interval_s=None,
                     stats_interval_steps=1, diverged_speed_bound=bound, engine=engine)


@pytest.mark.parametrize("engine", ["mujoco", pytest.param("warp", marks=pytest.mark.slow)])
def test_a_runaway_world_is_terminated_as_diverged_with_zero_reward(engine):
    """On both engines (MuJoCo Warp on its CPU device here): the guard is masks, no host sync."""
    env = _humanoid(bound=100.0, engine=engine)
    env.reset()
    _spin_world_after_physics(env, world=1)
    _, rewards, dones, extras = env.step(torch.zeros(2, env.num_actions))
    assert dones.tolist() == [False, True]
    assert extras["terminated"].tolist() == [False, True]
    assert not extras["time_outs"].any()
    assert rewards[1].item() == 0.0 and rewards[0].item() != 0.0
    # the ended episode counts as diverged, and its zeroed step adds nothing to its sums
    episode = extras["episode"]
    assert episode["Episode/num_ended"].item() == 1.0
    assert episode["Episode_Termination/diverged"].item() == 1.0
    assert all(episode[f"Episode_Reward/{k}"].item() == 0.0 for k in env.reward_names)
    # reset in place: the world starts again from rest
    assert env.engine.field("qvel")[1].abs().max().item() < 1.0


def test_without_the_guard_the_runaway_world_earns_a_huge_penalty():
    """The guard's reason: the same spin, unguarded, costs ang_vel_xy_l2 ~ -2 x 300^2 x 0.05 x
    0.02 s = -180 in one step (and -1e10 at the speeds Warp reached) and the episode goes on."""
    env = _humanoid(bound=None)
    env.reset()
    _spin_world_after_physics(env, world=1)
    _, rewards, dones, _ = env.step(torch.zeros(2, env.num_actions))
    assert not dones[1]
    assert rewards[1].item() < -100.0


@pytest.mark.parametrize("speed_rad_s, diverged", [(99.0, False), (101.0, True), (float("nan"), True)])
def test_the_bound_applies_to_every_velocity_entry(speed_rad_s, diverged):
    """A joint speed (not only the base's) past the bound, or NaN, ends the episode; one just below does not."""
    env = _humanoid(bound=100.0)
    env.reset()
    simulate = env._simulate

    def joint_runaway():
        out = simulate()
        env.engine.field("qvel")[0, -1] = speed_rad_s  # the last joint
        return out

    env._simulate = joint_runaway
    _, rewards, dones, _ = env.step(torch.zeros(2, env.num_actions))
    assert dones.tolist() == [diverged, False]
    assert torch.isfinite(rewards).all()


def test_humanoid_tasks_get_the_humanoid_bound_and_others_the_generous_one():
    assert envs.make_cfg("humanoid-rough").diverged_speed_bound == 100.0
    assert envs.make_cfg("cartpole").diverged_speed_bound == 1000.0
