"""A universe's own genome and operators (``genr8_dist.evolution.variation``): the tables universes
evolve by Hornby & Pollack's operators, their genomes the texts' characters; GE stays the default
for grammar universes and under ``ea.variation = "ge"``; every draw comes from the island's streams."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.errors import ConfigError, UniverseError
from genr8_dist.evolution.island import Island
from genr8_dist.evolution.variation import genome_of, map_genome, text_genome, variation_for
from genr8_dist.grammar import load_universe


def _config(universe: str = "tables", **ea) -> RunConfig:
    return RunConfig.from_dict({
        "universe": universe, "seed": 4,
        "ea": {"population": 8, "generations": 3, "tournament": 3, "elites": 2, "crossover_rate": 0.5,
               **ea},
        "islands": {"count": 1, "migrants": 0}})


@pytest.fixture(scope="module")
def history():
    return Island(_config(), 0).run()


def _rows(generations):
    return [(i.genome, i.text, i.origin, i.parents, i.fitness) for g in generations for i in g]


def test_a_tables_island_breeds_text_genomes_by_the_papers_operators(history):
    hooks = load_universe("tables").hooks
    for generation in history:
        for ind in generation:
            assert ind.genome == text_genome(ind.text) and ind.codons_used == len(ind.genome)
            assert hooks.variation.write(hooks.voxels.parse(ind.text)) == ind.text
    assert all(ind.origin == "random" and len(hooks.voxels.parse(ind.text).productions) == 20
               for ind in history[0])
    later = [ind for g in history[1:] for ind in g]
    # (random: a newcomer in place of an offspring whose every re-variation repeated or failed)
    assert {ind.origin for ind in later} <= {"elite", "mutation", "crossover", "crossover+mutation",
                                             "random"}
    parents = {"random": 0, "elite": 1, "mutation": 1, "crossover": 2, "crossover+mutation": 2}
    assert all(len(ind.parents) == parents[ind.origin] for ind in later)
    assert {"mutation", "crossover"} & {ind.origin for ind in later}
    # elitism 2: the best never gets worse
    best = [min(ind.fitness for ind in g) for g in history]
    assert all(b <= a for a, b in itertools.pairwise(best))
    assert sum(ind.origin == "elite" for ind in history[1]) == 2


def test_the_same_seed_gives_the_same_generations_and_a_step_recomputes_one(history):
    again = Island(_config(), 0).run()
    assert _rows(again) == _rows(history)
    fresh = Island(_config(), 0)   # generation 2 from generation 1 as a store keeps it (a resumed run)
    assert _rows([fresh.step(history[1], 2)]) == _rows([history[2]])


def test_half_of_the_offspring_are_recombined_and_half_mutated():
    island = Island(_config(population=30), 0)
    founders = island.initial()
    kinds = [b.origin for g in (1, 2, 3) for b in island.breed(g, founders) if b.origin != "elite"]
    crossed = sum(k.startswith("crossover") for k in kinds)
    assert 0.35 < crossed / len(kinds) < 0.65 and "mutation" in kinds


def test_ge_stays_for_grammar_universes_and_under_ea_variation_ge():
    assert variation_for(_config("default"), load_universe("default")) is None
    ge = _config(variation="ge")
    assert variation_for(ge, load_universe("tables")) is None
    island = Island(ge, 0)
    founders = island.initial()
    assert island.variation is None
    universe = load_universe("tables")
    for ind in founders:   # GE genomes: codons mapped through the grammar
        assert max(ind.genome) <= ge.genome.codon_max and ind.genome != text_genome(ind.text or "")
        assert universe.map(list(ind.genome), max_depth=ge.genome.max_depth,
                            max_wraps=ge.genome.max_wraps).text == ind.text


def test_the_direct_universe_brings_the_direct_genome():
    island = Island(_config("tables_direct"), 0)
    founders = island.initial()
    hooks = load_universe("tables").hooks
    assert all(not hooks.voxels.parse(ind.text).productions for ind in founders)
    assert all(len(ind.text.split()) >= 4 for ind in founders)


def test_mapping_and_inverting_a_text_genome():
    config, universe = _config(), load_universe("tables")
    text = "P0(4,10) iterations 2\nP0(n0,n1): n0>1 -> f(3)\n"
    assert genome_of(config, universe, text) == text_genome(text)
    mapped = map_genome(config, universe, text_genome(text))
    assert mapped.valid and mapped.text == text and mapped.codons_used == len(text)
    bad = map_genome(config, universe, [0x110000])
    assert not bad.valid and "code points" in bad.reason


def test_a_bad_variation_and_a_bad_setting_are_one_line_errors():
    fake = SimpleNamespace(name="fake", hooks=SimpleNamespace(VARIATION=object()))
    with pytest.raises(UniverseError, match=r"hooks\.VARIATION needs the methods"):
        variation_for(_config(), fake)
    with pytest.raises(ConfigError, match=r"ea\.variation"):
        _config(variation="paper")
