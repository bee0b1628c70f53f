"""Compiled kernels of the triangulation (``genr8_dist.hemls.surface``), with numba.

Optional: ``surface`` imports this module the first time a triangulation needs it, only when numba
imports (the ``fast`` extra) and ``GENR8_COMPILED`` is not ``0``; otherwise the numpy/Python reference
code in ``surface`` runs. Each kernel performs the same IEEE operations in the same order as the
reference it replaces (no fastmath, no reassociation), so the triangles are the same bit for bit:

- ``best_triangulations``: the exact programme's triangle costs, the programme over spans (the first
  of equal totals wins, like ``argmin``) and the readback, from the pairwise values the reference
  computes with numpy (``surface._pairwise``);
- ``clip``, ``cut_runs``, ``flip``: ear clipping, ``_cut`` of every true-corner triangle of a large
  region, and the flips, with the directed-edge owner map as an open-addressing table whose
  first-insertion order gives the dictionary's initial stack. Plane coordinates and straight-corner
  tests stay numpy, in ``surface``.

Python's ``x ** 2`` calls the C library's ``pow``, which is not always ``x * x`` (it differs on about
1 in 1,200 random doubles, and on 6 of 2,398 random genomes' surfaces); ``cut_runs`` calls ``pow``
too, through an exponent passed at run time (a constant one would be folded into a product).

Compiled code is cached on disk (``cache=True``), so later processes (Ray workers) load it; where no
cache directory is writable the kernels are compiled in memory instead.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["best_triangulations", "clip", "cut_runs", "flip"]

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


# -- small array helpers (explicit loops: numba compiles them much faster than slicing) -------------

@_jit
def _where(mask: np.ndarray, out: np.ndarray) -> int:
    """``np.flatnonzero(mask)`` into ``out``: returns how many."""
    n = 0
    for v in range(len(mask)):
        if mask[v]:
            out[n] = v
            n += 1
    return n


@_jit
def _rows(a: np.ndarray, n: int) -> np.ndarray:
    """A copy of the first ``n`` rows of ``a`` (R, C)."""
    out = np.empty((n, a.shape[1]), dtype=a.dtype)
    for i in range(n):
        for j in range(a.shape[1]):
            out[i, j] = a[i, j]
    return out


@_jit
def _grown(a: np.ndarray, n: int) -> np.ndarray:
    """``a`` (R, C) with twice the rows, its first ``n`` copied."""
    out = np.empty((2 * a.shape[0], a.shape[1]), dtype=a.dtype)
    for i in range(n):
        for j in range(a.shape[1]):
            out[i, j] = a[i, j]
    return out


@_jit
def _sorted3(a: np.ndarray, row: int, out: np.ndarray) -> None:
    """``out[:] = sorted(a[row])`` for a row of three."""
    u, v, w = a[row, 0], a[row, 1], a[row, 2]
    if u > v:
        u, v = v, u
    if v > w:
        v, w = w, v
    if u > v:
        u, v = v, u
    out[0], out[1], out[2] = u, v, w


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


# -- large regions: ear clipping, cutting the straight runs back in, flips ---------------------------

@_jit
def _turn(xs: np.ndarray, ys: np.ndarray, a: int, b: int, c: int) -> float:
    return (xs[b] - xs[a]) * (ys[c] - ys[a]) - (ys[b] - ys[a]) * (xs[c] - xs[a])


@_jit
def clip(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """(T, 3) ear clipping of the polygon of plane coordinates ``xs``, ``ys`` (``_clip_and_flip``'s
    first part: never at a straight or reflex corner, never over a reflex vertex; the rest fanned)."""
    n = len(xs)
    nxt = np.empty(n, dtype=np.int64)
    prv = np.empty(n, dtype=np.int64)
    for v in range(n):
        nxt[v] = v + 1 if v + 1 < n else 0
        prv[v] = v - 1 if v > 0 else n - 1
    reflex = np.empty(n, dtype=np.bool_)
    for v in range(n):
        reflex[v] = _turn(xs, ys, prv[v], v, nxt[v]) <= EPS
    ridx = np.empty(n, dtype=np.int64)
    nr = _where(reflex, ridx)
    dirty = False
    tris = np.empty((max(n - 2, 0), 3), dtype=np.int64)
    nt = 0
    remaining, i, misses = n, 0, 0
    while remaining > 3 and misses <= remaining:
        a, c = prv[i], nxt[i]
        ear = not reflex[i] and _turn(xs, ys, a, i, c) > EPS
        if ear:
            if dirty:
                nr = _where(reflex, ridx)
                dirty = False
            for r in range(nr):
                q = ridx[r]
                if q in (a, c):
                    continue
                qx, qy = xs[q], ys[q]
                d1 = (xs[i] - xs[a]) * (qy - ys[a]) - (ys[i] - ys[a]) * (qx - xs[a])
                d2 = (xs[c] - xs[i]) * (qy - ys[i]) - (ys[c] - ys[i]) * (qx - xs[i])
                d3 = (xs[a] - xs[c]) * (qy - ys[c]) - (ys[a] - ys[c]) * (qx - xs[c])
                if d1 >= -EPS and d2 >= -EPS and d3 >= -EPS:
                    ear = False
                    break
        if not ear:
            i = c
            misses += 1
            continue
        tris[nt, 0], tris[nt, 1], tris[nt, 2] = a, i, c
        nt += 1
        nxt[a], prv[c] = c, a
        remaining -= 1
        for v in (a, c):
            if reflex[v] and _turn(xs, ys, prv[v], v, nxt[v]) > EPS:
                reflex[v] = False
                dirty = True
        i, misses = a, 0
    rest = np.empty(max(remaining, 1), dtype=np.int64)
    rest[0] = i
    size = 1
    j = nxt[i]
    while j != i and size < remaining:
        rest[size] = j
        size += 1
        j = nxt[j]
    for k in range(1, size - 1):
        tris[nt, 0], tris[nt, 1], tris[nt, 2] = rest[0], rest[k], rest[k + 1]
        nt += 1
    return _rows(tris, nt)


@_jit
def _d2(p: np.ndarray, u: int, v: int, two: float) -> float:
    """Squared distance as the reference computes it: ``(pu - pv) ** 2`` is the C library's pow."""
    return (math.pow(p[u, 0] - p[v, 0], two) + math.pow(p[u, 1] - p[v, 1], two)
            + math.pow(p[u, 2] - p[v, 2], two))


