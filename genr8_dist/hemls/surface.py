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
import math
from collections.abc import Callable
from types import ModuleType
from typing import TYPE_CHECKING, cast

import numpy as np

from genr8_dist.errors import GrowthError
from genr8_dist.hemls._kernels import KernelSwitch

if TYPE_CHECKING:
    import numpy.typing as npt

    from genr8_dist.hemls.meshing import Mesh

__all__ = ["Surface"]


def _frozen(a: np.ndarray, dtype: npt.DTypeLike) -> np.ndarray:
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
                 masses: np.ndarray | None = None, stopped: np.ndarray | None = None,
                 meshing: int | None = None) -> None:
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
        from genr8_dist.hemls.meshing import MESHING, check_meshing

        self.meshing = MESHING if meshing is None else check_meshing(meshing)

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
                return cast(np.ndarray, u)
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
        """(T, 3) vertex indices covering every region with ``m - 2`` triangles for ``m`` vertices (no
        new vertex), oriented like the regions, region after region; no triangle has zero area where
        the region can be cut without one (``triangulate_polygons``)."""
        return self._triangles

    @functools.cached_property
    def _triangles(self) -> np.ndarray:
        tri = triangulate_polygons(self.vertices, self.region_offsets, self.region_vertices)
        tri.setflags(write=False)
        return tri

    def with_meshing(self, meshing: int) -> Surface:
        """This map (the same arrays) cut by meshing version ``meshing`` (``hemls.meshing``): what a
        run's stored meshing gives its regrown surfaces."""
        if int(meshing) == self.meshing:
            return self
        return Surface(self.vertices, self.edges, self.labels, self.ages, self.region_offsets,
                       self.region_vertices, self._perimeter, self.masses, self.stopped, meshing=meshing)

    def mesh(self) -> Mesh:
        """The triangle mesh exports, pictures and the studio use, cut by this surface's ``meshing``
        (``hemls.meshing``): points (the vertices first, then any meshing added), triangles, the region
        of each triangle."""
        return self._mesh

    @functools.cached_property
    def _mesh(self) -> Mesh:
        from genr8_dist.hemls.meshing import mesh_surface

        return mesh_surface(self, self.meshing, cut=triangulate_polygons)

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



# -- triangulating regions ---------------------------------------------------------------------------
#
# A region is a cycle of m vertices, nearly planar, often non-convex after growth, and its straight
# sides carry runs of collinear vertices (a side split by every derivation step). A fan from one
# corner cuts such a region into zero-area triangles between collinear neighbours. Instead each region
# is cut into m - 2 triangles on its own vertices so that no triangle is degenerate where that is
# possible and thin triangles are avoided:
#
# - regions of at most ``_EXACT_MAX`` vertices (nearly all): the triangulation with the least total
#   ``1 / quality`` of its triangles (quality = 4 sqrt(3) area / sum of squared sides, 1 for an
#   equilateral triangle, 0 for a degenerate one; measured in 3D, on the triangles that are exported),
#   among those whose triangles all turn counter-clockwise in the region's best-fit plane (so lie
#   inside it): the classical O(m^3) dynamic programme over sub-polygons, run with numpy on all
#   regions of about one size at once;
# - larger regions (nearly all of them straight sides carrying long collinear runs): the straight
#   corners are set aside and the true corners triangulated as above (or, past ``_EXACT_MAX`` true
#   corners, by ear clipping and flips: see ``_clip_and_flip``); then each triangle whose sides carry
#   set-aside vertices is cut again without degenerate triangles: a fan from the corner opposite the
#   one side that carries them, a strip between the two sides that do, or, when all three do, a cut
#   from the middle vertex of the longest side to the opposite corner first; then flips to the
#   constrained Delaunay triangulation and flips that lower the programme's cost, at most
#   ``_FLIPS_PER_TRIANGLE`` edge tests per triangle each. Linear in m beyond the true corners'
#   programme, so a region of thousands of vertices costs milliseconds, not seconds.
#
# With numba (the ``fast`` extra) the loops run as compiled kernels (``_compiled``) that repeat the
# code below operation for operation, so the triangles are the same bit for bit, about 6x faster.

