"""Distributions that randomizers draw from: small, explicit and JSON-loggable.

Every draw uses the ``numpy.random.Generator`` handed in, so a frame's values are
a function of (seed, randomizer, frame) alone; that is what makes frames
regenerable one at a time and shards on several workers identical to one run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np


class Distribution:
    def sample(self, rng: np.random.Generator, size: int | None = None) -> np.ndarray:
        raise NotImplementedError


@dataclass(frozen=True)
class Uniform(Distribution):
    low: Any
    high: Any

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``low`` and ``high`` as float arrays (made once)."""
        return np.asarray(self.low, float), np.asarray(self.high, float)

    def sample(self, rng, size=None):
        low, high = self.bounds
        shape = low.shape if size is None else (size, *low.shape)
        return rng.uniform(low, high, shape)


@dataclass(frozen=True)
class Normal(Distribution):
    mean: Any
    std: Any

    def sample(self, rng, size=None):
        mean, std = np.asarray(self.mean, float), np.asarray(self.std, float)
        shape = mean.shape if size is None else (size, *mean.shape)
        return rng.normal(mean, std, shape)


@dataclass(frozen=True)
class UniformInt(Distribution):
    low: int
    high: int
    """Inclusive."""

    def sample(self, rng, size=None):
        return rng.integers(self.low, self.high + 1, size)


@dataclass(frozen=True)
class Choice(Distribution):
    options: Sequence[Any]

    def sample(self, rng, size=None):
        index = rng.integers(0, len(self.options), size)
        if size is None:
            return self.options[int(index)]
        return [self.options[int(i)] for i in index]


@dataclass(frozen=True)
class Constant(Distribution):
    value: Any

    def sample(self, rng, size=None):
        value = np.asarray(self.value)
        return value if size is None else np.broadcast_to(value, (size, *value.shape)).copy()


def uniform(low, high) -> Uniform:
    return Uniform(low, high)


def normal(mean, std) -> Normal:
    return Normal(mean, std)


def uniform_int(low: int, high: int) -> UniformInt:
    return UniformInt(low, high)


def choice(options: Sequence[Any]) -> Choice:
    return Choice(tuple(options))


def constant(value) -> Constant:
    return Constant(value)


def draw_rows(rng: np.random.Generator, distributions: Sequence, rows: int) -> list[list[float]]:
    """``rows`` rows of one number from each of ``distributions`` (scalar ones; numbers are constants):
    the numbers ``float(d.sample(rng))`` for each distribution in turn, row after row, would give.
    When all are scalar ``Uniform``s they are drawn in one call: a uniform draw is ``low + (high - low)
    * u`` for the generator's next ``u`` whether drawn alone or in an array, in C order."""
    dists = [as_distribution(d) for d in distributions]
    if dists and all(isinstance(d, Uniform) and d.bounds[0].ndim == d.bounds[1].ndim == 0 for d in dists):
        low = np.array([d.bounds[0] for d in dists])
        high = np.array([d.bounds[1] for d in dists])
        return rng.uniform(low, high, (rows, len(dists))).tolist()
    return [[float(d.sample(rng)) for d in dists] for _ in range(rows)]


def as_distribution(value) -> Distribution:
    """Numbers and tuples become constants, so configs can say ``intensity=0.8``."""
    return value if isinstance(value, Distribution) else Constant(value)
