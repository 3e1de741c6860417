"""FastSAC/FastTD3's joint-limit action bounds: each action bounded by its joint's farther limit from the
default pose (``OffPolicyCfg.joint_limit_bounds``), the rough tasks' default."""

import math

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
    obs = torch.zeros(64, rough.num_obs)
    assert torch.allclose(actor(obs), bounds.expand(64, -1), atol=1e-4)
    torch.manual_seed(0)
    explored = runner.alg.explore(obs, torch.full((64, 1), 5.0))  # fast-td3: noise far past the bound
    assert (explored.abs() <= bounds + 1e-5).all()
    knee = rough.robot.joint_names.index("left_knee")
    # most explored knee targets sit past the one bound flat ground uses (2: 0.5 rad); the median, as
    # fast-td3's noise of std 5 around a mean at the bound 8 sends a few of 64 below 2
    assert explored[:, knee].median() > 2.0


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


def _learner(bounds: torch.Tensor, target_per_action: float):
    from ambulo.rl.offpolicy.learner import FastOffPolicy

    # a bare learner on made-up sizes: no task, so no mirror maps for humanoid-walk's symmetry
    cfg = offpolicy_cfg("humanoid-walk", "fast-sac", num_envs=2, actor_hidden_dims=(8,), critic_hidden_dims=(8,),
                        target_entropy_per_action=target_per_action, symmetry=False)
    return FastOffPolicy(cfg, 3, 3, bounds.numel(), "cpu", action_bounds=bounds)


def test_the_entropy_target_is_in_action_units_so_wider_bounds_do_not_widen_the_noise():
    """The temperature's drive ``E[log pi] + target`` is the same for two policies with the same spread of
    actions (std 0.05 in action units), one bounded at 1 and one at 4: the bound-4 policy is not pushed
    to explore more. Its tanh output is 4x narrower, so its log-probabilities are log 4 higher per action."""
    torch.manual_seed(0)
    drives = []
    for bound in (1.0, 4.0):
        learner = _learner(torch.full((6,), bound), target_per_action=-2.0)
        actor = learner.actor
        with torch.no_grad():  # mean 0, pre-tanh std 0.05 / bound: actions ~ N(0, 0.05) (tanh ~ linear there)
            actor.net[-1].weight.zero_()
            actor.net[-1].bias.zero_()
            log_std = torch.tensor(math.log(0.05 / bound))
            unit = (log_std - actor.log_std_min) / (0.5 * (actor.log_std_max - actor.log_std_min)) - 1.0
            actor.net[-1].bias[6:] = torch.atanh(unit)
            actions, log_prob, _ = actor.sample(torch.zeros(20000, 3))
        assert actions.std().item() == pytest.approx(0.05, rel=0.02)
        drives.append(log_prob.mean().item() + learner.target_entropy)
    assert drives[0] == pytest.approx(drives[1], abs=0.05)
    # and by hand: 6 actions of N(0, 0.05): entropy 6 x 0.5 log(2 pi e 0.05^2) = -9.46 nats, under the target
    # -12, so the temperature falls (the drive, log pi + target = 9.46 - 12, is negative)
    assert drives[0] == pytest.approx(-6 * 0.5 * math.log(2 * math.pi * math.e * 0.05 ** 2) - 12.0, abs=0.05)


def test_the_walking_tasks_target_is_unchanged_at_their_bound_of_2():
    """humanoid-walk's FastSAC (bound 2 on every action) tunes its temperature exactly as before the target
    moved to action units: the tanh output's entropy target is still 0."""
    learner = _learner(torch.full((21,), 2.0), target_per_action=offpolicy_cfg("humanoid-walk").target_entropy_per_action)
    assert learner.target_entropy == pytest.approx(0.0, abs=1e-5)


def test_joint_limit_bounds_lower_the_tanh_target_by_each_bounds_log(rough):
    bounds = rough.action_bounds()
    cfg = offpolicy_cfg("humanoid-rough", "fast-sac", num_envs=2, actor_hidden_dims=(8,), critic_hidden_dims=(8,))
    learner = OffPolicyRunner(rough, cfg, training=False).alg
    expected = math.log(2.0) * rough.num_actions - sum(math.log(b) for b in bounds.tolist())
    assert learner.target_entropy == pytest.approx(expected, abs=1e-4)
    assert learner.target_entropy < -10.0  # knees (8), hips (7.6): far narrower tanh noise than at bound 2
