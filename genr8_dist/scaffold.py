"""The scaffold as curves: a map's edges joined into lines and drawn as cubic B-splines.

Genr8 drew its surfaces as a scaffold of B-spline lines through the map's edges, "smoother than the
polygonal surface mesh" (thesis 2.6.2). Here each edge belongs to exactly one *line*: at every vertex
the two edges that continue each other most straightly (at least ``_STRAIGHT`` degrees apart) are
joined, pair by pair, most straight first, and the lines are the chains (or loops) this makes. Each line
is a cubic B-spline whose control points are its vertices: clamped for an open chain (it starts and
ends at the chain's ends), periodic for a loop; a straight run stays straight. The pictures sample
these curves (``scaffold_curves``); ``.3dm`` exports write them as NURBS curves.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["SurfaceEdges", "sample_line", "scaffold_curves", "scaffold_lines"]


class SurfaceEdges(Protocol):
    """What the scaffold reads of a surface (``genr8_dist.hemls.Surface`` has it)."""

    @property
    def vertices(self) -> np.ndarray: ...

    @property
    def edges(self) -> np.ndarray: ...

_STRAIGHT = 135.0   # two edges at a vertex continue each other when at least this far apart (degrees)


def scaffold_lines(vertices: ArrayLike, edges: ArrayLike) -> list[tuple[np.ndarray, bool]]:
    """The map's edges joined into lines: ``(vertex ids, closed)`` each, every edge in exactly one, in a
    fixed order (deterministic)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    at: list[list[int]] = [[] for _ in range(len(v))]
    for k, (a, b) in enumerate(e.tolist()):
        at[a].append(k)
        at[b].append(k)
    partner: dict[tuple[int, int], int] = {}       # (vertex, edge) -> the edge it continues into
    limit = math.cos(math.radians(_STRAIGHT))
    for x, incident in enumerate(at):
        if len(incident) < 2:
            continue
        other = [int(e[k, 1] if e[k, 0] == x else e[k, 0]) for k in incident]
        d = v[other] - v[x]
        n = np.linalg.norm(d, axis=1)
        d = d / np.where(n > 0, n, 1.0)[:, None]
        cos = d @ d.T
        count = len(incident)
        pairs = sorted((float(cos[i, j]), i, j) for i in range(count) for j in range(i + 1, count)
                       if cos[i, j] <= limit)
        used: set[int] = set()
        for _, i, j in pairs:
            if i in used or j in used:
                continue
            used.update((i, j))
            partner[(x, incident[i])] = incident[j]
            partner[(x, incident[j])] = incident[i]
    seen = np.zeros(len(e), dtype=bool)
    lines: list[tuple[np.ndarray, bool]] = []

    def walk(start_vertex: int, edge: int) -> list[int]:
        """Vertices from ``start_vertex`` along ``edge`` and on through the joins."""
        path = [start_vertex]
        x, k = start_vertex, edge
        while True:
            seen[k] = True
            y = int(e[k, 1] if e[k, 0] == x else e[k, 0])
            path.append(y)
            nxt = partner.get((y, k))
            if nxt is None or seen[nxt]:
                return path
            x, k = y, nxt

    for k in range(len(e)):
        if seen[k]:
            continue
        a, b = int(e[k, 0]), int(e[k, 1])
        forward = walk(a, k)
        closed = len(forward) > 2 and forward[-1] == a and partner.get((a, k)) is not None
        if closed:
            lines.append((np.array(forward[:-1], dtype=np.int64), True))
            continue
        back = partner.get((a, k))
        if back is not None and not seen[back]:
            behind = walk(a, back)
            forward = behind[::-1][:-1] + forward
        lines.append((np.array(forward, dtype=np.int64), False))
    return lines


def sample_line(points: np.ndarray, closed: bool, per_span: int = 8) -> np.ndarray:
    """(S, 3) points along the cubic B-spline whose control points are ``points`` (n, 3): clamped
    (through its ends) when open, periodic when ``closed``; two points give the straight segment."""
    from scipy.interpolate import BSpline

    p = np.asarray(points, dtype=np.float64)
    n = len(p)
    if n < 3 and not closed:
        return p.copy()
    if closed:
        degree = min(3, n - 1)
        ctrl = np.concatenate([p, p[:degree]])
        m = len(ctrl)
        knots = np.arange(m + degree + 1, dtype=np.float64)
        u = np.linspace(knots[degree], knots[m], n * per_span + 1)
    else:
        degree = min(3, n - 1)
        ctrl = p
        inner = np.arange(1, n - degree, dtype=np.float64)
        knots = np.concatenate([np.zeros(degree + 1), inner, np.full(degree + 1, float(n - degree))])
        u = np.linspace(0.0, float(n - degree), (n - 1) * per_span + 1)
    return np.asarray(BSpline(knots, ctrl, degree)(u))


def scaffold_curves(surface: SurfaceEdges, per_span: int = 8) -> list[np.ndarray]:
    """The scaffold's lines sampled as B-spline curves (each (S, 3)), for drawing."""
    v = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    return [sample_line(v[ids], closed, per_span) for ids, closed in scaffold_lines(v, surface.edges)]
