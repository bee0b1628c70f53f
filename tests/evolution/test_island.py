"""The island: generations, provenance, determinism, recomputation, migrants and injections, and
selection that improves fitness."""

from __future__ import annotations

import dataclasses
import itertools
import math
import statistics
from pathlib import Path

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.errors import ConfigError
from genr8_dist.evolution import ORIGINS, Individual, Island, IslandStats

TIMINGS = {"eval_seconds", "map_seconds", "grow_seconds", "score_seconds"}


def untimed(individual: Individual) -> dict:
    return {k: v for k, v in dataclasses.asdict(individual).items() if k not in TIMINGS}


def small_config(**changes) -> RunConfig:
    base = {
        "seed": 11,
        "genome": {"length": 40},
        "ea": {"population": 12, "generations": 3, "tournament": 3, "elites": 2},
        "environment": {"steps": 2},
        "islands": {"count": 2, "migrants": 2},
    }
    for key, value in changes.items():
        base[key] = {**base[key], **value} if isinstance(value, dict) and key in base else value
    return RunConfig.from_dict(base)


@pytest.fixture(scope="module")
def history():
    config = small_config()
    return config, Island(config, 0).run()


def test_generation_zero(history):
    config, hist = history
    gen0 = hist[0]
    assert [ind.index for ind in gen0] == list(range(config.ea.population))
    assert all(ind.generation == 0 and ind.island == 0 and ind.origin == "random" for ind in gen0)
    # 40 codons, or a bushy redraw's derivation tree, which keeps its own length
    assert all(len(ind.genome) >= 40 and all(0 <= c <= 255 for c in ind.genome) for ind in gen0)
    assert sum(len(ind.genome) == 40 for ind in gen0) >= len(gen0) // 2
    assert len({ind.genome for ind in gen0}) == len(gen0)
    for ind in gen0:
        if ind.valid:
            assert math.isfinite(ind.fitness) and ind.stage is None and ind.text
            assert ind.fitness == pytest.approx(config.fitness.evaluate(ind.criteria))
        else:
            assert ind.fitness == math.inf and ind.stage in ("map", "parse", "grow", "score") and ind.error


def test_provenance(history):
    config, hist = history
    for g in range(1, len(hist)):
        previous = {ind.id: ind for ind in hist[g - 1]}
        population = hist[g]
        assert [ind.index for ind in population] == list(range(config.ea.population))
        assert all(ind.origin in ORIGINS and ind.generation == g for ind in population)
        elites = [ind for ind in population if ind.origin == "elite"]
        assert len(elites) == config.ea.elites
        best = sorted((p for p in hist[g - 1] if math.isfinite(p.fitness)),
                      key=lambda p: (p.fitness, p.index))[: config.ea.elites]
        assert [e.parents[0] for e in elites] == [b.id for b in best]
        for ind in population:
            assert all(pid in previous for pid in ind.parents)
            if ind.origin == "elite":
                parent = previous[ind.parents[0]]
                assert ind.genome == parent.genome and ind.fitness == parent.fitness
            elif ind.origin.startswith("crossover"):
                assert len(ind.parents) == 2
            elif ind.origin == "random":   # a newcomer: re-variation could not escape a copy
                assert ind.parents == ()
            else:
                assert ind.origin == "mutation" and len(ind.parents) == 1
                assert ind.genome != previous[ind.parents[0]].genome or len(ind.genome) == 0


def test_same_config_and_seed_give_identical_populations(history):
    config, hist = history
    again = Island(small_config(), 0).run()
    assert [[untimed(i) for i in pop] for pop in again] == [[untimed(i) for i in pop] for pop in hist]
    other_seed = Island(small_config(seed=12), 0).initial()
    assert [i.genome for i in other_seed] != [i.genome for i in hist[0]]
    other_island = Island(config, 1).initial()
    assert [i.genome for i in other_island] != [i.genome for i in hist[0]]


def test_a_generation_is_recomputed_from_the_stored_one(history):
    config, hist = history
    for g in range(1, len(hist)):
        stored = [Individual(**dataclasses.asdict(ind)) for ind in hist[g - 1]]  # as the store rebuilds it
        recomputed = Island(config, 0).step(stored, g)
        assert [untimed(i) for i in recomputed] == [untimed(i) for i in hist[g]]


