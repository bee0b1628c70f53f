"""Evolution: the ``Individual`` record, the operators, the evaluation of a genome and the island.

The island is plain Python (no Ray): ``Island(config, i).initial()`` builds generation 0 and
``Island.step(previous, g, migrants, injected)`` each next one, every draw from the seeded streams of
``genr8_dist.rng``. ``evaluate_genome`` maps, grows and scores one genome; failures are data.
"""

from __future__ import annotations

from genr8_dist.evolution.evaluate import Evaluation, Evaluator, evaluate_genome, evaluate_text
from genr8_dist.evolution.individual import ORIGINS, Individual, individual_id
from genr8_dist.evolution.island import Island, IslandStats
from genr8_dist.evolution.operators import (
    int_flip_mutation,
    one_point_crossover,
    random_genome,
    select_elites,
    tournament_select,
)

__all__ = [
    "ORIGINS",
    "Evaluation",
    "Evaluator",
    "Individual",
    "Island",
    "IslandStats",
    "evaluate_genome",
    "evaluate_text",
    "individual_id",
    "int_flip_mutation",
    "one_point_crossover",
    "random_genome",
    "select_elites",
    "tournament_select",
]
