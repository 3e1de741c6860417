"""FastSAC/FastTD3's joint-limit action bounds: each action bounded by its joint's farther limit from the
default pose (``OffPolicyCfg.joint_limit_bounds``), the rough tasks' default."""

import pytest
import torch

import ambulo.envs as envs
from ambulo.rl.offpolicy import OffPolicyRunner, offpolicy_cfg
from ambulo.rl.offpolicy.networks import Actor

# humanoid.xml: knee range (-0.05, 2.4) rad, home 0.4 -> 2.0 / 0.25 = 8.0; ankle roll (-0.4, 0.4), home 0
# -> 1.6; hip pitch (-2.1, 0.5), home -0.2 -> 1.9 / 0.25 = 7.6 (humanoid-walk's action_scale 0.25)
BY_HAND = {"left_knee": 8.0, "right_knee": 8.0, "left_ankle_roll": 1.6, "left_hip_pitch": 7.6}


@pytest.fixture(scope="module")
def rough():
    env = envs.make("humanoid-rough", num_envs=2, device="cpu")
    yield env
    env.close()


def test_a_humanoids_bounds_are_its_joints_farther_limits_in_action_units(rough):
    bounds = rough.action_bounds()
    names = rough.robot.joint_names
    assert bounds.shape == (rough.num_actions,)
    for joint, value in BY_HAND.items():
        assert bounds[names.index(joint)].item() == pytest.approx(value, abs=1e-5)


@pytest.mark.parametrize("algo", ["fast-sac", "fast-td3"])
def test_the_actor_reaches_each_joints_bound_and_no_further(rough, algo):
    cfg = offpolicy_cfg("humanoid-rough", algo, num_envs=2, actor_hidden_dims=(16,), critic_hidden_dims=(16,))
    assert cfg.joint_limit_bounds  # the rough tasks' default
    runner = OffPolicyRunner(rough, cfg, training=False)
    actor, bounds = runner.alg.actor, rough.action_bounds()
    with torch.no_grad():  # a mean far past the tanh's knee: the deterministic action sits at the bound
        actor.net[-1].bias[:rough.num_actions] = 20.0
        actor.net[-1].weight.zero_()
    obs = torch.zeros(4, rough.num_obs)
    assert torch.allclose(actor(obs), bounds.expand(4, -1), atol=1e-4)
    explored = runner.alg.explore(obs, torch.full((4, 1), 5.0))  # fast-td3: noise far past the bound
    assert (explored.abs() <= bounds + 1e-5).all()
    knee = rough.robot.joint_names.index("left_knee")
    assert explored[:, knee].min() > 2.0  # past the one bound flat ground uses (0.5 rad)


def test_without_joint_limit_bounds_every_action_has_the_one_bound(rough):
    cfg = offpolicy_cfg("humanoid-rough", num_envs=2, actor_hidden_dims=(16,), critic_hidden_dims=(16,),
                        joint_limit_bounds=False)
    actor = OffPolicyRunner(rough, cfg, training=False).alg.actor
    assert torch.equal(actor.action_bound, torch.full((rough.num_actions,), cfg.action_bound))


def test_a_task_without_bounds_is_refused_in_one_line():
    env = envs.make("cartpole", num_envs=2, device="cpu")
    cfg = offpolicy_cfg("cartpole", joint_limit_bounds=True)
    with pytest.raises(ValueError, match="gives no per-action bounds") as err:
        OffPolicyRunner(env, cfg, training=False)
    assert "\n" not in str(err.value)
    env.close()


def test_bounds_stay_out_of_checkpoints():
    # rebuilt from the run's settings and env; checkpoints saved before the bounds were a tensor load as before
    actor = Actor(3, 2, (8,), stochastic=True, action_bound=torch.tensor([1.0, 4.0]))
    assert "action_bound" not in actor.state_dict()
    Actor(3, 2, (8,), stochastic=True, action_bound=2.0).load_state_dict(actor.state_dict())
    with pytest.raises(ValueError, match="finite and > 0"):
        Actor(3, 2, (8,), stochastic=True, action_bound=torch.tensor([1.0, float("inf")]))
