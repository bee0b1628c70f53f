"""Meshing: the triangle mesh a surface map is exported, drawn and shown as, by version.

A surface map's regions are polygons (journal Definition 3), often non-convex, nearly planar but bent
by the environment, their straight sides carrying runs of collinear vertices. What a designer gets
(``genr8 grow -o``, ``genr8 show -o``, the pictures, the studio) is a triangle mesh of them, and how
it is cut is versioned, so that a run regrows its surfaces as it stored them:

- **meshing 1** (runs created before meshing was recorded): each region of ``m`` vertices cut into
  ``m - 2`` triangles on its own vertices (``Surface.triangles``; ``surface.triangulate_polygons``).
  Long thin regions and regions whose sides carry runs of vertices become fans of slivers.
- **meshing 2** (runs created in round 5, kept bit for bit): each region triangulated into
  well-shaped triangles with added points. Every map edge is first split into equal pieces no longer
  than the thinner of the two regions beside it is wide (``_SPACING`` x twice its area over its
  perimeter; at most ``_MAX_SPLIT`` pieces), so the two regions share the same points on it and the
  mesh stays watertight. Each region is then mapped to 2D in its best-fit plane (orthogonal
  projection onto the plane through its centroid normal to its Newell normal) and meshed there by
  Shewchuk's Triangle (the ``triangle`` package): the constrained Delaunay triangulation of its
  sides, refined with points inside it until no angle is below ``_MIN_ANGLE`` degrees (Ruppert's
  refinement). One free pass lets Triangle split the sides (those points then go on the map's edge,
  for both regions), the last keeps them whole. Each added point is lifted back to 3D by linear
  (barycentric) interpolation over the region's meshing-1 triangles mapped into the same plane, so
  the mesh lies on the surface meshing 1 gave. A region that is not a simple polygon in that plane
  (it folds over or touches itself, has a side of no length, or no area), or whose added points fall
  outside its meshing-1 triangles, is cut as meshing 1 cuts it, with the shared points on its sides.
- **meshing 3** (runs created in rounds 10 to 13, kept bit for bit): meshing 2 with two changes.
  - *A region that crosses itself in its best-fit plane is unrolled* (``_unfold``): its meshing-1
    triangles laid flat one by one across their shared diagonals, each keeping its three side
    lengths (a polygon's triangulation has a tree of diagonals, so this is well defined). A curved
    or bent region that overlaps itself in any plane lies flat so; it is meshed there and its points
    lifted through the same triangles, so inside each meshing-1 triangle the mesh keeps its angles
    in space. Only a region simple in neither chart is cut as meshing 1 cuts it.
  - *The sides' points are settled, not fixed after one pass*: passes repeat (``_PASSES`` at most)
    until no region's mesh puts a point on a side; each pass meshes again only the regions whose
    sides gained points. A region may split its own sides in ``_OWN_SPLITS`` passes (Triangle's
    refinement near a small corner would halve the sides there forever); after that it keeps them
    whole. Triangle marks side j of a ring j + 2, so a point on a side names it exactly. Meshing 2
    kept every side whole after one pass, so a side a neighbour split finely next to one it left
    coarse left thin triangles that Triangle may not repair (3.6% of the triangles of regions whose
    corners are all at least 20 degrees).

- **meshing 4** (runs created before meshing 5, kept bit for bit): meshing 3 with five changes.
  - *A curved region is unrolled first* (``_chart``): where its projection keeps less than 90% of
    its area (``_UNROLL_BELOW``: it slopes away from its plane), its unfolding is its chart when
    that is simple, its projection only when it is not. Each piece of the unfolding is one of its
    meshing-1 triangles laid flat with its side lengths, so a mesh made there keeps its angles in
    space; a projection shrinks whatever slopes away from the plane, and lifting back stretches it
    (a strip of a cylinder's wall turning 170 degrees: smallest angle 8 degrees projected, 28
    unrolled). A nearly flat region stays projected.
  - *A projected region spans its sides as a membrane* (``_membrane``): its added points, lifted
    onto its meshing-1 triangles, have their offsets from the ring's best-fit plane relaxed
    ``_MEMBRANE_PASSES`` times to their neighbours' mean. Meshing 1's fan of a bent polygon is a
    fan of slivers creased in space, and a mesh lifted onto it copies the creases as thin triangles
    (one bent 759-gon of a random default surface: 622 of its 4,145 triangles under 15 degrees).
  - *A needle whose refinement runs out of points keeps its sides whole* (``_NEEDLE``): a region
    with a corner under a hundredth of a degree in its chart whose Triangle call spends its whole
    point budget is meshed again at once with its sides whole, and keeps them so in later passes.
    Near such a corner the refinement splits the sides without end: under meshing 3 one corner of a
    millionth of a degree split them into 311,040 points in one pass, every neighbour inherited
    them, and the surface came out as millions of triangles, most of them thin. Wider corners are
    left to refine (guarded from 20 degrees, 98 random tiles surfaces had 0.97% of their triangles
    under 15 degrees, against 0.29%).
  - *A region simple in no chart is cut into pieces* (``_pieces``): one that overlaps itself both
    projected and unrolled (a strip winding past a full turn) is cut along a diagonal of its
    meshing-1 triangles, the most even one, and each half again while it is not simple, up to
    ``_PIECE_DEPTH`` cuts deep; the pieces are meshed as neighbouring regions (sharing the diagonal's
    points) and their triangles counted as the region's. Meshing 3 cut such a region as meshing 1
    does (108 random ``symmetric`` surfaces: 10 regions, 6.4% of all triangles under 15 degrees, 1.5%
    with the pieces).
  - *A long thin region gets the points it needs* (``_SHAPE_CAP``): every other region's budget
    grows by its shape, ``P^2 / A`` of its corners in its chart (about 4 L / w for a strip of
    length L and width w, the cells of its width it takes to cover it; 16 for a square), at most
    ``_SHAPE_CAP``. Under meshing 3's budget a strip 270 times as long as wide ran out of points
    with 1,112 of its 1,460 triangles thin; with 8,073 points it has none.

- **meshing 5** (runs created before meshing 6, kept bit for bit): meshing 4 with two changes.
  - *Each region's triangles are tidied in space once lifted* (``_tidy``): where one has an angle
    under ``_TIDY_BELOW`` degrees, edges inside the region are flipped and its added points moved to
    their neighbours' mean where that raises the smallest angle round them without turning a
    triangle over, the ring's points held so the region still meets its neighbours on them.
    Triangle's angles hold in the chart; lifting bends them across the creases of meshing 1's
    triangles and where a projected region slopes (60 random default genomes: 0.29% of the
    triangles of regions with corners of at least 20 degrees under 15 degrees, 0.17% tidied).
  - *Twin points on a side are one* (``_TWIN``): two regions splitting the same stretch of a shared
    side in one pass each place their point in their own chart, Triangle's concentric-shell splits
    then differ by about 1e-4 of the gap, far more than the 1e-9 tolerance on an edge's parameter,
    and both regions held a side 10,000 times shorter than its neighbours with needle-thin triangles
    on it. Points nearer than ``_TWIN`` of the larger gap beside them are merged.
  300 random genomes of each built-in universe: 0.04-0.61% of the triangles of regions whose corners
  are all at least 20 degrees under 15 degrees (meshing 4: 0.10-0.76%). What is left lies almost all
  in regions that cross themselves in their plane (a figure eight whose lobes turn opposite ways, a
  spike folded back over the region): any mesh of such a ring that lies on the region folds, and the
  triangles across the fold are flattened; no flip or move on the surface mends them. In those simple
  in their plane, 0.00-0.03% are left (60 genomes; meshing 4: 0.00-0.14%).
- **meshing 6**: meshing 5, then the whole surface's mesh mended across
  regions (``hemls.mending``). Inside one region nothing mends a thin triangle whose corners are its
  ring's points: a neighbour split the shared side finely beside a corner that the region, keeping
  its sides whole in its last pass, could not grade to match (a 64-degree corner with side points
  0.5e-3 and 2e-3 from it). The assembled mesh is one watertight mesh, so there edges inside a region
  are flipped, added points collapsed (a side's only along that side, so both regions lose it
  together), moved or slid along their side, and edges split (a side in both regions) then flipped
  round the new point, wherever that leaves fewer triangles under 15 degrees among those it touched.
  Every region keeps its outline, the surface its vertices. 60 random genomes of each built-in
  universe (``bench/meshing.py``): in regions whose outline does not cross itself and whose corners
  are all at least 20 degrees in their plane and in space, meshing 5 left 661 triangles under 15
  degrees (0.00-0.03%), meshing 6 leaves 5 (0.0000-0.0003%: 4 reversible, beside needle-thin
  neighbours, and 1 tiles); of all triangles, 0.14-5.25% were under 15 degrees, 0.01-0.58% are.
  Mending adds up to 80% to meshing 5's CPU (the most where regions fold over themselves: thousands
  of thin triangles, few of which anything mends).
- **meshing 7**: meshing 6, but mending counts the thin triangles of regions
  whose corners are all at least 15 degrees before those of regions with a sharper corner (a needle,
  any mesh of which has a thin triangle there), goes on with its rounds until nothing changes,
  repeats a last try while it changes something, and judges a side point straight by its distance
  from its neighbours' line, so a point beside a very short gap may slide or go (``hemls.mending``).
  Under 6, of the thin triangles left in regions with wide corners nearly all lay beside a needle:
  splitting the side they share gave the needle a thin triangle for the one it mended, and was
  undone; 4 rounds stopped repairs still spreading (one reversible surface: 209 thin triangles, 6
  in wide-cornered regions; 21 and 0 under 7); and a side point 2.4e-7 from the next, 1e-15 off its
  side's line by rounding, could neither slide nor go. 300 random genomes of each built-in universe
  (``bench/meshing.py``): in regions whose outline does not cross itself and whose corners are all at
  least 20 degrees in their plane and in space, meshing 6 left 87 triangles under 15 degrees,
  meshing 7 leaves 2 (tiles); of all triangles 0.02-0.57% were under 15 degrees, 0.01-0.49% are;
  CPU per surface up to about 25% more than meshing 6 (reversible 1.04 -> 1.27 s).
- **meshing 8** (new runs, ``MESHING``): meshing 7, but mending's last tries also split the longer
  side of a thin triangle's corner at the shorter one's length from it, and try two steps, an edge
  flipped whatever that does or a point beside the triangle moved, then what that left mended
  (``hemls.mending``). Meshing 7 left 2 triangles under 15 degrees in the regions counted above, both
  tiles: one at a corner of 29.6 degrees cut in two (14.6 + 15.0) by an edge to a point that could be
  neither flipped nor collapsed away, one of 8.7 degrees among triangles of 15.0-15.6 that every
  single change took under 15. Meshing 8 leaves none over the same 300 genomes of each universe, for
  the same CPU (within 3% either way).

Deterministic: the same map gives the same points and triangles bit for bit (Triangle uses exact
predicates and a fixed seed; everything else is numpy in a fixed order).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np

from genr8_dist.hemls.mending import dot, mend, triangle_min_angles
from genr8_dist.hemls.mending import normal as _normal
from genr8_dist.hemls.mending import smallest as _smallest
from genr8_dist.meshings import MESHING, MESHINGS, check_meshing

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ["MESHING", "MESHINGS", "Mesh", "check_meshing", "mesh_surface", "region_roundness",
           "triangle_min_angles"]

# MESHINGS, MESHING and check_meshing are declared below every layer (genr8_dist.meshings).

_MIN_ANGLE = 28.0   # Triangle's quality bound (degrees) inside each region
_SPACING = 2.0      # edge pieces at most this x the thinner neighbouring region's width (2 area/perimeter)
_MAX_SPLIT = 64     # pieces one map edge is split into, at most
_STEINER = 8         # points Triangle may add to a region: this x its ring's points ...
_STEINER_FLOOR = 256 # ... plus this many (a bound on the mesh's size where a region has tiny features)
_FREE_PASSES = 1     # passes in which Triangle may split the sides (their points then shared)
_SIMPLE_MAX = 4000  # regions of more vertices than this are cut as meshing 1 cuts them
_TOL = 1e-9         # tolerance of orientation tests in a region's plane, scaled to unit extent
_PASSES = 8         # meshing 3: passes settling the sides' points, at most ...
_OWN_SPLITS = 3     # ... in at most this many of which one region may split its own sides
_CHUNK = 1_000_000  # pair tests (simplicity) or barycentric tests (lifting) handled at once
_NEEDLE = 0.01      # meshing 4: a region with a corner under this (degrees) whose refinement runs
                    # out of points keeps its sides whole
_SHAPE_CAP = 50_000 # meshing 4: the most points a region's shape (P^2 / A) adds to its budget
_UNROLL_BELOW = 0.9 # meshing 4: a region is unrolled first when its projection keeps less of its area
_MEMBRANE_PASSES = 50   # meshing 4: relaxations of a projected region's added points (``_membrane``)
_PIECE_DEPTH = 6        # meshing 4: cuts at most, one inside another, of a region into pieces
_TIDY_BELOW = 20.0      # meshing 5: triangles with an angle under this (degrees) in space are tidied ...
_TIDY_ROUNDS = 3        # ... in at most this many rounds of edge flips and point moves
_TWIN = 0.01            # meshing 5: side points nearer than this x their gaps are one (``_EdgeSplit``)


class Mesh(NamedTuple):
    """A surface's triangle mesh: ``points`` (P, 3), the surface's vertices first (point i is vertex
    i for i < V) then the points meshing added; ``triangles`` (T, 3) indices into ``points``, each
    oriented like its region; ``regions`` (T,) the region each triangle covers, region after region;
    ``fallback`` the regions cut on their ring alone (no point inside), as meshing 1 cuts them."""

    points: np.ndarray
    triangles: np.ndarray
    regions: np.ndarray
    fallback: np.ndarray   # the regions cut as meshing 1 cuts them (every region under meshing 1)


def _frozen(a: np.ndarray, dtype: npt.DTypeLike) -> np.ndarray:
    out = np.ascontiguousarray(a, dtype=dtype)
    out.setflags(write=False)
    return out


def mesh_surface(surface: Any, meshing: int = MESHING, *,
                 cut: Callable[..., np.ndarray] | None = None) -> Mesh:
    """The triangle mesh of ``surface``'s regions under ``meshing`` (see the module docstring); ``cut``
    is meshing 1's cut of polygons (``surface.triangulate_polygons``, passed by ``Surface.mesh``)."""
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    offsets = np.asarray(surface.region_offsets, dtype=np.int64)
    cycles = np.asarray(surface.region_vertices, dtype=np.int64)
    coarse = np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    sizes = np.diff(offsets)
    owners = np.repeat(np.arange(len(sizes)), np.maximum(sizes - 2, 0))
    if check_meshing(meshing) == 1 or not len(coarse):
        return Mesh(_frozen(vertices, np.float64), _frozen(coarse, np.int64), _frozen(owners, np.int64),
                    _frozen(np.arange(len(sizes)), np.int64))
    if cut is None:
        raise ValueError("mesh_surface: meshing 2 needs meshing 1's cut (Surface.mesh passes it)")
    refine = _refine if meshing == 2 else partial(_refine3, guarded=meshing >= 4)
    origin = None
    if meshing >= 4:
        offsets, cycles, coarse, owners, origin, known = _pieces(vertices, offsets, cycles, coarse, owners)
        refine = partial(_refine3, guarded=True, known=known, tidy=meshing >= 5)
    points, triangles, regions, fallback = refine(vertices, offsets, cycles, coarse, owners, cut)
    if meshing >= 6:
        points, triangles, regions = mend(points, triangles, regions, len(vertices),
                                          meshing=meshing)
    if origin is not None:
        regions, fallback = origin[regions], np.unique(origin[fallback])
    return Mesh(_frozen(points, np.float64), _frozen(triangles, np.int64), _frozen(regions, np.int64),
                _frozen(fallback, np.int64))


