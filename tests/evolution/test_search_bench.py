"""bench/search.py's figures: every evaluation counted, per stored individual, the run's best's
vertices, and the founder-machinery baseline bought with the run's evaluations."""

from __future__ import annotations

import math

from genr8_dist.config import RunConfig


def test_a_small_run_counts_every_evaluation_and_reports_the_runs_best(bench_module):
    bench = bench_module("search")
    config = RunConfig.from_dict({"universe": "tiles", "seed": 2, "genome": {"length": 40},
                                  "ea": {"population": 6, "elites": 1},
                                  "environment": {"steps": 2}, "islands": {"count": 2, "migrants": 1}})
    history, spent, growths = bench.run_islands(config, 2)
    figures = bench.describe((history, spent, growths), math.inf)
    everyone = [ind for gen in history for pop in gen for ind in pop]
    best = min(everyone, key=lambda ind: ind.fitness)
    assert figures["evaluations"] == spent[-1] and spent == sorted(spent)
    assert figures["per_stored"] == spent[-1] / len(everyone) == spent[-1] / 36
    assert figures["grown_per_stored"] == growths / 36 > 0
    assert figures["founder_cost"] == spent[0] / 12 >= 1.0
    assert figures["best_vertices"] == best.sizes["vertices"]
    founded, evaluations = bench.founder_sample(config, spent[-1], figures["founder_cost"])
    assert len(founded) == round(spent[-1] / figures["founder_cost"])
    assert evaluations >= len(founded) and all(ind.generation == 0 for ind in founded)
