"""A frame's random streams: randomizer ``k`` of frame ``i`` draws from Philox keyed (seed, k, i // every_n).

Why Philox: it is counter-based, so any two keys give independent streams without a hash of
the key (Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC'11); the key *is*
(seed, k, block), and a stream is made by setting a reused generator's key and zeroing its
counter (~2 us) instead of building a ``default_rng`` (SeedSequence hashing, PCG64: ~10-25 us,
seven a frame). The randomizers draw from it with NumPy (``Distribution.sample_host``).

``DRAWS`` names this scheme in a dataset's fingerprint (``manifest``): frames drawn by another
scheme (before 2026-11-30: ``default_rng([seed, k, block])`` seeding torch draws) have other
numbers, so such a dataset is never resumed with these.
"""

from __future__ import annotations

import threading

import numpy as np

DRAWS = "philox4x64 key (seed, k << 32 | block), numpy draws"
"""The draw scheme, as the fingerprint records it."""

_WORD32 = 1 << 32
_WORD64 = 1 << 64
_local = threading.local()  # a generator per thread: producers, draw pools and tests may share a process


def frame_key(seed: int, k: int, block: int) -> tuple[int, int]:
    """The Philox key (two 64-bit words) of randomizer ``k``'s draws for frame block ``block`` of ``seed``.

    ``(seed, k << 32 | block)`` when ``0 <= seed < 2**64`` and ``k``, ``block`` fit 32 bits (every
    dataset ambulo makes); otherwise the first two words ``SeedSequence([seed, k, block])`` makes (a
    hash: another key with probability 2**-128), which also refuses a negative seed as NumPy does.
    """
    if 0 <= seed < _WORD64 and 0 <= k < _WORD32 and 0 <= block < _WORD32:
        return int(seed), (int(k) << 32) | int(block)
    a, b = np.random.SeedSequence([seed, k, block]).generate_state(2, np.uint64).tolist()
    return a, b


def frame_rng(seed: int, k: int, block: int) -> np.random.Generator:
    """The generator of randomizer ``k`` for frame block ``block`` of ``seed``, at the start of its stream.

    One generator per thread, re-keyed on each call: it is valid until the next ``frame_rng`` call
    of the same thread (a randomizer's ``sample`` uses it and lets it go).
    """
    state = getattr(_local, "state", None)
    if state is None:
        bits = np.random.Philox(0)
        # a fresh generator's state (counter 0, empty buffer), a copy: only its key is changed below
        state = _local.state = (np.random.Generator(bits), bits, bits.state)
    rng, bits, template = state
    template["state"]["key"][:] = frame_key(seed, k, block)
    bits.state = template  # copied into the bit generator: the stream starts at counter 0
    return rng


__all__ = ["DRAWS", "frame_key", "frame_rng"]