def test_migrants_and_injected_enter_first(history):
    config, hist = history
    island1 = Island(config, 1)
    arrivals = sorted(hist[2], key=lambda i: (i.fitness, i.index))[:2]
    donor = next(ind for ind in hist[2] if ind.valid)
    text_source = next(ind for ind in hist[0] if ind.valid)
    injected = [text_source.text, list(donor.genome), donor]
    gen1 = island1.step(island1.initial(), 1, migrants=arrivals, injected=injected)
    assert [i.origin for i in gen1[:5]] == ["migrant", "migrant", "injected", "injected", "injected"]
    for m, arrived in zip(gen1[:2], arrivals, strict=True):
        assert m.parents == (arrived.id,) and m.genome == arrived.genome and m.fitness == arrived.fitness
        assert m.island == 1 and m.generation == 1
    assert gen1[2].text == text_source.text and gen1[2].parents == ()       # through the inverse mapper
    assert gen1[3].genome == donor.genome and gen1[3].parents == ()
    assert gen1[4].parents == (donor.id,) and gen1[4].fitness == donor.fitness
    assert len(gen1) == config.ea.population


def test_migrants_from_another_configuration_version_are_re_evaluated(history):
    config, hist = history
    changed = config.replace(fitness={"size": {"weight": 7.0}})
    island = Island(changed, 1, config_version=2)
    migrant = next(ind for ind in hist[1] if ind.valid)
    gen = island.step(hist[1], 2, migrants=[migrant])
    assert gen[0].config_version == 2
    assert gen[0].fitness == pytest.approx(changed.fitness.evaluate(migrant.criteria))
    assert gen[0].criteria == migrant.criteria


def test_too_many_incoming_is_refused(history):
    config, hist = history
    with pytest.raises(ConfigError, match="do not fit"):
        Island(config, 0).step(hist[0], 1, migrants=hist[0], injected=[hist[0][0]])


def test_identical_genomes_are_evaluated_once(history):
    config, hist = history
    config = config.replace(ea={"unique_retries": 0})   # no offspring varied again: one evaluation each
    island = Island(config, 0)
    genome = list(hist[0][0].genome)
    island.step(hist[0], 1, injected=[genome] * 6)
    assert island.stats.evaluated <= config.ea.population - 6 - config.ea.elites + 1


def test_genomes_evaluated_elsewhere_complete_the_generation_step_builds(history):
    from genr8_dist.evolution import Evaluator

    config, hist = history
    config = config.replace(ea={"unique_retries": 0})   # every evaluation is then one of ``pending``
    donor = hist[2][3]
    kwargs = {"migrants": hist[2][:2], "injected": [list(donor.genome)] * 3}
    alone = Island(config, 1).step(hist[2], 3, **kwargs)

    island = Island(config, 1)
    births = island.breed(3, hist[2], **kwargs)
    pending = island.pending(births)
    # migrants and elites keep their evaluations; a genome born three times is evaluated once
    assert len(pending) == len(set(pending)) <= config.ea.population - 2 - config.ea.elites - 2
    assert donor.genome in pending
    elsewhere = Evaluator(config)
    shared = island.complete(3, births, {genome: elsewhere.evaluate(genome) for genome in pending})
    assert [untimed(i) for i in shared] == [untimed(i) for i in alone]
    unevaluated = sum(1 for b in births if b.evaluation is None)
    assert island.stats.evaluated == len(pending)
    assert island.stats.cache_hits == unevaluated - len(pending) >= 2
    # each evaluation made elsewhere keeps its timing at its first use, as a local one does
    first = {}
    for ind in shared:
        if ind.origin not in ("migrant", "elite"):
            first.setdefault(ind.genome, ind)
    assert all(ind.eval_seconds > 0 for ind in first.values())


def test_invalid_individuals_are_data_not_exceptions():
    # founders not redrawn (a bushy redraw maps whatever the length)
    config = small_config(genome={"length": 3, "max_wraps": 0}, ea={"founder_retries": 0})
    hist = Island(config, 0).run(2)
    invalid = [ind for pop in hist for ind in pop if not ind.valid]
    assert invalid, "three-codon genomes that may not wrap should mostly fail to map"
    assert all(ind.fitness == math.inf and ind.stage and ind.error for ind in invalid)


