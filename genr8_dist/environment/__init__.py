"""The environment a surface grows in (thesis 2.7, journal 4.7): parameters, forces, boundaries, noise.

``Environment`` is one frozen, validated value with Genr8's defaults; ``load_environment`` reads it
from TOML (docs/environment.md lists every field). ``Environment.increase_size`` is part 1 of a
derivation step: growth away from the centre, attractors/repellers/gravity, repelling points, noise,
fixed perimeter/centre, uniform cells, then boundaries (slide, cut-off, reflect, soft).
"""

from __future__ import annotations

from genr8_dist.environment.boundaries import (
    BEHAVIOURS,
    Behaviour,
    Boundary,
    BoxBoundary,
    MeshBoundary,
    PlaneBoundary,
    SphereBoundary,
)
from genr8_dist.environment.forces import LAWS, PointForce
from genr8_dist.environment.model import Environment, SizeIncrease, load_environment

__all__ = [
    "BEHAVIOURS",
    "LAWS",
    "Behaviour",
    "Boundary",
    "BoxBoundary",
    "Environment",
    "MeshBoundary",
    "PlaneBoundary",
    "PointForce",
    "SizeIncrease",
    "SphereBoundary",
    "load_environment",
]
