"""Mending: the last step of meshings 6 to 8, thin triangles of a whole mesh mended across regions.

Meshing 5 leaves a few triangles under 15 degrees in regions whose corners are all wider. Where a
neighbour split a shared side finely next to a corner, the region, keeping its sides whole in its
last pass, cannot grade its own points to match (a corner of 64 degrees with side points 0.5e-3
and 2e-3 from it); where two regions' concentric shells land at different radii on the two sides of
a corner, the triangle across the corner is thin. Inside one region nothing mends them, since its
ring's points are fixed. The assembled mesh is one watertight triangle mesh, so here its thin
triangles are mended by operations that keep it watertight and keep every region's outline:

- *flip* an edge inside a region (both triangles beside it in that region);
- *collapse* a point the meshing added into a neighbour: a point inside a region into any, a point
  on a side only along that side (into the next point on it, the one beyond on the same straight
  line), so both regions beside the side lose it together;
- *move* a point inside a region to its neighbours' mean, or *slide* a point on a side to the middle
  of the two beside it on that side;
- *split* one of the thin triangle's two longer edges (a side in both regions beside it): at its
  middle; graded, at the shortest edge's length from the end they share; or the longest at its
  middle with the new point moved to the thin triangle's circumcentre where it is inside a region
  (Delaunay refinement's point); then flip the edges facing the new point where that raises their
  triangles' smaller angle, and mend the thin triangles the split touched with the other operations.

An operation is kept only if the triangles it touched, in every region, end with fewer under
``_BELOW`` degrees, or as many and a larger smallest angle, and none turned over; else it is undone.
The thin triangles are tried thinnest first, over ``_ROUNDS`` rounds, each after the first trying
again only those beside what changed. A region whose thin triangles fail ``_GIVE_UP`` times in a row
is left (one that folds over itself or crosses its own outline has thousands nothing mends), and a
triangle whose smallest angle is its region's own corner is not tried. Last, in regions with at most
``_FEW`` thin triangles left, each gets a slower try: compass searches for a point's place too,
after every operation the thin triangles it touched are mended before the whole is judged, and the
best of all the operations is taken; failing that, once more with each operation taken whatever it
does to its own triangles and what it touched mended for its worst angle (a degenerate triangle
flipped into two thin ones, whose apex a search then lifts). The surface's own vertices never move.

Meshing 7 mends as meshing 6 does, with four changes:

- the thin triangles of *free* regions, whose corners are all at least ``_BELOW`` degrees, count
  before those of *pinched* ones (``pinched``: a needle-thin region, any mesh of which has a thin
  triangle at its sharp corner), so a side that a free region shares with a needle may be split to
  mend the free region although the needle gains a thin triangle (under 6 that undid the repair:
  one thin triangle out, one in);
- the rounds go on until nothing changes (under 6, 4 rounds stopped repairs that were still
  spreading: one reversible surface kept 209 thin triangles, 6 in regions with wide corners, where
  7 leaves 21 and none);
- a last try is repeated while it changes something and the triangle stays thin (``_AGAIN``): a
  wider triangle may open a repair the thinner one did not; and the last tries are run again while
  a pass changed something, for the thin triangles a repair left beside it;
- a point is on a straight side when its distance from the line of its neighbours there is within
  ``_LINE`` of their span, not when the sine of its angle is: two side points 2.4e-7 apart on a side
  whose other gaps are 1.5e-5 sat 1e-15 off the line, a sine of 4e-9 from rounding alone, so neither
  could slide or be collapsed and the thin triangle on that short gap stayed.

Meshing 8 mends as meshing 7 does, with two more last tries:

- where a thin triangle's smallest angle is at a point of its region's outline whose two sides there
  differ in length, the longer side is split at the shorter one's length from that point (a side
  in both regions beside it): a corner of 29.6 degrees cut in two by an edge inside it, 14.6 + 15.0,
  becomes one triangle, since its inner point lay on the corner's side of the line through its other
  neighbours and could not be flipped or collapsed away;
- for each thin triangle left in a free region with at most ``_FEW`` thin ones, *two steps*: an
  edge round its points flipped whatever that does, or a neighbouring point moved by a compass
  search, then the triangle and what the first step touched mended as a last try does; the first pair
  that is better is kept. A triangle of 8.7 degrees among others of 15.0 to 15.6 is mended by no
  single operation, since each takes one of them under 15 degrees.

Deterministic: a fixed order, Python floats.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np

_BELOW = 15.0       # degrees: a thin triangle, as the benches and the ``slivers`` criterion count it
_ROUNDS = {6: 4, 7: 64, 8: 64}   # passes over the thin triangles, at most (from 7: until nothing changes)
_SPLIT_FLIPS = 24   # flips round a split's new point, at most
_NEAR = 2           # rings of triangles round the thin ones that take part
_SEARCH = 6         # halvings of a compass search's step (the last try only)
_FEW = 3            # regions with at most this many thin triangles left get a last, slower try
_AGAIN = 4          # last tries of one thin triangle, at most (meshing 7)
_GIVE_UP = 8        # a region's thin triangles tried in a row in vain before the rest of them are left
_LINE = 1e-9        # a side point is on the line of its neighbours on its side to this (the sine of the
                    # angle there; from meshing 7 its distance from the line over their span)

Point = tuple[float, float, float]
Tri = tuple[int, int, int]
Seen = list[tuple[float, bool]]   # triangles' smallest angles, each with whether its region is free


def normal(a: Point, b: Point, c: Point) -> Point:
    """Twice the area vector of the triangle ``a b c`` (its orientation)."""
    ux, uy, uz, wx, wy, wz = b[0] - a[0], b[1] - a[1], b[2] - a[2], c[0] - a[0], c[1] - a[1], c[2] - a[2]
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


def smallest(a: Point, b: Point, c: Point) -> float:
    """The triangle's smallest angle (degrees): the one facing its shortest side; 0 when degenerate."""
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = a, b, c
    ux, uy, uz, wx, wy, wz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
    vx, vy, vz = cx - bx, cy - by, cz - bz
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    twice = math.sqrt(nx * nx + ny * ny + nz * nz)
    ab, ac, bc = ux * ux + uy * uy + uz * uz, wx * wx + wy * wy + wz * wz, vx * vx + vy * vy + vz * vz
    if bc <= ab and bc <= ac:
        facing = ux * wx + uy * wy + uz * wz                    # at a
    elif ac <= ab:
        facing = -(ux * vx + uy * vy + uz * vz)                 # at b
    else:
        facing = wx * vx + wy * vy + wz * vz                    # at c
    return math.degrees(math.atan2(twice, facing))