def _local(cyc: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Triangles ``tri`` of vertex ids as indices into the cycle ``cyc`` (its vertices unique)."""
    return cast(np.ndarray, np.argsort(cyc)[np.searchsorted(np.sort(cyc), tri)])


def _pieces(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray, coarse: np.ndarray,
            owners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                         list[tuple[np.ndarray | None, bool] | None]]:
    """Meshing 4: every region that is simple neither projected nor unrolled (``_chart``) cut along
    diagonals of its meshing-1 triangles, the most even cut first, until each piece is (or is one
    triangle, or ``_PIECE_DEPTH`` cuts deep): the pieces' offsets, cycles, meshing-1 triangles and
    their owners, each piece's region (``origin``), and the chart found for each region left whole
    (``known``, None elsewhere: ``_refine3`` reuses it rather than unrolling the region again). The
    pieces share the diagonals as map edges, so their meshes meet as neighbouring regions' do."""
    sizes = np.diff(offsets)
    starts = np.searchsorted(owners, np.arange(len(sizes) + 1))
    centroid, newell, *_ = _region_geometry(vertices, offsets, cycles)

    def simple(cyc: np.ndarray, tri: np.ndarray) -> bool:
        pos = vertices[cyc]
        centre = pos.mean(axis=0)
        normal = np.cross(pos - centre, np.roll(pos, -1, axis=0) - centre).sum(axis=0)
        return _chart(pos, _local(cyc, tri), centre, normal, unrolled_first=True)[0] is not None

    def cut(cyc: np.ndarray, tri: np.ndarray, depth: int) -> list[tuple[np.ndarray, np.ndarray]]:
        if len(tri) < 2 or depth >= _PIECE_DEPTH or (depth > 0 and simple(cyc, tri)):
            return [(cyc, tri)]
        at = {int(v): i for i, v in enumerate(cyc)}
        pairs = {}
        for t in tri:
            for k in range(3):
                a, b = int(t[k]), int(t[(k + 1) % 3])
                i, j = sorted((at[a], at[b]))
                if j - i > 1 and not (i == 0 and j == len(cyc) - 1):   # a diagonal, not a side
                    pairs[(i, j)] = abs(2 * (j - i) - len(cyc))
        if not pairs:
            return [(cyc, tri)]
        i, j = min(pairs, key=lambda ij: (pairs[ij], ij))
        halves = [cyc[i:j + 1], np.concatenate([cyc[j:], cyc[:i + 1]])]
        out = []
        for half in halves:
            inside = np.isin(tri, half).all(axis=1)
            out += cut(half, tri[inside], depth + 1)
        return out

    new_cycles, new_tri, origin = [], [], []
    known: list[tuple[np.ndarray | None, bool] | None] = []
    for r in range(len(sizes)):
        cyc = cycles[offsets[r]:offsets[r + 1]]
        tri = coarse[starts[r]:starts[r + 1]]
        whole, chart = [(cyc, tri)], None
        if sizes[r] >= 4 and len(np.unique(cyc)) == len(cyc) and len(tri) == sizes[r] - 2:
            # the chart _refine3 would find (the same centroid and Newell vector)
            chart = _chart(vertices[cyc], _local(cyc, tri), centroid[r], newell[r], unrolled_first=True)
            if chart[0] is None:
                whole, chart = cut(cyc, tri, 0), None
        for piece, piece_tri in whole:
            new_cycles.append(piece)
            new_tri.append(piece_tri)
            origin.append(r)
            known.append(chart)
    piece_sizes = [len(c) for c in new_cycles]
    new_offsets = np.concatenate([[0], np.cumsum(piece_sizes)]).astype(np.int64)
    new_owners = np.repeat(np.arange(len(new_cycles)), [len(t) for t in new_tri])
    return (new_offsets, np.concatenate(new_cycles).astype(np.int64),
            np.concatenate(new_tri).reshape(-1, 3).astype(np.int64), new_owners.astype(np.int64),
            np.asarray(origin, dtype=np.int64), known)


def _region_geometry(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per region: centroid (F, 3), Newell vector (F, 3: twice the vector area), perimeter (F,); per
    side (in ``cycles`` order): the region it bounds and its end vertex."""
    sizes = np.diff(offsets)
    n_regions = len(sizes)
    region_of = np.repeat(np.arange(n_regions), sizes)
    idx = np.arange(len(cycles))
    last = offsets[1:] - 1
    ends = np.where(idx == last[region_of], offsets[:-1][region_of], idx + 1) if len(cycles) else idx
    nxt = cycles[ends]
    pos = vertices[cycles]
    count = np.maximum(sizes, 1).astype(np.float64)
    centroid = np.stack([np.bincount(region_of, pos[:, k], n_regions) for k in range(3)], 1) / count[:, None]
    rel_a = pos - centroid[region_of]
    rel_b = vertices[nxt] - centroid[region_of]
    cross = np.cross(rel_a, rel_b)
    newell = np.stack([np.bincount(region_of, cross[:, k], n_regions) for k in range(3)], 1)
    side = np.linalg.norm(vertices[nxt] - pos, axis=1)
    perimeter = np.bincount(region_of, side, n_regions)
    return centroid, newell, perimeter, region_of, nxt


def region_roundness(surface: Any) -> np.ndarray:
    """(F,) each region's isoperimetric quotient ``4 pi area / perimeter**2`` in 3D (area: the length
    of its vector area, so a region folded over itself counts less): 1 for a disc, 0.60 for an
    equilateral triangle, near 0 for a thin strip; 0 for a region of no perimeter."""
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    offsets = np.asarray(surface.region_offsets, dtype=np.int64)
    cycles = np.asarray(surface.region_vertices, dtype=np.int64)
    _, newell, perimeter, _, _ = _region_geometry(vertices, offsets, cycles)
    area = 0.5 * np.linalg.norm(newell, axis=1)
    return np.where(perimeter > 0, 4.0 * math.pi * area / np.where(perimeter > 0, perimeter, 1.0) ** 2, 0.0)


def _frame(normal: np.ndarray) -> np.ndarray | None:
    """(2, 3) orthonormal axes of the plane normal to ``normal`` (counter-clockwise about it), or None
    for a normal of no length."""
    length = float(np.linalg.norm(normal))
    if not length > 1e-300:
        return None
    n = normal / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(n, e1)])


def _twice_area(xy: np.ndarray) -> float:
    """Twice the signed area of the closed polygon ``xy`` (m, 2): the shoelace sum, positive when
    counter-clockwise."""
    return float(np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]))


def _simple(xy: np.ndarray) -> bool:
    """Whether the closed polygon ``xy`` (m, 2; unit extent) is simple with some area: no side of no
    length, no two sides that are not neighbours meeting or touching (within ``_TOL``)."""
    m = len(xy)
    d = np.roll(xy, -1, axis=0) - xy
    if m < 3 or m > _SIMPLE_MAX or np.any(np.hypot(d[:, 0], d[:, 1]) <= _TOL):
        return False
    if _twice_area(xy) <= _TOL:
        return False
    q = xy + d
    lo, hi = np.minimum(xy, q) - _TOL, np.maximum(xy, q) + _TOL
    rows = max(1, _CHUNK // m)
    for start in range(0, m, rows):
        i = np.arange(start, min(m, start + rows))[:, None]
        j = np.arange(m)[None, :]
        pair = (j >= i + 2) & ~((i == 0) & (j == m - 1))
        if not pair.any():
            continue
        ii, jj = np.broadcast_to(i, pair.shape)[pair], np.broadcast_to(j, pair.shape)[pair]

        def orient(s: np.ndarray, p: np.ndarray) -> np.ndarray:
            return cast(np.ndarray, d[s, 0] * (p[:, 1] - xy[s, 1]) - d[s, 1] * (p[:, 0] - xy[s, 0]))

        def within(s: np.ndarray, p: np.ndarray) -> np.ndarray:
            return cast(np.ndarray, np.all((p >= lo[s]) & (p <= hi[s]), axis=1))

        o1, o2 = orient(ii, xy[jj]), orient(ii, q[jj])
        o3, o4 = orient(jj, xy[ii]), orient(jj, q[ii])
        proper = (o1 * o2 < 0) & (o3 * o4 < 0)
        touch = ((np.abs(o1) <= _TOL) & within(ii, xy[jj])) | ((np.abs(o2) <= _TOL) & within(ii, q[jj])) \
            | ((np.abs(o3) <= _TOL) & within(jj, xy[ii])) | ((np.abs(o4) <= _TOL) & within(jj, q[ii]))
        if np.any(proper | touch):
            return False
    return True


def _lift(new: np.ndarray, corners2: np.ndarray, corners3: np.ndarray) -> np.ndarray | None:
    """(N, 3) the points ``new`` (N, 2) of a region's plane lifted onto its meshing-1 triangles (T, 3
    corners, as ``corners2`` (T, 3, 2) in the plane and ``corners3`` (T, 3, 3) in space): barycentric
    interpolation in the triangle each lies most inside; None if one lies outside them all."""
    a, b, c = corners2[:, 0], corners2[:, 1], corners2[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    usable = np.abs(det) > _TOL * _TOL
    if not usable.any():
        return None
    a, b, c, det, corners3 = a[usable], b[usable], c[usable], det[usable], corners3[usable]
    out = np.empty((len(new), 3))
    rows = max(1, _CHUNK // len(a))
    for start in range(0, len(new), rows):
        p = new[start:start + rows, None, :]
        l1 = ((p[..., 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (p[..., 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) / det
        l2 = ((b[:, 0] - a[:, 0]) * (p[..., 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[..., 0] - a[:, 0])) / det
        l0 = 1.0 - l1 - l2
        inside = np.minimum(np.minimum(l0, l1), l2)
        best = np.argmax(inside, axis=1)
        rows_ = np.arange(len(best))
        if np.any(inside[rows_, best] < -1e-7):
            return None
        w = np.stack([l0[rows_, best], l1[rows_, best], l2[rows_, best]], 1)
        out[start:start + rows] = np.einsum("nk,nkd->nd", w, corners3[best])
    return out


class _Rings(NamedTuple):
    """The regions' sides with the points added on the map's edges: ``points`` (the vertices, then the
    added points edge after edge), ``ring`` and ``offsets`` (region r's ring is
    ``ring[offsets[r]:offsets[r + 1]]``, counter-clockwise like its cycle) and ``t`` (each ring
    entry's parameter along its side's map edge, 0 at the edge's lower-numbered vertex)."""

    points: np.ndarray
    ring: np.ndarray
    offsets: np.ndarray
    t: np.ndarray
    side: np.ndarray


def _rings(vertices: np.ndarray, cycles: np.ndarray, region_of: np.ndarray, n_regions: int, lo: np.ndarray,
           inverse: np.ndarray, elo: np.ndarray, ehi: np.ndarray, added: np.ndarray, t_flat: np.ndarray
           ) -> _Rings:
    """The rings of every region when map edge e carries ``added[e]`` points at the (sorted, in (0, 1))
    parameters ``t_flat`` (edge after edge) from its vertex ``elo[e]`` to ``ehi[e]``."""
    n_vertices = len(vertices)
    base = n_vertices + np.concatenate([[0], np.cumsum(added)[:-1]]).astype(np.int64)
    edge_of_point = np.repeat(np.arange(len(added)), added)
    t = t_flat[:, None]
    start_of = vertices[elo[edge_of_point]]
    on_edges = start_of + t * (vertices[ehi[edge_of_point]] - start_of)
    points = np.concatenate([vertices, on_edges])
    side_added = added[inverse]
    forward = cycles == lo
    counts = 1 + side_added
    ring = np.empty(int(counts.sum()), dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    ring[start] = cycles
    within = np.arange(len(ring)) - np.repeat(start, counts)              # 0 = the side's start
    extra = within > 0
    side = np.repeat(np.arange(len(cycles)), counts)
    e, k = inverse[side[extra]], within[extra]
    ring[extra] = np.where(forward[side[extra]], base[e] + k - 1, base[e] + side_added[side[extra]] - k)
    tt = np.where(forward[side], 0.0, 1.0)
    tt[extra] = t_flat[ring[extra] - n_vertices]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(region_of, counts, n_regions))]).astype(np.int64)
    return _Rings(points, ring, offsets, tt, side)


