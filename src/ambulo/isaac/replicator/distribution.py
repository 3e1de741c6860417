"""``rep.distribution``: Isaac Replicator's names over ``ambulo.core.randomize``'s distributions.

A Replicator distribution is a graph node: it produces a new value each time the node that
uses it runs, one per target prim. Here ``uniform``/``normal``/``choice`` return the core's
``Uniform``/``Normal``/``Choice`` under Replicator's parameter names (``lower``/``upper``,
``choices``), and ``draw(rng, n)`` gives those ``n`` values as NumPy data from the generator
ambulo hands a randomizer for (seed, node, frame) (``as_generator``), so frames are
reproducible under ``rep.set_global_seed`` and independent of run order.
"""

from __future__ import annotations

import numpy as np

from ambulo.core import randomize as core

from .errors import Namespace, unsupported


class RepDistribution:
    """A value source: ``draw(rng, n)`` returns ``n`` samples (a NumPy array or a list)."""

    def draw(self, rng, n: int):
        raise NotImplementedError


class Uniform(core.Uniform, RepDistribution):
    """Uniform between ``lower`` and ``upper`` (the core's ``low``/``high``)."""

    def __init__(self, lower, upper):
        super().__init__(lower, upper)

    lower = property(lambda self: self.low)
    upper = property(lambda self: self.high)

    def draw(self, rng, n):
        return self.sample(core.as_generator(rng), n).numpy()


class Normal(core.Normal, RepDistribution):
    """Gaussian with ``mean`` and standard deviation ``std``."""

    def draw(self, rng, n):
        return self.sample(core.as_generator(rng), n).numpy()


class Choice(core.Choice, RepDistribution):
    """One of ``choices`` (any objects) per draw, with optional ``weights``."""

    def __init__(self, choices, weights=None):
        super().__init__(tuple(choices), weights)

    choices = property(lambda self: self.options)

    def draw(self, rng, n):
        return [self.options[int(i)] for i in self.sample_index(core.as_generator(rng), n).tolist()]


def _one_draw_per_node(num: int, seed: int | None, what: str) -> None:
    if num != 1:
        raise unsupported(f"distribution.{what}(num={num})", "draws are one per target prim; leave num=1")
    if seed not in (None, -1):
        raise unsupported(f"distribution.{what}(seed={seed})",
                          "every draw comes from the global seed; call rep.set_global_seed(seed) instead")


def uniform(lower, upper, num: int = 1, seed: int | None = None, name: str | None = None) -> Uniform:
    """Uniform between ``lower`` and ``upper`` (scalars or tuples, per component)."""
    _one_draw_per_node(num, seed, "uniform")
    return Uniform(lower, upper)


def normal(mean, std, num: int = 1, seed: int | None = None, name: str | None = None) -> Normal:
    """Gaussian with ``mean`` and standard deviation ``std`` (scalars or tuples)."""
    _one_draw_per_node(num, seed, "normal")
    return Normal(mean, std)


def choice(choices, weights=None, num: int = 1, seed: int | None = None, with_replacements: bool = True,
           name: str | None = None) -> Choice:
    """One of ``choices`` per draw, with optional ``weights`` (normalised)."""
    _one_draw_per_node(num, seed, "choice")
    if not with_replacements:
        raise unsupported("distribution.choice(with_replacements=False)", "draws are independent per prim")
    choices = tuple(choices)
    if not choices:
        raise ValueError("rep.distribution.choice needs at least one choice")
    if weights is not None and len(weights) != len(choices):
        raise ValueError(f"rep.distribution.choice: {len(weights)} weights for {len(choices)} choices; "
                         "give one weight per choice")
    return Choice(choices, None if weights is None else tuple(float(w) for w in weights))


def draw(value, rng, n: int):
    """``n`` values of ``value``: samples of a distribution, or the constant repeated."""
    if isinstance(value, RepDistribution):
        return value.draw(rng, n)
    return np.broadcast_to(np.asarray(value, float), (n, *np.shape(value))).copy()


def is_random(value) -> bool:
    return isinstance(value, RepDistribution)


distribution = Namespace("distribution", {"uniform": uniform, "normal": normal, "choice": choice}, {
    "sequence": "draws are seeded per frame, not stepped in order; use rep.distribution.choice",
    "log_uniform": "use rep.distribution.uniform",
    "combine": "give the distribution itself to the modify/randomizer call",
})
