"""``OffPolicyCfg.overlap_collect``: each env step collected beside the updates of the steps before
it. On the CPU the same order runs sequentially; these tests check that order's rules: the ring
never hands out the slot being written, the worlds act with a copy of the actor one update round
old, the normalizers see every step, and a resumed run acts with its checkpoint's weights."""

import pytest
import torch

from ambulo import envs
from ambulo.rl.offpolicy import OffPolicyRunner, offpolicy_cfg
from ambulo.rl.offpolicy.replay import ReplayRing


def _ring(steps: int, capacity: int = 4) -> ReplayRing:
    ring = ReplayRing(1, capacity, 1, 0, 1, "cpu")
    ring.write_ahead = True
    for i in range(steps):
        one = torch.full((1, 1), float(i))
        ring.add(one, None, one, torch.tensor([float(i)]), one, None, torch.tensor([False]), torch.tensor([False]))
    ring.publish()
    return ring


def _slots(ring: ReplayRing) -> set[int]:
    g = torch.Generator().manual_seed(0)
    batch = ring.sample(4000, 1, 0.99, generator=g)
    return {int(x) for x in batch.obs.flatten()}  # obs of step i is i, in slot i % capacity


def test_a_full_ring_never_hands_out_the_slot_written_next():
    # 5 steps in 4 slots: step 4 overwrote slot 0; the next add overwrites slot 1 (step 1)
    ring = _ring(5)
    assert ring.ptr == 1 and _slots(ring) == {2, 3, 4}


def test_a_filling_ring_hands_out_every_step_written():
    assert _slots(_ring(2)) == {0, 1}


def test_returns_stop_at_the_newest_published_step():
    ring = _ring(5)
    newest = torch.tensor([0])  # slot 0 holds step 4, the newest
    batch = ring.transitions(newest, torch.tensor([0]), 3, 0.5)
    assert batch.returns.item() == 4.0 and batch.discount.item() == 0.5  # step 4's reward alone
    batch = ring.transitions(torch.tensor([2]), torch.tensor([0]), 3, 0.5)  # steps 2, 3, 4
    assert batch.returns.item() == pytest.approx(2 + 0.5 * 3 + 0.25 * 4)


def _runner(overlap: bool, seed: int = 0, **overrides) -> OffPolicyRunner:
    env = envs.make("cartpole", num_envs=8, seed=seed)
    torch.manual_seed(seed)
    cfg = offpolicy_cfg("cartpole", "fast-sac", num_envs=8, overlap_collect=overlap, **overrides)
    return OffPolicyRunner(env, cfg, seed=seed)


def test_before_the_updates_start_both_orders_collect_the_same_steps():
    a, b = _runner(False), _runner(True)
    assert b.overlap is not None and b.ring.write_ahead
    steps = a.cfg.learning_starts // a.cfg.num_steps_per_env  # iterations before the first update
    a.learn(steps)
    b.learn(steps)
    assert torch.equal(a.ring.obs, b.ring.obs) and torch.equal(a.ring.actions, b.ring.actions)
    for name in ("mean", "var", "count"):  # the deferred normalizer updates saw every step
        assert torch.equal(getattr(a.alg.actor.normalizer, name), getattr(b.alg.actor.normalizer, name)), name
        assert torch.equal(getattr(a.alg.critic.normalizer, name), getattr(b.alg.critic.normalizer, name)), name


def _acting_log(runner: OffPolicyRunner) -> list[tuple[bool, bool]]:
    """Per exploring step: (acted with the copy, the copy equal to the learner's actor then)."""
    log, explore = [], runner.alg.explore

    def recorded(obs, noise_std=None, noise=None, actor=None):
        same = all(torch.equal(p, q) for p, q in zip(actor.parameters(), runner.alg.actor.parameters()))
        log.append((actor is runner.overlap.acting, same))
        return explore(obs, noise_std, noise, actor=actor)

    runner.alg.explore = recorded
    return log


def test_the_worlds_act_with_the_actor_of_one_update_round_before():
    runner = _runner(True)
    log = _acting_log(runner)
    runner.learn(4)
    cfg = runner.cfg
    exploring = range(cfg.random_steps, 4 * cfg.num_steps_per_env)
    assert len(log) == len(exploring) and all(copy for copy, _ in log)
    updated = [same for step, (_, same) in zip(exploring, log) if step >= cfg.learning_starts]
    assert updated and not any(updated)  # the learner moved on while the step was collected
    assert all(torch.equal(p, q) for p, q in zip(runner.overlap.acting.parameters(), runner.alg.actor.parameters()))


def test_a_resumed_run_acts_with_its_checkpoints_weights(tmp_path):
    trained = _runner(True)
    trained.learn(3)
    trained.save(str(tmp_path / "model_2.pt"))
    resumed = _runner(True, seed=1, random_steps=0)  # other initial weights; explores at once
    resumed.load_for_resume(tmp_path / "model_2.pt")
    log = _acting_log(resumed)
    resumed.learn(1)
    # refreshed from the loaded actor before the first step (updates wait for learning_starts again)
    assert log and log[0] == (True, True)
