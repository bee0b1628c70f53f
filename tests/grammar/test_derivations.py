"""Sensible initialisation: sampled derivations are read by the mapper exactly as they were drawn."""

from __future__ import annotations

import pytest

from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.grammar.derivations import bushy_genome, ramped_genomes, sample_derivation
from genr8_dist.rng import stream

UNIVERSES = [info.name for info in list_universes()]


@pytest.mark.parametrize("name", UNIVERSES)
def test_the_mapper_reads_the_derivation_that_was_drawn(name):
    universe = load_universe(name)
    cg = universe.grammar
    depth = max(5, cg.min_depth[cg.start])  # the tables universe needs 6 levels to finish at all
    mapper = universe.mapper(depth)
    rng = stream(3, "derivations", name)
    for i in range(60):
        sample = sample_derivation(universe, rng, max_depth=depth, limit=2 + i % 4,
                                   method=("grow", "full")[i % 2], codon_max=255)
        assert all(0 <= c <= 255 for c in sample.codons)
        codons = iter(sample.codons + [0] * 10_000)
        out: list[str] = []
        mapper.derive(codons.__next__, out, set().add)
        assert out == sample.tokens
        assert sample.height <= depth


def test_full_trees_are_deeper_than_grown_ones():
    universe = load_universe("default")
    rng = stream(4, "depth")
    heights = {m: [sample_derivation(universe, rng, max_depth=6, limit=6, method=m, codon_max=255).height
                   for _ in range(40)] for m in ("grow", "full")}
    assert min(heights["full"]) == 6
    assert sum(heights["full"]) > sum(heights["grow"])


def test_ramped_genomes_are_seeded_valid_and_at_least_as_long_as_asked():
    universe = load_universe("default")
    a = ramped_genomes(universe, stream(5, "r"), 12, length=60, codon_max=255, max_depth=5)
    b = ramped_genomes(universe, stream(5, "r"), 12, length=60, codon_max=255, max_depth=5)
    assert a == b and len(a) == 12
    assert all(len(g) >= 60 for g in a)
    assert all(universe.map(g, max_depth=5, max_wraps=2).valid for g in a)
    with pytest.raises(ValueError, match="method"):
        sample_derivation(universe, stream(1), max_depth=5, limit=5, method="half", codon_max=255)


@pytest.mark.parametrize("name", ["default", "gecco", "tiles"])
def test_bushy_trees_are_read_as_drawn_over_the_first_two_labels_and_are_bushier(name):
    universe = load_universe(name)
    mapper = universe.mapper(5)
    rng = stream(6, "bushy", name)
    sizes = {}
    for rounds in (0, 8):
        sizes[rounds] = []
        for _ in range(20):
            sample = sample_derivation(universe, rng, max_depth=5, limit=5, method="grow", codon_max=255,
                                       births=False, rounds=rounds)
            codons = iter(sample.codons + [0] * 10_000)
            out: list[str] = []
            mapper.derive(codons.__next__, out, set().add)
            assert out == sample.tokens
            labels = {universe.label_of(t) for t in sample.tokens} - {None}
            assert labels <= {0, 1}
            sizes[rounds].append(len(sample.tokens))
    assert sum(sizes[8]) > 2 * sum(sizes[0])
    a = bushy_genome(universe, stream(7, "b"), length=60, codon_max=255, max_depth=5)
    assert a == bushy_genome(universe, stream(7, "b"), length=60, codon_max=255, max_depth=5)
    assert len(a) >= 60 and universe.map(a, max_depth=5).valid