def dot(u: Point, w: Point) -> float:
    """The dot product of two vectors."""
    return u[0] * w[0] + u[1] * w[1] + u[2] * w[2]


def circumcentre(a: Point, b: Point, c: Point) -> Point:
    """The centre of the circle through ``a b c`` (the point Delaunay refinement inserts)."""
    u = (a[0] - c[0], a[1] - c[1], a[2] - c[2])
    w = (b[0] - c[0], b[1] - c[1], b[2] - c[2])
    n = normal(c, a, b)
    nn = max(dot(n, n), 1e-300)
    uu, ww = dot(u, u), dot(w, w)
    d = (uu * w[0] - ww * u[0], uu * w[1] - ww * u[1], uu * w[2] - ww * u[2])
    x = (d[1] * n[2] - d[2] * n[1], d[2] * n[0] - d[0] * n[2], d[0] * n[1] - d[1] * n[0])
    return c[0] + x[0] / (2 * nn), c[1] + x[1] / (2 * nn), c[2] + x[2] / (2 * nn)


def triangle_min_angles(vertices: Any, triangles: Any) -> np.ndarray:
    """The smallest angle (degrees) of each triangle ``(T, 3)`` of ``vertices`` ``(V, 3)``; 0 for a
    degenerate one. The one measure of a triangle's shape: mending's and the tidy pass's (one
    triangle at a time: ``smallest``), the ``slivers`` criterion's and the benches'."""
    p = np.asarray(vertices, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"vertices must be a (V, 3) array, got shape {p.shape}")
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if not len(t):
        return np.zeros(0)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    first, second = _between(b - a, c - a), _between(a - b, c - b)
    third = np.clip(180.0 - first - second, 0.0, 180.0)
    return np.asarray(np.minimum(np.minimum(first, second), third))


def _between(u: np.ndarray, v: np.ndarray, degenerate: float = 0.0) -> np.ndarray:
    """The angle (degrees) between the rows of ``u`` and ``v``; ``degenerate`` where one is zero."""
    norms = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
    cos = np.einsum("ij,ij->i", u, v) / np.where(norms > 0, norms, np.inf)
    return np.where(norms > 0, np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), degenerate)


