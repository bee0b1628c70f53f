"""Hooks of the ``tables_direct`` universe: the same phenotype as ``tables`` (shipped with
genr8_dist beside this plugin), so the two universes differ in their encoding alone, and the paper's
direct genome with the same operators where they apply (``variation.DIRECT``: one command string of
up to 20,000 commands, 4 to 104 at first)."""

from __future__ import annotations

from genr8_dist.grammar import load_universe

_TABLES = load_universe("tables").hooks
PHENOTYPE = _TABLES.PHENOTYPE
VARIATION = _TABLES.variation.DIRECT
