"""genr8_dist: grow 3D surfaces from map L-systems and evolve them with Grammatical Evolution on Ray.

The pipeline, one subpackage per stage: ``grammar`` (universes, the GE mapper and its inverse) →
``hemls`` (rewrite systems, the surface map, growth) → ``environment`` → ``fitness`` → ``evolution``
(operators, the island) → ``distributed`` (Ray actors, migration, the coordinator) → ``store`` (the
Parquet run store) → ``history`` (queries over it). docs/ARCHITECTURE.md draws the whole picture.

The names below are the public API; they are imported on first use, so ``import genr8_dist`` stays
light (the ``genr8`` command answers ``--help`` without loading Ray, pyarrow or trimesh).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    "load_universe": "genr8_dist.grammar",
    "list_universes": "genr8_dist.grammar",
    "Universe": "genr8_dist.grammar",
    "MapResult": "genr8_dist.grammar",
    "parse": "genr8_dist.hemls",
    "load_system": "genr8_dist.hemls",
    "grow": "genr8_dist.hemls",
    "RewriteSystem": "genr8_dist.hemls",
    "Surface": "genr8_dist.hemls",
    "GrowthResult": "genr8_dist.hemls",
    "Environment": "genr8_dist.environment",
    "load_environment": "genr8_dist.environment",
    "CRITERIA": "genr8_dist.fitness",
    "FitnessSpec": "genr8_dist.fitness",
    "score_surface": "genr8_dist.fitness",
    "RunConfig": "genr8_dist.config",
    "load_config": "genr8_dist.config",
    "Individual": "genr8_dist.evolution",
    "Island": "genr8_dist.evolution",
    "evaluate_genome": "genr8_dist.evolution",
    "RunStore": "genr8_dist.store",
    "start_run": "genr8_dist.distributed",
    "resume_run": "genr8_dist.distributed",
    "Genr8Error": "genr8_dist.errors",
}

__all__ = ["__version__", *sorted(_EXPORTS)]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'genr8_dist' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