class _Mesh:
    """A triangle mesh being mended: its triangles by index (None once removed), each edge's
    triangles, each point's triangles, and a log of the changes of the operation under way. Regions
    beside one another may be oriented either way, so edges are kept undirected."""

    def __init__(self, points: dict[int, Point], triangles: np.ndarray, regions: np.ndarray,
                 angles: np.ndarray, frozen: set[int], fixed: int, n_points: int,
                 pinched: frozenset[int] = frozenset(), by_distance: bool = False,
                 corners: bool = False) -> None:
        self.pts = points
        self.n_points = n_points     # the next new point's id
        self.tris: list[Tri | None] = [(t[0], t[1], t[2]) for t in triangles.tolist()]
        self.reg: list[int] = regions.tolist()
        self.frozen = frozen        # the rim's points: they may not move, nor lose or gain a triangle
        self.fixed = fixed          # the surface's vertices (ids below it) may not move
        self.edge: dict[tuple[int, int], set[int]] = {}
        self.star: dict[int, set[int]] = {}
        self.ang: list[float] = angles.tolist()
        self.pinched = pinched      # regions with a corner under _BELOW: a thin triangle there weighs less
        self.by_distance = by_distance   # a side point's straightness by its distance from the line (7)
        self.corners = corners      # a last try also splits the longer side of a thin triangle's corner (8)
        self.judge: Callable[[Seen, Seen], bool] = _better    # whether a change is kept
        self.sides: dict[int, tuple[int, ...] | None] = {}    # ``side``, until a point's star changes
        # (triangle, its old corners, its old smallest angle) or (-1 - point, its old position, 0)
        self.log: list[tuple[int, object, float]] = []
        for i, t in enumerate(self.tris):
            assert t is not None
            self._link(i, t)

    def angle(self, t: Tri) -> float:
        return smallest(self.pts[t[0]], self.pts[t[1]], self.pts[t[2]])

    def normal(self, t: Tri) -> Point:
        return normal(self.pts[t[0]], self.pts[t[1]], self.pts[t[2]])

    def free(self, i: int) -> bool:
        """Whether triangle ``i``'s region is free: no corner under ``_BELOW`` degrees (not ``pinched``)."""
        return self.reg[i] not in self.pinched

    def seen(self, i: int, t: Tri | None = None) -> tuple[float, bool]:
        """Triangle ``i``'s smallest angle (or that of ``t`` in its place) and whether its region is free."""
        return self.ang[i] if t is None else self.angle(t), self.free(i)

    def _link(self, i: int, t: Tri) -> None:
        for k in range(3):
            self.sides.pop(t[k], None)
            self.edge.setdefault(_key(t[k], t[(k + 1) % 3]), set()).add(i)
            self.star.setdefault(t[k], set()).add(i)

    def _unlink(self, i: int, t: Tri) -> None:
        for k in range(3):
            self.sides.pop(t[k], None)
            key = _key(t[k], t[(k + 1) % 3])
            self.edge[key].discard(i)
            if not self.edge[key]:
                del self.edge[key]
            self.star[t[k]].discard(i)

    def beside(self, a: int, b: int) -> list[int]:
        return sorted(self.edge.get(_key(a, b), ()))

    def put(self, i: int, t: Tri | None) -> None:
        """Triangle ``i`` becomes ``t`` (None: removed), logged."""
        old = self.tris[i]
        self.log.append((i, old, self.ang[i]))
        if old is not None:
            self._unlink(i, old)
        self.tris[i] = t
        if t is not None:
            self._link(i, t)
            self.ang[i] = self.angle(t)

    def add(self, t: Tri, region: int) -> None:
        self.tris.append(None)
        self.reg.append(region)
        self.ang.append(0.0)
        self.put(len(self.tris) - 1, t)

    def move(self, v: int, to: Point) -> None:
        """Point ``v`` moves to ``to``, logged with its triangles' angles."""
        self.log.append((-1 - v, self.pts[v], 0.0))
        for i in sorted(self.star[v]):
            self.log.append((i, self.tris[i], self.ang[i]))
        self._moved(v)
        self.pts[v] = to
        for i in self.star[v]:
            t = self.tri(i)
            self.ang[i] = self.angle(t)

    def mark(self) -> tuple[int, int, int]:
        return len(self.log), self.n_points, len(self.tris)

    def touched(self, mark: tuple[int, int, int]) -> list[int]:
        """The triangles changed since ``mark``, in index order."""
        return sorted({i for i, _, _ in self.log[mark[0]:] if i >= 0})

    def changed(self, mark: tuple[int, int, int]) -> tuple[Seen, Seen]:
        """The triangles changed since ``mark`` as the judge sees them (``seen``), before and now."""
        before: dict[int, float | None] = {}
        for i, old, angle in self.log[mark[0]:]:
            if i >= 0 and i not in before:
                before[i] = angle if old is not None else None
        return ([(a, self.free(i)) for i, a in before.items() if a is not None],
                [self.seen(i) for i in before if self.tris[i] is not None])

    def better(self, mark: tuple[int, int, int]) -> bool:
        """Whether the triangles changed since ``mark`` are better (``judge``) than they were."""
        return self.judge(*self.changed(mark))

    def undo(self, mark: tuple[int, int, int]) -> None:
        while len(self.log) > mark[0]:
            i, old, angle = self.log.pop()
            if i < 0:
                self._moved(-1 - i)
                self.pts[-1 - i] = cast(Point, old)
                continue
            t = self.tris[i]
            if t is not None:
                self._unlink(i, t)
            self.tris[i] = cast("Tri | None", old)
            if old is not None:
                self._link(i, cast(Tri, old))
            self.ang[i] = angle
        for v in range(mark[1], self.n_points):
            del self.pts[v]
        self.n_points = mark[1]
        del self.tris[mark[2]:], self.reg[mark[2]:], self.ang[mark[2]:]

    def outline(self, a: int, b: int) -> bool:
        """Whether the edge a b lies on a region's outline (one triangle beside it, or two regions)."""
        got = self.edge.get(_key(a, b))
        if got is None or len(got) != 2:
            return True
        i, j = got
        return self.reg[i] != self.reg[j]

    def neighbours(self, v: int) -> set[int]:
        return {x for i in self.star.get(v, ()) for x in self.tris[i] or ()} - {v}

    def tri(self, i: int) -> Tri:
        """Triangle ``i``, which is in the mesh."""
        t = self.tris[i]
        assert t is not None
        return t

    def _moved(self, v: int) -> None:
        for x in self.neighbours(v) | {v}:
            self.sides.pop(x, None)

    def side(self, p: int) -> tuple[int, ...] | None:
        """For an added point ``p``: () inside a region; its two neighbours along the outline when
        it lies on a straight side between them; None otherwise (it may not move)."""
        if p not in self.sides:
            self.sides[p] = self._side(p)
        return self.sides[p]

    def _side(self, p: int) -> tuple[int, ...] | None:
        on = sorted(x for x in self.neighbours(p) if self.outline(p, x))
        if not on:
            return ()
        if len(on) != 2:
            return None
        (px, py, pz), (qx, qy, qz), (rx, ry, rz) = self.pts[p], self.pts[on[0]], self.pts[on[1]]
        u, w = (qx - px, qy - py, qz - pz), (rx - px, ry - py, rz - pz)
        n = normal(self.pts[p], self.pts[on[0]], self.pts[on[1]])
        if self.by_distance:     # within _LINE of the span from its line: a point beside a very short
            v = (rx - qx, ry - qy, rz - qz)          # gap is straight to rounding too
            bent = math.sqrt(dot(n, n)) > _LINE * dot(v, v)
        else:
            bent = math.sqrt(dot(n, n)) > _LINE * math.sqrt(dot(u, u) * dot(w, w))
        if bent or dot(u, w) >= 0.0:
            return None
        return on[0], on[1]

    def movable(self, v: int) -> tuple[int, ...] | None:
        """``side(v)`` for a point that may move (an added point off the patch's rim), else None."""
        return None if v < self.fixed or v in self.frozen else self.side(v)

    def upright(self, tris: list[Tri], normals: list[Point]) -> bool:
        """Whether no triangle of ``tris`` turned over against its old orientation ``normals``."""
        return all(dot(self.normal(t), n) > 0.0 for t, n in zip(tris, normals, strict=True))

    # operations: each changes the mesh and returns whether it may be kept (orientation)

    def flip(self, i: int, k: int, check: bool = True) -> bool:
        t = self.tri(i)
        a, b, c = t[k], t[(k + 1) % 3], t[(k + 2) % 3]
        got = self.beside(a, b)
        if len(got) != 2 or self.reg[got[0]] != self.reg[got[1]]:
            return False
        j = got[0] if got[1] == i else got[1]
        u = self.tri(j)
        d = next(x for x in u if x != a and x != b)
        if c == d or _key(c, d) in self.edge or u[(u.index(b) + 1) % 3] != a:
            return False
        n_old = self.normal(t)
        m_old = self.normal(u)
        old = (n_old[0] + m_old[0], n_old[1] + m_old[1], n_old[2] + m_old[2])
        new1, new2 = (c, a, d), (d, b, c)
        n1, n2 = self.normal(new1), self.normal(new2)
        if dot(n1, n2) <= 0.0 or dot(n1, old) <= 0.0 or dot(n2, old) <= 0.0:
            return False
        if check and not self.judge([self.seen(i), self.seen(j)], [self.seen(i, new1), self.seen(j, new2)]):
            return False
        self.put(i, new1)
        self.put(j, new2)
        return True

    def collapse(self, p: int, q: int, check: bool = True) -> bool:
        on = self.movable(p)
        if on is None or q in self.frozen or (on and q not in on):
            return False
        both = sorted(self.star[p] & self.star[q])
        if not both:
            return False
        third = {x for i in both for x in self.tris[i] or ()} - {p, q}
        if self.neighbours(p) & self.neighbours(q) != third:
            return False
        rest = sorted(self.star[p] - set(both))
        new: list[Tri] = []
        for i in rest:
            t = self.tri(i)
            n = (t[0] if t[0] != p else q, t[1] if t[1] != p else q, t[2] if t[2] != p else q)
            if dot(self.normal(n), self.normal(t)) <= 0.0:
                return False
            new.append(n)
        if check and not self.judge([self.seen(i) for i in sorted(self.star[p])],
                                    [self.seen(i, n) for i, n in zip(rest, new, strict=True)]):
            return False
        for i in both:
            self.put(i, None)
        for i, n in zip(rest, new, strict=True):
            self.put(i, n)
        return True

    def search(self, v: int) -> bool:
        """Point ``v`` moved by a compass search (eight directions in its triangles' mean plane, or
        two along its side, the step halved ``_SEARCH`` times from a quarter of its shortest edge)
        wherever that is better for the triangles round it."""
        on = self.movable(v)
        if on is None:
            return False
        home = self.pts[v]
        around = sorted(self.star[v])
        tris = [self.tri(i) for i in around]
        old = [self.normal(t) for t in tris]
        if on:
            q = self.pts[on[0]]
            u = (q[0] - home[0], q[1] - home[1], q[2] - home[2])
            norm = math.sqrt(dot(u, u))
            dirs = [(u[0] / norm, u[1] / norm, u[2] / norm)]
        else:
            n = (sum(x[0] for x in old), sum(x[1] for x in old), sum(x[2] for x in old))
            length = math.sqrt(dot(n, n))
            if length == 0.0:
                return False
            n = (n[0] / length, n[1] / length, n[2] / length)
            a = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
            e1 = (n[1] * a[2] - n[2] * a[1], n[2] * a[0] - n[0] * a[2], n[0] * a[1] - n[1] * a[0])
            norm = math.sqrt(dot(e1, e1))
            e1 = (e1[0] / norm, e1[1] / norm, e1[2] / norm)
            e2 = (n[1] * e1[2] - n[2] * e1[1], n[2] * e1[0] - n[0] * e1[2], n[0] * e1[1] - n[1] * e1[0])
            dirs = [(math.cos(k * math.pi / 4) * e1[0] + math.sin(k * math.pi / 4) * e2[0],
                     math.cos(k * math.pi / 4) * e1[1] + math.sin(k * math.pi / 4) * e2[1],
                     math.cos(k * math.pi / 4) * e1[2] + math.sin(k * math.pi / 4) * e2[2]) for k in range(4)]
        step = 0.25 * min(math.dist(self.pts[x], home) for x in self.neighbours(v))
        best, best_angles = home, [self.seen(i) for i in around]
        halvings = 0
        while halvings < _SEARCH:
            moved = False
            for d in dirs:
                for sign in (1.0, -1.0):
                    to = (best[0] + sign * step * d[0], best[1] + sign * step * d[1],
                          best[2] + sign * step * d[2])
                    self.pts[v] = to
                    got = [self.seen(i, t) for i, t in zip(around, tris, strict=True)]
                    if self.upright(tris, old) and self.judge(best_angles, got):
                        best, best_angles, moved = to, got, True
            self.pts[v] = home
            if not moved:
                step *= 0.5
                halvings += 1
        if best == home:
            return False
        self.move(v, best)
        return True

    def relax(self, v: int, check: bool = True) -> bool:
        """Point ``v`` moved to its neighbours' mean (inside a region) or to the middle of its two
        neighbours on its side."""
        on = self.movable(v)
        if on is None:
            return False
        near = list(on) or sorted(self.neighbours(v))
        to = (sum(self.pts[x][0] for x in near) / len(near), sum(self.pts[x][1] for x in near) / len(near),
              sum(self.pts[x][2] for x in near) / len(near))
        home = self.pts[v]
        around = sorted(self.star[v])
        tris = [self.tri(i) for i in around]
        old = [self.normal(t) for t in tris]
        self.pts[v] = to
        kept = self.upright(tris, old) and \
            (not check or self.judge([self.seen(i) for i in around],
                                     [self.seen(i, t) for i, t in zip(around, tris, strict=True)]))
        self.pts[v] = home
        if kept:
            self.move(v, to)
        return kept

    def split(self, a: int, b: int, f: float, to: Point | None = None) -> bool:
        """Edge a b split ``f`` of the way from a (the new point then moved ``to`` there, for an edge
        inside a region, if no triangle turns over), then the edges facing the new point flipped
        where that raises the smaller angle of their two triangles."""
        if (a in self.frozen and b in self.frozen) or len(self.beside(a, b)) > 2:
            return False       # the edge may have a triangle outside the mesh being mended
        pa, pb = self.pts[a], self.pts[b]
        m = self.n_points
        self.n_points += 1
        self.pts[m] = (pa[0] + f * (pb[0] - pa[0]), pa[1] + f * (pb[1] - pa[1]), pa[2] + f * (pb[2] - pa[2]))
        for i in self.beside(a, b):
            t = self.tri(i)
            k = t.index(a)
            x, y = (a, b) if t[(k + 1) % 3] == b else (b, a)
            c = next(v for v in t if v != x and v != y)
            self.put(i, (x, m, c))
            self.add((m, y, c), self.reg[i])
        if to is not None:
            if self.outline(a, m):
                return False
            tris = [self.tri(i) for i in sorted(self.star[m])]
            old = [self.normal(t) for t in tris]
            self.move(m, to)
            if not self.upright(tris, old):
                return False
        for _ in range(_SPLIT_FLIPS):
            for i in sorted(self.star[m]):
                t = self.tri(i)
                k = (t.index(m) + 1) % 3            # the edge facing m
                got = self.beside(t[k], t[(k + 1) % 3])
                if len(got) != 2 or self.reg[got[0]] != self.reg[got[1]]:
                    continue
                j = got[0] if got[1] == i else got[1]
                before = min(self.ang[i], self.ang[j])
                mark = self.mark()
                if self.flip(i, k) and min(self.ang[i], self.ang[j]) > before + 1e-9:
                    break
                self.undo(mark)
            else:
                break
        return True


