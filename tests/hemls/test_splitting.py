"""The static check on a rewrite system's text: a system it calls trivial grows one region, and two
texts with one effective text grow the same surface; the replay of a growth's topology
(``can_join``): a system it says can never join two branches grows one region; texts with one
growth key, or one copy key under a growth's reads, grow one surface (properties over random
genomes)."""

from __future__ import annotations

import dataclasses

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.evolution.evaluate import Evaluator
from genr8_dist.evolution.operators import random_genome
from genr8_dist.hemls import load_system, parse
from genr8_dist.hemls.splitting import can_join, can_split, copy_key, same_growth, screen
from genr8_dist.rng import stream


def test_the_predefined_tiles_split_and_the_koch_curves_do_not():
    assert can_split(load_system("four_sided_tiles"))
    assert can_split(load_system("three_sided_tiles"))
    assert not can_split(load_system("koch"))


def test_a_branch_only_a_rule_that_cannot_fire_draws_is_no_split():
    text = ("Edge0 + Edge0 + Edge0 + Edge0\nEdge0 -> Edge0 Edge0\n"
            "Edge1 -> Edge1 [ [ + Edge1 ] - Edge1 ] Edge1\n")
    assert not can_split(parse(text))
    assert can_split(parse(text), label_noise=True)   # noise may put Edge1 on the surface
    trivial, effective = screen(text)
    assert trivial and "Edge1 ->" not in effective
    reached = text.replace("Edge0 -> Edge0 Edge0", "Edge0 -> Edge0 Edge1")
    assert not screen(reached)[0]


def test_a_rule_whose_context_never_occurs_cannot_fire():
    text = "Edge0 + Edge0 + Edge0\nEdge2 < Edge0 -> Edge0 [ [ + Edge0 ] - Edge0 ] Edge0\n"
    trivial, effective = screen(text)
    assert trivial and "->" not in effective


@pytest.mark.parametrize("universe", ["default", "tiles", "symmetric"])
def test_screened_texts_grow_as_the_check_says(universe):
    """Over random genomes: every text called trivial grows at most one region (or fails), and the
    effective text grows the surface the whole text grows, bit for bit."""
    config = RunConfig.from_dict({"universe": universe, "genome": {"length": 40},
                                  "environment": {"steps": 3, "gravity": [0.0, 0.0, -0.5]}})
    evaluator = Evaluator(config)
    rng = stream(3, "test", "splitting", universe)
    called_trivial = reduced = 0
    for _ in range(60):
        evaluation = evaluator.evaluate(random_genome(rng, 40, 255))
        if evaluation.text is None:
            continue
        trivial, effective = screen(evaluation.text)
        if trivial:
            called_trivial += 1
            assert not evaluation.valid or evaluation.sizes["regions"] <= 1, evaluation.text
        if effective != evaluation.text:
            reduced += 1
            again = evaluator.evaluate_text(effective)
            assert (again.valid, again.phenotype_digest) == (evaluation.valid, evaluation.phenotype_digest)
    assert called_trivial > 0 and reduced > 0


def test_branches_drawn_from_one_vertex_a_step_never_join():
    """A rule that fires once draws its branches from one vertex: nothing to join (the first check
    lets it through: it draws a branch), and its growth stays one region, in any environment."""
    text = "Edge0 + Edge1 + Edge1 + Edge1\nEdge0 -> Edge1 [ [ + Edge2 ] - Edge2 ] Edge1\n"
    assert can_split(parse(text)) and not can_join(parse(text), 5)
    assert screen(text, False, 5)[0] and not screen(text)[0]
    config = RunConfig.from_dict({"universe": "default", "environment": {"steps": 5}})
    assert Evaluator(config).evaluate_text(text).sizes["regions"] == 1
    two = text.replace("Edge0 + Edge1", "Edge0 + Edge0")   # two edges draw: two vertices
    assert can_join(parse(two), 5) and not screen(two, False, 5)[0]


def test_branches_into_the_outside_or_along_the_line_never_join():
    """Branches that only point out of the seed polygon never join: the replay follows which side
    of each edge the polygon lies on (a reversed segment turns it over)."""
    inward = "Edge0 + Edge0 + Edge0 + Edge0\nEdge0 -> Edge1 [ + Edge2 ] Edge1\n"
    outward = inward.replace("[ + Edge2 ]", "[ - Edge2 ]")
    assert can_join(parse(inward), 3) and not can_join(parse(outward), 3)
    flipped = outward.replace("-> Edge1 [", "-> ~ Edge1 [")   # the first segment reversed
    config = RunConfig.from_dict({"universe": "default", "environment": {"steps": 3}})
    evaluator = Evaluator(config)
    assert evaluator.evaluate_text(outward).sizes["regions"] == 1
    # whatever the replay says of the reversed one, a system it calls trivial grows one region
    if not can_join(parse(flipped), 3):
        assert evaluator.evaluate_text(flipped).sizes["regions"] <= 1


def test_a_context_that_holds_at_one_edge_keeps_one_branch_vertex_a_step():
    """Contexts are replayed as growth reads them: a rule whose left context holds at one edge of
    the seed fires there alone."""
    text = "Edge1 + Edge0 + Edge0 + Edge0\nEdge1 < Edge0 -> Edge0 [ [ + Edge2 ] - Edge2 ] Edge3\n"
    free = text.replace("Edge1 < Edge0", "Edge0")
    assert not can_join(parse(text), 1) and can_join(parse(free), 1)