def _boundary_params(ring_xy: np.ndarray, found: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points ``found`` (k, 2) Triangle put on the sides of a region's ring ``ring_xy`` (n, 2): the
    ring segment each lies on (the nearest) and how far along it (0 to 1)."""
    d = np.roll(ring_xy, -1, axis=0) - ring_xy
    rel = found[:, None, :] - ring_xy[None, :, :]
    dd = np.maximum(np.einsum("sk,sk->s", d, d), 1e-300)
    f = np.clip(np.einsum("psk,sk->ps", rel, d) / dd, 0.0, 1.0)
    gap = rel - f[..., None] * d[None]
    segment = np.argmin(np.einsum("psk,psk->ps", gap, gap), axis=1)
    return segment, f[np.arange(len(found)), segment]


def _triangulate_region(xy: np.ndarray, options: str, marked: bool = False
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Triangle's mesh of the simple polygon ``xy`` (n, 2): (points (n + k, 2), the input first;
    triangles; markers, 1 for points on the polygon's sides), or None when it is not a mesh of it
    (triangles of no area, or not covering the polygon's area)."""
    import triangle

    n = len(xy)
    segments = np.stack([np.arange(n), np.roll(np.arange(n), -1)], 1)
    pslg = {"vertices": xy, "segments": segments}
    if marked:
        pslg["segment_markers"] = (np.arange(n, dtype=np.int32) + 2).reshape(-1, 1)
    out = triangle.triangulate(pslg, options)
    tri = np.asarray(out.get("triangles", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    points2 = np.asarray(out["vertices"], dtype=np.float64)
    if len(points2) < n or not np.array_equal(points2[:n], xy) or not len(tri):
        return None
    p = points2[tri]
    areas = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) \
        - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    shoelace = _twice_area(xy)
    if np.any(areas <= 0) or abs(float(areas.sum()) - shoelace) > 1e-9 * abs(shoelace):
        return None
    markers = np.asarray(out.get("vertex_markers", np.zeros((len(points2), 1))), dtype=np.int64).reshape(-1)
    return points2, tri, markers


def _in_plane(rings: _Rings, r: int, centroid: np.ndarray, frame: np.ndarray | None, keep: str
              ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """Meshing 2's mesh of region ``r``'s ring projected into its plane (``frame`` about ``centroid``;
    None: no mesh): the ring's point ids, its plane coordinates and ``_triangulate_region``'s answer;
    ``keep`` "Y" keeps the ring's sides whole, "" lets Triangle split them."""
    ids = rings.ring[rings.offsets[r]:rings.offsets[r + 1]]
    if frame is None:
        return ids, np.zeros((0, 2)), None
    xy = (rings.points[ids] - centroid) @ frame.T
    return ids, xy, _triangulate_region(xy, f"pq{_MIN_ANGLE:g}{keep}QS{_STEINER * len(ids) + _STEINER_FLOOR}")


class _EdgeSplit:
    """The points on the map's edges, shared by the two regions beside each: every edge first split
    into equal pieces no longer than ``_SPACING`` x the thinner region's width beside it (at most
    ``_MAX_SPLIT``), but an edge beside a region with no flat coordinates (``fixed``: it keeps its
    own); then any points a region's mesh put on its sides (``add``). ``merge`` (meshing 5): a point
    closer to the one before it than this x the larger gap on either side of the two is dropped."""

    def __init__(self, vertices: np.ndarray, cycles: np.ndarray, nxt: np.ndarray, region_of: np.ndarray,
                 width: np.ndarray, simple: np.ndarray, n_regions: int, merge: float = 0.0) -> None:
        n_vertices = len(vertices)
        self.merge = merge
        self.vertices, self.cycles, self.region_of, self.n_regions = vertices, cycles, region_of, n_regions
        lo, hi = np.minimum(cycles, nxt), np.maximum(cycles, nxt)
        keys, first, inverse = np.unique(lo * n_vertices + hi, return_index=True, return_inverse=True)
        spacing = np.full(len(keys), np.inf)
        np.minimum.at(spacing, inverse, _SPACING * width[region_of])
        fixed = np.zeros(len(keys), dtype=bool)
        np.logical_or.at(fixed, inverse, ~simple[region_of])
        elo, ehi = lo[first], hi[first]
        length = np.linalg.norm(vertices[ehi] - vertices[elo], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            pieces = np.where(spacing > 0, np.ceil(length / spacing * (1.0 - 1e-9)), 1.0)
        pieces = np.clip(np.nan_to_num(pieces, nan=1.0, posinf=_MAX_SPLIT), 1, _MAX_SPLIT).astype(np.int64)
        added = np.where(fixed, 0, pieces - 1)
        self.edge_of_point = np.repeat(np.arange(len(keys)), added)
        step = np.arange(len(self.edge_of_point)) \
            - np.repeat(np.concatenate([[0], np.cumsum(added)[:-1]]), added) + 1
        self.t_flat = step / pieces[self.edge_of_point]
        self.forward = cycles == lo
        self.lo, self.inverse, self.elo, self.ehi = lo, inverse, elo, ehi
        self.fixed, self.added = fixed, added
        self.changed = np.zeros(0, dtype=np.int64)
        self.n_edges = len(keys)
        self.rings = self._make()

    def _make(self) -> _Rings:
        return _rings(self.vertices, self.cycles, self.region_of, self.n_regions, self.lo, self.inverse,
                      self.elo, self.ehi, self.added, self.t_flat)

    def on_edges(self, rings: _Rings, r: int, segment: np.ndarray, frac: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The map edges and parameters of points ``frac`` of the way along region ``r``'s ring
        segments ``segment`` (entry j to entry j + 1)."""
        seg_at = rings.offsets[r] + segment
        last = segment + 1 == rings.offsets[r + 1] - rings.offsets[r]
        nxt_at = np.where(last, rings.offsets[r], seg_at + 1)
        s = rings.side[seg_at]
        t0 = rings.t[seg_at]
        # the segment's far end: the next ring entry, or its side's end vertex (t 1 up, 0 down the edge)
        same_side = rings.side[nxt_at] == s
        t1 = np.where(same_side, rings.t[nxt_at], np.where(self.forward[s], 1.0, 0.0))
        return self.inverse[s], t0 + frac * (t1 - t0)

    def _twins(self, e: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Which points (sorted by edge ``e``, then parameter ``t``) are a twin of the one before: nearer
        it than ``merge`` x the larger of the gaps before the pair and after it (an edge's ends count).
        Two regions splitting the same stretch of a side in one pass put their points there each in
        its own chart, whose scales differ, so Triangle's concentric-shell splits land about 1e-4 of
        the gap apart (a billionth of the edge or so, more than ``add``'s tolerance), and both
        regions' meshes then hold a side 10,000 times shorter than its neighbours, with needle-thin
        triangles on it (meshing 4)."""
        same = np.zeros(len(t), dtype=bool)
        same[1:] = e[1:] == e[:-1]
        gap = np.where(same, t - np.roll(t, 1), t)  # from the point before, or the edge start
        after = np.ones(len(t), dtype=bool)
        after[:-1] = ~same[1:]
        gap_next = np.where(after, 1.0 - t, np.roll(gap, -1))      # to the point after, or the edge's end
        gap_prev = np.roll(gap, 1)                                   # before the pair (only read where same)
        return same & (gap <= self.merge * np.maximum(gap_prev, gap_next))

    def add(self, edges: np.ndarray, t: np.ndarray) -> _Rings:
        """The rings once points at parameters ``t`` on map ``edges`` are added (but on fixed edges,
        at an end, or within 1e-9 of a point there)."""
        e_all = np.concatenate([self.edge_of_point, edges])
        t_all = np.concatenate([self.t_flat, t])
        order = np.lexsort((t_all, e_all))
        e_all, t_all = e_all[order], t_all[order]
        keep = (t_all > 1e-9) & (t_all < 1.0 - 1e-9) & ~self.fixed[e_all]
        e_all, t_all = e_all[keep], t_all[keep]
        close = np.zeros(len(t_all), dtype=bool)
        close[1:] = (e_all[1:] == e_all[:-1]) & (t_all[1:] - t_all[:-1] <= 1e-9)
        if self.merge:
            e_all, t_all = e_all[~close], t_all[~close]
            close = self._twins(e_all, t_all)
        old_e, old_t = self.edge_of_point, self.t_flat
        self.edge_of_point, self.t_flat = e_all[~close], t_all[~close]
        added = np.bincount(self.edge_of_point, minlength=self.n_edges).astype(np.int64)
        # the edges whose points changed (both lists sorted by edge, then parameter)
        changed = added != self.added
        same_old, same_new = ~changed[old_e], ~changed[self.edge_of_point]
        changed[old_e[same_old][old_t[same_old] != self.t_flat[same_new]]] = True
        self.changed = np.flatnonzero(changed)
        self.added = added
        self.rings = self._make()
        return self.rings


def _assemble(rings: _Rings, meshed: list[np.ndarray | None], inside: list[np.ndarray],
              triangulate_polygons: Callable[..., np.ndarray]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points, triangles, their regions and the regions cut as meshing 1 cuts them (those ``meshed``
    None: meshing 1's cut of their ring, its sides' shared points included)."""
    n_regions = len(meshed)
    failed = np.array([r for r in range(n_regions) if meshed[r] is None], dtype=np.int64)
    if len(failed):
        parts_ = [rings.ring[rings.offsets[r]:rings.offsets[r + 1]] for r in failed]
        fall_offsets = np.concatenate([[0], np.cumsum([len(x) for x in parts_])]).astype(np.int64)
        fallback = triangulate_polygons(rings.points, fall_offsets, np.concatenate(parts_))
        at = 0
        for r, x in zip(failed, parts_, strict=True):
            meshed[r] = fallback[at:at + len(x) - 2]
            at += len(x) - 2
    parts = [m for m in meshed if m is not None]
    triangles = np.concatenate(parts) if parts else np.zeros((0, 3), dtype=np.int64)
    regions = np.repeat(np.arange(n_regions), [len(m) if m is not None else 0 for m in meshed])
    points = np.concatenate([rings.points, *inside]) if inside else rings.points
    return points, triangles, regions, failed


def _membrane(points2: np.ndarray, tri: np.ndarray, ring3: np.ndarray, lifted: np.ndarray) -> np.ndarray:
    """Meshing 4's lift of a projected region's added points (``lifted``: onto its meshing-1
    triangles; ``points2`` its flat mesh, the ring's ``len(ring3)`` points first; ``tri`` its
    triangles): their offsets from the plane that best fits the ring relaxed ``_MEMBRANE_PASSES``
    times to their neighbours' mean, the ring's held, so the region spans its sides as a membrane
    rather than following the creases of meshing 1's fan, whose slivers bend in space."""
    n = len(ring3)
    flat = np.c_[points2, np.ones(len(points2))]
    fit, *_ = np.linalg.lstsq(flat[:n], ring3, rcond=None)
    base = flat @ fit
    offset = np.concatenate([ring3, lifted]) - base
    a = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2], tri[:, 1], tri[:, 2], tri[:, 0]])
    b = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0], tri[:, 0], tri[:, 1], tri[:, 2]])
    degree = np.maximum(np.bincount(a, minlength=len(offset)), 1).astype(np.float64)
    for _ in range(_MEMBRANE_PASSES):
        mean = np.stack([np.bincount(a, weights=offset[b, k], minlength=len(offset))
                         for k in range(3)], axis=1) / degree[:, None]
        offset[n:] = mean[n:]
    return cast(np.ndarray, (base + offset)[n:])