_EXACT_MAX = 64          # regions up to this many vertices get the exact best triangulation
_QUALITY_FLOOR = 1e-9    # a triangle of lower quality costs as much as a degenerate one
_OUTSIDE = 1e12          # extra cost of a triangle not counter-clockwise in the region's plane
_EPS = 1e-10             # tolerance of orientation tests in coordinates scaled to the region's extent
_WASTE = 1.5             # polygons solved together: padded work at most this x their own ...
_CALL = 5_000            # ... plus about what one more call costs, in triangles
_FLIPS_PER_TRIANGLE = 16  # edges tested for a flip per triangle of a large region, at most (linear)
_CHUNK = 250_000         # elements of the (regions, triangles) cost arrays handled at once


def _check_kernels(module: ModuleType) -> None:
    assert (module.EXACT_MAX, module.QUALITY_FLOOR, module.OUTSIDE, module.EPS) == (
        _EXACT_MAX, _QUALITY_FLOOR, _OUTSIDE, _EPS)


#: The compiled kernels load once a process has triangulated this many region vertices with the
#: reference code (about what loading them costs: ~0.4 s CPU), so a short run does not pay for numba
#: and a long one pays about twice the least it could (``_kernels.KernelSwitch``).
KERNELS = KernelSwitch("genr8_dist.hemls._compiled", 20_000, _check_kernels)
_load_kernels = KERNELS.load
_kernels = KERNELS.kernels


def triangulate_polygons(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray) -> np.ndarray:
    """(T, 3) triangles of ``vertices`` covering each polygon ``cycles[offsets[f]:offsets[f + 1]]``
    with ``m - 2`` triangles (polygons of fewer than 3 vertices get none), in polygon order and
    oriented like the polygons; deterministic. See the comment above for the rule."""
    vertices = np.asarray(vertices, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.int64)
    cycles = np.asarray(cycles, dtype=np.int64)
    reference = KERNELS.reference_work < KERNELS.load_after
    tri = _triangulate(vertices, offsets, cycles)
    if reference:               # counted after the call, so that one call takes one path
        KERNELS.count(len(cycles))
    return tri


