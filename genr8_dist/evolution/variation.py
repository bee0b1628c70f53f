"""A universe's own variation: its genome is its text, and its hooks bring the operators.

Grammatical Evolution (``operators``: int genomes mapped through the grammar, one-point crossover,
int-flip mutation) is the default for every universe. A plugin whose paper varies its texts
structurally (Hornby & Pollack's tables: mutation and recombination of an L-system) declares
``VARIATION`` in its ``hooks.py``, an object with three methods, each drawing only from the
``numpy.random.Generator`` it is given::

    founder(rng) -> text                 a random individual of generation 0
    mutate(rng, text) -> text            a small change of one parent
    recombine(rng, text, other) -> text  a copy of ``text`` with a small part of ``other`` put in

With ``ea.variation = "auto"`` (the default) a universe that declares one evolves with it; ``"ge"``
keeps GE whatever the universe declares. Under a universe's variation the stored genome is the
*text genome*: the text's characters as code points (``text_genome``), so a genome maps to its text
by reading it back (``map_genome``), the run store's ``genome`` column keeps what it always kept, and
determinism and resumption hold as for GE (every draw from the island's ``rng.stream``). Each
offspring is one child: recombination of two tournament winners with probability
``ea.crossover_rate`` (the paper: half and half), else mutation of one; ``ea.mutation_rate``,
``genome.length``, ``codon_max``, ``init`` and ``within_used`` play no part.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from genr8_dist.errors import UniverseError

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.grammar.universe import MapResult, Universe

__all__ = ["VARIATIONS", "Variation", "genome_of", "map_genome", "text_genome", "variation_for"]

VARIATIONS: tuple[str, ...] = ("auto", "ge")
_LARGEST = 0x10FFFF   # the largest code point


@runtime_checkable
class Variation(Protocol):
    """The operators a universe brings (``hooks.VARIATION``); texts in, texts out."""

    def founder(self, rng: np.random.Generator) -> str: ...

    def mutate(self, rng: np.random.Generator, text: str) -> str: ...

    def recombine(self, rng: np.random.Generator, text: str, other: str) -> str: ...


def variation_for(config: RunConfig, universe: Universe) -> Variation | None:
    """The variation ``config`` evolves ``universe`` with: its hooks' ``VARIATION`` under
    ``ea.variation = "auto"``, ``None`` (GE) under ``"ge"`` or when the universe declares none."""
    if getattr(getattr(config, "ea", None), "variation", "auto") == "ge":
        return None
    hooks = getattr(universe, "hooks", None)
    found = getattr(hooks, "VARIATION", None) if hooks is not None else None
    if found is None:
        return None
    if not isinstance(found, Variation):
        raise UniverseError(f"universe '{getattr(universe, 'name', '?')}': hooks.VARIATION needs the "
                            "methods founder(rng), mutate(rng, text) and recombine(rng, text, other)")
    return found


def text_genome(text: str) -> tuple[int, ...]:
    """The genome of ``text`` under a universe's variation: its characters' code points."""
    return tuple(ord(c) for c in text)


def map_genome(config: RunConfig, universe: Universe, genome: Sequence[int]) -> MapResult:
    """``genome`` mapped to its text as ``config`` maps it (a ``MapResult``): read back as a text
    genome under a universe's variation, else GE's ``universe.map``."""
    from genr8_dist.grammar.universe import MapResult

    if variation_for(config, universe) is None:
        return universe.map(list(genome), max_depth=config.genome.max_depth,
                            max_wraps=config.genome.max_wraps)
    try:
        text = "".join(map(chr, genome))   # chr refuses what is not a code point
    except (ValueError, TypeError, OverflowError):
        return MapResult(None, False, f"a text genome's codons are code points (0 to {_LARGEST})",
                         len(genome), 0)
    return MapResult(text, True, None, len(genome), 0)


def genome_of(config: RunConfig, universe: Universe, text: str) -> tuple[int, ...]:
    """A genome that maps to ``text`` under ``config``: its text genome under a universe's
    variation, else GE's inversion (``universe.invert``)."""
    if variation_for(config, universe) is None:
        return tuple(int(c) for c in universe.invert(text, max_depth=config.genome.max_depth))
    return text_genome(text)
