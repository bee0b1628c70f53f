"""Universes, the GE mapper and its inverse.

A *universe* is a Lark grammar file (``grammars/*.lark``, a plugin folder, or any path) whose
derivations are rewrite systems. ``load_universe(name).map(genome)`` runs Genr8's Grammatical
Evolution mapping; ``.invert(text)`` is the thesis's *regn8*, giving back a genome that maps to the
text. ``grammars/README.md`` says how to write a universe.

"""

from __future__ import annotations

from genr8_dist.grammar.discovery import (
    ENTRY_POINT_GROUP,
    UniverseInfo,
    find_source,
    list_universes,
    load_universe,
)
from genr8_dist.grammar.source import UniverseSource
from genr8_dist.grammar.universe import MapResult, Universe, build_universe, check_genome

__all__ = [
    "ENTRY_POINT_GROUP",
    "MapResult",
    "Universe",
    "UniverseInfo",
    "UniverseSource",
    "build_universe",
    "check_genome",
    "find_source",
    "list_universes",
    "load_universe",
]
