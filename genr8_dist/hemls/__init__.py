"""HEMLS: the rewrite-system language, the surface map, the turtle and the derivation step.

``parse`` / ``load_system`` read rewrite systems (language.py); ``grow`` (growth.py) applies
derivation steps in an environment and returns a ``Surface`` (surface.py); turtle.py draws successors.
"""

from __future__ import annotations

from genr8_dist.hemls.growth import GrowthResult, StepStats, grow, seed_surface
from genr8_dist.hemls.language import (
    PREDEFINED,
    AxiomEdge,
    Branch,
    Condition,
    RewriteSystem,
    Rule,
    Segment,
    Successor,
    load_system,
    parse,
)
from genr8_dist.hemls.surface import Surface

__all__ = [
    "PREDEFINED",
    "AxiomEdge",
    "Branch",
    "Condition",
    "GrowthResult",
    "RewriteSystem",
    "Rule",
    "Segment",
    "StepStats",
    "Successor",
    "Surface",
    "grow",
    "load_system",
    "parse",
    "seed_surface",
]
