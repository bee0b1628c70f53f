"""The variation and selection operators of the island, and the pipeline its offspring are bred by.

Each operator takes an explicit ``numpy.random.Generator`` (from ``genr8_dist.rng.stream``) and plain
values, so each can be tested alone and a generation can be recomputed draw for draw. Genomes are
tuples of non-negative ints (codons in ``0..codon_max``).

**The offspring pipeline.** ``Island.breed`` composes, in one place (``Island._offspring``), stages in
the style of LEAP's pipelines: each stage takes the iterator of the stage before and yields its own
items.

    select_matings                    selection: parents by tournament (a mate drawn again while a copy)
    -> crossover -> mutation          variation: GE's one-point crossover and int-flip mutation
       (or recombination)                        (or a universe's own operators on texts)
    -> screened                       the screen before evaluation: a child whose text shows it a copy,
                                      unmappable or trivial is varied again (``Look``: what it shows)
    -> births                         the island's ``Birth`` of each child

Evaluation (``Evaluator.preview``, then re-variation of what growth shows wasted) and replacement
(migrants, injected, elites, then these offspring, up to ``Island.generation_size``) are the island's
``complete`` and ``breed``. The pipeline is lazy: the island takes as many offspring as it has room
for, and no stage draws past the last child taken, so each random stream is drawn in the order one
loop would draw it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.evolution.variation import Variation

__all__ = [
    "Child",
    "Look",
    "Mating",
    "crossover",
    "int_flip_mutation",
    "mutation",
    "one_point_crossover",
    "parent_picker",
    "random_genome",
    "rank_key",
    "recombination",
    "screened",
    "select_elites",
    "select_matings",
    "selection",
    "tournament_select",
]

Genome = tuple[int, ...]
# Counts what a stage did: the name of an ``IslandStats`` counter and how much to add to it.
Tally = Callable[[str, int], None]
# One tournament over the pool: ``(rng, first)``, the position of the winner (``first``: a first parent).
Picker = Callable[[np.random.Generator, bool], int]


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
    return tuple(rng.integers(0, codon_max, size=length, endpoint=True).tolist())


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


def selection(config: RunConfig, pool: Sequence[Individual], fitnesses: list[float], room: int
              ) -> tuple[list[float], list[int], list[int]]:
    """By ``search.mode``: the scores tournaments compare (lower wins), the positions in ``pool``
    of the elites to keep, and the positions parents are drawn from (empty: the whole pool).

    ``weighted``: the fitness; the best ``ea.elites``. ``pareto``: NSGA-II's order (front, then
    crowding distance) over the weighted deviations of ``search.objectives``; the elites are the
    first front: its best ``ea.elites`` by the fitness first (the weighted sum, whose minimum is on
    the front when the objectives are the weighted criteria), then the least crowded, up to half
    the room. ``map-elites``:
    the whole archive of ``pool`` (every held cell's best, whatever the room: ``generation_size``
    makes room for the offspring after it); each pair's first parent drawn from it by a
    tournament of ``ea.tournament``, its mate uniformly (``ea.tournament = 1``: both uniformly,
    as in the original MAP-Elites)."""
    ea, search = config.ea, config.search
    if search.mode == "pareto":
        from genr8_dist.evolution.pareto import objectives_of, pareto_objectives, pareto_order

        names = pareto_objectives(config)
        ranks, position = pareto_order(objectives_of([p.criteria for p in pool], [p.valid for p in pool],
                                                     config.fitness, names))
        scores = [float(position[i]) if pool[i].valid else math.inf for i in range(len(pool))]
        front = sorted((i for i in range(len(pool)) if ranks[i] == 0 and pool[i].valid),
                       key=lambda i: scores[i])
        best = sorted(front, key=lambda i: (fitnesses[i], i))[:min(ea.elites, room)]
        keep = min(room, max(len(best), min(len(front), room // 2)))
        return scores, (best + [i for i in front if i not in best])[:keep], []
    if search.mode == "map-elites":
        from genr8_dist.evolution.archive import Grid

        grid = Grid.from_settings(search)
        where = {id(p): i for i, p in enumerate(pool)}
        elites = [where[id(ind)] for ind in grid.elites(pool, grid.size)]
        return list(fitnesses), elites, list(elites)
    return list(fitnesses), select_elites(fitnesses, min(ea.elites, room)), []


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
    n = int(np.count_nonzero(mask))
    if at_least_one and not n:
        mask[int(rng.integers(0, span))] = True
        n = 1
    if n:
        g = g.copy()
        g[mask] = rng.integers(0, codon_max, size=n, endpoint=True)
    return tuple(g.tolist()), n


# -- the offspring pipeline --------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Mating:
    """The parents of one variation, as positions in the pool: the first parent first; one parent
    when the child is its mutation alone."""

    parents: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Child:
    """An offspring on its way through the pipeline: its genome, origin and parents (positions in
    the pool, the first parent first; none for a newcomer), the codons the mapper read of what it
    was varied from (where a variation may fall under ``ea.within_used``) and the keys of copies it
    must not be (``screened``)."""

    genome: Genome
    origin: str          # "crossover", "mutation", "crossover+mutation", "random"; "copy" until mutated
    parents: tuple[int, ...]
    codons: int = 0
    avoid: frozenset[str] = frozenset()


@dataclass(frozen=True, slots=True)
class Look:
    """What a genome shows before it is grown: whether it is wasted for sure (it maps to no text, or
    its text is trivial), its key (equal keys, equal phenotypes), the codons the mapper read, and
    the ``IslandStats`` counter a re-variation for it counts under."""

    wasted: bool
    key: str | None
    read: int
    reason: str = "revaried_text"


def parent_picker(scores: Sequence[float], mates: Sequence[int], tournament: int) -> Picker:
    """One tournament of ``tournament`` over ``scores`` (lower wins) per call; with ``mates`` (the
    MAP-Elites archive's positions) the first parent by a tournament among them, its mate uniformly
    among them."""
    mate_scores = [scores[i] for i in mates]

    def pick(rng: np.random.Generator, first: bool = True) -> int:
        if mates:
            return mates[tournament_select(rng, mate_scores, tournament if first else 1)]
        return tournament_select(rng, scores, tournament)

    return pick


def select_matings(pick: Picker, rng: np.random.Generator, *, same: Callable[[int, int], bool],
                   retries: int, count: Tally, crossed: Callable[[], bool] | None = None
                   ) -> Iterator[Mating]:
    """Selection, without end: a first parent, then its mate, drawn again (up to ``retries`` times)
    while ``same`` says it is a copy of the first (counted as ``mates_redrawn``). With ``crossed``
    (asked between the two draws), a mate only when it says the child is a recombination."""
    while True:
        first = pick(rng, True)
        if crossed is not None and not crossed():
            yield Mating((first,))
            continue
        mate, tries = pick(rng, False), 0
        while tries < retries and same(first, mate):
            mate, tries = pick(rng, False), tries + 1
        count("mates_redrawn", tries)
        yield Mating((first, mate))


def crossover(matings: Iterator[Mating], rng: np.random.Generator, rate: float, *,
              genome: Callable[[int], Genome], read: Callable[[int], int], within_used: bool
              ) -> Iterator[Child]:
    """GE's crossover: two children per mating, one-point crossed with probability ``rate`` (origin
    ``crossover``; with ``within_used`` the cut within the codons both parents read), else copies of
    the parents (``copy``: mutation makes them children)."""
    for mating in matings:
        a, b = mating.parents
        used_a, used_b = read(a), read(b)
        if rng.random() < rate:
            within = min(used_a, used_b) if within_used and min(used_a, used_b) > 0 else None
            one, other = one_point_crossover(rng, genome(a), genome(b), within=within)
            yield Child(one, "crossover", (a, b), max(used_a, used_b))
            yield Child(other, "crossover", (b, a), max(used_a, used_b))
        else:
            yield Child(genome(a), "copy", (a,), used_a)
            yield Child(genome(b), "copy", (b,), used_b)


def mutation(children: Iterator[Child], rng: np.random.Generator, rate: float, codon_max: int, *,
             within_used: bool) -> Iterator[Child]:
    """GE's int-flip mutation of each child (a copy at least one codon, so no child is a silent copy;
    with ``within_used`` only the codons read): origin ``mutation``, or ``crossover+mutation`` for a
    crossed child a codon of which was redrawn."""
    for child in children:
        crossed = child.origin == "crossover"
        within = child.codons if within_used and child.codons > 0 else None
        genome, flipped = int_flip_mutation(rng, child.genome, rate, codon_max, at_least_one=not crossed,
                                            within=within)
        origin = ("crossover+mutation" if flipped else "crossover") if crossed else "mutation"
        yield replace(child, genome=genome, origin=origin)


def recombination(matings: Iterator[Mating], rng: np.random.Generator, variation: Variation,
                  text: Callable[[int], str]) -> Iterator[Child]:
    """A universe's own operators (``evolution.variation``): per mating one child, the recombination
    of the two parents' texts (origin ``crossover``) or the mutation of the one's (``mutation``); a
    parent whose text the operators cannot read gives a newcomer (origin ``random``, no parents)."""
    for mating in matings:
        a = mating.parents[0]
        try:
            if len(mating.parents) == 2:
                child, origin = variation.recombine(rng, text(a), text(mating.parents[1])), "crossover"
            else:
                child, origin = variation.mutate(rng, text(a)), "mutation"
            parents = mating.parents
        except Exception:   # a parent the operators cannot read (hand-written, say): a newcomer
            child, origin, parents = variation.founder(rng), "random", ()
        yield Child(tuple(ord(c) for c in child), origin, parents)


def screened(children: Iterator[Child], *, look: Callable[[Genome], Look],
             revary: Callable[[Genome, int], Genome], avoid: Callable[[tuple[int, ...]], set[str]],
             taken: set[str | None], retries: int, count: Tally,
             restart: Callable[[Child], tuple[Genome, int] | None] | None = None) -> Iterator[Child]:
    """The screen before evaluation: a child whose ``look`` shows it wasted, or whose key is one of
    its parents' (``avoid``) or of an earlier member's (``taken``, to which each child's key is
    added), is varied again (``revary`` of its genome and the codons read) up to ``retries`` times;
    a crossed child varied again is ``crossover+mutation``. ``restart``: the genome and codons read
    that a child whose text shows it trivial (reason ``screened``) is varied from instead of its own
    (its first parent's: its variation broke what made the parent split; ``None``: its own). No
    genome is grown here."""
    for child in children:
        keys = avoid(child.parents)
        genome, origin = child.genome, child.origin
        if retries > 0:
            seen = look(genome)
            for _ in range(retries):
                if not seen.wasted and seen.key not in keys and seen.key not in taken:
                    break
                count(seen.reason, 1)
                base = restart(child) if restart is not None and seen.reason == "screened" else None
                genome = revary(*base) if base is not None else revary(genome, seen.read)
                seen = look(genome)
                if origin == "crossover":
                    origin = "crossover+mutation"
            taken.add(seen.key)
        yield replace(child, genome=genome, origin=origin, avoid=frozenset(keys))