def _thin(seen: Seen) -> tuple[int, int]:
    """How many of ``seen`` are thin in free regions, and in all."""
    return sum(a < _BELOW and free for a, free in seen), sum(a < _BELOW for a, _ in seen)


def _smallest(seen: Seen) -> tuple[float, float]:
    """The smallest angle of ``seen`` in free regions, and in all."""
    return (min((a for a, free in seen if free), default=180.0), min((a for a, _ in seen), default=180.0))


def _better(old: Seen, new: Seen) -> bool:
    """Whether triangles ``new`` replacing ``old`` leave fewer thin ones in free regions; or as many
    and fewer in all; or as many of both and a larger smallest angle (``_wider``)."""
    thin_old, thin_new = _thin(old), _thin(new)
    if thin_new != thin_old:
        return thin_new < thin_old
    return _wider(old, new)


def _wider(old: Seen, new: Seen) -> bool:
    """Whether triangles ``new`` replacing ``old`` have a larger smallest angle in free regions, or
    the same and a larger one in all."""
    (free_old, all_old), (free_new, all_new) = _smallest(old), _smallest(new)
    if free_new > free_old + 1e-9 or free_old > free_new + 1e-9:
        return free_new > free_old + 1e-9
    return all_new > all_old + 1e-9


def _key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def mend(points: np.ndarray, triangles: np.ndarray, regions: np.ndarray, fixed: int, *,
         meshing: int = 6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(points, triangles, regions)`` of a watertight mesh whose first ``fixed`` points are the
    surface's vertices, with its thin triangles mended (the module docstring). Only the triangles
    within ``_NEAR`` rings of a thin one take part; the points on that patch's rim stay. Triangles
    stay grouped region after region, in their order, each region's new ones after them; points the
    mending removed are dropped, the others keep their order. ``meshing`` 7 mends as 6 does, but a
    thin triangle of a region with a corner under ``_BELOW`` degrees (``pinched``) counts after those
    of free regions, the rounds go on until nothing changes, a last try is repeated while it changes
    something, and a side point's straightness is judged by its distance from the line; meshing 8
    also splits the longer side of a thin triangle's corner and tries two steps (the module
    docstring)."""
    angles = triangle_min_angles(points, triangles)
    thin = angles < _BELOW
    if not thin.any():
        return points, triangles, regions
    near = thin.copy()
    for _ in range(_NEAR):
        near = np.asarray(np.isin(triangles, np.unique(triangles[near])).any(axis=1))
    used = np.unique(triangles[near])
    rim = np.intersect1d(used, triangles[~near])
    frozen = set(rim.tolist())
    local = np.flatnonzero(near)
    pts = {v: (x, y, z) for v, (x, y, z) in zip(used.tolist(), points[used].tolist(), strict=True)}
    mesh = _Mesh(pts, triangles[local], regions[local], angles[local], frozen, fixed, len(points),
                 pinched(points, triangles, regions) if meshing >= 7 else frozenset(), meshing >= 7,
                 meshing >= 8)
    _rounds(mesh, _ROUNDS[meshing])
    _last_try(mesh, again=meshing >= 7)
    if meshing >= 8:
        _two_steps(mesh)
    alive = [i for i, t in enumerate(mesh.tris) if t is not None]
    slot = np.concatenate([np.flatnonzero(~near),
                           np.where(np.asarray(alive) < len(local), local[np.minimum(alive, len(local) - 1)],
                                    len(triangles) + np.asarray(alive))])
    mended = np.asarray([mesh.tris[i] for i in alive], dtype=np.int64).reshape(-1, 3)
    tris = np.concatenate([triangles[~near], mended])
    regs = np.concatenate([regions[~near], np.asarray([mesh.reg[i] for i in alive], dtype=np.int64)])
    order_ = np.lexsort((slot, regs))
    tris, regs = tris[order_], regs[order_]
    out = np.concatenate([points, np.zeros((mesh.n_points - len(points), 3))])
    for v, p in mesh.pts.items():
        out[v] = p
    keep = np.ones(len(out), dtype=bool)
    keep[fixed:] = False
    keep[np.unique(tris)] = True
    index = np.cumsum(keep) - 1
    return out[keep], index[tris], regs


def pinched(points: np.ndarray, triangles: np.ndarray, regions: np.ndarray) -> frozenset[int]:
    """The regions with a corner under ``_BELOW`` degrees in space (the sum of the region's triangle
    angles at a point of its outline): every mesh of such a region has a thin triangle there."""
    if not len(triangles):
        return frozenset()
    p = points[triangles]
    # a corner of a degenerate triangle counts 90 degrees: it never makes a region pinched
    at = np.stack([_between(p[:, (k + 1) % 3] - p[:, k], p[:, (k + 2) % 3] - p[:, k], 90.0)
                   for k in range(3)], axis=1)
    span = int(triangles.max()) + 1
    corner = np.repeat(regions.astype(np.int64), 3) * span + triangles.reshape(-1)
    keys, index = np.unique(corner, return_inverse=True)
    sums = np.bincount(index.reshape(-1), weights=at.reshape(-1), minlength=len(keys))
    return frozenset(np.unique(keys[sums < _BELOW] // span).tolist())


_CHECKED = ("flip", "collapse", "relax")   # operations that judge their own triangles first (``check``)


def _rounds(mesh: _Mesh, rounds: int) -> None:
    """The rounds: thin triangles tried thinnest first, each round after the first only those beside
    what changed; a region's are left once ``_GIVE_UP`` in a row were tried in vain."""
    dirty: set[int] | None = None    # after the first round: the points round what an operation changed
    failed: dict[int, int] = {}      # each region's thin triangles tried in a row and left as they were
    for _ in range(rounds):
        order = sorted((a, i) for i, a in enumerate(mesh.ang)
                       if a < _BELOW and (t := mesh.tris[i]) is not None
                       and (dirty is None or set(t) & dirty))
        dirty = set()
        for _, i in order:
            if mesh.tris[i] is None or mesh.ang[i] >= _BELOW or _at_corner(mesh, i) \
                    or failed.get(mesh.reg[i], 0) >= _GIVE_UP:
                continue
            if _mend_one(mesh, i):
                failed[mesh.reg[i]] = 0
                for j, old, _a in mesh.log:
                    if j >= 0:
                        dirty.update(mesh.tris[j] or ())
                        dirty.update(cast("Tri | None", old) or ())
            else:
                failed[mesh.reg[i]] = failed.get(mesh.reg[i], 0) + 1
            del mesh.log[:]
        if not dirty:
            break