@_jit
def _cut(x: int, y: int, z: int, runs: np.ndarray, pts: np.ndarray, two: float, out: np.ndarray,
         nout: int) -> int:
    """``surface._cut`` of triangle (x, y, z) whose sides carry the ring positions
    ``runs[0]:runs[1]``, ``runs[2]:runs[3]``, ``runs[4]:runs[5]``: writes unordered corner triples to
    ``out`` from row ``nout`` on, returns the rows used. Its recursion is a stack, first call on top."""
    tasks = np.empty((64, 9), dtype=np.int64)
    tasks[0, 0], tasks[0, 1], tasks[0, 2] = x, y, z
    for s in range(6):
        tasks[0, 3 + s] = runs[s]
    ntask = 1
    corners = np.empty(3, dtype=np.int64)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    while ntask:
        ntask -= 1
        x, y, z = tasks[ntask, 0], tasks[ntask, 1], tasks[ntask, 2]
        corners[0], corners[1], corners[2] = x, y, z
        for s in range(3):
            lo[s], hi[s] = tasks[ntask, 3 + 2 * s], tasks[ntask, 4 + 2 * s]
        full = 0
        for s in range(3):
            full += hi[s] > lo[s]
        if full == 0:
            out[nout, 0], out[nout, 1], out[nout, 2] = x, y, z
            nout += 1
        elif full == 1:                       # a fan from the corner opposite the one side
            f = 0 if hi[0] > lo[0] else 1 if hi[1] > lo[1] else 2
            s, t, o = corners[f], corners[(f + 1) % 3], corners[(f + 2) % 3]
            prev = s
            for v in range(lo[f], hi[f]):
                out[nout, 0], out[nout, 1], out[nout, 2] = o, prev, v
                nout += 1
                prev = v
            out[nout, 0], out[nout, 1], out[nout, 2] = o, prev, t
            nout += 1
        elif full == 3:                       # cut from the longest side's middle vertex first
            n = 0
            for s in (1, 2):
                if hi[s] - lo[s] > hi[n] - lo[n]:
                    n = s
            s, t, o = corners[n], corners[(n + 1) % 3], corners[(n + 2) % 3]
            mid = lo[n] + (hi[n] - lo[n]) // 2
            if ntask + 2 > len(tasks):
                tasks = _grown(tasks, ntask)
            b, a = (n + 1) % 3, (n + 2) % 3
            second = tasks[ntask]             # _cut(mid, t, o, run[k + 1:], sides[n + 1], [])
            second[0], second[1], second[2] = mid, t, o
            second[3], second[4], second[5], second[6] = mid + 1, hi[n], lo[b], hi[b]
            second[7], second[8] = 0, 0
            first = tasks[ntask + 1]          # _cut(s, mid, o, run[:k], [], sides[n + 2])
            first[0], first[1], first[2] = s, mid, o
            first[3], first[4], first[5], first[6] = lo[n], mid, 0, 0
            first[7], first[8] = lo[a], hi[a]
            ntask += 2
        else:                                 # a strip between the two sides from their corner
            empty = 0 if hi[0] <= lo[0] else 1 if hi[1] <= lo[1] else 2
            sb, sa = (empty + 1) % 3, (empty + 2) % 3
            shared = corners[sa]
            nq = hi[sb] - lo[sb] + 2
            npp = hi[sa] - lo[sa] + 2
            q = np.empty(nq, dtype=np.int64)      # back along the side that ends at ``shared``
            q[0] = shared
            for k in range(hi[sb] - lo[sb]):
                q[1 + k] = hi[sb] - 1 - k
            q[nq - 1] = corners[sb]
            p = np.empty(npp, dtype=np.int64)     # out along the side that starts at it
            p[0] = shared
            for k in range(hi[sa] - lo[sa]):
                p[1 + k] = lo[sa] + k
            p[npp - 1] = corners[(sa + 1) % 3]
            out[nout, 0], out[nout, 1], out[nout, 2] = shared, q[1], p[1]
            nout += 1
            i = j = 1
            while i < nq - 1 or j < npp - 1:
                if j == npp - 1 or (i < nq - 1 and _d2(pts, q[i + 1], p[j], two)
                                    <= _d2(pts, q[i], p[j + 1], two)):
                    out[nout, 0], out[nout, 1], out[nout, 2] = q[i], q[i + 1], p[j]
                    i += 1
                else:
                    out[nout, 0], out[nout, 1], out[nout, 2] = q[i], p[j], p[j + 1]
                    j += 1
                nout += 1
    return nout


