"""Evaluating one genome: map -> parse -> grow -> score, failures as data, caches that change nothing."""

from __future__ import annotations

import math

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.errors import GenomeError
from genr8_dist.evolution import Evaluator, evaluate_genome, evaluate_text
from genr8_dist.evolution.operators import random_genome
from genr8_dist.fitness import CRITERIA
from genr8_dist.rng import stream

SQUARE = "Edge0 + Edge1 + Edge0 + Edge1\nEdge0 -> Edge0 [ [ + Edge1 ] - Edge1 ] Edge0\n" \
         "Edge1 -> Edge1 [ [ + Edge0 ] - Edge0 ] Edge1\nAngle 90\n"


@pytest.fixture(scope="module")
def config():
    return RunConfig.from_dict({"environment": {"steps": 2}})


def genomes(n, seed=0, length=60):
    rng = stream(seed, "test")
    return [random_genome(rng, length, 255) for _ in range(n)]


def untimed(e):
    return e.untimed()


def test_a_valid_genome_has_every_criterion_and_its_fitness(config):
    results = [evaluate_genome(g, config) for g in genomes(20)]
    valid = [r for r in results if r.valid]
    assert valid, "some random genomes of the default universe must grow"
    for r in valid:
        assert list(r.criteria) == list(CRITERIA)
        assert r.fitness == pytest.approx(config.fitness.evaluate(r.criteria))
        assert r.text and r.codons_used > 0 and r.sizes["vertices"] >= 3 and r.sizes["edges"] >= 3
        assert r.steps_done == 2 and r.capped is None and r.phenotype_digest
        assert r.eval_seconds >= r.map_seconds >= 0 and r.grow_seconds > 0


def test_evaluation_is_deterministic_and_caching_changes_nothing(config):
    batch = genomes(15, seed=1)
    fresh = [evaluate_genome(g, config).untimed() for g in batch]
    evaluator = Evaluator(config)
    cached = [evaluator.evaluate(g).untimed() for g in batch + batch]
    assert cached == fresh + fresh
    assert evaluator.evaluations == len(set(batch)) and evaluator.cache_hits == len(batch)


def test_a_screened_genome_is_mapped_once_and_evaluates_as_a_fresh_one(config, monkeypatch):
    """An island maps a child to screen it, then evaluates it: one mapping, the same evaluation and
    screen as an Evaluator that never screened it."""
    from genr8_dist.grammar.universe import Universe

    batch = genomes(12, seed=2)
    fresh = [evaluate_genome(g, config).untimed() for g in batch]
    evaluator = Evaluator(config)
    calls = []
    mapping = Universe.map
    monkeypatch.setattr(Universe, "map", lambda self, *a, **k: calls.append(1) or mapping(self, *a, **k))
    texts = [evaluator.mapped(g).text for g in batch]
    screens = [evaluator.screen(t) for t in texts if t is not None]
    assert [evaluator.evaluate(g).untimed() for g in batch] == fresh
    assert all(t is None or t == e.text for t, e in zip(texts, fresh, strict=True))
    assert len(calls) == len(set(batch))
    assert screens == [Evaluator(config).screen(t) for t in texts if t is not None]


def test_hand_written_square_matches_closed_form(config):
    r = evaluate_text(SQUARE, config)
    assert r.valid, r.error
    n = 2
    assert r.sizes["vertices"] == (2**n + 1) ** 2 and r.sizes["edges"] == 2 * 2**n * (2**n + 1)
    assert r.criteria["subdivisions"] == pytest.approx(r.sizes["vertices"] / r.sizes["edges"])
    assert r.criteria["undulation"] == 0.0 and r.criteria["symmetry"] == 1.0


def test_failures_are_data(config):
    no_wrap = config.replace(genome={"max_wraps": 0})
    failed = evaluate_genome([7], no_wrap)
    assert not failed.valid and failed.stage == "map" and failed.error and failed.fitness == math.inf
    bad = evaluate_text("Edge0 + + Edge1", config)
    assert not bad.valid and bad.stage == "parse" and "1:" in bad.error and bad.fitness == math.inf
    capped = evaluate_text(SQUARE, config.replace(environment={"max_edges": 10}))
    assert not capped.valid and capped.stage == "grow" and capped.capped and capped.fitness == math.inf
    assert capped.criteria == {} and capped.score_seconds == 0.0   # invalid anyway: never measured