def _few_left(mesh: _Mesh, free: bool = False) -> list[int]:
    """The thin triangles, in index order, of the regions with at most ``_FEW`` left (``free``: of
    the free regions only): those a last, slower try is spent on."""
    left: dict[int, list[int]] = {}
    for i, a in enumerate(mesh.ang):
        if a < _BELOW and mesh.tris[i] is not None and (not free or mesh.free(i)):
            left.setdefault(mesh.reg[i], []).append(i)
    return sorted(i for few in left.values() if len(few) <= _FEW for i in few)


def _last_try(mesh: _Mesh, again: bool = False) -> None:
    """A slower try for each thin triangle of a region with at most ``_FEW`` left (``_mend_one``'s
    ``last``, else ``widen``; ``again``: up to ``_AGAIN`` times while the triangle stays thin and a
    try changed something, since a wider triangle may open a repair that the thinner one did not, and
    up to ``_AGAIN`` passes while a pass changed something, since a repair may leave a new thin
    triangle beside it)."""
    for _ in range(_AGAIN if again else 1):
        changed_any = False
        for i in _few_left(mesh):
            for _ in range(_AGAIN if again else 1):
                if mesh.tris[i] is None or mesh.ang[i] >= _BELOW or _at_corner(mesh, i):
                    break
                changed = _mend_one(mesh, i, last=True) or _mend_one(mesh, i, last=True, widen=True)
                del mesh.log[:]
                changed_any = changed_any or changed
                if not changed:
                    break
        if not changed_any:
            break


