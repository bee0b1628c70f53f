"""The compiled growth kernels grow the reference code's surfaces bit for bit: the same vertices, edges,
labels, ages, regions, perimeter, masses and stop marks, the same per-step counts, work and cap, on
the predefined tiles and on random rewrite systems of every universe in environments that exercise
label noise, cone joins, every tie rule, stopped vertices and the edge cap."""

from __future__ import annotations

import numpy as np
import pytest

from genr8_dist.environment import Environment
from genr8_dist.environment.boundaries import BoxBoundary
from genr8_dist.errors import ParseError
from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.hemls import grow, load_system, parse
from genr8_dist.hemls import growth as module
from genr8_dist.rng import stream

pytest.importorskip("numba", reason="numba is not installed: the compiled kernels (extra `fast`) are off")

if module._load_kernels() is None:   # numba is installed, so only GENR8_COMPILED=0 turns them off
    pytest.skip("GENR8_COMPILED=0: the compiled kernels are off", allow_module_level=True)

_FIELDS = ("vertices", "edges", "labels", "ages", "region_offsets", "region_vertices", "masses", "stopped")


def _same_growth(system, env, **kwargs):
    """Grow ``system`` with the kernels and with the numpy reference; assert every result is equal."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(module, "_kernels", module._load_kernels)
        compiled = grow(system, env, **kwargs)
        patch.setattr(module, "_kernels", lambda: None)
        reference = grow(system, env, **kwargs)
    for name in _FIELDS:
        a, b = getattr(compiled.surface, name), getattr(reference.surface, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
        assert a.tobytes() == b.tobytes(), name   # bit for bit, signed zeros included
    assert np.array_equal(compiled.surface.perimeter(), reference.surface.perimeter())
    assert [(s.n_vertices, s.n_edges, s.n_regions) for s in compiled.steps] == [
        (s.n_vertices, s.n_edges, s.n_regions) for s in reference.steps]
    assert (compiled.work, compiled.capped) == (reference.work, reference.capped)
    return compiled


@pytest.mark.parametrize("name", ["four_sided_tiles", "three_sided_tiles", "koch"])
def test_predefined_systems(name):
    result = _same_growth(load_system(name), Environment(max_work=0), steps=5)
    assert result.surface.n_edges > 100


def test_reversed_and_timed_branches():
    """Joins whose first branch is reversed (``~``) and whose two branches differ in age."""
    system = parse("Edge0 + ~ Edge1 + ~ Edge0 + Edge1\n"
                   "Edge0 -> Edge0 [ [ + ~ Edge1_i+1 ] - Edge1 ] Edge0\n"
                   "Edge1 -> Edge1 [ [ + ~ Edge0_i+2 ] - Edge0 ] Edge1\n")
    result = _same_growth(system, Environment(max_work=0), steps=5)
    assert result.surface.n_regions > 100 and len(set(result.surface.ages.tolist())) > 2


def _systems(per_universe: int) -> list:
    """Rewrite systems of random genomes, ``per_universe`` of each universe whose texts are HEMLS."""
    systems = []
    for info in list_universes():
        universe = load_universe(info.name)
        rng = stream(3, "compiled growth", info.name)
        found = 0
        for _ in range(200):
            mapped = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 200))))
            if not mapped.valid:
                continue
            try:
                systems.append(parse(mapped.text))
            except ParseError:   # a universe of another phenotype
                break
            found += 1
            if found == per_universe:
                break
    return systems


_ENVIRONMENTS = {
    "default": Environment(steps=4),
    "noise and cone joins": Environment(steps=4, label_noise=0.1, position_noise=0.05, branch_join="cone"),
    "ties first": Environment(steps=4, branch_ties="first"),
    "ties none, work cap": Environment(steps=4, branch_ties="none", max_work=2000),
    "edge cap": Environment(steps=5, max_edges=1500),
    "cut-off box": Environment(steps=4, boundaries=(BoxBoundary(min=(-1.5, -1.5, -0.2), max=(1.5, 1.5, 0.2),
                                                                behaviour="cut-off"),)),
}


@pytest.mark.parametrize("env", list(_ENVIRONMENTS.values()), ids=list(_ENVIRONMENTS))
def test_random_systems_of_every_universe(env):
    grown = 0
    for i, system in enumerate(_systems(3)):
        result = _same_growth(system, env, seed=i)
        grown += result.surface.n_edges
    assert grown > 500


def test_kernels_load_after_some_reference_growth_or_as_asked(monkeypatch):
    monkeypatch.setattr(module.KERNELS, "reference_work", 0)
    monkeypatch.delenv("GENR8_COMPILED", raising=False)
    assert module._kernels() is None   # a short run does not load numba
    grow(load_system("four_sided_tiles"), Environment(max_work=0), steps=6)
    assert module.KERNELS.reference_work > 5000
    monkeypatch.setattr(module.KERNELS, "reference_work", module.KERNELS.load_after)
    assert module._kernels() is module._load_kernels() is not None
    monkeypatch.setattr(module.KERNELS, "reference_work", 0)
    monkeypatch.setenv("GENR8_COMPILED", "1")
    assert module._kernels() is not None
    monkeypatch.setenv("GENR8_COMPILED", "0")
    assert module._load_kernels.__wrapped__() is None   # what a process started so would load
