"""The static check on a rewrite system's text: a system it calls trivial grows one region, and two
texts with one effective text grow the same surface (a property over random genomes)."""

from __future__ import annotations

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.evolution.evaluate import Evaluator
from genr8_dist.evolution.operators import random_genome
from genr8_dist.hemls import load_system, parse
from genr8_dist.hemls.splitting import can_split, screen
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
