"""The surface map (journal Definition 3): vertices, edges and regions, as immutable numpy arrays.

A ``Surface`` is what growth hands to fitness and export: vertex positions, masses and cut-off flags,
edges as (start, end) pairs with their labels and ages, and regions as vertex cycles, each traversed
counter-clockwise about the surface's normal (the seed's +z for a seed in the xy plane). The outer
boundary (``perimeter()``) is not a region. Derived values (triangles, adjacency) are computed once
and cached.
"""

from __future__ import annotations

import functools
import hashlib

import numpy as np

from genr8_dist.errors import GrowthError

__all__ = ["Surface"]


def _frozen(a: np.ndarray, dtype) -> np.ndarray:
    out = np.ascontiguousarray(a, dtype=dtype)
    out.setflags(write=False)
    return out


class Surface:
    """A valid map after a derivation step: ``vertices`` (V, 3), ``edges`` (E, 2), ``labels``, ``ages``
    (E,), ``regions`` (list of vertex cycles), ``masses`` (V,), ``stopped`` (V,) cut-off vertices.

    ``region_offsets`` (F+1,) and ``region_vertices`` hold the same cycles flat: region f is
    ``region_vertices[region_offsets[f]:region_offsets[f+1]]``.
    """

    def __init__(self, vertices: np.ndarray, edges: np.ndarray, labels: np.ndarray, ages: np.ndarray,
                 region_offsets: np.ndarray, region_vertices: np.ndarray, perimeter: np.ndarray,
                 masses: np.ndarray | None = None, stopped: np.ndarray | None = None) -> None:
        self.vertices = _frozen(np.reshape(vertices, (-1, 3)), np.float64)
        n = len(self.vertices)
        self.edges = _frozen(np.reshape(edges, (-1, 2)), np.int64)
        self.labels = _frozen(labels, np.int64)
        self.ages = _frozen(ages, np.int64)
        self.region_offsets = _frozen(region_offsets, np.int64)
        self.region_vertices = _frozen(region_vertices, np.int64)
        self._perimeter = _frozen(perimeter, np.int64)
        self.masses = _frozen(np.ones(n) if masses is None else masses, np.float64)
        self.stopped = _frozen(np.zeros(n, bool) if stopped is None else stopped, bool)

    # -- sizes -----------------------------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return len(self.vertices)

    @property
    def n_edges(self) -> int:
        """Number of edges."""
        return len(self.edges)

    @property
    def n_regions(self) -> int:
        """Number of regions (faces inside the outer boundary)."""
        return len(self.region_offsets) - 1

    def __repr__(self) -> str:
        return (f"Surface(vertices={self.n_vertices}, edges={self.n_edges}, "
                f"regions={self.n_regions})")

    # -- regions and boundary ----------------------------------------------------------------------
    @functools.cached_property
    def regions(self) -> list[np.ndarray]:
        """Each region's vertex cycle (counter-clockwise about the surface normal)."""
        return np.split(self.region_vertices, self.region_offsets[1:-1]) if self.n_regions else []

    @functools.cached_property
    def region_sizes(self) -> np.ndarray:
        """Number of vertices (= edges) around each region."""
        return np.diff(self.region_offsets)

    def perimeter(self) -> np.ndarray:
        """The vertex cycle of the outer boundary, counter-clockwise like the regions."""
        return self._perimeter

    @functools.cached_property
    def perimeter_mask(self) -> np.ndarray:
        """(V,) True for vertices on the outer boundary."""
        mask = np.zeros(self.n_vertices, dtype=bool)
        mask[self._perimeter] = True
        mask.setflags(write=False)
        return mask

    @functools.cached_property
    def centre(self) -> np.ndarray:
        """The mean of the vertex positions (the centre growth scales away from)."""
        return self.vertices.mean(axis=0) if self.n_vertices else np.zeros(3)

    def mirror_line(self, tolerance: float = 1e-6) -> np.ndarray | None:
        """A line of symmetry: the unit xy direction ``u`` of a vertical plane through the centre that
        maps every vertex onto a vertex (within ``tolerance`` x the surface's extent) and every edge
        onto an edge (vertices at one place count as one point), or None.

        A mirror plane of a point set passes through its centre, and maps the vertices farthest from
        the vertical axis through the centre onto each other; so the candidates are the lines through
        one such vertex ``v`` and the bisectors of ``v`` and each other one.
        """
        n = self.n_vertices
        if n < 2:
            return np.array([1.0, 0.0]) if n else None
        from scipy.spatial import cKDTree

        rel = self.vertices - self.centre
        extent = float(np.max(np.abs(rel))) or 1.0
        tol = tolerance * extent
        radius = np.hypot(rel[:, 0], rel[:, 1])
        far = int(np.argmax(radius))
        if radius[far] <= tol:
            return np.array([1.0, 0.0])  # every vertex on the vertical axis
        v = rel[far, :2]
        candidates = [v]
        for w in rel[np.abs(radius - radius[far]) <= tol, :2]:
            if np.linalg.norm(w - v) > tol:
                candidates.append(v + w if np.linalg.norm(v + w) > tol else np.array([-v[1], v[0]]))
        tree = cKDTree(rel)
        # vertices at one place (a successor whose lines cross) count as one point
        first = np.array([min(near) for near in tree.query_ball_point(rel, tol)], dtype=np.int64)

        def edge_keys(ids: np.ndarray) -> np.ndarray:
            ends = np.sort(first[ids[self.edges]], axis=1)
            ends = ends[ends[:, 0] != ends[:, 1]]
            return np.unique(ends[:, 0] * n + ends[:, 1])

        keys = edge_keys(np.arange(n))
        for u in candidates:
            u = u / np.linalg.norm(u)
            mirrored = rel.copy()
            mirrored[:, :2] = 2.0 * (rel[:, :2] @ u)[:, None] * u - rel[:, :2]
            distance, image = tree.query(mirrored, distance_upper_bound=2.0 * tol)
            if np.all(distance <= tol) and np.array_equal(edge_keys(image), keys):
                return u
        return None

    # -- adjacency ---------------------------------------------------------------------------------
    @functools.cached_property
    def adjacency(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR neighbour lists ``(indptr, indices)``: the neighbours of v are
        ``indices[indptr[v]:indptr[v+1]]``, sorted."""
        n = self.n_vertices
        a = np.concatenate([self.edges[:, 0], self.edges[:, 1]])
        b = np.concatenate([self.edges[:, 1], self.edges[:, 0]])
        order = np.lexsort((b, a))
        a, b = a[order], b[order]
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(a, minlength=n), out=indptr[1:])
        indptr.setflags(write=False)
        b.setflags(write=False)
        return indptr, b

    def neighbours(self, v: int) -> np.ndarray:
        """The vertices joined to vertex ``v`` by an edge."""
        indptr, indices = self.adjacency
        return indices[indptr[v]:indptr[v + 1]]

    @functools.cached_property
    def degrees(self) -> np.ndarray:
        """Number of edges at each vertex."""
        return np.diff(self.adjacency[0])

    # -- triangles ---------------------------------------------------------------------------------
    def triangles(self) -> np.ndarray:
        """(T, 3) vertex indices covering every region: a fan for convex regions, ear clipping (in the
        region's best-fit plane) for the others; oriented like the regions."""
        return self._triangles

    @functools.cached_property
    def _triangles(self) -> np.ndarray:
        out: list[np.ndarray] = []
        sizes = self.region_sizes
        offsets = self.region_offsets
        pos = self.vertices
        convex = self._convex_regions()
        for m in np.unique(sizes):
            m = int(m)
            if m < 3:
                continue
            sel = np.flatnonzero((sizes == m) & convex)
            if len(sel):
                cyc = self.region_vertices[offsets[sel][:, None] + np.arange(m)]
                j = np.arange(1, m - 1)
                tri = np.stack([np.repeat(cyc[:, 0], m - 2), cyc[:, j].ravel(), cyc[:, j + 1].ravel()],
                               axis=1)
                out.append(tri)
        for f in np.flatnonzero(~convex & (sizes >= 3)):
            cyc = self.region_vertices[offsets[f]:offsets[f + 1]]
            out.append(_ear_clip(cyc, pos[cyc]))
        tri = np.zeros((0, 3), dtype=np.int64) if not out else np.concatenate(out).astype(np.int64)
        tri.setflags(write=False)
        return tri

    def _convex_regions(self) -> np.ndarray:
        """(F,) True where a region turns the same way at every corner about its own normal."""
        if self.n_regions == 0:
            return np.zeros(0, dtype=bool)
        rv = self.region_vertices
        offs = self.region_offsets
        sizes = np.diff(offs)
        region_of = np.repeat(np.arange(self.n_regions), sizes)
        idx = np.arange(len(rv))
        nxt = np.where(idx + 1 == offs[region_of + 1], offs[region_of], idx + 1)
        prv = np.where(idx == offs[region_of], offs[region_of + 1] - 1, idx - 1)
        p = self.vertices[rv]
        normal = np.zeros((self.n_regions, 3))
        cr = np.cross(p, self.vertices[rv[nxt]])
        for axis in range(3):
            normal[:, axis] = np.bincount(region_of, weights=cr[:, axis], minlength=self.n_regions)
        turn = np.cross(p - self.vertices[rv[prv]], self.vertices[rv[nxt]] - p)
        s = np.einsum("ij,ij->i", turn, normal[region_of])
        scale = np.einsum("ij,ij->i", normal, normal)[region_of]
        bad = s < -1e-12 * np.maximum(scale, 1e-300)
        return np.bincount(region_of, weights=bad, minlength=self.n_regions) == 0

    # -- checks ------------------------------------------------------------------------------------
    def validate(self, *, strict: bool = False) -> list[str]:
        """Problems that make this not a valid map (empty list when valid): edges out of range,
        loops or duplicates, dangling or isolated vertices, regions that are not closed cycles of
        edges, edges not bordered on both sides, Euler's V - E + F != 1 for a disc, non-finite
        positions. ``strict=True`` raises GrowthError instead of returning problems."""
        problems: list[str] = []
        n, e = self.n_vertices, self.edges
        if not np.all(np.isfinite(self.vertices)):
            problems.append("non-finite vertex positions")
        if len(e) and (e.min() < 0 or e.max() >= n):
            problems.append("edge endpoints out of range")
            return self._finish(problems, strict)
        if np.any(e[:, 0] == e[:, 1]):
            problems.append(f"{int(np.sum(e[:, 0] == e[:, 1]))} edges are loops")
        key = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
        if len(np.unique(key)) != len(key):
            problems.append("duplicate edges")
        deg = np.bincount(e.ravel(), minlength=n)
        if np.any(deg == 0):
            problems.append(f"{int(np.sum(deg == 0))} isolated vertices")
        if np.any(deg == 1):
            problems.append(f"{int(np.sum(deg == 1))} dangling edges (vertices of degree 1)")
        # every side of every edge is used exactly once by a region or by the perimeter
        sizes = self.region_sizes
        if np.any(sizes < 3):
            problems.append(f"{int(np.sum(sizes < 3))} regions with fewer than 3 vertices")
        if len(self._perimeter) < 3:
            problems.append(f"a perimeter of {len(self._perimeter)} vertices")
        rv = self.region_vertices
        if len(rv) and len(rv) == int(self.region_offsets[-1]):
            region_of = np.repeat(np.arange(self.n_regions), sizes)
            idx = np.arange(len(rv))
            nxt = np.where(idx + 1 == self.region_offsets[region_of + 1],
                           self.region_offsets[region_of], idx + 1)
            outer = self._perimeter[::-1]
            starts = np.concatenate([rv, outer])
            ends = np.concatenate([rv[nxt], np.roll(outer, -1)])
            skey = starts * n + ends
            directed = np.concatenate([e, e[:, ::-1]])
            dkey = directed[:, 0] * n + directed[:, 1]
            not_edges = ~np.isin(skey, dkey)
            if np.any(not_edges):
                problems.append(f"{int(np.sum(not_edges))} face sides are not edges "
                                "(a region is not a closed cycle of edges)")
            uniq, counts = np.unique(skey, return_counts=True)
            if np.any(counts > 1):
                problems.append(f"{int(np.sum(counts > 1))} edge sides used by two faces")
            orphan = ~np.isin(dkey, uniq)
            if np.any(orphan):
                problems.append(f"{int(np.sum(orphan))} edge sides belong to no face")
        elif len(rv) != int(self.region_offsets[-1]):
            problems.append("region offsets do not match the region vertices")
        euler = n - len(e) + self.n_regions
        if euler != 1:
            problems.append(f"Euler characteristic V - E + F = {euler}, not 1 (a disc)")
        return self._finish(problems, strict)

    @staticmethod
    def _finish(problems: list[str], strict: bool) -> list[str]:
        if strict and problems:
            raise GrowthError("invalid surface map: " + "; ".join(problems))
        return problems

    def digest(self) -> str:
        """Hex blake2b of the vertex positions' bytes: equal digests mean bit-identical growth."""
        return hashlib.blake2b(self.vertices.tobytes(), digest_size=16).hexdigest()


def _ear_clip(cycle: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Triangulate one simple polygon (vertex ids ``cycle`` at ``points``) by ear clipping in the plane
    of its Newell normal, testing each ear only against the reflex vertices; what is left when no ear
    can be found (a polygon that is not simple) is fanned."""
    normal = np.cross(points, np.roll(points, -1, axis=0)).sum(axis=0)
    norm = np.linalg.norm(normal)
    normal = np.array([0.0, 0.0, 1.0]) if norm < 1e-300 else normal / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(normal, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    px, py = points @ e1, points @ e2
    xs, ys = px.tolist(), py.tolist()
    n = len(cycle)
    nxt = [*range(1, n), 0]
    prv = [n - 1, *range(n - 1)]
    scale = max(float(np.ptp(px)), float(np.ptp(py)), 1e-300)
    eps = 1e-12 * scale * scale

    def turn(a: int, b: int, c: int) -> float:
        return (xs[b] - xs[a]) * (ys[c] - ys[a]) - (ys[b] - ys[a]) * (xs[c] - xs[a])

    reflex = np.array([turn(prv[i], i, nxt[i]) <= eps for i in range(n)], dtype=bool)
    ridx = np.flatnonzero(reflex)
    dirty = False
    tris: list[tuple[int, int, int]] = []
    remaining, i, misses = n, 0, 0
    while remaining > 3 and misses <= remaining:
        a, c = prv[i], nxt[i]
        ear = not reflex[i] and turn(a, i, c) > eps
        if ear:
            if dirty:
                ridx = np.flatnonzero(reflex)
                dirty = False
            q = ridx[(ridx != a) & (ridx != c)]
            if len(q):
                qx, qy = px[q], py[q]
                d1 = (xs[i] - xs[a]) * (qy - ys[a]) - (ys[i] - ys[a]) * (qx - xs[a])
                d2 = (xs[c] - xs[i]) * (qy - ys[i]) - (ys[c] - ys[i]) * (qx - xs[i])
                d3 = (xs[a] - xs[c]) * (qy - ys[c]) - (ys[a] - ys[c]) * (qx - xs[c])
                ear = not bool(np.any((d1 >= -eps) & (d2 >= -eps) & (d3 >= -eps)))
        if not ear:
            i = c
            misses += 1
            continue
        tris.append((a, i, c))
        nxt[a], prv[c] = c, a
        remaining -= 1
        for v in (a, c):
            if reflex[v] and turn(prv[v], v, nxt[v]) > eps:
                reflex[v] = False
                dirty = True
        i, misses = a, 0
    rest = [i]
    j = nxt[i]
    while j != i and len(rest) < remaining:
        rest.append(j)
        j = nxt[j]
    for k in range(1, len(rest) - 1):
        tris.append((rest[0], rest[k], rest[k + 1]))
    return cycle[np.array(tris, dtype=np.int64).reshape(-1, 3)]