@_jit
def cut_runs(reduced: np.ndarray, corners: np.ndarray, points: np.ndarray, two: float) -> np.ndarray:
    """(T, 3) polygon positions: each triangle of ``reduced`` (positions in ``corners``, the polygon's
    true corners) cut again with the set-aside vertices of its sides by ``_cut``, in the reference's
    order (``surface._large_polygon``); ``two`` is 2.0, passed at run time (see the module)."""
    r, m = len(corners), len(points)
    total = 0
    tri = np.empty(3, dtype=np.int64)
    for row in range(len(reduced)):
        _sorted3(reduced, row, tri)
        total += 1                            # a ring of 3 + (its sides' vertices) gives ring - 2
        for e in range(3):
            i, j = tri[e], tri[(e + 1) % 3]
            if j == (i + 1) % r:
                lo, hi = corners[i], corners[j]
                total += hi - lo - 1 if hi > lo else m - lo - 1 + hi
    cut = np.empty((total, 3), dtype=np.int64)
    ncut = 0
    ring = np.empty(m + 3, dtype=np.int64)
    runs = np.empty(6, dtype=np.int64)
    local = np.empty((m + 1, 3), dtype=np.int64)
    pts = np.empty((m + 3, 3))
    for row in range(len(reduced)):
        _sorted3(reduced, row, tri)
        size = 0
        for e in range(3):
            i, j = tri[e], tri[(e + 1) % 3]
            ring[size] = corners[i]
            size += 1
            runs[2 * e] = size
            if j == (i + 1) % r:              # one of the polygon's sides, not a diagonal
                lo, hi = corners[i], corners[j]
                for v in range(lo + 1, hi if hi > lo else m):
                    ring[size] = v
                    size += 1
                for v in range(0 if hi <= lo else hi, hi):
                    ring[size] = v
                    size += 1
            runs[2 * e + 1] = size
        for k in range(size):
            for e in range(3):
                pts[k, e] = points[ring[k], e]
        nlocal = _cut(0, runs[1], runs[3], runs, pts, two, local, 0)
        for row2 in range(nlocal):
            _sorted3(local, row2, tri)        # ``tri`` is free again: this row's corners are read
            cut[ncut, 0], cut[ncut, 1], cut[ncut, 2] = ring[tri[0]], ring[tri[1]], ring[tri[2]]
            ncut += 1
    return _rows(cut, ncut)