def _two_steps(mesh: _Mesh) -> None:
    """For each thin triangle left in a free region with at most ``_FEW`` thin ones (meshing 8): an
    edge round its points flipped whatever that does, or a point beside it moved by a compass
    search, then the triangle and what the first step touched mended as a last try does; the first
    such pair that is better is kept. A triangle among others only just over ``_BELOW`` degrees is
    mended by no one step: each takes one of them under it."""
    for i in _few_left(mesh, free=True):
        if mesh.tris[i] is None or mesh.ang[i] >= _BELOW or _at_corner(mesh, i):
            continue
        t = mesh.tri(i)
        firsts: list[tuple[str, tuple[Any, ...]]] = \
            [("flip", (j, k)) for j in sorted({j for v in t for j in mesh.star[v]}) for k in range(3)]
        firsts += [("search", (v,)) for v in sorted(set().union(*(mesh.neighbours(v) for v in t)) - set(t))]
        for name, args in firsts:
            mark = mesh.mark()
            if getattr(mesh, name)(*args, **({"check": False} if name == "flip" else {})):
                for j in [i, *(j for j in mesh.touched(mark) if j != i)]:
                    if mesh.tris[j] is not None and mesh.ang[j] < _BELOW:
                        _mend_one(mesh, j, deep=j == i, last=True)
                if mesh.better(mark):
                    del mesh.log[:]
                    break
            mesh.undo(mark)