@pytest.mark.parametrize("genome", [[], [-1, 2], ["a"]])
def test_a_genome_that_is_not_non_negative_ints_is_refused(config, genome):
    with pytest.raises(GenomeError):
        evaluate_genome(genome, config)


# -- growths shared across configurations of one process; judging again from raw criteria ----------------

def _other_fitness(config):
    """``config`` with other targets and weights: the same development, another fitness."""
    data = config.to_dict()
    data["fitness"] = {"size": {"target": 2.0, "weight": 3.0}, "subdivisions": {"target": 0.9, "weight": 0.5}}
    return RunConfig.from_dict(data)


@pytest.fixture(scope="module")
def tight():
    """Two derivation steps and a small work cap: some genomes grow, some are capped, some fail."""
    return RunConfig.from_dict({"environment": {"steps": 2, "max_work": 300}})


def test_a_fitness_only_change_grows_nothing_again_and_changes_no_result(tight):
    from genr8_dist.evolution import evaluate as ev

    config = tight
    other = _other_fitness(config)
    batch = genomes(25, seed=3)
    ev._DEVELOPED.clear()
    fresh = [Evaluator(other).evaluate(g).untimed() for g in batch]   # each grown for `other` itself
    ev._DEVELOPED.clear()
    first = Evaluator(config)
    for g in batch:
        first.evaluate(g)
    second = Evaluator(other)
    shared = [second.evaluate(g).untimed() for g in batch]
    assert shared == fresh
    assert second.growths == 0 and second.rescored == first.growths > 0
    assert any(e.valid for e in shared) and any(e.capped == "work" for e in shared)


def test_rescore_judges_a_stored_evaluation_as_evaluating_it_again_would(tight):
    import dataclasses

    from genr8_dist.evolution import evaluate as ev
    from genr8_dist.fitness import FitnessSpec

    config = tight
    other = _other_fitness(config)
    assert ev.development_key(other) == ev.development_key(config)
    elsewhere = RunConfig.from_dict({"environment": {"steps": 2}})
    assert ev.development_key(elsewhere) != ev.development_key(config)
    kinds = set()
    for g in genomes(40, seed=4):
        ev._DEVELOPED.clear()
        before = Evaluator(config).evaluate(g)
        ev._DEVELOPED.clear()
        after = Evaluator(other).evaluate(g)
        if before.stage == "map":
            continue
        judged = ev.rescore(before, other)
        assert judged is not None and judged.untimed() == after.untimed()
        kinds.add(before.capped or before.valid)
    assert kinds == {True, "work"}
    fewer = dataclasses.replace(config, fitness=FitnessSpec(names=("size", "symmetry")))
    grown = Evaluator(fewer).evaluate_text(SQUARE)
    assert list(grown.criteria) == ["size", "symmetry"]
    assert ev.rescore(grown, config) is None   # it lacks criteria `config` asks for: grow it again


# -- previews: developed now, measured only when kept -------------------------------------------------

@pytest.mark.parametrize("kept", [16, 0])
def test_a_preview_measured_later_is_what_evaluating_gives(tight, kept):
    from genr8_dist.evolution import evaluate as ev
    from genr8_dist.evolution.evaluate import Preview

    batch = genomes(25, seed=5)
    ev._DEVELOPED.clear()
    plain = Evaluator(tight)
    evaluated = [plain.evaluate(g).untimed() for g in batch]
    ev._DEVELOPED.clear()
    lazy = Evaluator(tight)
    lazy.DEVELOPED_KEPT = kept   # 0: nothing held, a kept preview is developed again
    previews = [lazy.preview(g) for g in batch]
    deferred = [p for p in previews if isinstance(p, Preview)]
    assert deferred and all(not p.criteria and p.fitness == math.inf and p.phenotype_digest for p in deferred)
    assert all(p.valid == (p.capped is None) for p in deferred)
    assert lazy.evaluations == plain.evaluations and lazy.growths == plain.growths
    # failures of mapping or development are finished evaluations: nothing would be measured
    assert {p.stage for p in previews if not isinstance(p, Preview)} <= {"map", "parse", "grow"}
    assert [lazy.measure(g, p).untimed() for g, p in zip(batch, previews, strict=True)] == evaluated
    # the oldest beyond DEVELOPED_KEPT were dropped and developed again
    assert lazy.growths - plain.growths == max(0, len({p.text for p in deferred}) - kept)
    # measured now: a repeat is a cache hit, in both calls
    assert [lazy.preview(g).untimed() for g in batch] == evaluated
    assert [lazy.evaluate(g).untimed() for g in batch] == evaluated


