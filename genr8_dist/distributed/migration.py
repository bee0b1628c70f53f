"""Migration between islands: who sends to whom, and which individuals leave.

Migration happens after every generation ``g > 0`` with ``g % migration_interval == 0``: each island's
*emigrants* are the best ``k`` individuals of its generation ``g`` (lowest fitness first, ties broken by
index), and they enter the destination's generation ``g + 1`` through ``Island.step(migrants=...)``.
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
    "plan_migration",
    "select_emigrants",
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


def destinations(topology: str, n_islands: int, seed: int, generation: int) -> dict[int, tuple[int, ...]]:
    """For each source island, the islands its emigrants go to after ``generation``."""
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


def plan_migration(
    populations: Mapping[int, Sequence[Individual]],
    topology: str,
    k: int,
    seed: int,
    generation: int,
) -> dict[int, list[Individual]]:
    """The migrants each island receives after ``generation``, from each island's population of it.

    ``populations`` maps every island index ``0..n-1`` to its generation ``generation``. The result maps
    every island to its incoming migrants (at most ``k``), ordered best first.
    """
    n = len(populations)
    if sorted(populations) != list(range(n)):
        raise ValueError(f"migration needs islands 0..{n - 1}, got {sorted(populations)}")
    incoming: dict[int, list[Individual]] = {i: [] for i in range(n)}
    if k == 0:
        return incoming
    for source, targets in destinations(topology, n, seed, generation).items():
        emigrants = select_emigrants(populations[source], k)
        for target in targets:
            incoming[target].extend(emigrants)
    return {i: sorted(arrived, key=_rank_key)[:k] for i, arrived in incoming.items()}
