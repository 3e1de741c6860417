"""rl.episodes and rl.log_writer: the pieces that replace reading rsl-rl's logger internals."""

from collections import deque

import torch

from ambulo.rl.episodes import EpisodeStats
from ambulo.rl.log_writer import ITERATION_TAGS, ProgressWriter


def test_episode_stats_keep_the_last_100_episodes_as_a_deque_does():
    """Random rewards and episode ends over 12 envs, with steps where more than the ring's
    capacity end at once: the kept returns and lengths, oldest first, are a deque(maxlen)'s."""
    gen = torch.Generator().manual_seed(0)
    n, capacity = 12, 7
    stats = EpisodeStats(n, "cpu", capacity=capacity)
    ret, length = torch.zeros(n), [0] * n  # float32 sums, as rsl-rl's logger keeps them
    kept_ret, kept_len = deque(maxlen=capacity), deque(maxlen=capacity)
    assert stats.means() == (None, None)
    for step in range(60):
        rewards = torch.randn(n, generator=gen)
        dones = torch.rand(n, generator=gen) < (0.9 if step % 10 == 0 else 0.2)
        stats.step(rewards, dones)
        for i in range(n):
            ret[i] += rewards[i]
            length[i] += 1
            if dones[i]:
                kept_ret.append(float(ret[i]))
                kept_len.append(length[i])
                ret[i], length[i] = 0.0, 0
        assert stats.returns() == list(kept_ret)
        assert stats.lengths() == [float(x) for x in kept_len]
    reward, steps = stats.means()
    assert abs(reward - sum(stats.returns()) / capacity) < 1e-9 and steps == sum(kept_len) / capacity


def test_restored_stats_continue_the_checkpoints_means():
    old = EpisodeStats(3, "cpu", capacity=5)
    for _ in range(4):
        old.step(torch.tensor([1.0, 2.0, 3.0]), torch.tensor([True, False, True]))
    new = EpisodeStats(3, "cpu", capacity=5)
    new.restore(old.returns(), old.lengths())
    assert new.means() == old.means() and new.returns() == old.returns()


def test_the_writer_closes_each_iteration_once_its_numbers_are_in(tmp_path):
    closed = []
    writer = ProgressWriter.factory(on_iteration=lambda *args: closed.append(args), means=lambda: (1.5, 20.0))(
        log_dir=str(tmp_path))
    for it in (3, 4):
        writer.add_scalar("Loss/surrogate", 0.1, it)
        writer.add_scalar("Train/mean_reward", -99.0, it)  # rsl-rl's own: replaced by ambulo's
        for k, tag in enumerate(ITERATION_TAGS):
            assert len(closed) == it - 3  # not before all three are in
            writer.add_scalar(tag, it + 0.1 * k, it)
    assert closed == [(3, 3.0, 3.1, 3.2), (4, 4.0, 4.1, 4.2)]
    writer.stop()
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(tmp_path))
    events.Reload()
    assert [e.value for e in events.Scalars("Train/mean_reward")] == [1.5, 1.5]
    assert "Perf/learning_time" in events.Tags()["scalars"]