@pytest.mark.slow
@pytest.mark.stochastic
def test_selection_improves_a_fitness_that_rewards_subdivisions():
    """Best and median fitness of a 30-individual island improve over 10 generations for most seeds."""
    zero = {"weight": 0.0}
    fitness = {"size": zero, "smoothness": zero, "undulation": zero, "symmetry": zero,
               "soft_boundary": zero, "subdivisions": {"target": 0.3, "weight": 1.0}}
    best_better = median_better = 0
    seeds = range(5)
    for seed in seeds:
        config = RunConfig.from_dict({
            "seed": seed, "genome": {"length": 60},
            "ea": {"population": 30, "generations": 10, "elites": 1, "tournament": 5},
            "fitness": fitness, "environment": {"steps": 2},
        })
        hist = Island(config, 0).run()
        first, last = [i.fitness for i in hist[0]], [i.fitness for i in hist[-1]]
        assert min(last) <= min(first)  # elitism: the best never gets worse
        best_better += min(last) < min(first)
        median_better += statistics.median(last) < statistics.median(first)
    # Measured (seeds 0-4): the median improves for all five, the best for four (seed 0's generation 0
    # already held a good one); allow one more miss of the best, which elitism keeps from getting worse.
    assert best_better >= 3 and median_better >= 4, (best_better, median_better)


def test_founders_are_redrawn_until_they_are_not_trivial_nor_repeated():
    from genr8_dist.evolution.island import is_trivial

    config = small_config(ea={"population": 30}, environment={"steps": 3})
    alive = Island(config, 0)
    founders = alive.initial()
    bare = Island(config.replace(ea={"founder_retries": 0}), 0).initial()
    assert sum(is_trivial(i) for i in founders) < sum(is_trivial(i) for i in bare)
    assert sum(is_trivial(i) for i in founders) <= alive.stats.unresolved
    digests = [i.phenotype_digest for i in founders if i.valid]
    assert len(set(digests)) == len(digests)
    assert alive.stats.founders_redrawn > 0
    assert [untimed(i) for i in founders] == [untimed(i) for i in Island(config, 0).initial()]


def test_founders_of_a_universe_whose_random_genomes_seldom_subdivide_are_redrawn_bushy():
    """gecco's random genomes subdivide about once in a thousand: the plain half of the redraws
    fails, the bushy half (longer repetitions, no label born) finds live, different founders (all but
    4% of 200 in quick.toml's environment, bench/search.py; about 10% in this one)."""
    import re

    from genr8_dist.evolution.island import is_trivial

    config = small_config(universe="gecco", ea={"population": 5, "elites": 1}, environment={"steps": 3})
    founders = Island(config, 0).initial()
    plain = Island(config.replace(ea={"founder_retries": 1}), 0).initial()   # one plain redraw only
    assert sum(is_trivial(i) for i in plain) == 5
    assert sum(is_trivial(i) for i in founders) <= 2
    assert len({i.phenotype_digest for i in founders}) == 5
    live = [i for i in founders if not is_trivial(i)]
    assert all(set(re.findall(r"Edge(\d+)", i.text)) <= {"0", "1"} for i in live)   # no label born


def test_bushy_redraws_give_way_to_plain_ones_where_plain_draws_do_better(monkeypatch):
    """Past the plain half of the retries a founder is drawn bushy only while bushy trees have given
    live founders at least as often as plain draws in this generation 0 (Laplace's rule)."""
    import genr8_dist.grammar.derivations as derivations

    calls = []

    def failing(universe, rng, **settings):   # one fixed genome: live at most once, then a repeat
        calls.append(1)
        return (0,) * 8

    monkeypatch.setattr(derivations, "bushy_genome", failing)
    # every draw grown (none set aside from its text), so each bushy call is one bushy founder tried
    monkeypatch.setattr(Island, "_screen", lambda self, text: (text is None, text))
    config = small_config(ea={"population": 30, "founder_retries": 2}, environment={"steps": 3})
    island = Island(config, 0)
    island.initial()
    assert 1 <= len(calls) <= 4
    assert island.founders.tally["bushy"][0] == len(calls) and island.founders.tally["bushy"][1] <= 1


def test_ramped_founders_are_seeded_and_alive():
    config = small_config(ea={"population": 16, "init": "ramped"})
    a, b = Island(config, 0).initial(), Island(config, 0).initial()
    assert [untimed(i) for i in a] == [untimed(i) for i in b]
    assert {i.origin for i in a} == {"random"}


