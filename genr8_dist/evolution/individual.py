"""The individual: one genome and everything learned about it, the row the run store keeps.

Failure is data: an individual that cannot be mapped, parsed, grown or scored is still an
``Individual``, with ``valid=False``, the ``stage`` that failed, the ``error``, and the worst fitness
(``math.inf``). Fields marked *timing* are measurements and are excluded from determinism checks;
every other field is a pure function of the run's configuration, seed and history.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["ORIGINS", "Individual", "individual_id"]

# How an individual came to be (the ``origin`` column).
ORIGINS: tuple[str, ...] = (
    "random",     # generation 0, or a random immigrant
    "elite",      # copied unchanged from the previous generation
    "crossover",  # one-point crossover of two parents, not mutated
    "mutation",   # int-flip mutation of one parent (no crossover)
    "crossover+mutation",
    "migrant",    # arrived from another island at a migration
    "injected",   # put in by a user's intervention (copy, hand-written system, another run)
)


def individual_id(island: int, generation: int, index: int) -> str:
    """The id of the ``index``-th individual of ``island`` in ``generation``: ``"I-G-N"``."""
    return f"{island}-{generation}-{index}"


@dataclass(frozen=True, slots=True)
class Individual:
    """One evaluated genome of one island in one generation."""

    island: int
    generation: int
    index: int
    genome: tuple[int, ...]
    origin: str
    parents: tuple[str, ...] = ()
    text: str | None = None              # the rewrite system the genome maps to
    valid: bool = False
    stage: str | None = None             # where it failed: "map", "parse", "grow" or "score"
    error: str | None = None
    fitness: float = math.inf            # weighted sum of deviations; lower is better
    criteria: dict[str, float] = field(default_factory=dict)  # raw value of every criterion
    config_version: int = 1
    codons_used: int = 0
    wraps: int = 0
    n_vertices: int = 0
    n_edges: int = 0
    n_regions: int = 0
    steps_done: int = 0
    capped: str | None = None            # which growth cap cut it short, if any
    surface_digest: str | None = None    # blake2b of the final vertex array, for bit-identical regrowth
    eval_seconds: float = 0.0            # timing
    map_seconds: float = 0.0             # timing
    grow_seconds: float = 0.0            # timing
    score_seconds: float = 0.0           # timing

    @property
    def id(self) -> str:
        return individual_id(self.island, self.generation, self.index)