def _triangulate(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray) -> np.ndarray:
    """``triangulate_polygons`` of checked arrays."""
    sizes = np.diff(offsets)
    parts: list[np.ndarray] = []
    owners: list[np.ndarray] = []
    for f in np.flatnonzero(sizes > _EXACT_MAX):
        cyc = cycles[offsets[f]:offsets[f + 1]]
        parts.append(cyc[_large_polygon(vertices[cyc])])
        owners.append(np.full(len(cyc) - 2, f, dtype=np.int64))
    # the rest together, smallest first, in groups each padded to its largest by repeating a polygon's
    # last vertex (the programme's sub-polygons i..j of an m-gon never reach past m - 1); a group grows
    # while the padded work stays within _WASTE x the work itself plus what one more call would cost
    sel = np.flatnonzero((sizes >= 3) & (sizes <= _EXACT_MAX))
    sel = sel[np.argsort(sizes[sel], kind="stable")]
    while len(sel):
        m = sizes[sel]
        work = m * (m - 1) * (m - 2) // 6                       # triangles (i, k, j) of an m-gon
        padded = np.arange(1, len(sel) + 1) * work
        over = np.flatnonzero(padded > _WASTE * np.cumsum(work) + _CALL)
        group = sel[:max(int(over[0]) if len(over) else len(sel), 1)]
        sel = sel[len(group):]
        per = max(1, _CHUNK // max(1, len(_triples(int(sizes[group[-1]]))[0])))
        for lo in range(0, len(group), per):
            chunk = group[lo:lo + per]
            m = sizes[chunk]
            size = int(m[-1])
            pos = np.minimum(np.arange(size)[None, :], m[:, None] - 1)
            cyc = cycles[offsets[chunk][:, None] + pos]
            local = _best_triangulations(vertices[cyc], m)           # (R, size - 2, 3) positions
            used = np.arange(size - 2)[None, :] < (m - 2)[:, None]
            parts.append(cyc[np.arange(len(chunk))[:, None, None], local][used])
            owners.append(np.repeat(chunk, m - 2))
    if not parts:
        return np.zeros((0, 3), dtype=np.int64)
    tri = np.concatenate(parts)
    return np.ascontiguousarray(tri[np.argsort(np.concatenate(owners), kind="stable")], dtype=np.int64)


@functools.cache
def _triples(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The programme's triangles (i, k, j), 0 <= i < k < j < m, span j - i by span from 2, k fastest,
    as flat pair indices ``i*m + k``, ``k*m + j``, ``i*m + j``, ``j*m + i``, and per span the slice
    of them it takes."""
    ik, kj, ij, ji, spans = [], [], [], [], []
    start = 0
    for span in range(2, m):
        i = np.repeat(np.arange(m - span), span - 1)
        k = i + np.tile(np.arange(1, span), m - span)
        j = i + span
        ik.append(i * m + k)
        kj.append(k * m + j)
        ij.append(i * m + j)
        ji.append(j * m + i)
        spans.append((start, start + len(i)))
        start += len(i)
    if not spans:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty, empty, []
    out = tuple(np.concatenate(x) for x in (ik, kj, ij, ji))
    return out[0], out[1], out[2], out[3], spans


def _plane_coordinates(points: np.ndarray) -> np.ndarray:
    """(..., m, 2) coordinates of polygons ``points`` (..., m, 3) in the plane of their Newell normal,
    translated to their first vertex and scaled to unit extent; each polygon is counter-clockwise
    there (the Newell normal points to the side it turns about)."""
    normal = np.cross(points, np.roll(points, -1, axis=-2)).sum(axis=-2)
    length = np.linalg.norm(normal, axis=-1, keepdims=True)
    normal = np.where(length > 1e-300, normal / np.where(length > 1e-300, length, 1.0), [0.0, 0.0, 1.0])
    helper = np.where(np.abs(normal[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = np.cross(normal, helper)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(normal, e1)
    rel = points - points[..., :1, :]
    xy = np.stack([np.einsum("...mk,...k->...m", rel, e1), np.einsum("...mk,...k->...m", rel, e2)], -1)
    extent = np.abs(xy).max(axis=(-2, -1), keepdims=True)
    return xy / np.where(extent > 0, extent, 1.0)


def _pairwise(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, M, M) squared distances and (R, M, M) cross products ``p_a x p_b . normal`` in the plane of
    each polygon ``points`` (R, M, 3), in coordinates centred on its mean and scaled to unit extent:
    a triangle's turn about the Newell normal is a sum of three cross products."""
    rel = points - points.mean(axis=1, keepdims=True)
    rel /= np.maximum(np.abs(rel).max(axis=(1, 2), keepdims=True), 1e-300)     # unit extent
    x, y, z = rel[..., 0], rel[..., 1], rel[..., 2]
    xn, yn, zn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1), np.roll(z, -1, axis=1)
    normal = np.stack([(y * zn - z * yn).sum(1), (z * xn - x * zn).sum(1), (x * yn - y * xn).sum(1)], 1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)  # Newell's, unit
    d2 = np.sum((rel[:, :, None, :] - rel[:, None, :, :]) ** 2, axis=-1)
    nx, ny, nz = normal[:, None, 0], normal[:, None, 1], normal[:, None, 2]
    side = np.stack([y * nz - z * ny, z * nx - x * nz, x * ny - y * nx], -1)     # p_b x normal
    return d2, np.einsum("rak,rbk->rab", rel, side)


def _best_triangulations(points: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """(R, M - 2, 3) corner positions of the least-cost triangulation of each polygon ``points``
    (R, M, 3) of ``sizes`` (R,) vertices (padded to M by repeating the last; the first ``m - 2`` rows
    are the polygon's): the dynamic programme over sub-polygons i..j, each closed by a triangle
    (i, k, j). A triangle that is not counter-clockwise in the polygon's plane costs ``_OUTSIDE``:
    a triangulation whose triangles all are lies inside the polygon and covers it once (the winding
    number of a simple polygon is 1 inside, 0 outside), so no diagonal test is needed."""
    R, M, _ = points.shape
    d2, cr = _pairwise(points)
    kernels = _kernels()
    if kernels is not None:
        return cast(np.ndarray, kernels.best_triangulations(d2, cr, np.asarray(sizes, dtype=np.int64)))
    ik, kj, ij, ji, spans = _triples(M)
    d2, cr = d2.reshape(R, M * M), cr.reshape(R, M * M)
    a2, b2, c2 = d2[:, ik], d2[:, kj], d2[:, ij]
    sides = a2 + b2 + c2
    # Heron: 16 area^2 = sides^2 - 2 (a^4 + b^4 + c^4); cost = sides / (4 sqrt(3) area), floored
    a2 *= a2
    b2 *= b2
    c2 *= c2
    a2 += b2
    a2 += c2
    heron = np.multiply(sides, sides)
    a2 *= 2.0
    heron -= a2
    np.maximum(heron, 0.0, out=heron)
    np.sqrt(heron, out=heron)
    heron *= np.sqrt(3.0)
    np.maximum(heron, _QUALITY_FLOOR * sides, out=heron)
    cost = np.divide(sides, heron, out=np.full_like(sides, 1.0 / _QUALITY_FLOOR), where=heron > 0)
    turn = cr[:, ik]
    turn += cr[:, kj]
    turn += cr[:, ji]
    np.add(cost, _OUTSIDE, out=cost, where=turn <= _EPS)
    best = np.zeros((R, M * M))
    choice = np.zeros((R, M * M), dtype=np.int64)
    for span, (lo, hi) in enumerate(spans, start=2):
        total = (best[:, ik[lo:hi]] + best[:, kj[lo:hi]] + cost[:, lo:hi]).reshape(R, M - span, span - 1)
        at = ij[lo:hi:span - 1]
        arg = total.argmin(axis=2)
        best[:, at] = np.take_along_axis(total, arg[..., None], axis=2)[..., 0]   # the minimum
        choice[:, at] = arg + np.arange(1, M - span + 1)
    choice = choice.reshape(R, M, M)
    # read the triangles back, sub-polygon by sub-polygon, all polygons at once; the middle corners k
    # of a triangulation's triangles (i, k, j) are 1..m-2, each once, so k - 1 is a triangle's place
    rows = np.arange(R)
    lo_ = np.zeros(R, dtype=np.int64)
    hi_ = np.asarray(sizes, dtype=np.int64) - 1
    out = np.zeros((R, max(M - 2, 0), 3), dtype=np.int64)
    while len(rows):
        k = choice[rows, lo_, hi_]
        out[rows, k - 1, 0], out[rows, k - 1, 1], out[rows, k - 1, 2] = lo_, k, hi_
        left, right = k - lo_ >= 2, hi_ - k >= 2
        rows = np.concatenate([rows[left], rows[right]])
        lo_, hi_ = np.concatenate([lo_[left], k[right]]), np.concatenate([k[left], hi_[right]])
    return out


def _large_polygon(points: np.ndarray) -> np.ndarray:
    """(m - 2, 3) corner positions triangulating one polygon ``points`` (m, 3) of more than
    ``_EXACT_MAX`` vertices: its true corners triangulated, then the vertices of its straight runs
    brought back in by ``_cut`` (see the comment above ``_EXACT_MAX``)."""
    m = len(points)
    into = points - np.roll(points, 1, axis=0)
    out = np.roll(points, -1, axis=0) - points
    bend = np.linalg.norm(np.cross(into, out), axis=1)
    lengths = np.linalg.norm(into, axis=1) * np.linalg.norm(out, axis=1)
    straight = (bend <= 1e-9 * lengths) & (np.einsum("ij,ij->i", into, out) > 0)
    corners = np.flatnonzero(~straight)
    r = len(corners)
    if r < 3 or r == m:
        return _clip_and_flip(points)
    if r <= _EXACT_MAX:
        reduced = _best_triangulations(points[corners][None], np.array([r]))[0]
    else:
        reduced = _clip_and_flip(points[corners])
    kernels = _kernels()
    if kernels is not None:
        # 2.0 passed at run time: the reference's ``x ** 2`` is the C library's pow, not x * x
        cut_ = kernels.cut_runs(reduced, corners, points, 2.0)
        return _flipped(cut_, points, _plane_coordinates(points), kernels)
    pts = points.tolist()
    cut: list[tuple[int, int, int]] = []
    for tri in reduced.tolist():
        a, b, c = sorted(tri)
        # the boundary of this triangle with the set-aside vertices of its sides that are the
        # polygon's own sides (consecutive true corners), in the polygon's (counter-clockwise) order
        sides: list[list[int]] = []
        for i, j in ((a, b), (b, c), (c, a)):
            if j != (i + 1) % r:          # a diagonal, not one of the polygon's sides
                sides.append([])
                continue
            lo, hi = int(corners[i]), int(corners[j])
            sides.append([*range(lo + 1, hi if hi > lo else m), *range(0 if hi <= lo else hi, hi)])
        ring = [int(corners[a]), *sides[0], int(corners[b]), *sides[1], int(corners[c]), *sides[2]]
        at = {v: n for n, v in enumerate(ring)}
        local: list[tuple[int, int, int]] = []
        _cut(at[ring[0]], at[int(corners[b])], at[int(corners[c])],
             [at[v] for v in sides[0]], [at[v] for v in sides[1]], [at[v] for v in sides[2]],
             [pts[v] for v in ring], local)
        for u, v, w in map(sorted, local):          # in ring order: counter-clockwise
            cut.append((ring[u], ring[v], ring[w]))
    xy = _plane_coordinates(points)
    xs, ys = xy[:, 0].tolist(), xy[:, 1].tolist()
    budget = _FLIPS_PER_TRIANGLE * len(cut)
    _flip(cut, xs, ys, _delaunay_test(xs, ys), budget)
    _flip(cut, xs, ys, _cost_test(points), budget)
    return np.array(cut, dtype=np.int64).reshape(-1, 3)


def _cut(x: int, y: int, z: int, xy: list[int], yz: list[int], zx: list[int], pts: list[list[float]],
         out: list[tuple[int, int, int]]) -> None:
    """Triangles (unordered corner triples) covering triangle (x, y, z) whose sides carry the vertices
    ``xy``, ``yz``, ``zx`` (in order from the side's first corner), none of them degenerate."""
    sides = [(x, y, z, xy), (y, z, x, yz), (z, x, y, zx)]
    full = [n for n, s in enumerate(sides) if s[3]]
    if not full:
        out.append((x, y, z))
    elif len(full) == 1:                       # a fan from the corner opposite the one side
        s, t, o, run = sides[full[0]]
        seq = [s, *run, t]
        out.extend((o, seq[k], seq[k + 1]) for k in range(len(seq) - 1))
    elif len(full) == 3:                       # cut from the longest side's middle vertex first
        n = max(range(3), key=lambda k: len(sides[k][3]))
        s, t, o, run = sides[n]
        k = len(run) // 2
        _cut(s, run[k], o, run[:k], [], sides[(n + 2) % 3][3], pts, out)
        _cut(run[k], t, o, run[k + 1:], sides[(n + 1) % 3][3], [], pts, out)
    else:                                      # a strip between the two sides from their corner
        empty = ({0, 1, 2} - set(full)).pop()
        shared = sides[(empty + 2) % 3][0]     # the corner of the two sides that carry vertices
        before, after = sides[(empty + 1) % 3], sides[(empty + 2) % 3]
        q = [shared, *reversed(before[3]), before[0]]     # back along the side that ends at it
        p = [shared, *after[3], after[1]]                 # out along the side that starts at it

        def d2(u: int, v: int) -> float:     # not sum(): Python 3.12's compensates its rounding
            (ux, uy, uz), (vx, vy, vz) = pts[u], pts[v]
            return (ux - vx) ** 2 + (uy - vy) ** 2 + (uz - vz) ** 2

        out.append((shared, q[1], p[1]))
        i = j = 1
        while i < len(q) - 1 or j < len(p) - 1:
            if j == len(p) - 1 or (i < len(q) - 1 and d2(q[i + 1], p[j]) <= d2(q[i], p[j + 1])):
                out.append((q[i], q[i + 1], p[j]))
                i += 1
            else:
                out.append((q[i], p[j], p[j + 1]))
                j += 1


def _clip_and_flip(points: np.ndarray) -> np.ndarray:
    """(m - 2, 3) corner positions triangulating one large polygon ``points`` (m, 3): ear clipping in
    its best-fit plane (never at a straight or reflex corner, never over another vertex), then edge
    flips until every inner edge is locally Delaunay (the constrained Delaunay triangulation), then
    flips that lower the total cost the exact programme minimises, while any does.
    What is left when no ear can be found (a polygon that is not simple in that plane) is fanned."""
    xy = _plane_coordinates(points)
    kernels = _kernels()
    if kernels is not None:
        return _flipped(kernels.clip(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])),
                        points, xy, kernels)
    xs: list[float]
    ys: list[float]
    xs, ys = xy[:, 0].tolist(), xy[:, 1].tolist()
    px, py = xy[:, 0], xy[:, 1]
    n = len(points)
    nxt = [*range(1, n), 0]
    prv = [n - 1, *range(n - 1)]

    def turn(a: int, b: int, c: int) -> float:
        return (xs[b] - xs[a]) * (ys[c] - ys[a]) - (ys[b] - ys[a]) * (xs[c] - xs[a])

    reflex = np.array([turn(prv[i], i, nxt[i]) <= _EPS for i in range(n)], dtype=bool)
    ridx = np.flatnonzero(reflex)
    dirty = False
    tris: list[tuple[int, int, int]] = []
    remaining, i, misses = n, 0, 0
    while remaining > 3 and misses <= remaining:
        a, c = prv[i], nxt[i]
        ear = not reflex[i] and turn(a, i, c) > _EPS
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
                ear = not bool(np.any((d1 >= -_EPS) & (d2 >= -_EPS) & (d3 >= -_EPS)))
        if not ear:
            i = c
            misses += 1
            continue
        tris.append((a, i, c))
        nxt[a], prv[c] = c, a
        remaining -= 1
        for v in (a, c):
            if reflex[v] and turn(prv[v], v, nxt[v]) > _EPS:
                reflex[v] = False
                dirty = True
        i, misses = a, 0
    rest = [i]
    j = nxt[i]
    while j != i and len(rest) < remaining:
        rest.append(j)
        j = nxt[j]
    tris.extend((rest[0], rest[k], rest[k + 1]) for k in range(1, len(rest) - 1))
    _flip(tris, xs, ys, _delaunay_test(xs, ys), _FLIPS_PER_TRIANGLE * len(tris))
    _flip(tris, xs, ys, _cost_test(points), _FLIPS_PER_TRIANGLE * len(tris))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def _flipped(tris: np.ndarray, points: np.ndarray, xy: np.ndarray, kernels: ModuleType) -> np.ndarray:
    """``tris`` (T, 3) after the compiled flips: to the constrained Delaunay triangulation, then
    those that lower the cost, ``_FLIPS_PER_TRIANGLE`` edge tests per triangle each at most."""
    xs, ys = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    kernels.flip(tris, xs, ys, points, False, _FLIPS_PER_TRIANGLE * len(tris))
    kernels.flip(tris, xs, ys, points, True, _FLIPS_PER_TRIANGLE * len(tris))
    return tris