def test_offspring_repeating_a_parent_or_a_sibling_are_varied_again_within_the_bound():
    config = small_config(ea={"population": 16, "mutation_rate": 0.0, "crossover_rate": 0.5})
    copies = config.replace(ea={"unique_retries": 0})
    hist = Island(config, 0).run(2)

    def repeats(gen, previous):
        parents = {p.id: p for p in previous}
        seen, count = set(), 0
        for ind in gen:
            if ind.origin in ("crossover", "mutation", "crossover+mutation") and ind.valid and (
                    ind.phenotype_digest in seen
                    or any(parents[p].phenotype_digest == ind.phenotype_digest for p in ind.parents)):
                count += 1
            if ind.valid:
                seen.add(ind.phenotype_digest)
        return count

    unique = Island(config, 0)
    gen = unique.step(hist[2], 3)
    wasteful = Island(copies, 0)
    gen_copies = wasteful.step(hist[2], 3)
    assert repeats(gen, hist[2]) <= unique.stats.unresolved
    assert repeats(gen_copies, hist[2]) > repeats(gen, hist[2])
    assert unique.stats.revaried_phenotype + unique.stats.revaried_text > 0
    assert wasteful.stats.revaried_phenotype == wasteful.stats.revaried_text == 0
    # bounded: never more re-variations than retries per offspring
    offspring = sum(i.origin != "elite" for i in gen)
    assert unique.stats.revaried_phenotype <= offspring * config.ea.unique_retries
    assert unique.stats.revaried_text <= offspring * config.ea.unique_retries
    one = config.replace(ea={"unique_retries": 1})
    bounded = Island(one, 0)
    bounded.step(hist[2], 3)
    assert bounded.stats.revaried_phenotype <= offspring and bounded.stats.revaried_text <= offspring


def test_invalid_offspring_are_varied_again_within_the_bound():
    # a small edge cap and no wraps: many offspring are capped or map to nothing
    # (founders redrawn once, plainly: their bushy redraws would only cost growth here)
    config = small_config(ea={"population": 16, "founder_retries": 1}, genome={"length": 40, "max_wraps": 0},
                          environment={"steps": 3, "max_edges": 60})
    hist = Island(config, 0).run(1)
    offspring = ("crossover", "mutation", "crossover+mutation")

    def invalid(gen):
        return sum(1 for i in gen if i.origin in offspring and not i.valid)

    failing = Island(config.replace(ea={"unique_retries": 0}), 0)
    plain = failing.step(hist[1], 2)
    revarying = Island(config, 0)
    gen = revarying.step(hist[1], 2)
    assert invalid(plain) >= 3
    assert invalid(gen) < invalid(plain)
    assert invalid(gen) <= revarying.stats.unresolved
    assert revarying.stats.revaried_invalid > 0 and failing.stats.revaried_invalid == 0
    born = sum(i.origin in (*offspring, "random") for i in gen)
    # at most unique_retries before evaluation (no rewrite system) and as many after (capped)
    assert revarying.stats.revaried_invalid <= born * 2 * config.ea.unique_retries
    # deterministic: the same generation again, row for row
    again = Island(config, 0).step(hist[1], 2)
    assert [untimed(i) for i in again] == [untimed(i) for i in gen]


def test_offspring_still_wasted_after_the_retries_are_replaced_by_newcomers_within_the_bound():
    # one re-variation only: many offspring stay invalid or repeat; newcomers replace them
    config = small_config(ea={"population": 16, "unique_retries": 1, "unique_redraws": 0},
                          genome={"length": 40, "max_wraps": 0}, environment={"steps": 3, "max_edges": 60})
    hist = Island(config, 0).run(1)
    offspring = ("crossover", "mutation", "crossover+mutation")

    def wasted(gen):
        seen, count = set(), 0
        for ind in gen:   # invalid, trivial (one region) or a repeat: what an island varies again
            if ind.origin in (*offspring, "random") and (not ind.valid or ind.phenotype_digest in seen
                                                         or ind.sizes.get("regions", 0) <= 1):
                count += 1
            if ind.valid:
                seen.add(ind.phenotype_digest)
        return count

    without = Island(config, 0)
    plain = without.step(hist[1], 2)
    redrawing = Island(config.replace(ea={"unique_redraws": 3}), 0)
    gen = redrawing.step(hist[1], 2)
    assert without.stats.redrawn == 0 and wasted(plain) >= 2
    assert 0 < redrawing.stats.redrawn <= 3 * 16
    assert wasted(gen) < wasted(plain) and wasted(gen) <= redrawing.stats.unresolved
    newcomers = [ind for ind in gen if ind.origin == "random"]
    assert newcomers and all(ind.parents == () for ind in newcomers)
    again = Island(config.replace(ea={"unique_redraws": 3}), 0).step(hist[1], 2)
    assert [untimed(i) for i in again] == [untimed(i) for i in gen]


def test_no_individual_is_mated_with_itself_when_others_differ():
    config = small_config(ea={"population": 16, "crossover_rate": 1.0, "tournament": 1})
    hist = Island(config, 0).run(1)
    gen = Island(config, 0).step(hist[1], 2)
    texts = {i.id: i.text for i in hist[1]}
    crossed = [i for i in gen if i.origin.startswith("crossover")]
    assert crossed
    for child in crossed:
        a, b = child.parents
        assert a != b and (texts[a] != texts[b] or texts[a] is None)


