"""Hooks of the ``tables_direct`` universe: the same phenotype as ``tables`` (shipped with
genr8_dist beside this plugin), so the two universes differ in their encoding alone."""

from __future__ import annotations

from genr8_dist.grammar import load_universe

PHENOTYPE = load_universe("tables").hooks.PHENOTYPE
