"""Selection and variation operators, each alone."""

from __future__ import annotations

import math
from collections import Counter

import pytest
from hypothesis import given
from hypothesis import strategies as st

from genr8_dist.evolution.operators import (
    int_flip_mutation,
    one_point_crossover,
    random_genome,
    select_elites,
    tournament_select,
)
from genr8_dist.rng import stream

genomes = st.lists(st.integers(0, 255), min_size=1, max_size=60)


def test_random_genome_is_in_range_and_seeded():
    g = random_genome(stream(1, "t"), 200, 7)
    assert len(g) == 200 and min(g) == 0 and max(g) == 7  # endpoint included
    assert g == random_genome(stream(1, "t"), 200, 7)
    assert g != random_genome(stream(2, "t"), 200, 7)


@given(genomes, genomes, st.integers(0, 2**32))
def test_one_point_crossover_swaps_tails(a, b, seed):
    c1, c2 = one_point_crossover(stream(seed, "x"), a, b)
    assert sorted([len(c1), len(c2)]) == sorted([len(a), len(b)])
    if min(len(a), len(b)) < 2:
        assert (c1, c2) == (tuple(a), tuple(b))
        return
    # the children are exactly a[:p] + b[p:] and b[:p] + a[p:] for some 1 <= p < min length
    assert any(c1 == tuple(a[:q]) + tuple(b[q:]) and c2 == tuple(b[:q]) + tuple(a[q:])
               for q in range(1, min(len(a), len(b))))


def test_crossover_of_distinct_parents_mixes_them():
    a, b = (0,) * 10, (1,) * 10
    c1, c2 = one_point_crossover(stream(0, "x"), a, b)
    assert c1[0] == 0 and c1[-1] == 1 and c2[0] == 1 and c2[-1] == 0


@given(genomes, st.floats(0, 1), st.integers(0, 2**32))
def test_mutation_keeps_length_and_range(genome, rate, seed):
    child, n = int_flip_mutation(stream(seed, "m"), genome, rate, 255)
    assert len(child) == len(genome) and all(0 <= c <= 255 for c in child)
    assert sum(1 for x, y in zip(child, genome, strict=True) if x != y) <= n


def test_mutation_rate_is_the_per_codon_probability():
    genome = (0,) * 1000
    flipped = [int_flip_mutation(stream(s, "m"), genome, 0.05, 10**6)[1] for s in range(20)]
    assert 40 < sum(flipped) / 20 < 60  # mean 50 of a Binomial(1000, 0.05)
    assert int_flip_mutation(stream(0, "m"), genome, 0.0, 9)[0] == genome


def test_at_least_one_codon_is_redrawn_when_asked():
    child, n = int_flip_mutation(stream(3, "m"), (5,) * 8, 0.0, 10**6, at_least_one=True)
    assert n == 1 and sum(1 for c in child if c != 5) == 1


def test_tournament_prefers_the_fitter():
    fitness = [float(i) for i in range(10)]
    rng = stream(0, "t")
    wins = Counter(tournament_select(rng, fitness, 3) for _ in range(2000))
    assert wins[0] > wins[5] > wins[9]
    assert all(tournament_select(stream(s, "t"), fitness, 1) in range(10) for s in range(5))
    # invalid individuals (inf, nan) lose to any finite one
    assert tournament_select(stream(0, "t"), [math.inf, 3.0, math.nan] * 3, 9) in (1, 4, 7)


def test_elites_are_the_best_finite_ones():
    assert select_elites([3.0, math.inf, 1.0, 2.0, 1.0], 3) == [2, 4, 3]
    assert select_elites([math.inf, math.nan], 2) == []
    assert select_elites([1.0], 0) == []


@pytest.mark.parametrize("bad", [lambda: tournament_select(stream(0), [], 2),
                                 lambda: tournament_select(stream(0), [1.0], 0),
                                 lambda: int_flip_mutation(stream(0), (1,), 1.5, 3),
                                 lambda: random_genome(stream(0), 0, 3),
                                 lambda: int_flip_mutation(object(), (1,), 0.1, 3)])
def test_operators_check_their_inputs(bad):
    with pytest.raises((ValueError, TypeError)):
        bad()


@given(genomes, genomes, st.integers(1, 70), st.integers(0, 2**32))
def test_crossover_within_used_cuts_only_inside_the_used_codons(a, b, used, seed):
    c1, c2 = one_point_crossover(stream(seed, "x"), a, b, within=used)
    shortest = min(len(a), len(b), used)
    if shortest < 2:
        assert (c1, c2) == (tuple(a), tuple(b))
        return
    # the cut p is where c1 stops following a: always inside 1..used-1
    p = next((i for i in range(1, len(c1)) if c1[i:] == tuple(b)[i:] and c1[:i] == tuple(a)[:i]), None)
    assert p is not None and 1 <= p < shortest


@given(genomes, st.integers(1, 70), st.integers(0, 2**32))
def test_mutation_within_used_never_flips_outside_the_used_codons(genome, used, seed):
    child, n = int_flip_mutation(stream(seed, "m"), genome, 0.5, 255, at_least_one=True, within=used)
    span = max(1, min(len(genome), used))
    assert child[span:] == tuple(genome)[span:]
    assert n >= 1


def test_a_child_its_text_shows_trivial_is_varied_again_from_its_first_parent():
    """``screened`` with ``restart``: a child whose look says ``screened`` (its text shows it
    trivial) is varied from what ``restart`` gives (its first parent), a copy from itself."""
    from genr8_dist.evolution.operators import Child, Look, screened

    parent = (7, 7, 7)
    looks = {(1, 1, 1): Look(True, "a", 3, "screened"), (2, 2, 2): Look(False, "p", 3),
             (3, 3, 3): Look(False, "b", 3), (4, 4, 4): Look(False, "c", 3)}
    varied: list[tuple[int, ...]] = []

    def revary(genome, codons):
        varied.append(genome)
        return {parent: (3, 3, 3), (2, 2, 2): (4, 4, 4)}[genome]

    children = [Child((1, 1, 1), "crossover", (0, 1)), Child((2, 2, 2), "mutation", (0,))]
    out = list(screened(iter(children), look=looks.__getitem__, revary=revary,
                        avoid=lambda parents: {"p"}, taken=set(), retries=3,
                        count=lambda name, n: None, restart=lambda child: (parent, 3)))
    assert [c.genome for c in out] == [(3, 3, 3), (4, 4, 4)]
    assert varied == [parent, (2, 2, 2)]   # the trivial one from its parent, the copy from itself
    assert out[0].origin == "crossover+mutation"