def _tidy(p: np.ndarray, tri: np.ndarray, fixed: int) -> tuple[np.ndarray, np.ndarray]:
    """Meshing 5: a region's lifted mesh (points ``p`` (P, 3), the ``fixed`` ring points first;
    triangles ``tri``) with its triangles under ``_TIDY_BELOW`` degrees in space improved: edges
    inside the region flipped where that raises the smaller angle of the two triangles beside them,
    and added points moved to their neighbours' mean where that raises the smallest angle round
    them, neither turning a triangle over; ``_TIDY_ROUNDS`` rounds at most, in a fixed order. The
    ring's points and sides stay, so the region still meets its neighbours on the same points.
    Triangle's angles hold in the chart, but lifting bends them: across the creases of meshing 1's
    triangles, where a projected region slopes, and where the region folds over itself."""
    bad = triangle_min_angles(p, tri) < _TIDY_BELOW
    if not bad.any():
        return p, tri
    # only the triangles round the thin ones' corners change: those corners' stars are whole there
    corners = np.unique(tri[bad])
    near = np.flatnonzero(np.isin(tri, corners).any(axis=1))
    movable = set(corners[corners >= fixed].tolist())
    hub = set(corners.tolist())      # a new edge ends at one, so every edge it could repeat is here
    used = np.unique(tri[near])
    pts = dict(zip(used.tolist(), map(tuple, p[used].tolist()), strict=True))
    tris = [tuple(t) for t in tri[near].tolist()]

    def normal(a: int, b: int, c: int) -> tuple[float, float, float]:
        return _normal(pts[a], pts[b], pts[c])

    def smallest(a: int, b: int, c: int) -> float:
        return _smallest(pts[a], pts[b], pts[c])

    owner = {(t[k], t[(k + 1) % 3]): i for i, t in enumerate(tris) for k in range(3)}
    angle = [smallest(*t) for t in tris]

    def flips(bad: list[int]) -> bool:
        changed = False
        queue, budget = deque(bad), 2 * len(bad)
        while queue and budget:
            i = queue.popleft()
            if angle[i] >= _TIDY_BELOW:
                continue
            for k in range(3):
                a, b, c = tris[i][k], tris[i][(k + 1) % 3], tris[i][(k + 2) % 3]
                j = owner.get((b, a))
                if j is None:
                    continue
                d = next(x for x in tris[j] if x != a and x != b)
                if c == d or (c not in hub and d not in hub) or (c, d) in owner or (d, c) in owner:
                    continue
                new1, new2 = (c, a, d), (d, b, c)
                got = min(smallest(*new1), smallest(*new2))
                if got <= min(angle[i], angle[j]) + 1e-9:
                    continue
                n1, n2 = normal(*new1), normal(*new2)
                (ux, uy, uz), (wx, wy, wz) = normal(*tris[i]), normal(*tris[j])
                old = (ux + wx, uy + wy, uz + wz)
                if dot(n1, n2) <= 0.0 or dot(n1, old) <= 0.0 or dot(n2, old) <= 0.0:
                    continue
                for t in (tris[i], tris[j]):
                    for m in range(3):
                        del owner[(t[m], t[(m + 1) % 3])]
                tris[i], tris[j] = new1, new2
                for idx, t in ((i, new1), (j, new2)):
                    for m in range(3):
                        owner[(t[m], t[(m + 1) % 3])] = idx
                    angle[idx] = smallest(*t)
                queue.extend(x for x in (i, j) if angle[x] < _TIDY_BELOW)
                budget -= 1
                changed = True
                break
        return changed

    def moves() -> bool:
        star: dict[int, list[int]] = {}
        for i, t in enumerate(tris):
            for v in t:
                star.setdefault(v, []).append(i)
        targets = sorted({v for i, t in enumerate(tris) if angle[i] < _TIDY_BELOW for v in t if v in movable})
        changed = False
        for v in targets:
            around = star[v]
            near = sorted({x for i in around for x in tris[i] if x != v})
            mean = tuple(sum(pts[x][d] for x in near) / len(near) for d in range(3))
            before = min(angle[i] for i in around)
            old_n = [normal(*tris[i]) for i in around]
            home = pts[v]
            for step in (1.0, 0.5):
                pts[v] = tuple(home[d] + step * (mean[d] - home[d]) for d in range(3))
                got = [smallest(*tris[i]) for i in around]
                if min(got) > before + 1e-9 and all(dot(normal(*tris[i]), n) > 0.0
                                                    for i, n in zip(around, old_n, strict=True)):
                    for i, g in zip(around, got, strict=True):
                        angle[i] = g
                    changed = True
                    break
                pts[v] = home
        return changed

    for _ in range(_TIDY_ROUNDS):
        flipped = flips([i for i in range(len(tris)) if angle[i] < _TIDY_BELOW])
        if not (moves() or flipped):
            break
    out = tri.copy()
    out[near] = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    moved = p.copy()
    at = np.asarray(sorted(movable), dtype=np.int64)
    moved[at] = np.asarray([pts[v] for v in at.tolist()], dtype=np.float64).reshape(-1, 3)
    return moved, out