def _delaunay_test(xs: list[float], ys: list[float]) -> Callable[[int, int, int, int], bool]:
    """Whether to flip the edge (a, b) of counter-clockwise triangles (a, b, c) and (b, a, d): d lies
    inside the circumcircle of (a, b, c) (Lawson's flips, to the constrained Delaunay triangulation)."""

    def inside(a: int, b: int, c: int, d: int) -> bool:
        rows = []
        for v in (a, b, c):
            ux, uy = xs[v] - xs[d], ys[v] - ys[d]
            rows.append((ux, uy, ux * ux + uy * uy))
        (a1, a2, a3), (b1, b2, b3), (c1, c2, c3) = rows
        return a1 * (b2 * c3 - b3 * c2) - a2 * (b1 * c3 - b3 * c1) + a3 * (b1 * c2 - b2 * c1) > _EPS

    return inside


def _cost_test(points: np.ndarray) -> Callable[[int, int, int, int], bool]:
    """Whether flipping the edge (a, b) of triangles (a, b, c) and (b, a, d) to (a, d, c) and (d, b, c)
    lowers their total ``1 / quality`` in 3D (the exact programme's cost) by more than rounding."""
    p = points.tolist()
    root3 = math.sqrt(3.0)

    def cost(a: int, b: int, c: int) -> float:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = p[a], p[b], p[c]
        ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, cx - ax, cy - ay, cz - az
        wx, wy, wz = cx - bx, cy - by, cz - bz
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        sides = ux * ux + uy * uy + uz * uz + vx * vx + vy * vy + vz * vz + wx * wx + wy * wy + wz * wz
        quad = 2.0 * root3 * math.sqrt(nx * nx + ny * ny + nz * nz)      # 4 sqrt(3) area
        return sides / quad if quad > _QUALITY_FLOOR * sides else 1.0 / _QUALITY_FLOOR

    def cheaper(a: int, b: int, c: int, d: int) -> bool:
        before = cost(a, b, c) + cost(b, a, d)
        return cost(a, d, c) + cost(d, b, c) < before * (1.0 - 1e-12)

    return cheaper