@_jit
def _slot(keys: np.ndarray, key: int) -> int:
    """Where ``key`` is in the open-addressing table ``keys`` (-1 empty, -2 removed), or -1."""
    mask = len(keys) - 1
    h = key ^ (key >> 17)
    h = (h * 0x2545F491) & mask
    while True:
        k = keys[h]
        if k == key:
            return h
        if k == -1:
            return -1
        h = (h + 1) & mask


@_jit
def _put(keys: np.ndarray, vals: np.ndarray, key: int, val: int) -> int:
    """Set ``key`` to ``val``: 0 if it was there, 1 if it took a removed slot, 2 an empty one."""
    mask = len(keys) - 1
    h = key ^ (key >> 17)
    h = (h * 0x2545F491) & mask
    free = -1
    while True:
        k = keys[h]
        if k == key:
            vals[h] = val
            return 0
        if k == -2 and free < 0:
            free = h
        elif k == -1:
            break
        h = (h + 1) & mask
    if free >= 0:
        keys[free], vals[free] = key, val
        return 1
    keys[h], vals[h] = key, val
    return 2


@_jit
def _rehash(keys: np.ndarray, vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The table without its removed slots."""
    fresh_keys = np.empty(len(keys), dtype=np.int64)
    for h in range(len(keys)):
        fresh_keys[h] = -1
    fresh_vals = np.empty(len(keys), dtype=np.int64)
    for h in range(len(keys)):
        if keys[h] >= 0:
            _put(fresh_keys, fresh_vals, keys[h], vals[h])
    return fresh_keys, fresh_vals


@_jit
def _inside(xs: np.ndarray, ys: np.ndarray, a: int, b: int, c: int, d: int) -> bool:
    """``surface._delaunay_test``: d inside the circumcircle of (a, b, c)."""
    a1, a2 = xs[a] - xs[d], ys[a] - ys[d]
    a3 = a1 * a1 + a2 * a2
    b1, b2 = xs[b] - xs[d], ys[b] - ys[d]
    b3 = b1 * b1 + b2 * b2
    c1, c2 = xs[c] - xs[d], ys[c] - ys[d]
    c3 = c1 * c1 + c2 * c2
    return a1 * (b2 * c3 - b3 * c2) - a2 * (b1 * c3 - b3 * c1) + a3 * (b1 * c2 - b2 * c1) > EPS


@_jit
def _cost(p: np.ndarray, a: int, b: int, c: int) -> float:
    """``surface._cost_test``'s cost: 1 / quality of triangle (a, b, c) in 3D, floored."""
    ax, ay, az, bx, by, bz, cx, cy, cz = p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], \
        p[c, 0], p[c, 1], p[c, 2]
    ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
    wx, wy, wz = cx - bx, cy - by, cz - bz
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    sides = ux * ux + uy * uy + uz * uz + vx * vx + vy * vy + vz * vz + wx * wx + wy * wy + wz * wz
    quad = 2.0 * math.sqrt(3.0) * math.sqrt(nx * nx + ny * ny + nz * nz)
    return sides / quad if quad > QUALITY_FLOOR * sides else 1.0 / QUALITY_FLOOR


