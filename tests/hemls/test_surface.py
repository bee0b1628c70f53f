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
def test_concave_regions_are_ear_clipped_without_overlap(name, steps):
    surface = grow(load_system(name), steps=steps).surface
    tri = surface.triangles()
    assert len(tri) == surface.n_vertices - 2
    areas = _areas(surface, tri)
    assert np.all(areas > 0)
    assert np.isclose(areas.sum(), _polygon_area(surface.vertices[surface.perimeter()]))


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
