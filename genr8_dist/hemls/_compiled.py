"""Compiled kernels of the triangulation (``genr8_dist.hemls.surface``), with numba.

Optional: ``surface`` imports this module the first time a triangulation needs it, only when numba
imports (the ``fast`` extra) and ``GENR8_COMPILED`` is not ``0``; otherwise the numpy/Python reference
code in ``surface`` runs. Each kernel performs the same IEEE operations in the same order as the
reference it replaces (no fastmath, no reassociation), so the triangles are the same bit for bit:

``best_triangulations``: the exact programme's triangle costs, the programme over spans (the first
of equal totals wins, like ``argmin``) and the readback, from the pairwise values the reference
computes with numpy (``surface._pairwise``).

Compiled code is cached on disk (``cache=True``), so later processes (Ray workers) load it; where no
cache directory is writable the kernels are compiled in memory instead.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["best_triangulations"]

# the values of the constants of ``surface`` (asserted equal there, where this module is imported)
EXACT_MAX = 64
QUALITY_FLOOR = 1e-9
OUTSIDE = 1e12
EPS = 1e-10


def _jit(fn):
    try:
        return numba.njit(cache=True)(fn)
    except RuntimeError:        # no writable cache location: compile in memory, every process
        return numba.njit(fn)


# -- the exact programme -----------------------------------------------------------------------------

@_jit
def _np_max(a: float, b: float) -> float:
    return a if a >= b or a != a else b    # np.maximum: NaN propagates


@_jit
def best_triangulations(d2: np.ndarray, cr: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """(R, M - 2, 3) corner positions of each polygon's least-cost triangulation from its squared
    distances ``d2`` (R, M, M) and plane cross products ``cr`` (R, M, M) (``surface._pairwise``);
    only polygon r's first ``sizes[r]`` vertices are used (padding never enters the programme)."""
    R, M = d2.shape[0], d2.shape[1]
    out = np.zeros((R, max(M - 2, 0), 3), dtype=np.int64)
    best = np.zeros((M, M))
    choice = np.zeros((M, M), dtype=np.int64)
    todo = np.zeros((M, 2), dtype=np.int64)
    root3 = math.sqrt(3.0)
    cap = 1.0 / QUALITY_FLOOR
    for r in range(R):
        m = sizes[r]
        best[:, :] = 0.0
        for span in range(2, m):
            for i in range(m - span):
                j = i + span
                c2 = d2[r, i, j]
                c4 = c2 * c2
                crji = cr[r, j, i]
                low = 0.0
                arg = i + 1
                for k in range(i + 1, j):
                    a2 = d2[r, i, k]
                    b2 = d2[r, k, j]
                    sides = a2 + b2 + c2
                    heron = sides * sides - 2.0 * (a2 * a2 + b2 * b2 + c4)
                    heron = _np_max(math.sqrt(_np_max(heron, 0.0)) * root3, QUALITY_FLOOR * sides)
                    cost = sides / heron if heron > 0 else cap
                    if cr[r, i, k] + cr[r, k, j] + crji <= EPS:
                        cost += OUTSIDE
                    total = best[i, k] + best[k, j] + cost
                    if k == i + 1:
                        low = total
                    elif low != low:
                        continue                  # argmin stops at the first NaN
                    elif total < low or total != total:
                        low, arg = total, k
                best[i, j] = low
                choice[i, j] = arg
        if m < 3:
            continue
        todo[0, 0], todo[0, 1] = 0, m - 1
        n = 1
        while n:
            n -= 1
            lo, hi = todo[n, 0], todo[n, 1]
            k = choice[lo, hi]
            out[r, k - 1, 0], out[r, k - 1, 1], out[r, k - 1, 2] = lo, k, hi
            if k - lo >= 2:
                todo[n, 0], todo[n, 1] = lo, k
                n += 1
            if hi - k >= 2:
                todo[n, 0], todo[n, 1] = k, hi
                n += 1
    return out