@pytest.mark.parametrize("universe", ["default", "tiles", "gecco", "symmetric", "reversible"])
def test_texts_the_replay_calls_trivial_grow_one_region(universe):
    """Over random genomes: every text ``can_join`` calls unable to join grows at most one region
    (or fails), in an environment that bends and stretches the surface; and it catches texts the
    first check lets through."""
    config = RunConfig.from_dict({"universe": universe, "genome": {"length": 60},
                                  "environment": {"steps": 3, "gravity": [0.0, 0.0, -0.5],
                                                  "scale": [1.3, 1.2, 1.0]}})
    evaluator = Evaluator(config)
    rng = stream(5, "test", "replay", universe)
    caught = 0
    for _ in range(150):
        genome = random_genome(rng, 60, 255)
        evaluation = evaluator.preview(genome)
        text = evaluation.text
        if text is None or screen(text)[0] or (not evaluation.valid and evaluation.stage == "parse"):
            continue
        if not can_join(parse(text), 3):
            caught += 1
            assert not evaluation.valid or evaluation.sizes["regions"] <= 1, text
    if universe in ("default", "tiles"):   # their rules seldom fire at more than one edge a step
        assert caught > 0


def _variants(text: str) -> list[str]:
    """Texts that differ from ``text`` in one place: Sync switched, BranchAngle changed, or one
    rule's successors replaced by the next rule's."""
    system = parse(text)
    out = [dataclasses.replace(system, sync=not system.sync).to_text(),
           dataclasses.replace(system, branch_angle=75.0 if system.branch_angle != 75.0 else 15.0).to_text()]
    rules = system.rules
    for i, rule in enumerate(rules):
        other = rules[(i + 1) % len(rules)]
        if other.successors != rule.successors:
            changed = (*rules[:i], dataclasses.replace(rule, successors=other.successors), *rules[i + 1:])
            out.append(dataclasses.replace(system, rules=changed).to_text())
    return out


@pytest.mark.parametrize("universe", ["default", "tiles", "symmetric"])
def test_texts_with_one_growth_key_grow_one_surface(universe):
    """Over random genomes and texts one change away from them: texts with one ``growth_key``
    (``same_growth`` without a growth's reads) grow the same surface bit for bit, in an environment
    that bends and stretches it; and the key tells apart texts that grow differently."""
    config = RunConfig.from_dict({"universe": universe, "genome": {"length": 60},
                                  "environment": {"steps": 3, "gravity": [0.0, 0.0, -0.5],
                                                  "scale": [1.3, 1.2, 1.0]}})
    evaluator = Evaluator(config)
    rng = stream(7, "test", "growth-key", universe)
    same = apart = 0
    for _ in range(40):
        evaluation = evaluator.evaluate(random_genome(rng, 60, 255))
        if evaluation.text is None or not evaluation.valid:
            continue
        for variant in _variants(evaluation.text):
            grown = evaluator.evaluate_text(variant)
            if same_growth(variant, evaluation.text):
                same += 1
                assert grown.phenotype_digest == evaluation.phenotype_digest, variant
            elif grown.phenotype_digest != evaluation.phenotype_digest:
                apart += 1
    assert same > 0 and apart > 0


@pytest.mark.parametrize("universe", ["default", "tiles"])
def test_a_text_that_differs_where_growth_did_not_read_grows_the_same_surface(universe):
    """Over random grown texts and texts one change away from them: a text whose ``copy_key`` under
    the growth's reads (which rules fired) equals the grown text's grows the same surface bit for
    bit; the key tells apart texts that grow differently; and it catches copies that the static key
    (``growth_key``) cannot, a changed successor of a rule that never fired among them."""
    config = RunConfig.from_dict({"universe": universe, "genome": {"length": 60},
                                  "environment": {"steps": 3, "gravity": [0.0, 0.0, -0.5]}})
    evaluator = Evaluator(config)
    rng = stream(11, "test", "copy-key", universe)
    copies = beyond = apart = 0
    for _ in range(60):
        evaluation = evaluator.evaluate(random_genome(rng, 60, 255))
        text = evaluation.text
        if text is None or not evaluation.valid:
            continue
        reads = evaluator.reads(text)
        assert reads is not None and len(reads) == len(parse(text).rules)
        own = copy_key(text, reads)
        for variant in _variants(text):
            grown = evaluator.evaluate_text(variant)
            if copy_key(variant, reads) == own:
                copies += 1
                assert grown.phenotype_digest == evaluation.phenotype_digest, variant
                beyond += not same_growth(variant, text)
            elif grown.phenotype_digest != evaluation.phenotype_digest:
                apart += 1
    assert copies > 0 and beyond > 0 and apart > 0


def test_sync_and_the_join_cone_count_only_where_growth_reads_them():
    """``Sync`` changes nothing where one group of rules, the last that can fire, draws every branch;
    the join cone (``BranchAngle``) nothing where no rule draws a branch; ``+ -`` nothing."""
    last = "Edge0 + Edge0 + Edge1\nEdge0 -> Edge0 Edge1\nEdge1 -> Edge1 [ [ + Edge1 ] - Edge1 ] Edge1\n"
    first = "Edge0 + Edge0 + Edge1\nEdge1 -> Edge1 [ [ + Edge1 ] - Edge1 ] Edge1\nEdge0 -> Edge0 Edge1\n"

    assert same_growth(last, last + "Sync\n")
    assert not same_growth(first, first + "Sync\n")
    assert not same_growth(last, last + "BranchAngle 75\n")
    plain = "Edge0 + Edge0 + Edge0\nEdge0 -> Edge0 Edge0\n"
    assert same_growth(plain, plain + "BranchAngle 75\nSync\n")
    assert same_growth(plain, plain.replace("-> Edge0", "-> + - Edge0"))
