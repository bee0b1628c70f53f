"""Property tests over random genomes of every built-in universe: the mapped text parses and prints
back, growth for up to 5 steps stays within the caps or says which cap it hit, every step's map is
valid, and the same inputs and seed regrow the same bytes."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.environment import Environment
from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.hemls import grow, parse
from genr8_dist.phenotype import SURFACES, phenotype_of

CAPS = Environment(max_edges=4000, max_seconds=5.0)
# Built-ins and the shipped plugins whose texts are HEMLS rewrite systems (not e.g. voxel tables).
UNIVERSES = [u.name for u in list_universes() if phenotype_of(load_universe(u.name)) is SURFACES]

genomes = st.lists(st.integers(0, 2**16), min_size=8, max_size=160)


def test_every_builtin_universe_is_tested():
    assert {"default", "reversible", "symmetric", "probabilistic"} <= set(UNIVERSES)


@pytest.mark.parametrize("universe", UNIVERSES)
@settings(max_examples=15)
@given(genome=genomes, steps=st.integers(1, 5), seed=st.integers(0, 2**31))
def test_mapped_rewrite_systems_grow_valid_maps(universe, genome, steps, seed):
    mapped = load_universe(universe).map(genome)
    if not mapped.valid:
        return  # an invalid individual is data with a reason, not a rewrite system
    system = parse(mapped.text, source=f"<{universe}>")
    assert parse(system.to_text()) == system
    result = grow(system, CAPS, steps=steps, seed=seed, keep_steps=True)
    assert result.capped in (None, "edges", "work", "time")
    if result.capped is None:
        assert len(result.steps) == steps
    assert result.surface.n_edges <= CAPS.max_edges
    for surface in result.history:
        assert surface.validate() == [], mapped.text
    again = grow(system, CAPS, steps=steps, seed=seed)
    if "time" not in (result.capped, again.capped):
        assert again.surface.digest() == result.surface.digest()
