"""Migration: topologies, emigrant selection, and the migrants each island receives."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from genr8_dist.distributed.migration import (
    destinations,
    is_migration_generation,
    migrants_for,
    plan_migration,
    select_emigrants,
    sources,
)
from genr8_dist.errors import ConfigError
from genr8_dist.evolution.individual import Individual


def _pop(island: int, fitnesses: list[float], generation: int = 5) -> list[Individual]:
    return [Individual(island=island, generation=generation, index=i, genome=(island, i), origin="random",
                       fitness=f, valid=math.isfinite(f)) for i, f in enumerate(fitnesses)]


def test_emigrants_are_the_best_by_fitness_then_index():
    pop = _pop(0, [3.0, 1.0, math.inf, 1.0, 0.5, math.nan])
    assert [x.index for x in select_emigrants(pop, 3)] == [4, 1, 3]
    assert [x.index for x in select_emigrants(pop, 6)][-2:] == [2, 5]
    assert select_emigrants(pop, 0) == []


def test_ring_sends_to_the_next_island():
    assert destinations("ring", 4, seed=1, generation=5) == {0: (1,), 1: (2,), 2: (3,), 3: (0,)}


def test_full_sends_to_every_other_island():
    d = destinations("full", 3, seed=1, generation=5)
    assert d == {0: (1, 2), 1: (0, 2), 2: (0, 1)}


@given(n=st.integers(2, 12), seed=st.integers(0, 2**32), g=st.integers(1, 1000))
def test_random_topology_is_a_ring_through_a_seeded_order(n, seed, g):
    d = destinations("random", n, seed, g)
    assert d == destinations("random", n, seed, g)
    targets = [t for (t,) in d.values()]
    assert sorted(targets) == list(range(n))           # everyone receives once
    assert all(src != t for src, (t,) in d.items())    # nobody sends to itself
    # following the arrows visits every island: one cycle
    seen, at = set(), 0
    for _ in range(n):
        seen.add(at)
        at = d[at][0]
    assert seen == set(range(n))


def test_random_topology_changes_between_migrations():
    orders = {tuple(sorted(destinations("random", 6, 7, g).items())) for g in range(5, 100, 5)}
    assert len(orders) > 1


def test_single_island_and_unknown_topology():
    assert destinations("ring", 1, 0, 5) == {0: ()}
    with pytest.raises(ConfigError, match="star"):
        destinations("star", 3, 0, 5)


def test_plan_migration_ring_moves_the_best_k():
    pops = {0: _pop(0, [5, 1, 3]), 1: _pop(1, [2, 9, 0.5]), 2: _pop(2, [7, 6, 8])}
    plan = plan_migration(pops, "ring", 2, seed=0, generation=5)
    assert [m.id for m in plan[1]] == ["0-5-1", "0-5-2"]
    assert [m.id for m in plan[2]] == ["1-5-2", "1-5-0"]
    assert [m.id for m in plan[0]] == ["2-5-1", "2-5-0"]


def test_plan_migration_full_keeps_the_best_k_of_all_arrivals():
    pops = {0: _pop(0, [5, 1, 3]), 1: _pop(1, [2, 9, 0.5]), 2: _pop(2, [7, 6, 8])}
    plan = plan_migration(pops, "full", 2, seed=0, generation=5)
    assert [m.id for m in plan[0]] == ["1-5-2", "1-5-0"]
    assert [m.id for m in plan[2]] == ["1-5-2", "0-5-1"]
    assert all(len(v) == 2 for v in plan.values())


def test_migration_generations():
    assert [g for g in range(21) if is_migration_generation(g, 5)] == [5, 10, 15, 20]
    assert not is_migration_generation(0, 1)


def test_epochs_end_where_migrants_leave():
    from genr8_dist.distributed.coordinator import epoch_end

    assert epoch_end(-1, 5, 20) == 5        # a new run: generations 0..5 in the first epoch
    assert epoch_end(5, 5, 20) == 10
    assert epoch_end(7, 5, 20) == 10        # resumed mid-epoch: on to the next migration
    assert epoch_end(15, 5, 18) == 18       # the last epoch ends with the run
    assert epoch_end(-1, 5, 0) == 0


def _shaped(island: int, rows: list[tuple[float, str, float]]) -> list[Individual]:
    """Individuals with (fitness, surface digest, undulation)."""
    return [Individual(island=island, generation=5, index=i, genome=(island, i), origin="random",
                       fitness=f, valid=True, phenotype_digest=d, criteria={"undulation": u})
            for i, (f, d, u) in enumerate(rows)]


def test_novel_emigrants_are_fit_surfaces_the_destination_lacks():
    from genr8_dist.distributed.migration import select_novel

    source = _shaped(0, [(0.1, "a", 0.0), (0.2, "b", 0.1), (0.3, "c", 5.0), (0.4, "d", 4.0),
                         (8.0, "e", 9.0), (9.0, "f", 9.0), (9.5, "g", 9.0)])
    destination = _shaped(1, [(0.1, "a", 0.0), (0.5, "x", 0.2)])
    chosen = select_novel(source, destination, 2)
    # "a" is already there; e, f, g are in the worse half; of b, c, d the two farthest from the
    # destination
    assert sorted(ind.phenotype_digest for ind in chosen) == ["c", "d"]
    plan = plan_migration({0: source, 1: destination}, "ring", 2, seed=0, generation=5, emigrants="novel")
    assert sorted(ind.phenotype_digest for ind in plan[1]) == ["c", "d"]
    with pytest.raises(ConfigError, match="emigrants"):
        plan_migration({0: source, 1: destination}, "ring", 2, seed=0, generation=5, emigrants="far")


@pytest.mark.parametrize("topology", ["ring", "random", "full"])
@pytest.mark.parametrize("mode", ["best", "novel"])
def test_one_islands_migrants_from_its_sources_alone_are_the_plans(topology, mode):
    """What an island receives, computed from its sources' populations alone (as soon as they have
    completed the generation), is what the whole plan gives it."""
    n = 5
    populations = {i: _pop(i, [((i * 7 + k * 3) % 11) / 3 for k in range(6)]) for i in range(n)}
    plan = plan_migration(populations, topology, 2, seed=3, generation=5, emigrants=mode)
    froms = sources(topology, n, seed=3, generation=5)
    for target in range(n):
        needed = set(froms[target]) | ({target} if mode == "novel" else set())
        alone = {i: populations[i] for i in needed}
        assert migrants_for(target, alone, n, topology, 2, 3, 5, mode) == plan[target]