def test_map_elites_carries_the_best_of_every_cell_into_the_next_generation():
    from genr8_dist.evolution.archive import Grid

    config = small_config(ea={"population": 16},
                          search={"mode": "map-elites", "descriptors": ["size_regions"], "ranges": [[1, 17]],
                                  "bins": [8], "offspring": 0.5})
    hist = Island(config, 0).run(3)
    grid = Grid.from_settings(config.search)
    for previous, gen in itertools.pairwise(hist):
        archive = grid.archive(previous)
        kept = {ind.parents[0] for ind in gen if ind.origin == "elite"}
        best = sorted(archive.values(), key=lambda ind: (ind.fitness, ind.index))
        assert kept == {ind.id for ind in best}
        # a cell's elite is never worse than before: the archive only improves
        after = grid.archive(gen)
        kept_cells = {grid.cell(i) for i in best}
        assert all(after[c].fitness <= archive[c].fitness for c in kept_cells)
        assert sum(ind.origin != "elite" for ind in gen) >= 8


def test_map_elites_archive_holds_every_cell_found_beyond_the_population():
    """The archive's capacity is the grid, not the population: a population of 6 over a grid of 24
    cells keeps every cell ever held, and still breeds ``search.offspring`` of the population anew."""
    from genr8_dist.evolution.archive import Grid

    config = small_config(ea={"population": 6},
                          search={"mode": "map-elites", "descriptors": ["size_regions", "size_vertices"],
                                  "ranges": [[1, 13], [3, 27]], "bins": [4, 6], "offspring": 0.5})
    hist = Island(config, 0).run(4)
    grid = Grid.from_settings(config.search)
    found: set[int] = set()
    for previous, gen in itertools.pairwise(hist):
        found |= set(grid.archive(previous))
        held = grid.archive(previous)
        kept = [ind for ind in gen if ind.origin == "elite"]
        assert {ind.parents[0] for ind in kept} == {ind.id for ind in held.values()}
        assert len(gen) == max(6, len(held) + 3) and len(gen) - len(kept) >= 3
        assert set(grid.archive(gen)) >= found   # no cell found is ever lost
    assert len(grid.archive(hist[-1])) > 6 and len(hist[-1]) > 6


def test_pareto_mode_keeps_the_first_front_and_ranks_it_as_the_reference_does():
    from genr8_dist.evolution.island import pareto_objectives
    from genr8_dist.evolution.pareto import non_dominated_ranks, objectives_of

    config = small_config(ea={"population": 16}, search={"mode": "pareto"},
                          fitness={"size": {"target": 6.0}, "subdivisions": {"target": 0.5}})
    hist = Island(config, 0).run(2)
    names = pareto_objectives(config)
    assert set(names) == {"size", "smoothness", "undulation", "subdivisions", "symmetry", "soft_boundary"}
    previous, gen = hist[1], hist[2]
    ranks = non_dominated_ranks(objectives_of([p.criteria for p in previous], [p.valid for p in previous],
                                              config.fitness, names))
    front = {p.id for p, r in zip(previous, ranks, strict=True) if r == 0 and p.valid}
    kept = {ind.parents[0] for ind in gen if ind.origin == "elite"}
    assert kept <= front and len(kept) == min(len(front), 8)
    # the objectives are the weighted criteria: the fitness is their sum, its best is on the front
    # and kept first
    best = min(previous, key=lambda p: (p.fitness, p.index))
    assert best.id in front and gen[0].origin == "elite" and gen[0].parents == (best.id,)


def test_map_elites_draws_first_parents_by_tournament_and_mates_uniformly_from_the_archive():
    from genr8_dist.evolution.archive import Grid

    search = {"mode": "map-elites", "descriptors": ["n_regions"], "ranges": [[1, 17]], "bins": [8],
              "offspring": 0.5}
    hist = Island(small_config(ea={"population": 16}, search=search), 0).run(1)
    grid = Grid.from_settings(small_config(search=search).search)
    elites = grid.elites(hist[1], 8)
    archive = {ind.id for ind in elites}
    share = {}
    for size in (1, 16):
        config = small_config(ea={"population": 16, "tournament": size, "crossover_rate": 1.0},
                              search=search)
        gen = Island(config, 0).step(hist[1], 2)
        born = [ind for ind in gen if ind.origin != "elite"]
        assert all(set(ind.parents) <= archive for ind in born)
        share[size] = sum(elites[0].id in ind.parents for ind in born) / len(born)
        assert len({p for ind in born for p in ind.parents}) > 2   # mates from other cells too
    # 16 contestants of 8 cells: the best cell wins nearly every first draw; uniformly, about 1 in 4
    assert share[16] >= 0.75 > share[1]


