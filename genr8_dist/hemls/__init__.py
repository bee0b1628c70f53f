"""HEMLS: the rewrite-system language, the surface map, the turtle and the derivation step.

``parse`` / ``load_system`` read rewrite systems (language.py); growth turns them into surfaces.
"""

from __future__ import annotations

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

__all__ = [
    "PREDEFINED",
    "AxiomEdge",
    "Branch",
    "Condition",
    "RewriteSystem",
    "Rule",
    "Segment",
    "Successor",
    "load_system",
    "parse",
]
