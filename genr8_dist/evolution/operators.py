"""The variation and selection operators of the island: small functions with checked inputs.

Each takes an explicit ``numpy.random.Generator`` (from ``genr8_dist.rng.stream``) and plain values, so
each can be tested alone and a generation can be recomputed draw for draw. Genomes are tuples of
non-negative ints (codons in ``0..codon_max``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "int_flip_mutation",
    "one_point_crossover",
    "random_genome",
    "rank_key",
    "select_elites",
    "tournament_select",
]

Genome = tuple[int, ...]


def _check_rng(rng: np.random.Generator) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy Generator from genr8_dist.rng.stream, got {type(rng).__name__}")


def random_genome(rng: np.random.Generator, length: int, codon_max: int) -> Genome:
    """A genome of ``length`` codons drawn uniformly from ``0..codon_max`` (generation 0)."""
    _check_rng(rng)
    if length < 1:
        raise ValueError(f"genome length must be >= 1, got {length}")
    if codon_max < 1:
        raise ValueError(f"codon_max must be >= 1, got {codon_max}")
    return tuple(int(c) for c in rng.integers(0, codon_max, size=length, endpoint=True))


def rank_key(fitness: float, index: int) -> tuple[float, int]:
    """The sort key of an individual: lower fitness first, ties broken by the lower index; NaN ranks last."""
    return (math.inf if math.isnan(fitness) else fitness, index)


def tournament_select(rng: np.random.Generator, fitnesses: Sequence[float], size: int) -> int:
    """The position of the winner of one tournament: ``size`` contestants drawn uniformly with
    replacement, the lowest fitness wins (ties: the lowest position)."""
    _check_rng(rng)
    n = len(fitnesses)
    if n == 0:
        raise ValueError("tournament over an empty population")
    if size < 1:
        raise ValueError(f"tournament size must be >= 1, got {size}")
    contestants = rng.integers(0, n, size=size)
    return min((int(i) for i in contestants), key=lambda i: rank_key(fitnesses[i], i))


def select_elites(fitnesses: Sequence[float], count: int) -> list[int]:
    """The positions of the ``count`` best individuals with finite fitness, best first."""
    if count < 0:
        raise ValueError(f"elite count must be >= 0, got {count}")
    finite = [i for i, f in enumerate(fitnesses) if math.isfinite(f)]
    finite.sort(key=lambda i: rank_key(fitnesses[i], i))
    return finite[:count]


def one_point_crossover(
    rng: np.random.Generator, a: Sequence[int], b: Sequence[int], *, within: int | None = None
) -> tuple[Genome, Genome]:
    """Swap the tails of ``a`` and ``b`` after one cut point drawn in ``1..min(len)-1``.

    The children are ``a[:p] + b[p:]`` and ``b[:p] + a[p:]``: with equal lengths both keep the length;
    otherwise the lengths are exchanged. Genomes shorter than 2 codons cannot be cut: copies come back
    (and no number is drawn). With ``within`` (the codons the mapper read of the parent that read
    fewer: PonyGE2's *within used*), the cut falls in ``1..within-1``, so it always changes codons the
    mapper reads; ``within`` below 2 leaves nowhere to cut (copies come back).
    """
    _check_rng(rng)
    a, b = tuple(a), tuple(b)
    shortest = min(len(a), len(b))
    if within is not None:
        shortest = min(shortest, int(within))
    if shortest < 2:
        return a, b
    p = int(rng.integers(1, shortest))
    return a[:p] + b[p:], b[:p] + a[p:]


def int_flip_mutation(
    rng: np.random.Generator,
    genome: Sequence[int],
    rate: float,
    codon_max: int,
    *,
    at_least_one: bool = False,
    within: int | None = None,
) -> tuple[Genome, int]:
    """Replace each codon with probability ``rate`` by a uniform draw from ``0..codon_max``.

    Returns the mutated genome and how many codons were redrawn. With ``at_least_one``, a genome that no
    codon was drawn for gets one codon (at a uniform position) redrawn, so the child is never a silent
    copy. A redrawn codon can equal the old one by chance; it still counts as redrawn. With ``within``
    (the codons the mapper read), only the first ``within`` codons may be redrawn (PonyGE2's *within
    used*); the rest of the genome is kept as it is.
    """
    _check_rng(rng)
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"mutation rate must be in [0, 1], got {rate}")
    if codon_max < 1:
        raise ValueError(f"codon_max must be >= 1, got {codon_max}")
    g = np.asarray(genome, dtype=np.int64)
    if g.size == 0:
        return (), 0
    span = g.size if within is None else max(1, min(g.size, int(within)))
    mask = np.zeros(g.size, dtype=bool)
    mask[:span] = rng.random(span) < rate
    if at_least_one and not mask.any():
        mask[int(rng.integers(0, span))] = True
    n = int(mask.sum())
    if n:
        g = g.copy()
        g[mask] = rng.integers(0, codon_max, size=n, endpoint=True)
    return tuple(int(c) for c in g), n
