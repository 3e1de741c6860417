"""A frame's random streams (``replicator.streams``): Philox keyed by (seed, randomizer, block), made
by re-keying one generator, and the randomizers' NumPy draws from them (issue 22, item 6)."""

import numpy as np
import pytest

from ambulo import replicator as rep
from ambulo.replicator.streams import frame_key, frame_rng

KEYS = [(0, 0, 0), (1, 6, 12345), (2**64 - 1, 3, 2**32 - 1), (2**64, 0, 7), (5, 1, 2**40 + 3), (2**70 + 1, 2, 9)]


def _fresh(seed, k, block):
    return np.random.Generator(np.random.Philox(key=np.array(frame_key(seed, k, block), np.uint64)))


@pytest.mark.parametrize("seed, k, block", KEYS)
def test_a_rekeyed_stream_is_a_fresh_philox_of_its_key_whatever_was_drawn_before(seed, k, block):
    frame_rng(9, 9, 9).standard_normal(3)  # leave the reused generator mid-stream, odd normal count
    frame_rng(9, 9, 9).integers(0, 10, 5)
    got = frame_rng(seed, k, block)
    expected = _fresh(seed, k, block)
    np.testing.assert_array_equal(got.random(5), expected.random(5))
    np.testing.assert_array_equal(got.standard_normal(3), expected.standard_normal(3))
    np.testing.assert_array_equal(got.integers(0, 1 << 40, 4), expected.integers(0, 1 << 40, 4))


def test_keys_are_the_numbers_themselves_and_distinct_where_they_fit_and_hashed_beyond():
    assert frame_key(3, 2, 7) == (3, (2 << 32) | 7)
    small = {frame_key(s, k, b) for s in range(3) for k in range(3) for b in range(3)}
    assert len(small) == 27
    big = frame_key(2**70 + 1, 2, 9)
    assert big == tuple(np.random.SeedSequence([2**70 + 1, 2, 9]).generate_state(2, np.uint64).tolist())
    assert frame_rng(1, 0, 5).random() != frame_rng(1, 0, 6).random() != frame_rng(1, 1, 5).random()
    with pytest.raises(ValueError):
        frame_key(-1, 0, 0)


def test_a_frames_draws_depend_on_seed_and_index_alone_and_every_n_frames_keeps_a_block():
    """The same frame drawn after other frames, in another order, or by a fresh cache has the same log; a
    randomizer with every_n_frames=4 keeps its draw within a block of 4 and redraws across."""
    config = rep.example_config(32, 24)
    config.randomizers[0].every_n_frames = 4  # the robot's joints
    producer = rep.FrameProducer(config)
    try:
        def draw(index, fresh=False):
            if fresh:
                producer._cache.clear()
            return producer.randomize(3, index)

        logs = {index: draw(index) for index in (0, 1, 5, 9, 4)}
        assert draw(5, fresh=True) == logs[5] and draw(1) == logs[1] and draw(0, fresh=True) == logs[0]
        assert logs[0] != logs[1]
        joints = {index: log["robot_joints"] for index, log in logs.items()}
        assert joints[0] == joints[1] and joints[4] == joints[5] and joints[0] != joints[4] != joints[9]
        assert logs[0]["objects"] != logs[1]["objects"]
    finally:
        producer.close()