def test_evaluating_a_previewed_genome_measures_it(tight):
    from genr8_dist.evolution import evaluate as ev
    from genr8_dist.evolution.evaluate import Preview

    ev._DEVELOPED.clear()
    lazy = Evaluator(tight)
    g = next(g for g in genomes(40, seed=6)
             if isinstance(p := lazy.preview(g), Preview) and p.capped is None)   # capped: never measured
    full = lazy.evaluate(g)
    assert not isinstance(full, Preview) and full.criteria and lazy.cache_hits == 1
    assert full.untimed() == Evaluator(tight).evaluate(g).untimed()
    assert full.map_seconds == full.grow_seconds == 0.0 and full.score_seconds > 0   # paid now: measuring



def test_a_copy_known_without_development_counts_as_an_evaluation_when_it_is_developed(tight):
    """An island knows some offspring copy a parent without developing them (``Island._copy``: a
    ``Preview`` no evaluator made); one kept after all is developed by ``measure``, and that counts as
    the evaluation it is, so a bench's evaluations per stored individual miss none."""
    from dataclasses import replace

    from genr8_dist.evolution import evaluate as ev
    from genr8_dist.evolution.evaluate import Preview

    ev._DEVELOPED.clear()
    source = Evaluator(tight)
    g, known = next((g, p) for g in genomes(40, seed=6)
                    if isinstance(p := source.preview(g), Preview) and p.capped is None)
    lazy = Evaluator(tight)
    ev._DEVELOPED.clear()
    measured = lazy.measure(g, replace(known))
    assert (lazy.evaluations, lazy.growths) == (1, 1)
    assert measured.untimed() == Evaluator(tight).evaluate(g).untimed()
    assert lazy.measure(g, replace(known)).untimed() == measured.untimed()   # developed now: a cache hit
    assert (lazy.evaluations, lazy.growths) == (1, 1)

# --- an individual nested too deep is an invalid row, not a crash -------------------------------------

NESTING_UNIVERSE = '''\
start: axiom _NL rewrite_rule _NL "Angle" "30" _NL "BranchAngle" "15" _NL
axiom: EDGE "+" EDGE "+" EDGE
rewrite_rule: PRED "->" successor
successor: EDGE nest EDGE
nest: "[" "[" "[" "[" "[" "[" "[" "[" "[" "[" nest "]" "]" "]" "]" "]" "]" "]" "]" "]" "]"
    | "+" EDGE
EDGE: /Edge[0-9]+/
PRED: /Edge[0-9]+/
_NL: "\\n"
%ignore " "
'''


@pytest.mark.parametrize("levels", [500, 5000])
def test_a_text_nested_too_deep_evaluates_to_an_invalid_individual(levels):
    text = ("Edge1 + Edge1 + Edge1\nEdge1 -> Edge1 " + "[ " * levels + "+ Edge1 " + "] " * levels
            + "Edge1\n")
    result = evaluate_text(text, RunConfig.from_dict({"environment": {"steps": 2}}))
    assert not result.valid and result.stage == "parse"
    assert result.error is not None and "2:216: brackets nest deeper than 100 levels" in result.error


def test_a_genome_the_universe_maps_too_deep_is_an_invalid_individual(tmp_path):
    """A universe of ten brackets a level: at max_depth 60 a genome of zeros nests 560 brackets deep."""
    (tmp_path / "nest.lark").write_text(NESTING_UNIVERSE)
    config = RunConfig.from_dict({"universe": str(tmp_path / "nest.lark"), "environment": {"steps": 2},
                                  "genome": {"max_depth": 60, "length": 400}})
    result = evaluate_genome([0] * 400, config)
    assert result.text is not None and result.text.count("[") == 560
    assert not result.valid and "brackets nest deeper than 100 levels" in (result.error or "")
    shallow = evaluate_genome([0] * 400, config.replace(genome={"max_depth": 8}))
    assert shallow.text is not None and shallow.text.count("[") == 40
    assert "nest deeper" not in (shallow.error or "")