def _corner_split(mesh: _Mesh, i: int, apex: int) -> list[tuple[str, tuple[Any, ...]]]:
    """Where thin triangle ``i``'s smallest angle is at ``apex``, a point of its region's outline
    with two sides there of unequal length: the longer side split at the shorter one's length from
    the apex (meshing 8). A corner just under twice ``_BELOW`` degrees split by an edge inside it
    needs a point there so that one triangle spans the corner: 14.6 + 15.0 degrees became one of
    29.6."""
    region = mesh.reg[i]
    on = sorted(x for x in mesh.neighbours(apex) if mesh.outline(apex, x)
                and any(mesh.reg[j] == region for j in mesh.beside(apex, x)))
    if len(on) != 2:
        return []
    (near, _), (far, x) = sorted((math.dist(mesh.pts[apex], mesh.pts[v]), v) for v in on)
    if far <= near * (1.0 + 1e-6):
        return []
    return [("split", (apex, x, near / far))]


def _sides(mesh: _Mesh, t: Tri) -> tuple[list[float], list[int]]:
    """Triangle ``t``'s squared side lengths (side k from t[k] to t[k + 1]) and its sides from the
    shortest, which its smallest angle faces."""
    p = [mesh.pts[v] for v in t]
    length = [dot(d, d) for d in ((p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]),
                                   (p[2][0] - p[1][0], p[2][1] - p[1][1], p[2][2] - p[1][2]),
                                   (p[0][0] - p[2][0], p[0][1] - p[2][1], p[0][2] - p[2][2]))]
    return length, sorted(range(3), key=lambda k: (length[k], k))


