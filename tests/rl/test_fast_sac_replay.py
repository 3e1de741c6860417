"""The replay ring's n-step returns and the categorical projection, against hand-computed values."""

import pytest
import torch

from ambulo.rl.offpolicy.categorical import expected, project
from ambulo.rl.offpolicy.replay import ReplayRing

GAMMA = 0.5


def _ring_after(steps):
    """A ring of 2 worlds and 5 slots after ``steps``: (rewards (2,), terminated (2,), ended (2,))
    per step; observations are 100 * step + world, next observations 1000 + that."""
    ring = ReplayRing(num_envs=2, capacity=5, obs_dim=1, critic_obs_dim=0, action_dim=1, device="cpu")
    for i, (rewards, terminated, ended) in enumerate(steps):
        obs = torch.tensor([[100.0 * i], [100.0 * i + 1]])
        ring.add(obs, None, obs / 10, torch.tensor(rewards, dtype=torch.float32), obs + 1000, None,
                 torch.tensor(terminated), torch.tensor(ended))
    return ring


# world 0 terminates at step 1; world 1 times out at step 2
FIRST_FOUR = [((1.0, 10.0), (False, False), (False, False)),
              ((2.0, 20.0), (True, False), (True, False)),
              ((3.0, 30.0), (False, False), (False, True)),
              ((4.0, 40.0), (False, False), (False, False))]


def _at(ring, slots, worlds, n_step=3):
    return ring.transitions(torch.tensor(slots), torch.tensor(worlds), n_step, GAMMA)


def test_n_step_returns_stop_at_episode_ends_and_the_newest_step():
    ring = _ring_after(FIRST_FOUR)
    batch = _at(ring, [0, 2, 3, 0, 1], [0, 0, 0, 1, 1])
    # (0,0): 1 + .5*2, then terminated: no bootstrap
    # (2,0): 3 + .5*4, stops at the newest slot: bootstraps from step 3's next obs, gamma^2
    # (3,0): the newest step alone
    # (0,1): 10 + .5*20 + .25*30, the time-out at step 2 still bootstraps
    # (1,1): 20 + .5*30, ends at the time-out
    torch.testing.assert_close(batch.returns, torch.tensor([2.0, 5.0, 4.0, 27.5, 35.0]))
    torch.testing.assert_close(batch.discount, torch.tensor([0.0, 0.25, 0.5, 0.125, 0.25]))
    torch.testing.assert_close(batch.next_obs[:, 0], torch.tensor([1100.0, 1300.0, 1300.0, 1201.0, 1201.0]))
    torch.testing.assert_close(batch.obs[:, 0], torch.tensor([0.0, 200.0, 300.0, 1.0, 101.0]))
    torch.testing.assert_close(batch.actions[:, 0], torch.tensor([0.0, 20.0, 30.0, 0.1, 10.1]))
    # the critic reads the policy observations when the task has no privileged ones
    assert torch.equal(batch.critic_obs, batch.obs) and torch.equal(batch.next_critic_obs, batch.next_obs)


def test_one_step_returns_are_the_reward():
    ring = _ring_after(FIRST_FOUR)
    batch = _at(ring, [0, 1, 2], [1, 1, 1], n_step=1)
    torch.testing.assert_close(batch.returns, torch.tensor([10.0, 20.0, 30.0]))
    torch.testing.assert_close(batch.discount, torch.tensor([0.5, 0.5, 0.5]))


def test_returns_run_across_the_wrap_and_never_into_overwritten_slots():
    more = [((5.0, 0.0), (False, False), (False, False)),
            ((6.0, 0.0), (False, False), (False, False)),
            ((7.0, 0.0), (False, False), (False, False))]
    ring = _ring_after(FIRST_FOUR + more)  # steps 5, 6 overwrote slots 0, 1
    assert (ring.ptr, ring.size) == (2, 5)
    batch = _at(ring, [3, 1, 2, 4], [0, 0, 0, 0])
    # slot 3 (step 3): 4 + .5*5 + .25*6 across the wrap to slot 0
    # slot 1 (step 6): the newest, alone
    # slot 2 (step 2, the oldest): 3 + .5*4 + .25*5, its own episode's steps 3 and 4
    # slot 4 (step 4): 5 + .5*6 + .25*7
    torch.testing.assert_close(batch.returns, torch.tensor([8.0, 7.0, 6.25, 9.75]))
    torch.testing.assert_close(batch.discount, torch.tensor([0.125, 0.5, 0.125, 0.125]))
    torch.testing.assert_close(batch.next_obs[:, 0], torch.tensor([1500.0, 1600.0, 1400.0, 1600.0]))


def test_samples_draw_written_slots_only():
    ring = _ring_after(FIRST_FOUR[:2])
    batch = ring.sample(256, 3, GAMMA, torch.Generator().manual_seed(0))
    assert set(batch.obs[:, 0].tolist()) == {0.0, 1.0, 100.0, 101.0}


def test_projection_splits_mass_between_neighbouring_atoms():
    probs = torch.tensor([[0.2, 0.3, 0.5]] * 3)  # atoms 0, 1, 2
    returns, discount = torch.tensor([0.5, 1.5, 0.25]), torch.tensor([0.5, 1.0, 0.0])
    target = project(probs, returns, discount, v_min=0.0, v_max=2.0)
    # row 0: atoms move to 0.5, 1.0, 1.5; row 1: to 1.5, 2.5, 3.5, clipped at 2; row 2: all at 0.25
    torch.testing.assert_close(target, torch.tensor([[0.1, 0.65, 0.25], [0.0, 0.1, 0.9], [0.75, 0.25, 0.0]]))
    # inside the support the projection keeps the mean: returns + discount * E[z]
    atoms = torch.tensor([0.0, 1.0, 2.0])
    assert expected(target[0], atoms) == pytest.approx(0.5 + 0.5 * 1.3)


def test_samples_are_uniform_over_the_written_slots_and_worlds():
    """Every written (slot, world) pair is drawn about equally often and unwritten slots never:
    a chi-square statistic over the 3 x 2 written cells, then over the full 5 x 2 ring."""
    for steps, slots in ((FIRST_FOUR[:3], 3), (FIRST_FOUR + FIRST_FOUR[:2], 5)):  # partly filled, wrapped
        ring = _ring_after(steps)
        draws = 60_000
        batch = ring.sample(draws, 1, GAMMA, torch.Generator().manual_seed(1))
        # observations are 100 * step + world; a wrapped ring keeps steps 1 .. 5 in slots 0 .. 4
        steps_seen = (batch.obs[:, 0] // 100).long() - (len(steps) - slots)
        worlds = (batch.obs[:, 0] % 100).long()
        assert steps_seen.min() >= 0 and steps_seen.max() < slots, "drew an unwritten or overwritten slot"
        counts = torch.bincount(steps_seen * 2 + worlds, minlength=2 * slots).double()
        expected = draws / (2 * slots)
        chi2 = float(((counts - expected) ** 2 / expected).sum())
        # chi-square with 2 * slots - 1 <= 9 degrees of freedom: 99.99th percentile < 34; one cell
        # never drawn adds draws / (2 * slots) >= 6,000
        assert chi2 < 34.0, (counts.tolist(), chi2)
