"""Multi-objective ranking (NSGA-II, Deb et al. 2002): non-dominated fronts and crowding distance.

The objectives of an individual are the weighted deviations of chosen criteria from their targets
(``FitnessSpec.deviations``), each minimised; an invalid individual has every objective ``inf`` and
lands in the last front. ``rank 0`` is the non-dominated front. Plain numpy, no state: the ranks of
a generation are a pure function of its rows.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from genr8_dist.fitness import FitnessSpec

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig

__all__ = ["crowding_distance", "hypervolume", "non_dominated", "non_dominated_ranks", "objectives_of",
           "pareto_objectives", "pareto_order"]


def pareto_objectives(config: RunConfig) -> tuple[str, ...]:
    """The criteria a Pareto search treats as objectives: ``search.objectives``, or every criterion
    with a weight above 0."""
    if config.search.objectives:
        return tuple(config.search.objectives)
    return tuple(name for name in config.fitness.names if config.fitness[name].weight > 0)


def objectives_of(criteria: Sequence[Mapping[str, float]], valid: Sequence[bool], spec: FitnessSpec,
                  names: Sequence[str]) -> np.ndarray:
    """The (N, k) matrix of the weighted deviations of ``names`` under ``spec`` (a ``FitnessSpec``);
    a row of ``inf`` for an invalid individual."""
    out = np.full((len(criteria), len(names)), np.inf)
    for i, (raw, ok) in enumerate(zip(criteria, valid, strict=True)):
        if ok:
            out[i] = [spec[name].deviation(raw.get(name, np.nan)) for name in names]
    return out


def non_dominated_ranks(objectives: np.ndarray) -> np.ndarray:
    """The front of each row of ``objectives`` (N, k), all minimised: 0 for the non-dominated rows,
    1 for those dominated only by front 0, and so on. NaN counts as ``inf``."""
    f = np.nan_to_num(np.asarray(objectives, dtype=np.float64), nan=np.inf)
    n = len(f)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    if f.ndim != 2:
        raise ValueError(f"objectives must be an (N, k) array, got shape {f.shape}")
    # dominates[i, j]: row i dominates row j (no worse in every objective, better in one)
    le = (f[:, None, :] <= f[None, :, :]).all(axis=2)
    lt = (f[:, None, :] < f[None, :, :]).any(axis=2)
    dominates = np.asarray(le & lt)
    count = dominates.sum(axis=0)             # how many rows dominate each row
    ranks = np.full(n, -1, dtype=np.int64)
    front = np.flatnonzero(count == 0)
    rank = 0
    while front.size:
        ranks[front] = rank
        count = count - dominates[front].sum(axis=0)
        count[ranks >= 0] = -1
        front = np.flatnonzero(count == 0)
        rank += 1
    return ranks


def non_dominated(objectives: np.ndarray) -> np.ndarray:
    """Which rows of ``objectives`` (N, k), all minimised, are non-dominated: the rows of rank 0 of
    ``non_dominated_ranks``, found without comparing every pair (a generation of thousands in
    milliseconds). Rows are taken in lexicographic order, so every row that dominates another comes
    before it, and each is compared only with the front found so far. NaN counts as ``inf``."""
    f = np.nan_to_num(np.asarray(objectives, dtype=np.float64), nan=np.inf)
    if f.ndim != 2:
        raise ValueError(f"objectives must be an (N, k) array, got shape {f.shape}")
    on = np.zeros(len(f), dtype=bool)
    front = np.empty((0, f.shape[1]))
    for i in np.lexsort(f.T[::-1]) if len(f) else ():
        row = f[i]
        if not ((front <= row).all(axis=1) & (front < row).any(axis=1)).any():
            on[i] = True
            front = np.vstack([front, row])
    return on


def crowding_distance(objectives: np.ndarray, ranks: np.ndarray) -> np.ndarray:
    """NSGA-II's crowding distance of each row within its front: the sum over objectives of the gap
    between its neighbours, normalised by the front's range; ``inf`` for each front's extremes (and
    for fronts of one or two)."""
    f = np.nan_to_num(np.asarray(objectives, dtype=np.float64), nan=np.inf)
    out = np.zeros(len(f))
    for rank in np.unique(ranks):
        members = np.flatnonzero(ranks == rank)
        if members.size <= 2:
            out[members] = np.inf
            continue
        for m in range(f.shape[1]):
            values = f[members, m]
            order = members[np.argsort(values, kind="stable")]
            sorted_values = f[order, m]
            out[order[0]] = out[order[-1]] = np.inf
            span = sorted_values[-1] - sorted_values[0]
            if not np.isfinite(span) or span <= 0:
                continue
            out[order[1:-1]] += (sorted_values[2:] - sorted_values[:-2]) / span
    return out


def pareto_order(objectives: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(ranks, position)``: each row's front, and its place in NSGA-II's order (front first, then
    the larger crowding distance, then the lower index): position 0 is the best."""
    ranks = non_dominated_ranks(objectives)
    crowd = crowding_distance(objectives, ranks)
    order = sorted(range(len(ranks)), key=lambda i: (int(ranks[i]), -float(crowd[i]), i))
    position = np.empty(len(ranks), dtype=np.int64)
    position[order] = np.arange(len(ranks))
    return ranks, position


def hypervolume(points: np.ndarray, reference: Sequence[float]) -> float:
    """The volume of objective space (all minimised) that ``points`` (N, k) dominate and that
    dominates ``reference`` (k,): the standard measure of a front's quality and spread (Zitzler and
    Thiele 1998). Exact, by slicing along the last objective down to a sweep in two (a front of
    300 points in four objectives in about a second).
    Points not strictly better than the reference in every objective add nothing."""
    f = np.asarray(points, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if f.size == 0:
        return 0.0
    if f.ndim != 2 or ref.shape != (f.shape[1],):
        raise ValueError(f"hypervolume needs (N, k) points and a (k,) reference, got {f.shape} and "
                         f"{ref.shape}")
    f = f[np.isfinite(f).all(axis=1) & (f < ref).all(axis=1)]
    return _volume(np.unique(f[non_dominated(f)], axis=0), ref)


def _volume(f: np.ndarray, ref: np.ndarray) -> float:
    if len(f) == 0:
        return 0.0
    k = f.shape[1]
    if k == 1:
        return float(ref[0] - f[:, 0].min())
    if k == 2:
        # sweep x: between consecutive x values the lowest y so far bounds the dominated strip
        f = f[np.lexsort((f[:, 1], f[:, 0]))]
        widths = np.diff(np.append(f[:, 0], ref[0]))
        return float(np.sum(widths * (ref[1] - np.minimum.accumulate(f[:, 1]))))
    # slices between consecutive values of the last objective: each is the (k-1)-volume of the
    # points at or below it, times its thickness
    f = f[np.argsort(f[:, -1], kind="stable")]
    levels = np.append(f[:, -1], ref[-1])
    total = 0.0
    for i in range(len(f)):
        thickness = levels[i + 1] - levels[i]
        if thickness > 0:
            total += thickness * _volume(f[: i + 1, :-1], ref[:-1])
    return total
