"""The Surface value: triangles cover the regions, validation catches broken maps, adjacency, digest."""

from __future__ import annotations

import numpy as np
import pytest

from genr8_dist.errors import GrowthError
from genr8_dist.hemls import Surface, grow, load_system


def _areas(surface: Surface, tri: np.ndarray) -> np.ndarray:
    v = surface.vertices
    return 0.5 * np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])[:, 2]


def _polygon_area(points: np.ndarray) -> float:
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_four_sided_tiles_three_steps_is_64_quads_of_two_triangles():
    surface = grow(load_system("four_sided_tiles"), steps=3).surface
    tri = surface.triangles()
    assert tri.shape == (128, 3) and surface.n_vertices == 81
    assert np.all(_areas(surface, tri) > 0)  # oriented like the regions: counter-clockwise
    assert np.isclose(_areas(surface, tri).sum(), _polygon_area(surface.vertices[surface.perimeter()]))


@pytest.mark.parametrize(("name", "steps"), [("koch", 4), ("quadratic_koch", 2)])
def test_concave_regions_are_triangulated_without_overlap(name, steps):
    surface = grow(load_system(name), steps=steps).surface
    tri = surface.triangles()
    assert len(tri) == surface.n_vertices - 2
    areas = _areas(surface, tri)
    assert np.all(areas > 0)
    assert np.isclose(areas.sum(), _polygon_area(surface.vertices[surface.perimeter()]))


# -- triangulating regions with collinear runs -------------------------------------------------------

def _with_runs(corners, per_side: int) -> np.ndarray:
    """(m, 3) a polygon through ``corners`` (counter-clockwise, z = 0) with ``per_side - 1`` more
    vertices evenly along every side: the straight sides growth leaves, split at every step."""
    corners = np.asarray(corners, dtype=float)
    t = np.arange(per_side)[:, None] / per_side
    sides = [a + t * (b - a) for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True)]
    points = np.concatenate(sides)
    return np.column_stack([points, np.zeros(len(points))])


def _one_region(points: np.ndarray) -> Surface:
    """A surface of one region, the polygon ``points``."""
    m = len(points)
    cycle = np.arange(m)
    edges = np.stack([cycle, np.roll(cycle, -1)], axis=1)
    return Surface(points, edges, np.zeros(m, int), np.zeros(m, int), np.array([0, m]), cycle, cycle)


