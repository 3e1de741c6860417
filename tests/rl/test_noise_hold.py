"""``OffPolicyCfg.noise_hold_steps``: exploration noise held for k env steps per world, drawn anew when the hold
runs out or the world resets (gSDE-style consistent exploration), for fast-sac and fast-td3."""

import pytest
import torch

from ambulo import envs
from ambulo.rl.offpolicy import OffPolicyRunner, offpolicy_cfg


def _runner(algo: str, hold: int):
    env = envs.make("cartpole", num_envs=3, seed=0)
    cfg = offpolicy_cfg("cartpole", algo, num_envs=3, random_steps=0, learning_starts=64, noise_hold_steps=hold,
                        exploration_noise_std_range=(0.3, 0.3))
    runner = OffPolicyRunner(env, cfg, seed=0)
    actor = runner.alg.actor
    with torch.no_grad():  # the actor's mean 0 and, for fast-sac, a std of 0.3 everywhere: actions are noise only
        actor.net[-1].weight.zero_()
        actor.net[-1].bias.zero_()
        if algo == "fast-sac":
            unit = (torch.log(torch.tensor(0.3)) - actor.log_std_min) / (0.5 * (actor.log_std_max - actor.log_std_min))
            actor.net[-1].bias[env.num_actions:] = torch.atanh(unit - 1.0)
    taken = []
    explore = runner.alg.explore
    runner.alg.explore = lambda *a, **k: taken.append(explore(*a, **k)) or taken[-1]
    return runner, taken


def _end_world_1_at(runner, call: int):
    """Make the env report world 1 done at its ``call``-th step (0-based)."""
    step, calls = runner.env.step, [0]

    def stepped(actions):
        out = step(actions)
        if calls[0] == call:
            out[2][1] = True
        calls[0] += 1
        return out
    runner.env.step = stepped


@pytest.mark.parametrize("algo", ["fast-sac", "fast-td3"])
def test_noise_is_held_for_k_steps_then_drawn_anew(algo):
    runner, taken = _runner(algo, hold=4)
    _end_world_1_at(runner, 5)
    for _ in range(10):
        runner._collect()
    a = torch.stack(taken)  # (10, 3, A)
    world0 = a[:, 0]
    for start in (0, 4):  # steps 0-3 and 4-7 share their draw; each block differs from the next
        assert torch.equal(world0[start:start + 4], world0[start].expand(4, -1))
    assert not torch.equal(world0[3], world0[4]) and not torch.equal(world0[7], world0[8])
    # world 1 ended at step 5: step 6 draws anew although its hold had 2 steps left
    world1 = a[:, 1]
    assert torch.equal(world1[4], world1[5]) and not torch.equal(world1[5], world1[6])
    assert torch.equal(world1[6], world1[9])  # and holds from there: steps 6-9
    assert not torch.equal(a[0, 0], a[0, 2])  # worlds draw their own noise


def test_without_a_hold_every_step_draws_anew():
    runner, taken = _runner("fast-sac", hold=1)
    for _ in range(3):
        runner._collect()
    assert not torch.equal(taken[0], taken[1]) and not torch.equal(taken[1], taken[2])


def test_a_hold_below_one_is_refused():
    with pytest.raises(Exception, match="noise_hold_steps"):
        offpolicy_cfg("cartpole", "fast-sac", noise_hold_steps=0)