def test_after_a_fitness_only_edit_the_pool_is_judged_from_its_stored_criteria(history):
    """Generation g-1 made under version 1 competes in generation g under version 2 (other targets
    and weights): judged again from its rows, not grown again, with the rows evaluation would give."""
    from genr8_dist.evolution import evaluate as ev

    config, hist = history
    changed = config.replace(fitness={"size": {"weight": 7.0, "target": 3.0}})
    ev._DEVELOPED.clear()
    plain = Island(changed, 0, config_version=2)
    regrown = plain.step(hist[2], 3)
    ev._DEVELOPED.clear()
    island = Island(changed, 0, config_version=2, config_of={1: config, 2: changed}.get)
    rescored = island.step(hist[2], 3)
    assert [i.untimed() for i in rescored] == [i.untimed() for i in regrown]
    pool_texts = {p.text for p in hist[2] if p.text and p.stage != "map"}
    assert island.evaluator.growths < plain.evaluator.growths
    assert plain.evaluator.growths - island.evaluator.growths >= len(pool_texts) - len(
        pool_texts & {i.text for i in rescored if i.origin != "elite"})


def test_only_the_individuals_kept_are_measured_and_the_rows_are_those_measuring_all_gives(monkeypatch):
    # founders redrawn and offspring varied again are decided by what growth found: the ones
    # discarded are never measured, and the generations are those of measuring every one
    from genr8_dist.evolution import evaluate as ev
    from genr8_dist.evolution.evaluate import Evaluator

    config = small_config(ea={"population": 12}, environment={"steps": 2})
    measured: list[str] = []
    real = ev._measure
    monkeypatch.setattr(ev, "_measure", lambda *a: measured.append(a[0].text) or real(*a))
    ev._DEVELOPED.clear()   # nothing grown by earlier tests: every kept text is measured here
    lazy = Island(config, 0)
    hist = lazy.run(1)
    kept = {i.text for gen in hist for i in gen if i.stage not in ("map", "parse")}
    assert len(measured) == len(set(measured)) and set(measured) == kept
    ev._DEVELOPED.clear()
    monkeypatch.setattr(Evaluator, "preview", Evaluator.evaluate)
    eager = Island(config, 0)
    assert [[untimed(i) for i in gen] for gen in eager.run(1)] == [[untimed(i) for i in gen] for gen in hist]
    assert eager.stats == lazy.stats
    assert lazy.evaluator.growths == eager.evaluator.growths > len(kept)

def _texts_grown(monkeypatch) -> list[str]:
    """The texts every Evaluator grows from now on, in order (a spy on ``Evaluator._grown``)."""
    from genr8_dist.evolution.evaluate import Evaluator

    grown: list[str] = []
    develop = Evaluator._grown

    def spy(self, text, defer=False):
        grown.append(text)
        return develop(self, text, defer)

    monkeypatch.setattr(Evaluator, "_grown", spy)
    return grown


def test_trivial_offspring_are_varied_again_at_little_cost_and_screened_texts_never_grown(monkeypatch):
    """No evolved generation keeps a trivial surface (one region) while the evaluations per stored
    individual stay near one: a text that shows it is trivial is set aside before growth, and a
    child that grows trivial is varied again from its parent (quick.toml's settings, one island)."""
    from genr8_dist.config import load_config
    from genr8_dist.hemls.splitting import screen

    quick = Path(__file__).resolve().parents[2] / "examples" / "quick.toml"
    config = load_config(quick).replace(
        islands={"count": 1, "migrants": 0}, ea={"generations": 6})
    grown = _texts_grown(monkeypatch)
    island = Island(config, 0)
    hist = island.run()
    stored = sum(len(gen) for gen in hist)
    later = [ind for gen in hist[1:] for ind in gen]
    assert island.evaluator.evaluations / stored <= 1.3
    assert sum(not ind.valid or ind.sizes["regions"] <= 1 for ind in later) <= 0.1 * len(later)
    assert grown and not any(screen(text)[0] for text in grown)   # no text called trivial was grown


