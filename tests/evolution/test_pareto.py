"""NSGA-II ranks and crowding distances against brute-force references on random fronts."""

from __future__ import annotations

import numpy as np
import pytest

from genr8_dist.evolution.pareto import (
    crowding_distance,
    hypervolume,
    non_dominated,
    non_dominated_ranks,
    pareto_order,
)
from genr8_dist.rng import stream


def brute_ranks(f: np.ndarray) -> list[int]:
    """Peel fronts: a row is in the current front when no remaining row dominates it."""
    remaining, ranks, rank = set(range(len(f))), [0] * len(f), 0
    while remaining:
        front = {i for i in remaining
                 if not any(np.all(f[j] <= f[i]) and np.any(f[j] < f[i]) for j in remaining)}
        for i in front:
            ranks[i] = rank
        remaining -= front
        rank += 1
    return ranks


def brute_crowding(f: np.ndarray, ranks: list[int]) -> list[float]:
    out = [0.0] * len(f)
    for r in set(ranks):
        members = [i for i in range(len(f)) if ranks[i] == r]
        if len(members) <= 2:
            for i in members:
                out[i] = float("inf")
            continue
        for m in range(f.shape[1]):
            s = sorted(members, key=lambda i: (f[i, m], i))
            out[s[0]] = out[s[-1]] = float("inf")
            span = f[s[-1], m] - f[s[0], m]
            for a, i, b in zip(s, s[1:], s[2:], strict=False):
                if span > 0 and out[i] != float("inf"):
                    out[i] += (f[b, m] - f[a, m]) / span
    return out


@pytest.mark.parametrize("trial", range(30))
def test_ranks_and_crowding_equal_the_references_on_random_fronts(trial):
    rng = stream(trial, "fronts")
    n, k = int(rng.integers(1, 40)), int(rng.integers(2, 4))
    # integer values make ties and duplicate points, which a reference must agree on too
    f = rng.integers(0, 6, size=(n, k)).astype(float)
    if trial % 3 == 0:
        f[rng.random(n) < 0.2] = np.inf   # invalid individuals
    ranks = non_dominated_ranks(f)
    assert ranks.tolist() == brute_ranks(f)
    if not np.isinf(f).any():
        assert crowding_distance(f, ranks) == pytest.approx(brute_crowding(f, ranks.tolist()))


def test_the_order_puts_the_front_first_and_its_extremes_before_its_middle():
    f = np.array([[0.0, 3.0], [1.0, 1.0], [3.0, 0.0], [2.0, 2.0], [0.9, 1.5], [np.inf, np.inf]])
    ranks, position = pareto_order(f)
    assert ranks.tolist() == [0, 0, 0, 1, 0, 2]
    assert sorted(position[[0, 2]].tolist()) == [0, 1]          # extremes first
    assert position[5] == 5 and position[3] == 4


@pytest.mark.parametrize("trial", range(40))
def test_the_non_dominated_mask_equals_rank_zero_with_ties_and_infinities(trial):
    rng = stream(11, "non-dominated", trial)
    n, k = int(rng.integers(0, 50)), int(rng.integers(1, 4))
    f = rng.integers(0, 4, (n, k)).astype(np.float64)   # few values: many ties and equal rows
    f[rng.random(n) < 0.2] = np.inf
    f[rng.random((n, k)) < 0.05] = np.nan
    assert non_dominated(f).tolist() == [r == 0 for r in brute_ranks(np.nan_to_num(f, nan=np.inf))]


def inclusion_exclusion_volume(f: np.ndarray, ref: np.ndarray) -> float:
    """The union of the boxes [point, ref] by inclusion-exclusion (a few points only)."""
    import itertools

    f = f[(f < ref).all(axis=1)]
    total = 0.0
    for size in range(1, len(f) + 1):
        for subset in itertools.combinations(range(len(f)), size):
            corner = f[list(subset)].max(axis=0)
            total += (-1) ** (size + 1) * float(np.prod(ref - corner))
    return total


@pytest.mark.parametrize("k", [2, 3, 4])
def test_hypervolume_equals_inclusion_exclusion_on_random_fronts(k):
    for trial in range(15):
        rng = stream(7, "hypervolume", k, trial)
        n = int(rng.integers(1, 9))
        f = rng.random((n, k))
        if trial % 3 == 0:
            f = np.round(f * 4) / 4          # ties and duplicates
        ref = np.full(k, 1.1)
        assert hypervolume(f, ref) == pytest.approx(inclusion_exclusion_volume(f, ref), abs=1e-12)


def test_hypervolume_counts_unit_cells_on_an_integer_grid():
    import itertools

    rng = stream(7, "hypervolume-grid")
    f = rng.integers(0, 6, size=(40, 3)).astype(float)
    cells = sum(1 for c in itertools.product(range(6), repeat=3)
                if any((np.array(c) >= p).all() for p in f))
    assert hypervolume(f, np.full(3, 6.0)) == pytest.approx(cells)


def test_hypervolume_ignores_points_beyond_the_reference_and_non_finite_ones():
    ref = np.array([1.0, 1.0])
    assert hypervolume(np.array([[0.5, 0.5], [2.0, 0.0], [np.inf, 0.1]]), ref) == pytest.approx(0.25)
    assert hypervolume(np.empty((0, 2)), ref) == 0.0
