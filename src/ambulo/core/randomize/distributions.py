"""Distributions: one hierarchy of value sources, drawn in batches from a seeded ``torch.Generator``.

Why torch and not numpy: the RL task events draw one value per world on the engine's device
(a GPU for training); a numpy draw there would need a host-to-device copy, which waits for the
device, on every reset. A ``torch.Generator`` draws on either device, and the CPU case (the
replicator's one world) is the N = 1 case of the same code. Host callers that hold a
``numpy.random.Generator`` (the replicator hands one per (seed, randomizer, frame)) draw from it
with ``sample_host``: NumPy's own draws, not torch's numbers, and a few microseconds cheaper
a call than a torch draw and its seeding (``as_generator`` still turns one into a torch generator).

Every ``sample`` draws in float64 and only then casts to ``dtype``: the float32 GPU engine and
the float64 CPU engine see the same numbers from one seed (as ``RLEnv._uniform`` does).
Shapes: a distribution's parameters broadcast to its value shape ``S`` (``()`` for scalars,
``(3,)`` for a colour); ``sample(g, num)`` returns ``(num, *S)``, ``sample(g)`` returns ``S``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch


def as_generator(rng, reuse: torch.Generator | None = None) -> torch.Generator:
    """A ``torch.Generator``: ``rng`` itself, one seeded with the int ``rng``, or (for a
    ``numpy.random.Generator``) one seeded with the next 64 bits ``rng`` draws. ``reuse``: a
    CPU generator to reseed instead of making one (a per-frame caller saves the allocation)."""
    if isinstance(rng, np.random.Generator):  # first: the replicator's per-frame case
        rng = int(rng.bit_generator.random_raw())  # the next 64 raw bits: a full-width seed
    elif isinstance(rng, torch.Generator):
        return rng
    if isinstance(rng, (int, np.integer)):
        return (torch.Generator() if reuse is None else reuse).manual_seed(int(rng))
    raise TypeError(f"a random generator is a torch.Generator, a numpy Generator or an int seed; got {rng!r}")


def _shape(num: int | None, value_shape: tuple[int, ...]) -> tuple[int, ...]:
    return value_shape if num is None else (int(num), *value_shape)


class Distribution:
    """A value source: ``sample(generator, num, dtype=...)`` gives ``num`` draws, ``(num, *S)``."""

    def sample(self, generator: torch.Generator, num: int | None = None, *,
               dtype: torch.dtype = torch.float64) -> torch.Tensor:
        raise NotImplementedError

    def sample_host(self, rng: np.random.Generator, num: int | None = None) -> np.ndarray:
        """``num`` draws ``(num, *S)`` (``S`` without ``num``) in float64, drawn by NumPy from ``rng``:
        for host callers (the replicator) that go on in NumPy or plain floats. The same kind of
        values as ``sample``, not its numbers. This default seeds a torch generator from ``rng``
        (a distribution without its own NumPy draw still depends on ``rng`` alone)."""
        return self.sample(as_generator(rng), num, dtype=torch.float64).cpu().numpy()


@dataclass(frozen=True)
class _Pair(Distribution):
    """Two broadcast parameters (bounds, or mean and std), as tensors cached per (device, dtype) on the
    distribution itself: every sampler of it (``sample``, the replicator's device draws) reads them here."""

    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def _params(self) -> tuple[Any, Any]:
        raise NotImplementedError

    _span = False
    """Whether the second tensor is the difference of the two parameters (a uniform's width)."""

    def param_tensors(self, device: torch.device, dtype: torch.dtype):
        """The two parameters as tensors of the value shape ``S`` in ``dtype`` on ``device`` (0-d for
        scalars), and ``S``: made once per (device, dtype), so a GPU caller does not copy them from
        pageable memory each time (``replicator.device_draws`` samples with them)."""
        key = ("params", device, dtype)
        hit = self._cache.get(key)
        if hit is None:
            a, b = (np.asarray(p, np.float64) for p in self._params())
            shape = np.broadcast_shapes(a.shape, b.shape)
            hit = self._cache[key] = (
                *(torch.as_tensor(np.broadcast_to(x, shape).copy(), dtype=dtype, device=device) for x in (a, b)), shape)
        return hit

    def _tensors(self, device: torch.device, dtype: torch.dtype):
        """The two parameters (or, with ``_span``, the first and the difference) as Python floats
        for scalars, else as ``param_tensors``; and the value shape. The arithmetic is that of
        ``a + (b - a) * u`` on floats or on ``dtype`` tensors."""
        key = (device, dtype)
        hit = self._cache.get(key)
        if hit is None:
            a, b = (np.asarray(p, np.float64) for p in self._params())
            if not np.broadcast_shapes(a.shape, b.shape):
                first, second, shape = float(a), float(b), ()  # float64 arithmetic, whatever dtype
            else:
                first, second, shape = self.param_tensors(device, dtype)
            hit = first, (second - first) if self._span else second, shape
            self._cache[key] = hit
        return hit

    def sample_host(self, rng, num=None):
        # the arithmetic of ``sample`` (a + b * u, in float64) on NumPy's draw
        first, second, shape = self._host_params()
        u = self._draw_host(rng, _shape(num, shape))
        u *= second
        u += first
        return u

    def _host_params(self):
        """``_tensors`` for the host in float64, as floats or NumPy arrays."""
        hit = self._cache.get("numpy")
        if hit is None:
            first, second, shape = self._tensors(torch.device("cpu"), torch.float64)
            hit = self._cache["numpy"] = (first if not shape else first.numpy(),
                                          second if not shape else second.numpy(), shape)
        return hit


@dataclass(frozen=True)
class Uniform(_Pair):
    """Uniform in ``[low, high)``, per component (scalars or sequences that broadcast)."""

    low: Any
    high: Any
    _span = True

    @staticmethod
    def _draw_host(rng, shape):
        return np.asarray(rng.random(shape))  # a 0-d array for shape (): ``*=`` needs an array

    def _params(self):
        return self.low, self.high

    def sample(self, generator, num=None, *, dtype=torch.float64):
        low, span, shape = self._tensors(generator.device, dtype)
        u = torch.rand(_shape(num, shape), generator=generator, dtype=torch.float64, device=generator.device)
        return u.to(dtype).mul_(span).add_(low)  # low + (high - low) * u, in place on the fresh draw


@dataclass(frozen=True)
class Normal(_Pair):
    """Gaussian with ``mean`` and standard deviation ``std``, per component."""

    mean: Any
    std: Any

    @staticmethod
    def _draw_host(rng, shape):
        return np.asarray(rng.standard_normal(shape))

    def _params(self):
        return self.mean, self.std

    def sample(self, generator, num=None, *, dtype=torch.float64):
        mean, std, shape = self._tensors(generator.device, dtype)
        z = torch.randn(_shape(num, shape), generator=generator, dtype=torch.float64, device=generator.device)
        return z.to(dtype).mul_(std).add_(mean)


@dataclass(frozen=True)
class UniformInt(Distribution):
    """Integers uniform in ``[low, high]`` (both inclusive), as int64 whatever ``dtype``."""

    low: int
    high: int

    def sample(self, generator, num=None, *, dtype=torch.int64):
        return torch.randint(int(self.low), int(self.high) + 1, _shape(num, ()), generator=generator,
                             device=generator.device)

    def sample_host(self, rng, num=None):
        return np.asarray(rng.integers(int(self.low), int(self.high) + 1, _shape(num, ()), dtype=np.int64))


@dataclass(frozen=True)
class Choice(Distribution):
    """One of ``options`` per draw, with optional relative ``weights``.

    ``sample`` gives the picked options as a tensor (numeric options: numbers or equal-length
    tuples); ``sample_index`` gives the indices, for options of any kind."""

    options: Sequence[Any]
    weights: Sequence[float] | None = None

    def __post_init__(self):
        if not len(self.options):
            raise ValueError("a choice needs at least one option")
        if self.weights is not None and len(self.weights) != len(self.options):
            raise ValueError(f"{len(self.weights)} weights for {len(self.options)} options; "
                             "give one weight per option")

    def sample_index(self, generator: torch.Generator, num: int | None = None) -> torch.Tensor:
        """Indices into ``options``: ``(num,)`` int64, or a 0-d tensor when ``num`` is None."""
        count = 1 if num is None else int(num)
        if self.weights is None:
            index = torch.randint(len(self.options), (count,), generator=generator, device=generator.device)
        else:
            weights = torch.as_tensor(self.weights, dtype=torch.float64, device=generator.device)
            index = torch.multinomial(weights, count, replacement=True, generator=generator)
        return index[0] if num is None else index

    def sample(self, generator, num=None, *, dtype=torch.float64):
        options = torch.as_tensor(np.asarray(self.options, np.float64), dtype=dtype, device=generator.device)
        return options[self.sample_index(generator, num)]

    def sample_index_host(self, rng: np.random.Generator, num: int | None = None) -> np.ndarray:
        """``sample_index`` drawn by NumPy from ``rng``: ``(num,)`` int64, or 0-d when ``num`` is None."""
        p = None if self.weights is None else np.asarray(self.weights, np.float64) / float(np.sum(self.weights))
        return np.asarray(rng.choice(len(self.options), size=_shape(num, ()), p=p), np.int64)

    def sample_host(self, rng, num=None):
        return np.asarray(self.options, np.float64)[self.sample_index_host(rng, num)]


@dataclass(frozen=True)
class Constant(Distribution):
    """Always ``value`` (draws nothing from the generator)."""

    value: Any

    def sample(self, generator, num=None, *, dtype=torch.float64):
        value = torch.as_tensor(np.asarray(self.value, np.float64), dtype=dtype, device=generator.device)
        return value if num is None else value.expand(int(num), *value.shape).clone()

    def sample_host(self, rng, num=None):
        value = np.asarray(self.value, np.float64)
        return value.copy() if num is None else np.broadcast_to(value, (int(num), *value.shape)).copy()


def uniform(low, high) -> Uniform:
    return Uniform(low, high)


def normal(mean, std) -> Normal:
    return Normal(mean, std)


def uniform_int(low: int, high: int) -> UniformInt:
    return UniformInt(low, high)


def choice(options: Sequence[Any], weights: Sequence[float] | None = None) -> Choice:
    return Choice(tuple(options), None if weights is None else tuple(float(w) for w in weights))


def constant(value) -> Constant:
    return Constant(value)


def as_distribution(value) -> Distribution:
    """Numbers and tuples become constants, so configs can say ``intensity=0.8``."""
    return value if isinstance(value, Distribution) else Constant(value)


_NUMBER = (int, float, np.integer, np.floating)


class Columns:
    """Scalar distributions drawn side by side: ``sample(g, num)`` is ``(num, k)``, one column each.

    Made once (a randomizer's ``initialize``) so a frame pays only for the draw. When every one is
    a scalar ``Uniform`` (a scatter's x, y and yaw) they are drawn in one ``(num, k)`` call, row
    after row; otherwise one distribution after the other (numbers are constants)."""

    def __init__(self, distributions: Sequence):
        self.distributions = [as_distribution(d) for d in distributions]
        self._uniform = bool(self.distributions) and all(
            type(d) is Uniform and isinstance(d.low, _NUMBER) and isinstance(d.high, _NUMBER)
            for d in self.distributions)
        self._bounds = np.array([[float(d.low), float(d.high)] for d in self.distributions]) \
            if self._uniform else None
        self._bounds_span = self._bounds[:, 1] - self._bounds[:, 0] if self._uniform else None
        self._tensors: dict = {}

    def _low_span(self, device, dtype) -> tuple[torch.Tensor, torch.Tensor]:
        """The (k,) lows and widths in ``dtype`` on ``device``, made once per (device, dtype)."""
        low = torch.as_tensor(self._bounds[:, 0].copy(), dtype=dtype, device=device)
        high = torch.as_tensor(self._bounds[:, 1].copy(), dtype=dtype, device=device)
        low_span = self._tensors[(device, dtype)] = (low, high - low)
        return low_span

    def sample(self, generator: torch.Generator, num: int, *, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        device = generator.device
        if self._uniform:
            key = (device, dtype)
            low_span = self._tensors.get(key) or self._low_span(device, dtype)
            u = torch.rand((int(num), len(self.distributions)), generator=generator, dtype=torch.float64,
                           device=device)
            return u.to(dtype).mul_(low_span[1]).add_(low_span[0])
        if not self.distributions:
            return torch.zeros(int(num), 0, dtype=dtype, device=device)
        return torch.stack([d.sample(generator, num, dtype=dtype).reshape(int(num)) for d in self.distributions],
                           dim=1)

    def sample_host(self, rng: np.random.Generator, num: int) -> np.ndarray:
        """``(num, k)`` float64 drawn by NumPy from ``rng`` (host callers; ``Distribution.sample_host``):
        all-uniform columns in one ``(num, k)`` draw, row after row, else one column after the other."""
        if self._uniform:
            u = rng.random((int(num), len(self.distributions)))
            u *= self._bounds_span
            u += self._bounds[:, 0]
            return u
        if not self.distributions:
            return np.zeros((int(num), 0))
        return np.stack([d.sample_host(rng, num).reshape(int(num)) for d in self.distributions], axis=1)


def sample_columns(generator: torch.Generator, distributions: Sequence, num: int, *,
                   dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """``Columns(distributions).sample(generator, num)``, for a one-off draw."""
    return Columns(distributions).sample(generator, num, dtype=dtype)


__all__ = ["Choice", "Columns", "Constant", "Distribution", "Normal", "Uniform", "UniformInt", "as_distribution",
           "as_generator", "choice", "constant", "normal", "sample_columns", "uniform", "uniform_int"]
