"""Every random draw in genr8_dist comes from a stream named by a seed and a path of keys.

``stream(seed, "island", 3, "generation", 12, "mutation")`` always gives the same generator, in any
process and on any machine, so a generation can be recomputed from the stored one before it, and a run
that is interrupted and resumed draws exactly what an uninterrupted one draws. Never use the global
``random`` module or ``np.random.*`` functions.
"""

from __future__ import annotations

import functools
import hashlib
from typing import Any

import numpy as np

__all__ = ["seed_sequence", "stream"]


def _key_words(key: int | str) -> list[int]:
    if isinstance(key, bool) or not isinstance(key, (int, np.integer, str)):
        raise TypeError(f"stream keys are ints or strings, got {key!r}")
    if isinstance(key, str):
        digest = hashlib.blake2b(key.encode(), digest_size=8).digest()
        return [1, int.from_bytes(digest, "little")]
    value = int(key)
    if value < 0:
        raise ValueError(f"stream keys must be non-negative, got {value}")
    return [0, value]


def seed_sequence(seed: int, *keys: int | str) -> np.random.SeedSequence:
    """The SeedSequence for ``seed`` and the key path ``keys`` (strings are hashed stably)."""
    if int(seed) < 0:
        raise ValueError(f"seed must be non-negative, got {seed}")
    words: list[int] = []
    for key in keys:
        words.extend(_key_words(key))
    return np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(words))


@functools.lru_cache(maxsize=1024)
def _initial_state(seed: int, keys: tuple[int | str, ...]) -> Any:
    return np.random.PCG64(seed_sequence(seed, *keys)).state


def stream(seed: int, *keys: int | str) -> np.random.Generator:
    """A fresh PCG64 generator for ``seed`` and the key path ``keys`` (its seeded state is computed
    once per process: a growth or an island asks for the same streams again and again)."""
    try:
        state = _initial_state(int(seed), keys)
    except TypeError:   # an unhashable key: seed_sequence names the problem
        return np.random.Generator(np.random.PCG64(seed_sequence(seed, *keys)))
    bits = np.random.PCG64(0)
    bits.state = state
    return np.random.Generator(bits)