def _flip(tris: list[tuple[int, int, int]], xs: list[float], ys: list[float],
          better: Callable[[int, int, int, int], bool], budget: int | None = None) -> None:
    """Flip, in place, inner edges (a, b) of counter-clockwise triangles ``tris`` (a, b, c), (b, a, d)
    to (c, d) while ``better(a, b, c, d)`` and the two make a strictly convex quadrilateral in the
    plane (so the new pair is counter-clockwise and covers the same ground); a bounded number of
    flips, every edge a flip touches tested again."""
    # directed edge (a, b) -> a * n + b; its triangle's third corner is found where it is stored
    n = len(xs)
    owner: dict[int, int] = {}
    for t, (a, b, c) in enumerate(tris):
        owner[a * n + b] = owner[b * n + c] = owner[c * n + a] = t
    stack = [divmod(k, n) for k in owner if k // n < k % n and (k % n) * n + k // n in owner]
    get = owner.get
    budget = 8 * len(tris) * len(tris) + 16 if budget is None else budget
    while stack and budget:
        budget -= 1
        a, b = stack.pop()
        t1, t2 = get(a * n + b), get(b * n + a)
        if t1 is None or t2 is None:
            continue
        u, v, w = tris[t1]
        c = w if u == a and v == b else u if v == a and w == b else v
        u, v, w = tris[t2]
        d = w if u == b and v == a else u if v == b and w == a else v
        # both new triangles counter-clockwise: (a, d, c) and (d, b, c) turn left in the plane
        xa, ya, xc, yc, xd, yd = xs[a], ys[a], xs[c], ys[c], xs[d], ys[d]
        if (xd - xa) * (yc - ya) - (yd - ya) * (xc - xa) <= _EPS:
            continue
        if (xs[b] - xd) * (yc - yd) - (ys[b] - yd) * (xc - xd) <= _EPS or not better(a, b, c, d):
            continue
        tris[t1], tris[t2] = (a, d, c), (d, b, c)
        del owner[a * n + b], owner[b * n + a]
        owner[a * n + d] = owner[d * n + c] = owner[c * n + a] = t1
        owner[d * n + b] = owner[b * n + c] = owner[c * n + d] = t2
        stack.extend([(a, d), (d, b), (b, c), (c, a)])