def test_an_offspring_trivial_again_after_its_re_variation_is_kept_and_saves_growths(monkeypatch):
    """A child that grows trivial is varied again from its first parent ``_TRIVIAL_RETRIES`` times;
    trivial again, it is kept (``IslandStats.kept_trivial`` counts it), so the growths a parent with
    a mostly trivial neighbourhood costs stay bounded (quick.toml's settings in its former shell
    environment, one island)."""
    from genr8_dist.config import load_config
    from genr8_dist.environment import load_environment
    from genr8_dist.evolution import island as island_module

    examples = Path(__file__).resolve().parents[2] / "examples"
    # screen 1: under 2 the replay catches before growth the children this test needs to grow trivial
    config = load_config(examples / "quick.toml").replace(
        islands={"count": 1, "migrants": 0}, ea={"generations": 8, "screen": 1},
        environment=load_environment(examples / "environments" / "shell.toml"))

    def run() -> tuple[list[Individual], int, int]:
        island = Island(config, 0)
        kept: list[int] = []
        island.hooks.append(lambda population: kept.append(island.stats.kept_trivial))
        hist = island.run()
        later = [ind for gen in hist[1:] for ind in gen if ind.origin in _OFFSPRING_ORIGINS]
        return later, sum(kept), island.evaluator.evaluations

    later, kept, evaluations = run()
    trivial = [ind for ind in later if ind.valid and ind.sizes["regions"] <= 1]
    assert kept > 0 and len(trivial) == kept < 0.1 * len(later)
    monkeypatch.setattr(island_module, "_TRIVIAL_RETRIES", 1000)
    later, kept, unbounded = run()
    assert kept == 0 and not any(ind.valid and ind.sizes["regions"] <= 1 for ind in later)
    assert unbounded > evaluations


_OFFSPRING_ORIGINS = ("crossover", "mutation", "crossover+mutation")


def _rows_digest(config: RunConfig) -> str:
    import hashlib

    hist = Island(config, 0).run()
    rows = [(i.genome, i.text, repr(i.fitness), i.origin, i.parents) for gen in hist for i in gen]
    return hashlib.sha256(repr(rows).encode()).hexdigest()


@pytest.mark.parametrize("mode, before, replayed", [
    ("weighted", "87da54dbc284f87e4607072ad4aac0ce790d2122022443fb9d88862801103018",
     "4b4652d20511d2e46763e3f572af609b75c1eb510964fbc2b368e1b224f7be96"),
    ("pareto", "5d018a831bbd7638136350bc2eea3a64645170f0240eb9513b3ea9a77869414c",
     "815a8ec0e8a4309a38ce8fcddd208bb5d35cee6166b2c0e6ab40ecf589a7c48d"),
])
def test_screen_1_breeds_as_round_7_and_screen_2_as_round_12(mode, before, replayed):
    """``ea.screen = 1`` (what a run created before the screen was recorded reads) breeds the rows
    it bred before the replay existed, bit for bit (these digests are round 7's); ``ea.screen = 2``
    breeds other rows, those it bred before the bound on work existed (round 12's), on every run."""
    def config(screen: int) -> RunConfig:
        return RunConfig.from_dict({"universe": "tiles", "seed": 3, "search": {"mode": mode},
                                    "ea": {"population": 10, "generations": 4, "screen": screen},
                                    "environment": {"steps": 3}})

    assert _rows_digest(config(1)) == before
    assert _rows_digest(config(2)) == replayed != before


def test_screen_3_grows_no_text_sure_to_be_capped_and_spends_fewer_growths(monkeypatch):
    """Under ``ea.screen = 3`` no text whose least work (``hemls.budget.least_work``) passes the
    environment's ``max_work`` is grown, where screen 2 grows such texts and sees them capped; the
    growths spent fall (subdivide.toml's settings, 8 generations)."""
    from genr8_dist.config import load_config
    from genr8_dist.hemls import parse
    from genr8_dist.hemls.budget import least_work

    subdivide = Path(__file__).resolve().parents[2] / "examples" / "subdivide.toml"
    grown = _texts_grown(monkeypatch)
    spent, past = {}, {}
    for version in (2, 3):
        config = load_config(subdivide).replace(ea={"generations": 8, "screen": version})
        env = config.environment
        grown.clear()
        island = Island(config, 0)
        stored = sum(len(gen) for gen in island.run())
        spent[version] = island.evaluator.evaluations / stored
        past[version] = sum(least_work(parse(text), env.steps) > env.max_work for text in set(grown))
    assert past[2] > 0 and past[3] == 0
    assert spent[3] < spent[2]


