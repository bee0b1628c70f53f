"""genr8_dist: grow 3D surfaces from map L-systems and evolve them with Grammatical Evolution on Ray.

The pipeline, one subpackage per stage: ``grammar`` (universes, the GE mapper and its inverse) →
``hemls`` (rewrite systems, the surface map, growth) → ``environment`` → ``fitness`` → ``evolution``
(operators, the island) → ``distributed`` (Ray actors, migration, the coordinator) → ``store`` (the
Parquet run store) → ``history`` (queries over it). docs/ARCHITECTURE.md draws the whole picture.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