def _twice_areas(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    return np.cross(b - a, c - a)[:, 2]


def _inside(points: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Even-odd test of points ``xy`` (n, 2) against the polygon ``points``."""
    x, y = points[:, 0], points[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    px, py = xy[:, :1], xy[:, 1:]
    crosses = ((y > py) != (y2 > py)) & (px < x + (py - y) * (x2 - x) / np.where(y2 != y, y2 - y, 1.0))
    return np.count_nonzero(crosses, axis=1) % 2 == 1


SQUARE = [(0, 0), (1, 0), (1, 1), (0, 1)]
LONG = [(0, 0), (6, 0), (6, 1), (0, 1)]
# a U: non-convex, its arms' inner sides facing each other across a slot
U_SHAPE = [(0, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]
COMB = [(0, 0), (8, 0), (8, 3), (7, 3), (7, 1), (5, 1), (5, 3), (4, 3), (4, 1.5), (3, 1.5), (3, 3),
        (1, 3), (1, 1), (0.5, 1), (0.5, 3), (0, 3)]


@pytest.mark.parametrize("corners", [SQUARE, LONG, U_SHAPE, COMB], ids=["square", "long", "u", "comb"])
@pytest.mark.parametrize("per_side", [1, 3, 7, 12])
def test_regions_with_collinear_runs_are_cut_inside_their_outline_without_zero_area_triangles(
        corners, per_side):
    points = _with_runs(corners, per_side)
    tri = _one_region(points).triangles()
    assert tri.shape == (len(points) - 2, 3)                  # m - 2 triangles, no new vertex
    twice = _twice_areas(points, tri)
    assert np.all(twice > 1e-9)                                # none degenerate, all counter-clockwise
    assert np.isclose(twice.sum() / 2, _polygon_area(points))  # they cover the region once
    centroids = points[tri].mean(axis=1)[:, :2]
    assert np.all(_inside(points, centroids))                  # inside the outline, notches kept out


def test_a_side_split_many_times_gets_no_sliver_a_fan_would_give():
    """A square whose sides carry 2 more vertices each: a fan from a corner gives zero-area triangles
    between collinear neighbours; the triangulation's thinnest triangle has 18.4 degrees (atan 1/3)."""
    from genr8_dist.fitness import slivers, triangle_min_angles

    surface = _one_region(_with_runs(SQUARE, 3))
    angles = triangle_min_angles(surface.vertices, surface.triangles())
    assert angles.min() == pytest.approx(np.degrees(np.arctan(1 / 3)))
    assert slivers(surface) == 0.0


def _total_cost(points: np.ndarray, tri: np.ndarray) -> float:
    """Sum over the triangles of 1 / quality (sum of squared sides / (4 sqrt(3) area))."""
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    sides = np.sum((b - a) ** 2 + (c - a) ** 2 + (c - b) ** 2, axis=1)
    return float(np.sum(sides / (2.0 * np.sqrt(3.0) * np.linalg.norm(np.cross(b - a, c - a), axis=1))))


@pytest.mark.parametrize(("corners", "per_side", "lift"),
                         [(COMB, 6, 0.3), (U_SHAPE, 10, 0.0), (LONG, 20, 0.3), (SQUARE, 1200, 0.0)])
def test_a_large_region_is_cut_on_its_true_corners_then_its_runs(monkeypatch, corners, per_side, lift):
    """More than _EXACT_MAX vertices, few true corners: the true corners get the exact programme and
    the straight runs fans and strips, then flips, never ear clipping's quadratic path; the triangles
    lie inside the outline, none degenerate, within 0.5% of the exact programme's total cost (run on
    the same region by raising the limit; the lifted shapes have z = 0.3 x y)."""
    from genr8_dist.hemls import surface as module

    points = _with_runs(corners, per_side)
    points[:, 2] = lift * points[:, 0] * points[:, 1]
    assert len(points) > module._EXACT_MAX

    def refuse(points):
        raise AssertionError("ear clipping used on a region of few true corners")

    monkeypatch.setattr(module, "_clip_and_flip", refuse)
    tri = _one_region(points).triangles()
    twice = _twice_areas(points, tri)
    assert len(tri) == len(points) - 2 and np.all(twice > 1e-9)
    assert np.isclose(twice.sum() / 2, _polygon_area(points))
    assert np.all(_inside(points, points[tri].mean(axis=1)[:, :2]))
    if len(points) <= 128:
        monkeypatch.setattr(module, "_EXACT_MAX", 128)
        exact = _one_region(points).triangles()
        assert _total_cost(points, tri) <= 1.005 * _total_cost(points, exact)


def test_a_large_region_of_many_true_corners_is_clipped_and_flipped_inside_its_outline():
    """A large region whose every vertex is a corner (a zigzag): ear clipping and flips, inside the
    outline, none degenerate."""
    xs = np.linspace(0.0, 10.0, 60)
    top = np.column_stack([xs[::-1], 2.0 + 0.3 * (np.arange(60) % 2), np.zeros(60)])
    bottom = np.column_stack([xs, -0.3 * (np.arange(60) % 2), np.zeros(60)])
    points = np.concatenate([bottom, top])
    tri = _one_region(points).triangles()
    twice = _twice_areas(points, tri)
    assert len(tri) == len(points) - 2 and np.all(twice > 1e-9)
    assert np.isclose(twice.sum() / 2, _polygon_area(points))
    assert np.all(_inside(points, points[tri].mean(axis=1)[:, :2]))


def test_grown_surfaces_mesh_consistently_and_repeatably():
    """A grown surface with long straight sides: every region gets m - 2 triangles, the mesh's winding
    is consistent, its open edges are exactly the perimeter's, and the same surface gives the same
    bytes."""
    import trimesh

    from genr8_dist.environment import Environment
    from genr8_dist.hemls import parse

    text = "A + A + A + A\nA -> A [ + A ] A\nBranchAngle 60\nAngle 90\n"
    # "first": the square's two tied joins cross, and the default branch_ties makes neither
    surface = grow(parse(text), Environment(steps=4, branch_ties="first")).surface
    assert surface.n_regions > 4 and surface.region_sizes.max() > 8
    tri = surface.triangles()
    assert len(tri) == int(np.sum(surface.region_sizes - 2))
    mesh = trimesh.Trimesh(surface.vertices, tri, process=False)
    assert mesh.is_winding_consistent
    edges = np.sort(mesh.edges, axis=1)
    keys, counts = np.unique(edges, axis=0, return_counts=True)
    ring = surface.perimeter()
    perimeter = np.sort(np.stack([ring, np.roll(ring, -1)], axis=1), axis=1)
    assert counts.max() == 2
    assert np.array_equal(keys[counts == 1], np.unique(perimeter, axis=0))
    again = Surface(surface.vertices, surface.edges, surface.labels, surface.ages, surface.region_offsets,
                    surface.region_vertices, surface.perimeter())
    assert again.triangles().tobytes() == tri.tobytes()


def test_regions_and_perimeter_are_counter_clockwise_cycles_of_edges():
    surface = grow(load_system("three_sided_tiles"), steps=2).surface
    for region in surface.regions:
        assert _polygon_area(surface.vertices[region]) > 0
    assert _polygon_area(surface.vertices[surface.perimeter()]) > 0
    assert surface.perimeter_mask.sum() == len(surface.perimeter()) == 12


def test_adjacency_and_degrees():
    surface = grow(load_system("four_sided_tiles"), steps=1).surface
    centre = int(np.argmin(np.linalg.norm(surface.vertices - surface.centre, axis=1)))
    assert len(surface.neighbours(centre)) == 4
    assert np.bincount(surface.degrees).tolist() == [0, 0, 4, 4, 1]  # 4 corners, 4 sides, 1 centre
    indptr, indices = surface.adjacency
    assert indptr[-1] == len(indices) == 2 * surface.n_edges


def test_validate_finds_a_dangling_edge_and_a_broken_euler_count():
    good = grow(load_system("four_sided_tiles"), steps=1).surface
    assert good.validate() == []
    edges = good.edges[1:]  # drop one edge: two regions lose a side
    broken = Surface(good.vertices, edges, good.labels[1:], good.ages[1:], good.region_offsets,
                     good.region_vertices, good.perimeter())
    problems = broken.validate()
    assert any("not edges" in p for p in problems) and any("Euler" in p for p in problems)
    with pytest.raises(GrowthError, match="invalid surface map"):
        broken.validate(strict=True)
    extra = np.vstack([good.vertices, [[5.0, 5.0, 0.0]]])
    dangling = Surface(extra, np.vstack([good.edges, [[0, 9]]]), np.append(good.labels, 0),
                       np.append(good.ages, 0), good.region_offsets, good.region_vertices, good.perimeter())
    assert any("dangling" in p for p in dangling.validate())


def test_arrays_are_read_only_and_digest_tracks_vertex_bytes():
    surface = grow(load_system("square"), steps=2).surface
    with pytest.raises(ValueError):
        surface.vertices[0, 0] = 1.0
    again = grow(load_system("square"), steps=2).surface
    assert surface.digest() == again.digest()
    moved = Surface(surface.vertices + 1e-12, surface.edges, surface.labels, surface.ages,
                    surface.region_offsets, surface.region_vertices, surface.perimeter())
    assert moved.digest() != surface.digest()


def test_mirror_line_finds_a_line_of_symmetry_and_only_a_true_one():
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import parse

    tiles = grow(load_system("four_sided_tiles"), Environment(steps=3)).surface
    u = tiles.mirror_line()
    assert u is not None and np.isclose(np.linalg.norm(u), 1.0)
    # a bend that turns one way only has no mirror line
    bent = grow(parse("A + A + A + A\nA -> A + A - A\nAngle 30\n"), Environment(steps=2)).surface
    assert bent.mirror_line() is None
    # the same vertices with one edge moved: vertices match, edges do not
    moved = tiles.edges.copy()
    moved[0] = (moved[0, 0], next(v for v in range(tiles.n_vertices) if v not in moved[0]))
    other = Surface(tiles.vertices, moved, tiles.labels, tiles.ages, tiles.region_offsets,
                    tiles.region_vertices, tiles.perimeter())
    assert other.mirror_line() is None