def _at_corner(mesh: _Mesh, i: int) -> bool:
    """Whether thin triangle ``i``'s smallest angle is a corner of its region's outline (both its
    sides there are on the outline): nothing mends that."""
    t = mesh.tri(i)
    k = _sides(mesh, t)[1][0]
    apex = t[(k + 2) % 3]
    return mesh.outline(apex, t[k]) and mesh.outline(apex, t[(k + 1) % 3])


def _mend_one(mesh: _Mesh, i: int, deep: bool = True, last: bool = False, widen: bool = False) -> bool:
    """Try the operations on thin triangle ``i`` in turn; keep the first that is better. ``deep``:
    splits too (last), and after a split the thin triangles it touched are mended (not deep) before
    the whole is judged. ``last``: compass searches too, and after every operation the thin
    triangles it touched are mended before the whole is judged, so that a repair of two steps is
    found; ``widen``: the operation is taken whatever it does to its own triangles, and what it
    touched is mended for its worst angle (a degenerate triangle flipped into two thin ones, which
    a move of their apex then widens)."""
    t = mesh.tri(i)
    length, edges = _sides(mesh, t)
    tries: list[tuple[str, tuple[Any, ...]]] = [("flip", (i, k)) for k in range(3)]
    for k in edges:
        a, b = t[k], t[(k + 1) % 3]
        tries += [("collapse", (a, b)), ("collapse", (b, a))]
    tries += [("relax", (v,)) for v in t]
    if last:
        tries += [("search", (v,)) for v in t]
    short = t[edges[0]], t[(edges[0] + 1) % 3]
    if last and deep and mesh.corners:
        tries += _corner_split(mesh, i, t[(edges[0] + 2) % 3])
    if deep:
        k = edges[2]
        tries.append(("split", (t[k], t[(k + 1) % 3], 0.5, circumcentre(*(mesh.pts[v] for v in t)))))
    for k in (edges[2], edges[1]) if deep else ():
        a, b = t[k], t[(k + 1) % 3]
        tries.append(("split", (a, b, 0.5)))
        if length[k] > 4.0 * length[edges[0]]:     # grade it from the end it shares with the shortest
            f = math.sqrt(length[edges[0]] / length[k])
            tries.append(("split", (a, b, f) if a in short else (b, a, f)))
    def attempt(name: str, args: tuple[Any, ...], mark: tuple[int, int, int]) -> bool:
        if not getattr(mesh, name)(*args, **({"check": False} if widen and name in _CHECKED else {})):
            return False
        if deep and (last or name == "split"):     # judged once what it touched is mended too
            mesh.judge = _wider if widen else _better
            for j in mesh.touched(mark):
                if mesh.tris[j] is not None and mesh.ang[j] < _BELOW:
                    _mend_one(mesh, j, deep=False, last=widen)
            mesh.judge = _better
        return mesh.better(mark)

    best: tuple[tuple[int, int, float, float], int] | None = None     # last: the best of them all is taken
    for k, (name, args) in enumerate(tries):
        mark = mesh.mark()
        if attempt(name, args, mark):
            if not (last and deep):
                return True
            old, new = mesh.changed(mark)
            (free_old, all_old), (free_new, all_new) = _thin(old), _thin(new)
            (low_old, lowest_old), (low_new, lowest_new) = _smallest(old), _smallest(new)
            gain = (free_old - free_new, all_old - all_new, low_new - low_old, lowest_new - lowest_old)
            if best is None or gain > best[0]:
                best = gain, k
        mesh.undo(mark)
    if best is None:
        return False
    return attempt(*tries[best[1]], mesh.mark())
