"""rep.distribution: Isaac's names and signatures over ambulo.core.randomize's distributions."""

import numpy as np
import pytest
import torch

from ambulo.core import randomize as dr
from ambulo.isaac.replicator import distribution as rd


def test_isaac_names_are_the_core_distributions_under_replicators_parameter_names():
    u = rd.uniform((-1, -1, 0), (1, 1, 0))
    assert isinstance(u, dr.Uniform) and rd.is_random(u) and (u.lower, u.upper) == ((-1, -1, 0), (1, 1, 0))
    n = rd.normal(0.0, 2.0)
    assert isinstance(n, dr.Normal) and (n.mean, n.std) == (0.0, 2.0)
    c = rd.choice(["a", "b", "c"], weights=[1, 0, 1])
    assert isinstance(c, dr.Choice) and c.choices == ("a", "b", "c") and not rd.is_random((1.0, 2.0))


def test_draws_are_the_core_draws_from_the_frames_generator():
    u = rd.uniform((0.0, 10.0, 5.0), (1.0, 20.0, 5.0))
    got = u.draw(np.random.default_rng([4, 2]), 6)
    expected = dr.Uniform((0.0, 10.0, 5.0), (1.0, 20.0, 5.0)).sample(dr.as_generator(np.random.default_rng([4, 2])), 6)
    assert isinstance(got, np.ndarray) and got.shape == (6, 3) and np.array_equal(got, expected.numpy())
    assert (got[:, 0] < 1).all() and (got[:, 1] >= 10).all() and (got[:, 2] == 5).all()
    picks = rd.choice(["a", "b", "c"], weights=[1, 0, 1]).draw(np.random.default_rng(0), 200)
    assert set(picks) == {"a", "c"}  # a zero weight is never drawn
    g = torch.Generator().manual_seed(1)
    assert np.array_equal(rd.draw(rd.normal(1.0, 0.0), g, 3), [1.0, 1.0, 1.0])
    assert rd.draw((0.5, 0.25), g, 2).tolist() == [[0.5, 0.25], [0.5, 0.25]]  # a constant, repeated


def test_what_replicator_offers_but_ambulo_does_not_fails_in_one_line():
    with pytest.raises(Exception, match="num=1"):
        rd.uniform(0, 1, num=3)
    with pytest.raises(Exception, match="set_global_seed"):
        rd.normal(0, 1, seed=4)
    with pytest.raises(ValueError, match="2 weights for 3 choices"):
        rd.choice([1, 2, 3], weights=[1, 2])
    with pytest.raises(ValueError, match="at least one"):
        rd.choice([])