def _lifted(rings: _Rings, sizes: np.ndarray,
            final: Callable[[int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None],
            triangulate_polygons: Callable[..., np.ndarray], membrane: np.ndarray | None = None,
            tidy: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The mesh of every region from ``final(r)``: its flat mesh (points, the ring's first;
    triangles) and its meshing-1 triangles' corners flat and in space, through which the added points
    are lifted (where ``membrane[r]``, then relaxed: ``_membrane``; where ``tidy``, then tidied in
    space: ``_tidy``); a region ``final`` gives None for, or whose points fall outside those triangles,
    is cut as meshing 1 cuts it (``_assemble``)."""
    meshed: list[np.ndarray | None] = [None] * len(sizes)
    inside: list[np.ndarray] = []
    next_point = len(rings.points)
    for r in range(len(sizes)):
        if sizes[r] < 3:
            meshed[r] = np.zeros((0, 3), dtype=np.int64)
        got = final(r)
        if got is None:
            continue
        points2, tri, corners2, corners3 = got
        ids = rings.ring[rings.offsets[r]:rings.offsets[r + 1]]     # as meshed (points renumbered since)
        new = points2[len(ids):]
        lifted = np.zeros((0, 3))
        if len(new):
            got_lift = _lift(new, corners2, corners3)
            if got_lift is None:
                continue
            lifted = got_lift
            if membrane is not None and membrane[r]:
                lifted = _membrane(points2, tri, rings.points[ids], lifted)
        if tidy:
            moved, tri = _tidy(np.concatenate([rings.points[ids], lifted]), tri, len(ids))
            lifted = moved[len(ids):]
        if len(new):
            inside.append(lifted)
        local_ids = np.concatenate([ids, next_point + np.arange(len(new))])
        next_point += len(new)
        meshed[r] = local_ids[tri]
    return _assemble(rings, meshed, inside, triangulate_polygons)


def _refine(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray, coarse: np.ndarray,
            owners: np.ndarray, triangulate_polygons: Callable[..., np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Meshing 2 of checked arrays (``coarse``: the meshing-1 triangles, ``owners`` their regions):
    points, triangles, their regions, and the regions cut as meshing 1 cuts them."""
    sizes = np.diff(offsets)
    n_regions = len(sizes)
    centroid, newell, perimeter, region_of, nxt = _region_geometry(vertices, offsets, cycles)
    width = np.where(perimeter > 0, np.linalg.norm(newell, axis=1) / np.where(perimeter > 0, perimeter, 1.0),
                     0.0)                                                   # 2 area / perimeter
    frames: list[np.ndarray | None] = [None] * n_regions
    for r in range(n_regions):
        frame = _frame(newell[r]) if sizes[r] >= 3 else None
        if frame is None:
            continue
        xy0 = (vertices[cycles[offsets[r]:offsets[r + 1]]] - centroid[r]) @ frame.T
        extent = float(np.abs(xy0).max())
        if extent > 0 and _simple(xy0 / extent):
            frames[r] = frame
    split = _EdgeSplit(vertices, cycles, nxt, region_of, width,
                       np.array([f is not None for f in frames], dtype=bool), n_regions)
    rings = split.rings
    # free passes: Triangle free to split the sides; the points it puts there go on the map's edges,
    # for both regions beside each, so the last pass (sides kept) meshes every region watertight
    for _ in range(_FREE_PASSES):
        found_edges: list[np.ndarray] = []
        found_t: list[np.ndarray] = []
        for r in range(n_regions):
            ids, xy, got = _in_plane(rings, r, centroid[r], frames[r], "")
            if got is None:
                continue
            points2, _, markers = got
            on_side = np.flatnonzero(markers[len(ids):] != 0) + len(ids)
            if not len(on_side):
                continue
            segment, frac = _boundary_params(xy, points2[on_side])
            edges, t = split.on_edges(rings, r, segment, frac)
            found_edges.append(edges)
            found_t.append(t)
        if not found_edges:
            break
        rings = split.add(np.concatenate(found_edges), np.concatenate(found_t))

    coarse_start = np.searchsorted(owners, np.arange(n_regions + 1))

    def final(r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        frame = frames[r]
        _, _, got = _in_plane(rings, r, centroid[r], frame, "Y")
        if got is None or frame is None:
            return None
        own = coarse[coarse_start[r]:coarse_start[r + 1]]
        return got[0], got[1], (vertices[own] - centroid[r]) @ frame.T, vertices[own]

    return _lifted(rings, sizes, final, triangulate_polygons)

def _unfold(pos: np.ndarray, tri: np.ndarray) -> np.ndarray | None:
    """(m, 2) a region's cycle (``pos`` (m, 3)) laid flat by unfolding its meshing-1 triangles
    (``tri`` (m - 2, 3), indices into the cycle, counter-clockwise) from the first, across their shared
    diagonals (their dual graph is a tree), each keeping its three side lengths, each to the left of
    the diagonal it shares; None if a triangle has a side of no length or a vertex is placed twice."""
    m = len(pos)
    uv = np.full((m, 2), np.nan)
    by_edge = {(int(t[k]), int(t[(k + 1) % 3])): i for i, t in enumerate(tri) for k in range(3)}

    def apex(p: int, q: int, w: int) -> bool:
        """Place ``w`` left of p -> q at its 3D distances from ``p`` and ``q``; False if it cannot be."""
        if not np.isnan(uv[w, 0]):
            return False
        d = uv[q] - uv[p]
        span = math.hypot(float(d[0]), float(d[1]))
        if not span > 0.0:
            return False
        dp2 = float(np.sum((pos[w] - pos[p]) ** 2))
        dq2 = float(np.sum((pos[w] - pos[q]) ** 2))
        x = (dp2 - dq2 + span * span) / (2.0 * span)
        y = math.sqrt(max(dp2 - x * x, 0.0))
        e = d / span
        uv[w] = uv[p] + x * e + y * np.array([-e[1], e[0]])
        return True

    a, b, c = (int(v) for v in tri[0])
    uv[a] = 0.0, 0.0
    uv[b] = float(np.linalg.norm(pos[b] - pos[a])), 0.0
    if not apex(a, b, c):
        return None
    queue, seen = [0], {0}
    while queue:
        t = tri[queue.pop(0)]
        for k in range(3):
            u, v = int(t[k]), int(t[(k + 1) % 3])
            other = by_edge.get((v, u))
            if other is None or other in seen:
                continue
            seen.add(other)
            queue.append(other)
            w = next(int(x) for x in tri[other] if x != u and x != v)
            if not apex(v, u, w):
                return None
    return None if np.isnan(uv).any() else uv


def _chart(pos: np.ndarray, tri: np.ndarray, centroid: np.ndarray, normal: np.ndarray,
           unrolled_first: bool = False) -> tuple[np.ndarray | None, bool]:
    """Meshing 3's flat coordinates (m, 2) of a region's cycle (``pos`` (m, 3), unique vertices): its
    projection into its best-fit plane if simple there, else its unfolding (``_unfold``) if simple;
    None if neither is; and whether it is the projection. ``unrolled_first`` (meshing 4): the
    unfolding first, then the projection, where the projection keeps less than ``_UNROLL_BELOW`` of
    the meshing-1 triangles' area."""
    frame = _frame(normal)
    if frame is None:
        return None, False

    def projected() -> np.ndarray | None:
        return cast(np.ndarray, (pos - centroid) @ frame.T)

    def unfolded() -> np.ndarray | None:
        uv = _unfold(pos, tri) if len(tri) == len(pos) - 2 and len(tri) else None
        return None if uv is None else uv - uv.mean(axis=0)

    if unrolled_first and len(tri):   # only where the projection shrinks the region (it slopes away)
        t3, t2 = pos[tri], ((pos - centroid) @ frame.T)[tri]
        area3 = float(np.linalg.norm(np.cross(t3[:, 1] - t3[:, 0], t3[:, 2] - t3[:, 0]), axis=1).sum())
        u, w = t2[:, 1] - t2[:, 0], t2[:, 2] - t2[:, 0]
        area2 = float(np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]).sum())
        unrolled_first = area3 > 0.0 and area2 < _UNROLL_BELOW * area3
    for make in ((unfolded, projected) if unrolled_first else (projected, unfolded)):
        uv = make()
        if uv is None:
            continue
        extent = float(np.abs(uv).max())
        if extent > 0 and _simple(uv / extent):
            return uv, make is projected
    return None, False


def _sides_found(xy: np.ndarray, points2: np.ndarray, markers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points Triangle put on the sides of a ring ``xy`` (n, 2; side j from entry j to j + 1, its
    segment marker j + 2): their sides and how far along them (0 to 1)."""
    n = len(xy)
    on = np.flatnonzero(markers[n:] >= 2) + n
    segment = markers[on] - 2
    a, b = xy[segment], xy[(segment + 1) % n]
    d = b - a
    f = np.einsum("pk,pk->p", points2[on] - a, d) / np.maximum(np.einsum("pk,pk->p", d, d), 1e-300)
    return segment, np.clip(f, 0.0, 1.0)


def _budgets(charts: list[np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    """Meshing 4's guards per region, from its corners in its chart: whether it is a needle (a
    corner under ``_NEEDLE`` degrees), and the points its shape adds to its budget (``P^2 / A``, at
    most ``_SHAPE_CAP``; none for a needle or a region with no chart)."""
    needle = np.zeros(len(charts), dtype=bool)
    extra = np.zeros(len(charts), dtype=np.int64)
    for r, uv in enumerate(charts):
        if uv is None:
            continue
        a, b = uv - np.roll(uv, 1, 0), np.roll(uv, -1, 0) - uv
        turn = np.degrees(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b)))
        needle[r] = bool(np.any(180.0 - turn < _NEEDLE))
        area = 0.5 * abs(_twice_area(uv))
        perimeter = float(np.linalg.norm(b, axis=1).sum())
        if not needle[r] and area > 0.0:
            extra[r] = int(min(perimeter * perimeter / area, _SHAPE_CAP))
    return needle, extra


def _refine3(vertices: np.ndarray, offsets: np.ndarray, cycles: np.ndarray, coarse: np.ndarray,
             owners: np.ndarray, triangulate_polygons: Callable[..., np.ndarray], *, guarded: bool = False,
             known: list[tuple[np.ndarray | None, bool] | None] | None = None, tidy: bool = False
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Meshing 3 of checked arrays (as ``_refine``): each region in its chart (``_chart``), the sides'
    points settled by passes until no region's own mesh splits a side (``_PASSES`` at most);
    ``guarded``: meshing 4, curved regions unrolled first, projected ones lifted as membranes,
    needles whose refinement runs out of points keep their sides whole, budgets follow shapes
    (``_budgets``); ``mesh_surface`` has cut regions simple in no chart into pieces (``_pieces``),
    and ``known`` holds the charts it found on the way (None: find it here); ``tidy``: meshing 5,
    each region's triangles tidied in space once lifted (``_tidy``) and twin side points merged
    (``_TWIN``)."""
    sizes = np.diff(offsets)
    n_regions = len(sizes)
    centroid, newell, perimeter, region_of, nxt = _region_geometry(vertices, offsets, cycles)
    width = np.where(perimeter > 0, np.linalg.norm(newell, axis=1) / np.where(perimeter > 0, perimeter, 1.0),
                     0.0)
    coarse_start = np.searchsorted(owners, np.arange(n_regions + 1))
    charts: list[np.ndarray | None] = [None] * n_regions

    def coarse_of(r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Region r's cycle, its meshing-1 triangles, and those as indices into the cycle."""
        cyc = cycles[offsets[r]:offsets[r + 1]]
        own = coarse[coarse_start[r]:coarse_start[r + 1]]
        local = _local(cyc, own) if len(own) else own.reshape(-1, 3)
        return cyc, own, local

    membrane = np.zeros(n_regions, dtype=bool)     # meshing 4: projected regions lift as membranes
    for r in range(n_regions):
        cyc, _, local = coarse_of(r)
        found = known[r] if known is not None else None
        if found is not None:
            charts[r], membrane[r] = found
        elif sizes[r] >= 3 and len(np.unique(cyc)) == len(cyc):
            charts[r], membrane[r] = _chart(vertices[cyc], local, centroid[r], newell[r],
                                            unrolled_first=guarded)
    membrane &= guarded
    simple = np.array([c is not None for c in charts], dtype=bool)
    needle, extra = _budgets(charts) if guarded else (np.zeros(n_regions, dtype=bool),
                                                      np.zeros(n_regions, dtype=np.int64))
    split = _EdgeSplit(vertices, cycles, nxt, region_of, width, simple, n_regions, _TWIN if tidy else 0.0)
    rings = split.rings
    n_vertices = len(vertices)

    def ring_xy(r: int) -> tuple[np.ndarray, np.ndarray]:
        """Region r's ring ids and their chart coordinates (a side's points at their parameter)."""
        at = slice(rings.offsets[r], rings.offsets[r + 1])
        ids, s, t = rings.ring[at], rings.side[at], rings.t[at]
        uv = charts[r]
        assert uv is not None
        k = s - offsets[r]
        here, there = uv[k], uv[(k + 1) % sizes[r]]
        fwd = split.forward[s][:, None]
        p_lo, p_hi = np.where(fwd, here, there), np.where(fwd, there, here)
        xy = p_lo + t[:, None] * (p_hi - p_lo)
        corner = ids < n_vertices
        xy[corner] = here[corner]
        return ids, xy

    done: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    splits = np.zeros(n_regions, dtype=np.int64)     # passes in which each region split its sides
    pending = [r for r in range(n_regions) if simple[r]]
    spent = np.zeros(n_regions, dtype=bool)   # needles whose refinement ran out of points
    for pass_ in range(_PASSES + 1):
        found_edges: list[np.ndarray] = []
        found_t: list[np.ndarray] = []
        for r in pending:
            ids, xy = ring_xy(r)
            keep = splits[r] >= _OWN_SPLITS or pass_ == _PASSES or bool(spent[r])
            budget = _STEINER * len(ids) + _STEINER_FLOOR + int(extra[r])
            got = _triangulate_region(xy, f"pq{_MIN_ANGLE:g}{'Y' if keep else ''}QS{budget}", marked=True)
            if needle[r] and not keep and got is not None and len(got[0]) - len(xy) >= budget:
                spent[r] = True     # its refinement ran out of points: its sides stay as they are
                got = _triangulate_region(xy, f"pq{_MIN_ANGLE:g}YQS{budget}", marked=True)
            if got is None:
                continue
            points2, tri, markers = got
            segment, frac = _sides_found(xy, points2, markers)
            if not len(segment):
                done[r] = (points2, tri)
                continue
            splits[r] += 1
            edges, t = split.on_edges(rings, r, segment, frac)
            found_edges.append(edges)
            found_t.append(t)
        if not found_edges:
            break
        rings = split.add(np.concatenate(found_edges), np.concatenate(found_t))
        for r in np.unique(region_of[np.isin(split.inverse, split.changed)]):
            done.pop(int(r), None)          # its sides have new points: meshed again
        pending = [r for r in range(n_regions) if simple[r] and r not in done]
    def final(r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        if r not in done:
            return None
        _, own, local = coarse_of(r)
        uv = charts[r]
        assert uv is not None
        return done[r][0], done[r][1], uv[local], vertices[own]

    return _lifted(rings, sizes, final, triangulate_polygons, membrane, tidy)
