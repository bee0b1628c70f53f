"""Meshing versions (genr8_dist.hemls.meshing): well-shaped triangles, the same bytes twice, old runs
keeping meshing 1, new runs recording the meshing they use."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from genr8_dist.environment import Environment
from genr8_dist.fitness import SLIVER_DEGREES, sliver_roundness, slivers
from genr8_dist.hemls import grow, load_system, parse
from genr8_dist.hemls.meshing import MESHING, mesh_surface, triangle_min_angles

DATA = Path(__file__).resolve().parents[1] / "data"


def _random_surfaces(n: int):
    from genr8_dist.grammar import load_universe
    from genr8_dist.rng import stream

    universe, rng = load_universe("default"), stream(0, "test", "meshing")
    out = []
    while len(out) < n:
        result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
        if result.valid:
            surface = grow(parse(result.text), Environment()).surface
            if surface.n_regions > 1:
                out.append(surface)
    return out


def _fresh(s, meshing=None):
    from genr8_dist.hemls import Surface

    return Surface(s.vertices, s.edges, s.labels, s.ages, s.region_offsets, s.region_vertices,
                   s.perimeter(), s.masses, s.stopped, meshing=meshing)


def test_tiles_meshed_without_an_angle_below_twenty_degrees_and_watertight():
    surface = grow(load_system("three-sided-tiles"), Environment(steps=3)).surface
    assert surface.meshing == MESHING == 8
    mesh = surface.mesh()
    assert np.array_equal(mesh.points[:surface.n_vertices], surface.vertices)
    assert triangle_min_angles(mesh.points, mesh.triangles).min() >= 20.0
    # every inner mesh edge is shared by exactly two triangles: regions meet on the same points
    e = np.sort(np.concatenate([mesh.triangles[:, [0, 1]], mesh.triangles[:, [1, 2]],
                                mesh.triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() == 2
    assert not len(mesh.fallback)


def _strip(turn_degrees: float, n: int = 24, height: float = 0.6):
    """One region: a strip of a cylinder's wall turning ``turn_degrees`` about the z axis. Beyond 180
    degrees it folds back over itself in its best-fit plane, but it unrolls flat."""
    from genr8_dist.hemls import Surface

    theta = np.radians(np.linspace(0.0, turn_degrees, n))
    bottom = np.c_[np.cos(theta), np.sin(theta), np.zeros(n)]
    top = np.c_[np.cos(theta), np.sin(theta), np.full(n, height)][::-1]
    vertices = np.concatenate([bottom, top])
    cycle = np.arange(len(vertices))
    zeros = np.zeros(len(cycle), dtype=np.int64)
    return Surface(vertices, np.c_[cycle, np.roll(cycle, -1)], zeros, zeros, np.array([0, len(cycle)]),
                   cycle, cycle)


@pytest.mark.parametrize("turn", [200.0, 300.0])
def test_a_region_crossing_itself_in_its_plane_is_meshed_unrolled(turn):
    """Meshing 2 cuts such a region as meshing 1 does; meshing 3 unfolds it and meshes it well."""
    strip = _strip(turn)
    assert strip.with_meshing(2).mesh().fallback.tolist() == [0]
    mesh = strip.mesh()
    assert not len(mesh.fallback) and len(mesh.triangles) > 2 * strip.n_vertices
    assert triangle_min_angles(mesh.points, mesh.triangles).min() >= 20.0
    # every added point lies on the cylinder's wall, between its bottom and its top
    radius = np.hypot(mesh.points[:, 0], mesh.points[:, 1])
    assert radius.min() > np.cos(np.pi / 23) - 1e-9 and radius.max() <= 1.0 + 1e-9
    assert mesh.points[:, 2].min() >= -1e-12 and mesh.points[:, 2].max() <= 0.6 + 1e-12


def test_a_curved_region_with_wide_corners_has_no_triangle_under_fifteen_degrees():
    """A 40-gon on a dome (all its corners 171 degrees) next to a square: no thin triangle, and the
    two regions meet on the same points."""
    from genr8_dist.hemls import Surface

    n = 40
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.c_[np.cos(angle), np.sin(angle)] * 2.0
    dome = np.c_[ring, 0.3 * (4.0 - (ring ** 2).sum(1)) + 0.2 * ring[:, 0]]
    vertices = np.concatenate([dome, [[0.0, 0.0, 0.0]]])
    cycle = np.arange(n)
    zeros = np.zeros(n, dtype=np.int64)
    surface = Surface(vertices, np.c_[cycle, np.roll(cycle, -1)], zeros, zeros, np.array([0, n]), cycle,
                      cycle)
    mesh = surface.mesh()
    angles = triangle_min_angles(mesh.points, mesh.triangles)
    assert not len(mesh.fallback) and angles.min() >= 15.0
    assert len(mesh.triangles) > n


def test_meshing_2_is_kept_bit_for_bit_for_runs_that_recorded_it():
    """Runs created under meshing 2 regrow their meshes as they were (this digest is round 5's)."""
    import hashlib

    surface = grow(load_system("three-sided-tiles"), Environment(steps=3)).surface.with_meshing(2)
    mesh = surface.mesh()
    digest = hashlib.sha256(mesh.points.tobytes() + mesh.triangles.tobytes()).hexdigest()
    assert digest == "d82b58f327724b64390c91825a168f704eccd0fbcc38f6e201aae77ee3c459be"


def test_random_default_surfaces_far_fewer_thin_triangles_than_meshing_1():
    thin = {1: [0, 0], MESHING: [0, 0]}
    for surface in _random_surfaces(6):
        for meshing in (1, MESHING):
            mesh = surface.with_meshing(meshing).mesh()
            angles = triangle_min_angles(mesh.points, mesh.triangles)
            thin[meshing][0] += int(np.sum(angles < 15.0))
            thin[meshing][1] += len(angles)
    share1, share = thin[1][0] / thin[1][1], thin[MESHING][0] / thin[MESHING][1]
    assert share1 > 0.5 and share < share1 / 10


@pytest.mark.parametrize(("meshing", "expected"), [
    (3, "7631c24e1a9db3a8fe68d72109ec5151ecf0677e62fbf28619d7a2e1702f6f5b"),   # round 13's code
    (4, "9d7b784c84e10b0529e7a9b6233880c41b5daf0ab398ea0695a93f225ced7876"),   # before meshing 5
    (5, "f419dfff0369e1327e410ca7944155b682b93df2e11144658b692f37c977b6ce"),   # before meshing 6
    (6, "12059ca063d442b0018ca16fcb0c567a52e3e8318b49364b78936ae4c53e18bd"),   # before meshing 7
    (7, "ab42e2652c7fb09c9c74e2ac1dc4e5960354e06a9f881f86b20f9cc02d335578"),   # before meshing 8
])
def test_an_old_meshing_is_kept_bit_for_bit_for_runs_that_recorded_it(meshing, expected):
    """Runs created under meshing 3 to 7 regrow their meshes as they were: the digests are those of
    the code before the next meshing was written."""
    import hashlib

    digest = hashlib.sha256()
    for surface in _random_surfaces(3):
        mesh = surface.with_meshing(meshing).mesh()
        digest.update(mesh.points.tobytes() + mesh.triangles.tobytes())
    assert digest.hexdigest() == expected


def _square_and_needle(reach: float):
    """Two regions sharing a side: a unit square, and a needle from that side to a point ``reach``
    away (its corner there is 2 atan(0.5 / (reach - 1)): 0.0006 degrees at 100,000)."""
    from genr8_dist.hemls import Surface

    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [reach, 0.5, 0]], dtype=np.float64)
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [1, 4], [4, 2]])
    zeros = np.zeros(len(edges), dtype=np.int64)
    return Surface(vertices, edges, zeros, zeros, np.array([0, 4, 7]), np.array([0, 1, 2, 3, 1, 4, 2]),
                   np.array([0, 1, 4, 2, 3]))


