"""The work a growth spends (``Budget``) and the least of it a rewrite system's text shows
(``least_work``): exact on a system that doubles its edges, and a lower bound on every growth of
random genomes of every built-in universe, so a text it puts past ``max_work`` is always capped."""

from __future__ import annotations

from pathlib import Path

import pytest

from genr8_dist.config import RunConfig
from genr8_dist.environment import Environment
from genr8_dist.evolution.operators import random_genome
from genr8_dist.grammar import load_universe
from genr8_dist.hemls import grow, parse
from genr8_dist.hemls.budget import WORK_BATCH, least_work
from genr8_dist.rng import stream

_SQUARE = "Edge0 + Edge0 + Edge0 + Edge0\n"


def test_a_system_that_doubles_its_edges_spends_what_the_bound_says_and_one_batch_a_step():
    """4 edges become 8, 16, 32: each step counts the edges alive at its start and the edges it
    adds (8 + 16 + 32 = 56), and one successor placed on one batch a step (``WORK_BATCH``)."""
    text = _SQUARE + "Edge0 -> Edge0 Edge0\n"
    assert least_work(parse(text), 3) == 56
    assert grow(parse(text), Environment(max_work=0), steps=3).work == 56 + 3 * WORK_BATCH


def test_a_context_may_leave_the_edge_and_a_condition_is_read_on_the_age():
    """A rule with a context may not fire (the bound takes the edge as left alone); a condition is
    decided by the edge's age, which growth sets when it makes the edge: ages 0 and 1 double, age 2
    stays (4 + 4, then 8 + 8, then 16 alive: 40, and two batches)."""
    context = _SQUARE + "Edge1 < Edge0 -> Edge0 Edge0\n"
    assert least_work(parse(context), 3) == 4 * 3          # never sure to fire: 4 edges, 3 steps
    aged = _SQUARE + "Edge0_i -> Edge0_i+1 Edge0_i+1 If i < 2\n"
    assert least_work(parse(aged), 3) == 40
    assert grow(parse(aged), Environment(max_work=0), steps=3).work == 40 + 2 * WORK_BATCH
    untimed = aged.replace("_i+1", "")                     # untimed segments start at age 0
    assert least_work(parse(untimed), 3) == 56


_TIMED = Path(__file__).resolve().parents[2] / "plugins" / "timed"   # ages and conditions


@pytest.mark.parametrize("universe", ["default", "tiles", "gecco", "symmetric", "reversible",
                                      "probabilistic", "timed"])
def test_no_growth_of_random_genomes_spends_less_than_the_bound(universe):
    """Over random genomes, in an environment that bends and stretches the surface: an uncapped
    growth spends at least ``least_work``, and every text the bound puts past ``max_work`` is capped
    (so an island never misses a growth it screens out as capped); ``plugins/timed`` writes ages
    and conditions on them."""
    config = RunConfig.from_dict({"genome": {"length": 60},
                                  "environment": {"steps": 4, "gravity": [0.0, 0.0, -0.5],
                                                  "scale": [1.3, 1.2, 1.0], "max_work": 4000}})
    grammar = load_universe(str(_TIMED) if universe == "timed" else universe)
    env = config.environment
    rng = stream(11, "test", "budget", universe)
    grown = past = 0
    for _ in range(120):
        mapped = grammar.map(list(random_genome(rng, 60, 255)), max_depth=config.genome.max_depth,
                             max_wraps=config.genome.max_wraps)
        if not mapped.valid:
            continue
        try:
            system = parse(mapped.text)
            result = grow(system, env)
        except Exception:   # a text that fails to parse or grow spends nothing to compare
            continue
        bound = least_work(system, env.steps)
        grown += 1
        if result.capped is None:
            assert bound <= result.work, mapped.text
        if bound > env.max_work:
            past += 1
            assert result.capped is not None, mapped.text
    assert grown >= 20
    if universe not in ("tiles", "gecco"):   # their systems seldom outgrow a cap in 4 steps
        assert past > 0
