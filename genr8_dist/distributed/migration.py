"""Migration between islands: who sends to whom, and which individuals leave.

Migration happens after every generation ``g > 0`` with ``g % migration_interval == 0``: each island's
*emigrants* are the best ``k`` individuals of its generation ``g`` (lowest fitness first, ties broken by
index), or with ``islands.emigrants = "novel"`` the fitter ones least like the destination's
population, and they enter the destination's generation ``g + 1`` through
``Island.step(migrants=...)``.
Everything here is a pure function of the committed generation, the run seed and ``g``, so a resumed or
recovered run migrates exactly what an uninterrupted one does.

Topologies (every island receives at most ``k`` migrants, whatever the topology):

``ring``
    island ``i`` sends to ``(i + 1) % n``.
``random``
    a ring through a random order of the islands, drawn afresh at every migration from
    ``stream(seed, "migration", g)``: every island sends to exactly one other and receives from one.
``full``
    every island sends to every other; a destination keeps the best ``k`` of all that arrive
    (fitness, then source island, then index).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence

from genr8_dist.config import TOPOLOGIES
from genr8_dist.errors import ConfigError
from genr8_dist.evolution.individual import Individual
from genr8_dist.rng import stream

__all__ = [
    "TOPOLOGIES",
    "destinations",
    "is_migration_generation",
    "migrants_for",
    "plan_migration",
    "select_emigrants",
    "select_novel",
    "sources",
]

def _rank_key(individual: Individual) -> tuple[float, int, int]:
    fitness = individual.fitness if not math.isnan(individual.fitness) else math.inf
    return (fitness, individual.island, individual.index)


def is_migration_generation(generation: int, interval: int) -> bool:
    """Whether migrants leave after ``generation`` (and so enter ``generation + 1``)."""
    if interval <= 0:
        return False
    return generation > 0 and generation % interval == 0


def select_emigrants(population: Sequence[Individual], k: int) -> list[Individual]:
    """The best ``k`` individuals of ``population``: lowest fitness first, ties by index (NaN as worst)."""
    if k < 0:
        raise ValueError(f"the number of migrants must be non-negative, got {k}")
    return sorted(population, key=_rank_key)[:k]


def _features(individuals: Sequence[Individual]) -> list[list[float]]:
    names = sorted({name for ind in individuals for name in ind.criteria})
    sizes = sorted({name for ind in individuals for name in ind.sizes})
    rows = []
    for ind in individuals:
        row = [float(ind.criteria.get(name, math.nan)) for name in names]
        rows.append([v if math.isfinite(v) else 0.0 for v in row]
                    + [math.log1p(max(ind.sizes.get(name, 0), 0)) for name in sizes])
    return rows


def select_novel(population: Sequence[Individual], destination: Sequence[Individual], k: int
                 ) -> list[Individual]:
    """``k`` emigrants unlike ``destination``: among the valid individuals of the better half of
    ``population`` whose phenotype the destination does not hold, the ``k`` farthest from every member
    of the destination (criteria and the logs of the phenotype's sizes, each scaled by its spread over both
    populations), ties to the fitter; topped up with the best when too few qualify."""
    if k <= 0:
        return []
    ranked = sorted(population, key=_rank_key)
    held = {ind.phenotype_digest for ind in destination if ind.valid}
    half = ranked[:max(k, (len(ranked) + 1) // 2)]
    candidates = [ind for ind in half if ind.valid and ind.phenotype_digest not in held]
    there = [ind for ind in destination if ind.valid]
    if candidates and there:
        rows = _features(candidates + there)
        spread = [max(col) - min(col) or 1.0 for col in zip(*rows, strict=True)]
        scaled = [[v / s for v, s in zip(row, spread, strict=True)] for row in rows]
        mine, theirs = scaled[:len(candidates)], scaled[len(candidates):]
        distance = [min(math.dist(a, b) for b in theirs) for a in mine]
        order = sorted(range(len(candidates)), key=lambda i: (-distance[i], _rank_key(candidates[i])))
        chosen = [candidates[i] for i in order[:k]]
    else:
        chosen = candidates[:k]
    ids = {ind.id for ind in chosen}
    chosen += [ind for ind in ranked if ind.id not in ids][:k - len(chosen)]
    return sorted(chosen, key=_rank_key)


@functools.lru_cache(maxsize=16)
def destinations(topology: str, n_islands: int, seed: int, generation: int) -> dict[int, tuple[int, ...]]:
    """For each source island, the islands its emigrants go to after ``generation`` (computed once
    per migration: every island asks; read it, never change it)."""
    if topology not in TOPOLOGIES:
        raise ConfigError(
            f"islands.topology: {topology!r} is not a migration topology; use one of {', '.join(TOPOLOGIES)}"
        )
    if n_islands < 2:
        return {i: () for i in range(n_islands)}
    if topology == "ring":
        return {i: ((i + 1) % n_islands,) for i in range(n_islands)}
    if topology == "full":
        return {i: tuple(j for j in range(n_islands) if j != i) for i in range(n_islands)}
    order = [int(x) for x in stream(seed, "migration", generation).permutation(n_islands)]
    return {order[j]: (order[(j + 1) % n_islands],) for j in range(n_islands)}


@functools.lru_cache(maxsize=16)
def sources(topology: str, n_islands: int, seed: int, generation: int) -> dict[int, tuple[int, ...]]:
    """For each destination island, the islands whose emigrants it receives after ``generation``
    (what its migrants wait for: ``migrants_for``; computed once per migration, read it, never change
    it)."""
    out: dict[int, list[int]] = {i: [] for i in range(n_islands)}
    for source, targets in destinations(topology, n_islands, seed, generation).items():
        for target in targets:
            out[target].append(source)
    return {i: tuple(found) for i, found in out.items()}


def migrants_for(
    target: int,
    populations: Mapping[int, Sequence[Individual]],
    n_islands: int,
    topology: str,
    k: int,
    seed: int,
    generation: int,
    emigrants: str = "best",
) -> list[Individual]:
    """The migrants ``target`` receives after ``generation`` (at most ``k``, best first), from the
    populations of its ``sources`` (and its own, for novel emigrants): ``plan_migration``'s answer for
    that island alone (of ``n_islands``), available as soon as those islands have completed
    ``generation``."""
    if k == 0:
        return []
    if emigrants not in ("best", "novel"):
        raise ConfigError(f"islands.emigrants: {emigrants!r} is not one of 'best', 'novel'")
    arrived: list[Individual] = []
    for source in sources(topology, n_islands, seed, generation)[target]:
        arrived.extend(select_emigrants(populations[source], k) if emigrants == "best"
                       else select_novel(populations[source], populations[target], k))
    return sorted(arrived, key=_rank_key)[:k]


def plan_migration(
    populations: Mapping[int, Sequence[Individual]],
    topology: str,
    k: int,
    seed: int,
    generation: int,
    emigrants: str = "best",
) -> dict[int, list[Individual]]:
    """The migrants each island receives after ``generation``, from each island's population of it.

    ``populations`` maps every island index ``0..n-1`` to its generation ``generation``. The result maps
    every island to its incoming migrants (at most ``k``), ordered best first. ``emigrants``:
    ``"best"`` sends each island's best ``k``; ``"novel"`` sends, to each destination, ``k`` of the
    source's better half that are unlike the destination's population (``select_novel``), so that
    islands exchange what they lack rather than converge on one design.
    """
    n = len(populations)
    if sorted(populations) != list(range(n)):
        raise ValueError(f"migration needs islands 0..{n - 1}, got {sorted(populations)}")
    incoming: dict[int, list[Individual]] = {i: [] for i in range(n)}
    if k == 0:
        return incoming
    if emigrants not in ("best", "novel"):
        raise ConfigError(f"islands.emigrants: {emigrants!r} is not one of 'best', 'novel'")
    for source, targets in destinations(topology, n, seed, generation).items():
        best = select_emigrants(populations[source], k)
        for target in targets:
            incoming[target].extend(best if emigrants == "best"
                                    else select_novel(populations[source], populations[target], k))
    return {i: sorted(arrived, key=_rank_key)[:k] for i, arrived in incoming.items()}