def test_a_needle_keeps_its_sides_whole_and_hands_its_neighbours_no_points():
    """Meshing 3 lets the needle's refinement split its sides towards its 0.0006-degree corner until
    its budget runs out, and the square inherits the points (118,071 triangles for two regions,
    2,842 under 15 degrees); meshing 4 then keeps them whole: a mesh of the needle's own size, the
    square still well shaped, the two meeting watertight."""
    surface = _square_and_needle(100_000.0)
    assert len(surface.with_meshing(3).mesh().triangles) > 100_000
    mesh = surface.mesh()
    assert len(mesh.triangles) < 200 and not len(mesh.fallback)
    angles = triangle_min_angles(mesh.points, mesh.triangles)
    assert angles[mesh.regions == 0].min() >= 20.0
    e = np.sort(np.concatenate([mesh.triangles[:, [0, 1]], mesh.triangles[:, [1, 2]],
                                mesh.triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert counts.max() == 2


def test_meshing_4_budgets_follow_each_region_shape():
    """A needle (a corner under a hundredth of a degree) is marked and adds nothing; a square adds
    P^2/A = 16 points; a strip 270 times as long as wide about 4 x 270, the cells of its width."""
    from genr8_dist.hemls.meshing import _budgets

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    strip = square * np.array([3.3, 3.3 / 270])
    needle = np.array([[0.0, 0.0], [100_000.0, 0.5], [0.0, 1.0]])
    flags, extra = _budgets([square, strip, needle, None])
    assert flags.tolist() == [False, False, True, False]
    assert extra[0] == 16 and 4 * 270 <= extra[1] <= 4 * 272 and extra[2] == extra[3] == 0


@pytest.mark.parametrize("turn", [150.0, 170.0])
def test_a_curved_region_is_meshed_unrolled_so_its_triangles_keep_their_angles_in_space(turn):
    """Meshing 3 meshes a strip of a cylinder turning 150-170 degrees in its best-fit plane (it is
    simple there), and lifting it back onto the wall bends its triangles (170: smallest angle 8
    degrees); meshing 4 meshes it unrolled first, so no angle is under 28 degrees in space."""
    strip = _strip(turn)
    if turn == 170.0:
        old = strip.with_meshing(3).mesh()
        assert triangle_min_angles(old.points, old.triangles).min() < 15.0
    mesh = strip.mesh()
    assert not len(mesh.fallback) and triangle_min_angles(mesh.points, mesh.triangles).min() >= 27.0


def test_the_same_map_meshes_to_the_same_bytes():
    for surface in _random_surfaces(3):
        a, b = _fresh(surface).mesh(), _fresh(surface).mesh()
        assert a.points.tobytes() == b.points.tobytes()
        assert a.triangles.tobytes() == b.triangles.tobytes()


def test_meshing_1_is_the_old_cut_on_the_map_vertices():
    surface = _random_surfaces(1)[0].with_meshing(1)
    mesh = surface.mesh()
    assert mesh.points.tobytes() == surface.vertices.tobytes()
    assert mesh.triangles.tobytes() == surface.triangles().tobytes()
    assert mesh_surface(surface, 1).triangles.tobytes() == surface.triangles().tobytes()


def test_slivers_measures_thin_regions_under_meshing_2_and_triangles_under_meshing_1():
    surface = _random_surfaces(1)[0]
    old = surface.with_meshing(1)
    angles = triangle_min_angles(old.vertices, old.triangles())
    assert slivers(old) == pytest.approx(float(np.mean(angles < SLIVER_DEGREES)))
    from genr8_dist.hemls.meshing import region_roundness

    assert slivers(surface) == pytest.approx(float(np.mean(region_roundness(surface) < sliver_roundness())))
    tiles = grow(load_system("four-sided-tiles"), Environment(steps=3)).surface
    assert slivers(tiles) == 0.0          # squares are not thin


def test_unknown_meshing_is_a_config_error():
    from genr8_dist.config import RunConfig
    from genr8_dist.errors import ConfigError

    with pytest.raises(ConfigError, match="meshing"):
        RunConfig.from_toml("meshing = 9\n")
    assert RunConfig.from_toml("meshing = 1\n").meshing == 1
    assert RunConfig.from_toml("").meshing == MESHING


def test_new_runs_record_their_meshing_and_old_runs_keep_meshing_1(tmp_path):
    from genr8_dist.store import RunStore

    new = RunStore.create(tmp_path / "new", "universe = \"default\"\n[ea]\npopulation = 6\n")
    assert new.meshing == MESHING and new.config(1).meshing == MESHING
    named = RunStore.create(tmp_path / "named", "meshing = 1\n")
    assert RunStore.open(tmp_path / "named").meshing == 1 and named.config(1).meshing == 1
    old = RunStore.open(DATA / "run-schema-v2")
    assert old.meshing == 1 and old.config(1).meshing == 1


@pytest.mark.slow
def test_an_old_run_regrows_with_meshing_1(tmp_path):
    """The checked-in run regrows bit for bit (its digests) and is cut and measured as meshing 1: the
    map's own triangles. (Its stored crit_slivers predate issue 10's cut of meshing 1, so they are not
    compared here; tests/distributed checks a run's rows regrow.)"""
    from genr8_dist.history import HistoryError, _regrow
    from genr8_dist.store import RunStore

    run = tmp_path / "old"
    shutil.copytree(DATA / "run-schema-v2", run)
    store = RunStore.open(run)
    table = store.dataset().to_table().to_pylist()
    checked = 0
    for row in table:
        if not row.get("valid") or row.get("crit_slivers") is None:
            continue
        try:
            result = _regrow.regrow(run, row["id"])
        except HistoryError:      # grown before a later growth change (main fails on it too)
            continue
        assert result.developed.value.meshing == 1
        surface = result.developed.value
        assert surface.mesh().triangles.tobytes() == surface.triangles().tobytes()
        angles = triangle_min_angles(surface.vertices, surface.triangles())
        assert slivers(surface) == float(np.mean(angles < SLIVER_DEGREES))
        checked += 1
        if checked == 3:
            break
    assert checked >= 1


def test_a_bent_region_spans_its_sides_as_a_membrane_not_meshing_1s_creased_fan():
    """An oval of 240 corners whose height rises and falls three times round it (bent, but not
    enough to unroll): meshing 1's fan of it is creased in space, and meshing 3's points lifted
    onto the fan copy the creases (smallest angle 9 degrees, 26 triangles under 15); meshing 4's
    membrane has none under 25 and stays within the heights of its sides."""
    from genr8_dist.hemls import Surface

    n = 240
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    radius = 2.0 * (1.0 + 0.3 * np.cos(2 * angle))
    ring = np.c_[radius * np.cos(angle), radius * np.sin(angle), 0.3 * np.cos(3 * angle)]
    cycle = np.arange(n)
    zeros = np.zeros(n, dtype=np.int64)
    surface = Surface(ring, np.c_[cycle, np.roll(cycle, -1)], zeros, zeros, np.array([0, n]), cycle, cycle)
    old = surface.with_meshing(3).mesh()
    assert triangle_min_angles(old.points, old.triangles).min() < 15.0
    mesh = surface.mesh()
    assert not len(mesh.fallback) and triangle_min_angles(mesh.points, mesh.triangles).min() >= 25.0
    assert mesh.points[:, 2].min() >= -0.3 - 1e-9 and mesh.points[:, 2].max() <= 0.3 + 1e-9


def test_a_region_overlapping_itself_in_every_chart_is_meshed_in_pieces():
    """A ramp winding 420 degrees round an axis (a spiral stair's flight) overlaps itself projected
    and unrolled: meshing 3 cuts it as meshing 1 does (64 of 78 triangles under 15 degrees); meshing
    4 cuts it into pieces along its meshing-1 diagonals, meshes them as neighbours, and counts every
    triangle as the ramp's, none under 25 degrees."""
    from genr8_dist.hemls import Surface

    theta = np.radians(np.linspace(0.0, 420.0, 40))
    inner = np.c_[np.cos(theta), np.sin(theta), 0.02 * theta]
    outer = np.c_[2.0 * np.cos(theta), 2.0 * np.sin(theta), 0.02 * theta][::-1]
    vertices = np.concatenate([inner, outer])
    cycle = np.arange(len(vertices))
    zeros = np.zeros(len(cycle), dtype=np.int64)
    ramp = Surface(vertices, np.c_[cycle, np.roll(cycle, -1)], zeros, zeros, np.array([0, len(cycle)]),
                   cycle, cycle)
    assert ramp.with_meshing(3).mesh().fallback.tolist() == [0]
    mesh = ramp.mesh()
    assert not len(mesh.fallback) and set(mesh.regions.tolist()) == {0}
    assert triangle_min_angles(mesh.points, mesh.triangles).min() >= 25.0
    assert np.array_equal(mesh.points[:len(vertices)], vertices)


def test_meshing_5_leaves_far_fewer_thin_triangles_in_regions_with_wide_corners(bench_module):
    """Three random default surfaces (the first, fifth and sixth of ``_random_surfaces(6)``): in regions
    whose corners are all at least 20 degrees in their plane, meshing 4 leaves 460 triangles under 15
    degrees, 295 of them in regions that do not fold over themselves; meshing 5 tidies them to 84 and
    12. What is left lies in regions that cross themselves in their plane, or on their sides."""
    bench = bench_module("meshing")   # its region_shapes and folded define the regions
    thin = {4: [0, 0], 5: [0, 0]}
    for surface in [s for i, s in enumerate(_random_surfaces(6)) if i in (0, 4, 5)]:
        good = bench.region_shapes(surface)[0]
        flat = good & ~bench.folded(surface)
        for meshing in (4, 5):
            mesh = surface.with_meshing(meshing).mesh()
            under = triangle_min_angles(mesh.points, mesh.triangles) < 15.0
            thin[meshing][0] += int(np.sum(under & good[mesh.regions]))
            thin[meshing][1] += int(np.sum(under & flat[mesh.regions]))
            if meshing == 5:
                e = np.sort(np.concatenate([mesh.triangles[:, [0, 1]], mesh.triangles[:, [1, 2]],
                                            mesh.triangles[:, [2, 0]]]), axis=1)
                assert np.unique(e, axis=0, return_counts=True)[1].max() <= 2     # still conforming
    assert thin[5][0] * 4 < thin[4][0] and thin[5][1] * 10 < thin[4][1]


def test_tidy_flips_a_thin_pair_and_moves_a_point_off_the_ring_but_holds_the_ring():
    """A rhombus cut along its long diagonal (two triangles of 11 degrees) is cut along the short one;
    a point crowded against one side of a square moves to its neighbours' mean; ring points stay."""
    from genr8_dist.hemls.meshing import _tidy

    rhombus = np.array([[-5.0, 0.0, 0.0], [0.0, -1.0, 0.0], [5.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    points, tri = _tidy(rhombus, np.array([[0, 1, 2], [0, 2, 3]]), 4)
    assert np.array_equal(points, rhombus)
    assert {tuple(sorted(t)) for t in tri.tolist()} == {(0, 1, 3), (1, 2, 3)}
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.02, 0.0]])
    fan = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    points, tri = _tidy(square, fan, 4)
    assert np.array_equal(points[:4], square[:4]) and np.array_equal(tri, fan)
    assert triangle_min_angles(points, tri).min() > triangle_min_angles(square, fan).min()
    assert points[4, 1] > 0.2


def test_twin_points_on_a_side_are_one_under_meshing_5():
    """Points sorted by edge and parameter: a point nearer the one before it than a hundredth of the
    gaps beside the pair is a twin; an edge's ends count as gaps, another edge's points do not."""
    from genr8_dist.hemls.meshing import _TWIN, _EdgeSplit

    split = object.__new__(_EdgeSplit)
    split.merge = _TWIN
    e = np.array([0, 0, 0, 1, 1, 2])
    t = np.array([0.25, 0.5, 0.5001, 0.5, 0.5004, 0.5])
    assert split._twins(e, t).tolist() == [False, False, True, False, True, False]
    assert not split._twins(e, np.array([0.25, 0.5, 0.6, 0.5, 0.52, 0.5])).any()
