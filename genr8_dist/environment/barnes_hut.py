"""Barnes–Hut: every point's inverse-square field from every other point in O(V log V).

The field at point i is ``Σ_{j≠i} (p_i − p_j) / |p_i − p_j|^3`` (unit charges): the repelling-points
sum of thesis 2.7.2 when every vertex pushes every other one. The points are sorted along a Morton
(Z-order) curve, which makes every cell of the octree a run of consecutive points; the tree is
walked one level at a time for all points at once (numpy arrays of (point, cell) pairs). A cell of
edge ``s`` whose centre of mass is at distance ``d`` from the point, and that does not hold the
point, counts as its point count at its centre of mass when ``s < θ · d`` (θ the *opening angle*);
otherwise it is opened into its children, or, when it holds at most ``LEAF`` points or is at the
deepest level, summed point by point. θ = 0 opens every cell: the exact sum.

The error grows with θ (``python bench/repelling.py`` measures it against the exact sum); the
walk visits O(log V / θ^3) cells per point. Sums run in a fixed order: the same points give the
same bytes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LEAF", "inverse_square_field"]

#: Cells of at most this many points are summed point by point.
LEAF = 8
_DEPTH = 16          # levels below the root: cells of 1/65,536 of the bounding cube's edge
_BLOCK = 4_000_000   # (point, cell) or (point, point) pairs handled at a time


def _morton(grid: np.ndarray) -> np.ndarray:
    """Interleave the bits of integer coordinates (V, 3) in [0, 2^_DEPTH) into Z-order codes."""
    code = np.zeros(len(grid), dtype=np.int64)
    for bit in range(_DEPTH):
        for axis in range(3):
            code |= ((grid[:, axis] >> bit) & 1) << (3 * bit + 2 - axis)
    return code


def _levels(code: np.ndarray, points: np.ndarray
            ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """For each level 0.._DEPTH: the cells as (prefix, first point, end point, count, centre of mass),
    points in Morton order."""
    n = len(code)
    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(points, axis=0)])
    levels: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for level in range(_DEPTH + 1):
        prefix = code >> (3 * (_DEPTH - level))
        start = np.flatnonzero(np.r_[True, prefix[1:] != prefix[:-1]])
        end = np.r_[start[1:], n]
        count = end - start
        com = (cumulative[end] - cumulative[start]) / count[:, None]
        levels.append((prefix[start], start, end, count, com))
    return levels


def _direct(out: np.ndarray, points: np.ndarray, tgt: np.ndarray, first: np.ndarray,
            last: np.ndarray) -> None:
    """Add to ``out[tgt]`` the exact field of points ``first..last-1`` (one range per target)."""
    sizes = last - first
    total = int(sizes.sum())
    if not total:
        return
    step = max(1, _BLOCK // max(1, int(sizes.max())))
    for b in range(0, len(tgt), step):
        t, f, s = tgt[b:b + step], first[b:b + step], sizes[b:b + step]
        rows = np.repeat(t, s)
        offsets = np.arange(int(s.sum())) - np.repeat(np.cumsum(s) - s, s)
        cols = np.repeat(f, s) + offsets
        keep = cols != rows
        rows, cols = rows[keep], cols[keep]
        delta = points[rows] - points[cols]
        d2 = np.einsum("ij,ij->i", delta, delta)
        safe = np.where(d2 > 0.0, d2, 1.0)
        push = np.where(d2 > 0.0, 1.0 / (safe * np.sqrt(safe)), 0.0)[:, None] * delta
        for axis in range(3):
            out[:, axis] += np.bincount(rows, weights=push[:, axis], minlength=len(out))


def inverse_square_field(points: np.ndarray, theta: float = 0.5) -> np.ndarray:
    """``Σ_{j≠i} (p_i − p_j) / |p_i − p_j|^3`` for every point i, by Barnes–Hut with opening angle
    ``theta`` (0: exact). Coincident points do not push each other."""
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    out = np.zeros((n, 3))
    if n < 2:
        return out
    low = points.min(axis=0)
    edge = float(np.max(points.max(axis=0) - low)) or 1.0
    edge *= 1.0 + 1e-9
    grid = np.minimum(((points - low) / edge * (1 << _DEPTH)).astype(np.int64), (1 << _DEPTH) - 1)
    code = _morton(grid)
    order = np.argsort(code, kind="stable")
    code, sorted_points = code[order], points[order]
    levels = _levels(code, sorted_points)
    field = np.zeros((n, 3))
    tgt = np.arange(n, dtype=np.int64)       # (target point, cell) pairs still to settle
    cell = np.zeros(n, dtype=np.int64)
    for level, (prefix, start, end, count, com) in enumerate(levels):
        if not len(tgt):
            break
        last = level == _DEPTH
        if level:   # the root holds every point
            size = edge / (1 << level)
            delta = sorted_points[tgt] - com[cell]
            d2 = np.einsum("ij,ij->i", delta, delta)
            inside = (code[tgt] >> (3 * (_DEPTH - level))) == prefix[cell]
            far = ~inside & (size * size < theta * theta * d2)
            if np.any(far):
                dd = d2[far]
                push = (count[cell[far]] / (dd * np.sqrt(dd)))[:, None] * delta[far]
                for axis in range(3):
                    field[:, axis] += np.bincount(tgt[far], weights=push[:, axis], minlength=n)
                tgt, cell = tgt[~far], cell[~far]
        small = (count[cell] <= LEAF) | last
        if np.any(small):
            _direct(field, sorted_points, tgt[small], start[cell[small]], end[cell[small]])
            tgt, cell = tgt[~small], cell[~small]
        if last or not len(tgt):
            break
        # open the rest: the children of a cell are the next level's cells inside its run of points
        child_start = levels[level + 1][1]
        c0 = np.searchsorted(child_start, start[cell])
        c1 = np.searchsorted(child_start, end[cell])
        k = c1 - c0
        tgt = np.repeat(tgt, k)
        cell = np.repeat(c0, k) + (np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k))
    out[order] = field
    return out
