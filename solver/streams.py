"""Random streams keyed by what they belong to: a seeded simulation is a function of its seed, not of the CPU.

A simulation takes decisions (is this candidate pose inside the limits, did the operator's aim land, has
an iteration converged) whose outcome a last-bit difference can flip, and the last bit depends on the
CPU: OpenBLAS picks its kernels by processor, and they round differently. With one sequential generator a
flipped decision changes how many numbers a step draws, and so every draw after it. Here each random
quantity comes from a stream of its own, keyed by the path of names and numbers it belongs to (the
session's part, the point, the capture, the round), as the spawn key of numpy's ``SeedSequence``: a
decision that flips changes what it decided and nothing else.
"""

from __future__ import annotations

import zlib

import numpy as np

Seed = int | np.random.SeedSequence | np.random.Generator


def _word(part: str | int) -> int:
    """One spawn-key word: a name by its CRC-32 (stable across runs and machines), a number as itself."""
    if isinstance(part, str):
        return zlib.crc32(part.encode())
    return int(part)


def root(seed: Seed) -> np.random.SeedSequence:
    """The root of a simulation's streams.

    Parameters
    ----------
    seed : int, SeedSequence, or Generator. A Generator gives exactly one fixed-size draw (two 63-bit
        words), so that what the caller draws after handing it over does not depend on what was done here.

    Returns
    -------
    numpy.random.SeedSequence
    """
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, np.random.Generator):
        return np.random.SeedSequence(seed.integers(0, 2**63 - 1, size=2).tolist())
    return np.random.SeedSequence(int(seed))


def child(seed: Seed, *key: str | int) -> np.random.SeedSequence:
    """The seed sequence of the quantity at ``key`` below ``seed`` (names or non-negative numbers)."""
    r = root(seed)
    return np.random.SeedSequence(r.entropy, spawn_key=(*r.spawn_key, *map(_word, key)))


def stream(seed: Seed, *key: str | int) -> np.random.Generator:
    """A generator for the quantity at ``key`` below ``seed``: independent of every other key's draws."""
    return np.random.default_rng(child(seed, *key))