@_jit
def flip(tris: np.ndarray, xs: np.ndarray, ys: np.ndarray, points: np.ndarray, cost: bool,
         budget: int) -> None:
    """``surface._flip`` in place on ``tris`` (T, 3), with ``_cost_test(points)`` when ``cost``, else
    ``_delaunay_test(xs, ys)``: the same edges tested in the same order, so the same flips."""
    n, T = len(xs), len(tris)
    cap = 16
    while cap < 8 * 3 * T:
        cap *= 2
    keys = np.empty(cap, dtype=np.int64)
    for h in range(cap):
        keys[h] = -1
    vals = np.empty(cap, dtype=np.int64)
    order = np.empty(3 * T, dtype=np.int64)       # the keys in the dictionary's insertion order
    norder = 0
    for t in range(T):
        for e in range(3):
            key = tris[t, e] * n + tris[t, (e + 1) % 3]
            if _put(keys, vals, key, t) == 2:
                order[norder] = key
                norder += 1
    used = norder
    stack = np.empty((max(norder, 16), 2), dtype=np.int64)
    top = 0
    for o in range(norder):
        a, b = order[o] // n, order[o] % n
        if a < b and _slot(keys, b * n + a) >= 0:
            stack[top, 0], stack[top, 1] = a, b
            top += 1
    while top and budget:
        budget -= 1
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        h1, h2 = _slot(keys, a * n + b), _slot(keys, b * n + a)
        if h1 < 0 or h2 < 0:
            continue
        t1, t2 = vals[h1], vals[h2]
        u, v, w = tris[t1, 0], tris[t1, 1], tris[t1, 2]
        c = w if u == a and v == b else u if v == a and w == b else v
        u, v, w = tris[t2, 0], tris[t2, 1], tris[t2, 2]
        d = w if u == b and v == a else u if v == b and w == a else v
        xa, ya, xc, yc, xd, yd = xs[a], ys[a], xs[c], ys[c], xs[d], ys[d]
        if (xd - xa) * (yc - ya) - (yd - ya) * (xc - xa) <= EPS:
            continue
        if (xs[b] - xd) * (yc - yd) - (ys[b] - yd) * (xc - xd) <= EPS:
            continue
        if cost:
            before = _cost(points, a, b, c) + _cost(points, b, a, d)
            if not _cost(points, a, d, c) + _cost(points, d, b, c) < before * (1.0 - 1e-12):
                continue
        elif not _inside(xs, ys, a, b, c, d):
            continue
        tris[t1, 0], tris[t1, 1], tris[t1, 2] = a, d, c
        tris[t2, 0], tris[t2, 1], tris[t2, 2] = d, b, c
        keys[h1] = -2
        keys[h2] = -2
        used += _put(keys, vals, a * n + d, t1) == 2
        used += _put(keys, vals, d * n + c, t1) == 2
        used += _put(keys, vals, c * n + a, t1) == 2
        used += _put(keys, vals, d * n + b, t2) == 2
        used += _put(keys, vals, b * n + c, t2) == 2
        used += _put(keys, vals, c * n + d, t2) == 2
        if 2 * used > cap:
            keys, vals = _rehash(keys, vals)
            used = 0
            for h in range(cap):
                used += keys[h] >= 0
        if top + 4 > len(stack):
            stack = _grown(stack, top)
        stack[top, 0], stack[top, 1] = a, d
        stack[top + 1, 0], stack[top + 1, 1] = d, b
        stack[top + 2, 0], stack[top + 2, 1] = b, c
        stack[top + 3, 0], stack[top + 3, 1] = c, a
        top += 4