def test_screen_2_grows_no_text_the_replay_shows_trivial_and_wastes_less(monkeypatch):
    """Under ``ea.screen = 2`` no text whose replay shows no join can happen is grown; in
    ``weighted`` mode the evaluations per stored individual fall, in ``pareto`` mode the trivial
    share of the evolved generations (tiles, seed 2)."""
    from genr8_dist.hemls.splitting import screen

    grown = _texts_grown(monkeypatch)
    spent, trivial = {}, {}
    for mode, version in itertools.product(("weighted", "pareto"), (1, 2)):
        config = RunConfig.from_dict({"universe": "tiles", "seed": 2, "search": {"mode": mode},
                                      "ea": {"population": 16, "generations": 6, "screen": version},
                                      "environment": {"steps": 3}})
        grown.clear()
        island = Island(config, 0)
        hist = island.run()
        spent[mode, version] = island.evaluator.evaluations / sum(len(gen) for gen in hist)
        later = [ind for gen in hist[1:] for ind in gen]
        trivial[mode, version] = sum(not i.valid or i.sizes["regions"] <= 1 for i in later) / len(later)
        if version == 2:
            assert grown and not any(screen(text, False, 3)[0] for text in grown)
    assert spent["weighted", 2] < spent["weighted", 1]
    assert trivial["pareto", 2] < min(trivial["pareto", 1], 0.1)


def test_an_offspring_known_to_copy_its_parent_is_not_grown_and_the_rows_stay_the_same(monkeypatch):
    """An offspring whose text differs from a valid parent's only where the parent's growth read
    nothing (``hemls.splitting.same_growth``) is varied again as a repeated phenotype is, without
    being grown: every row is the one the island builds when it grows such copies, and fewer
    genomes are evaluated and fewer texts grown (subdivide.toml's settings, 10 generations)."""
    from collections import OrderedDict

    from genr8_dist.config import load_config
    from genr8_dist.evolution import evaluate

    subdivide = Path(__file__).resolve().parents[2] / "examples" / "subdivide.toml"
    config = load_config(subdivide).replace(ea={"generations": 10})
    monkeypatch.setattr(evaluate, "_DEVELOPED", OrderedDict())   # no growth shared between the runs
    copying = Island(config, 0)
    rows = [(i.genome, i.text, repr(i.fitness), i.phenotype_digest, i.origin, i.parents)
            for gen in copying.run() for i in gen]
    copied = copying.evaluator.evaluations, copying.evaluator.growths
    monkeypatch.setattr(Island, "_copy", lambda self, birth, genome: None)
    monkeypatch.setattr(evaluate, "_DEVELOPED", OrderedDict())
    growing = Island(config, 0)
    assert rows == [(i.genome, i.text, repr(i.fitness), i.phenotype_digest, i.origin, i.parents)
                    for gen in growing.run() for i in gen]
    assert copied[0] < growing.evaluator.evaluations and copied[1] < growing.evaluator.growths


def test_repeat_growths_bounds_the_developments_an_offspring_spends_on_repeats(monkeypatch):
    """Under ``ea.repeat_growths = 1`` an offspring whose development repeats a parent's or an
    earlier member's table is kept, not varied again: no offspring costs more than one development
    unless it grew trivial (varied again from its parent), while tries known to copy before
    development are still varied again for free. Without the bound the same run spends more."""
    from collections import OrderedDict

    from genr8_dist.config import load_config
    from genr8_dist.evolution import evaluate

    tables = Path(__file__).resolve().parents[2] / "examples" / "tables.toml"
    config = load_config(tables).replace(
        islands={"count": 1, "migrants": 0},
        ea={"generations": 20, "repeat_growths": 1, "unique_redraws": 0})

    def run(config: RunConfig) -> tuple[Island, list[list[Individual]], list[IslandStats]]:
        monkeypatch.setattr(evaluate, "_DEVELOPED", OrderedDict())   # no growth shared between runs
        island = Island(config, 0)
        stats: list[IslandStats] = []
        island.hooks.append(lambda population: stats.append(dataclasses.replace(island.stats)))
        return island, island.run(), stats

    _, hist, stats = run(config)
    for gen, counted in zip(hist[1:], stats[1:], strict=True):
        bred = sum(ind.origin in _OFFSPRING_ORIGINS for ind in gen)
        assert counted.evaluated <= bred + counted.revaried_trivial
    assert sum(s.kept_repeat for s in stats) > 0 and sum(s.copied for s in stats) > 0
    _, _, unbounded = run(config.replace(ea={"repeat_growths": 0}))
    assert sum(s.evaluated for s in stats[1:]) < 0.7 * sum(s.evaluated for s in unbounded[1:])
