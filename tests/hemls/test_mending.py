"""Mending (genr8_dist.hemls.mending, meshing 6): thin triangles mended across regions, every
region's outline and the surface's border kept, the mesh watertight, the same bytes twice."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
import pytest

from genr8_dist.hemls.mending import mend, triangle_min_angles

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_meshing import _random_surfaces


def _edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)


def _outline(points: np.ndarray, triangles: np.ndarray) -> tuple[float, np.ndarray]:
    """The length of the edges used by one triangle only (a region's outline, or the border), and
    the points on them."""
    edges, counts = _edges(triangles)
    once = edges[counts == 1]
    return float(np.linalg.norm(points[once[:, 0]] - points[once[:, 1]], axis=1).sum()), np.unique(once)


def _two_halves(y: float):
    """A unit square of two regions (x < 0.5, x > 0.5) meeting on the side x = 0.5, which carries one
    added point at height ``y``: near the bottom it makes thin triangles on both sides."""
    points = np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0], [1, 1, 0], [0.5, 1, 0], [0, 1, 0], [0.5, y, 0]],
                      dtype=np.float64)
    triangles = np.array([[0, 1, 6], [0, 6, 5], [6, 4, 5], [1, 2, 6], [2, 3, 6], [6, 3, 4]])
    return points, triangles, np.array([0, 0, 0, 1, 1, 1])


def test_a_point_on_a_shared_side_moves_or_goes_only_along_that_side():
    points, triangles, regions = _two_halves(0.02)
    assert triangle_min_angles(points, triangles).min() < 3.0
    out_p, out_t, out_r = mend(points, triangles, regions, 6)
    assert triangle_min_angles(out_p, out_t).min() >= 15.0
    assert np.array_equal(out_p[:6], points[:6])          # the surface's vertices stay
    assert np.all(out_p[6:, 0] == 0.5)                    # an added point stays on the side x = 0.5
    for r in (0, 1):                                      # each region still covers its half
        p = out_p[out_t[out_r == r]]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        assert abs(area - 0.5) < 1e-12
        assert np.all(out_p[np.unique(out_t[out_r == r])][:, 0] * (1 if r else -1) >= (0.5 if r else -0.5))
    assert _edges(out_t)[1].max() == 2
    assert list(out_r) == sorted(out_r)                   # region after region


def test_a_mesh_without_thin_triangles_is_returned_as_it_is():
    points, triangles, regions = _two_halves(0.5)
    out = mend(points, triangles, regions, 6)
    assert out[0] is points and out[1] is triangles and out[2] is regions


@pytest.mark.slow
def test_meshing_6_mends_random_surfaces_keeping_outlines_border_and_watertightness(bench_module):
    """The first, fifth and sixth random default surfaces of ``test_meshing``: meshing 5 leaves 112
    triangles under 15 degrees, 12 of them in regions whose corners are all at least 20 degrees and
    whose outline does not cross itself; meshing 6 leaves 19 and none. Every region's outline is as
    long as it was and lies on the same sides, the mesh conforms, the same bytes come twice."""
    bench = bench_module("meshing")   # its region_shapes defines the regions
    surfaces = [s for i, s in enumerate(_random_surfaces(6)) if i in (0, 4, 5)]
    thin = {5: [0, 0], 6: [0, 0]}
    digest = hashlib.sha256()
    for surface in surfaces:
        simple = bench.region_shapes(surface)[1]
        five, six = surface.with_meshing(5).mesh(), surface.with_meshing(6).mesh()
        for meshing, mesh in ((5, five), (6, six)):
            under = triangle_min_angles(mesh.points, mesh.triangles) < 15.0
            thin[meshing][0] += int(np.sum(under))
            thin[meshing][1] += int(np.sum(under & simple[mesh.regions]))
        assert np.array_equal(six.points[:surface.n_vertices], surface.vertices)
        assert np.isin(np.arange(surface.n_vertices, len(six.points)), six.triangles).all()   # none unused
        assert _edges(six.triangles)[1].max() == 2
        assert np.array_equal(np.unique(six.regions), np.unique(five.regions))
        assert np.all(np.diff(six.regions) >= 0)
        scale = np.ptp(surface.vertices, axis=0).max()
        for r in np.unique(five.regions).tolist():
            length5, _ = _outline(five.points, five.triangles[five.regions == r])
            length6, on = _outline(six.points, six.triangles[six.regions == r])
            assert abs(length6 - length5) <= 1e-9 * length5
            e5, c5 = _edges(five.triangles[five.regions == r])     # meshing 5's outline of the region
            a, b = five.points[e5[c5 == 1, 0]], five.points[e5[c5 == 1, 1]]
            p = six.points[on][:, None, :]
            d = b - a
            f = np.clip(np.einsum("psk,sk->ps", p - a, d) / np.einsum("sk,sk->s", d, d), 0.0, 1.0)
            assert np.linalg.norm(p - (a + f[..., None] * d), axis=2).min(axis=1).max() <= 1e-9 * scale
        digest.update(six.points.tobytes() + six.triangles.tobytes())
    assert thin == {5: [112, 12], 6: [19, 0]}
    again = hashlib.sha256()
    for surface in surfaces:
        six = surface.with_meshing(6).mesh()
        again.update(six.points.tobytes() + six.triangles.tobytes())
    assert again.hexdigest() == digest.hexdigest()


# A tiles surface (the 42nd random genome of bench/meshing.py's tiles set) with a region whose
# corners are all at least 20 degrees beside a needle-thin neighbour (a corner of 0.1 degree).
_BESIDE_A_NEEDLE = """Edge0 + ~ Edge2 + ~ Edge2
Edge2 -> & Edge1 [ [ + Edge2 ] - Edge2 ] Edge2 ^
Edge2 < Edge1 -> ^ Edge0 [ [ + + Edge0 ] - - Edge0 ] Edge1 &
Edge0 -> Edge2 [ [ [ [ + Edge1 ] + + Edge1 ] - Edge1 ] - - Edge1 ] Edge2
Angle 45
"""


def _thin_in_sound_regions(surface, meshing: int, sound: np.ndarray) -> tuple[int, int]:
    """Triangles under 15 degrees under ``meshing``: in regions ``sound`` marks, and in all."""
    mesh = surface.with_meshing(meshing).mesh()
    under = triangle_min_angles(mesh.points, mesh.triangles) < 15.0
    return int(np.sum(under & sound[mesh.regions])), int(np.sum(under))


def _outlines_kept(before: tuple[np.ndarray, ...], after: tuple[np.ndarray, ...]) -> None:
    """Every region of ``before`` (points, triangles, regions) has the same outline length in ``after``."""
    for r in np.unique(before[2]).tolist():
        old, _ = _outline(before[0], before[1][before[2] == r])
        new, _ = _outline(after[0], after[1][after[2] == r])
        assert abs(new - old) <= 1e-9 * old


def _mended_in_sound_regions(surface, bench_module, old: int, left: int) -> None:
    """Meshing ``old`` leaves ``left`` thin triangles in ``surface``'s sound regions (corners at
    least 20 degrees, outline simple), meshing ``old + 1`` none; the newer mesh is watertight, keeps
    the surface's vertices and every region's outline length."""
    sound = bench_module("meshing").region_shapes(surface)[2]
    assert _thin_in_sound_regions(surface, old, sound)[0] == left
    assert _thin_in_sound_regions(surface, old + 1, sound)[0] == 0
    before, after = surface.with_meshing(old).mesh(), surface.with_meshing(old + 1).mesh()
    _outlines_kept((before.points, before.triangles, before.regions),
                   (after.points, after.triangles, after.regions))
    assert _edges(after.triangles)[1].max() == 2
    assert np.array_equal(after.points[:surface.n_vertices], surface.vertices)


def test_meshing_7_splits_a_side_shared_with_a_needle_for_the_wide_cornered_region(bench_module):
    """Meshing 6 leaves one triangle of 8.2 degrees in a region whose corners are all at least 20
    degrees: the repair splits the side it shares with a needle-thin region, which then holds one
    more thin triangle, so the count of thin triangles among those touched stays the same and the
    split is undone. Meshing 7 counts a thin triangle of a region with a corner under 15 degrees
    (``pinched``: any mesh of it has one) after those of free regions, and mends it."""
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, parse
    from genr8_dist.hemls.mending import pinched

    surface = grow(parse(_BESIDE_A_NEEDLE), Environment()).surface
    sound = bench_module("meshing").region_shapes(surface)[2]   # corners >= 20 degrees, outline simple
    assert _thin_in_sound_regions(surface, 6, sound)[0] == 1
    assert _thin_in_sound_regions(surface, 7, sound)[0] == 0
    mesh = surface.with_meshing(7).mesh()
    assert _edges(mesh.triangles)[1].max() == 2
    assert np.array_equal(mesh.points[:surface.n_vertices], surface.vertices)
    needles = pinched(mesh.points, mesh.triangles, mesh.regions)
    assert needles and not needles & set(np.flatnonzero(sound).tolist())


# A reversible surface (the 104th random genome of bench/meshing.py's reversible set) whose repairs
# were still spreading when meshing 6's four rounds ended.
_STILL_SPREADING = """Edge0 + ~ Edge2 + Edge0
Edge1 Edge0 Edge2 -> & Edge2 [ [ + Edge3 ] - Edge3 ] Edge1 ^ Edge3
Edge3 < Edge1 > Edge2 -> Edge2 [ [ + Edge3 ] - Edge3 ] Edge1 Edge4
Edge0 -> Edge2 [ [ + Edge4 ] - Edge4 ] Edge1 Edge2
Edge2 -> & Edge2 [ [ + Edge2 ] - Edge2 ] Edge3 ^ Edge2
Edge3 -> & ^ Edge0
Edge4 -> ^ Edge4 & Edge3
Angle 30
Sync
BranchAngle 75
"""


def test_meshing_7_mends_until_nothing_changes(bench_module):
    """Meshing 6 stops after 4 rounds and leaves 209 triangles under 15 degrees, 6 of them in a region
    whose corners are all at least 20 degrees; meshing 7's rounds go on until nothing changes."""
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, parse

    surface = grow(parse(_STILL_SPREADING), Environment()).surface
    sound = bench_module("meshing").region_shapes(surface)[2]
    assert _thin_in_sound_regions(surface, 6, sound) == (6, 209)
    assert _thin_in_sound_regions(surface, 7, sound) == (0, 21)


# A tiles surface (the 264th random genome of bench/meshing.py's tiles set): two points on a straight
# side 2.4e-7 apart, the side's other gaps 1.5e-5, a triangle of 3.3 degrees on the short gap.
_SHORT_GAP = """Edge2 + Edge3 + ~ Edge2 + ~ Edge0 + ~ Edge1 + Edge0 + Edge4
Edge1 -> & Edge2 [ [ + Edge0 ] - Edge0 ] Edge1 ^
Edge4 < Edge0 -> & Edge3 [ [ + + Edge4 ] - - Edge4 ] Edge5 ^
Edge2 -> Edge4
Edge3 -> Edge4 [ [ + Edge5 ] - Edge5 ] Edge5
Edge4 -> Edge5 [ [ [ [ + Edge2 ] + + Edge2 ] - Edge2 ] - - Edge2 ] Edge4
Edge5 -> Edge1 [ [ [ [ + Edge5 ] + + Edge3 ] - Edge3 ] - - Edge5 ] Edge4
Angle 30
BranchAngle 15
"""


def test_meshing_7_lets_a_point_beside_a_very_short_gap_slide_along_its_side(bench_module):
    """The points sit 1e-15 off their side's line by rounding: a sine of 4e-9 at a point 2.4e-7 from
    the next, so meshing 6 held them as corners and kept the 3.3-degree triangle (and 3 more thin ones
    in regions with wide corners); meshing 7 measures the distance from the line against the span
    and mends them, every region's outline kept."""
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, parse

    _mended_in_sound_regions(grow(parse(_SHORT_GAP), Environment()).surface, bench_module, 6, 4)


# A tiles surface (the 264th random genome of bench/meshing.py's tiles set, as meshing 7 cuts it): a
# corner of 29.6 degrees at a surface vertex cut in two by an edge to a point inside the region, 14.6
# and 15.0 degrees; the point lies on the corner's side of the line through its other neighbours, so
# neither flipping that edge nor collapsing the point is kept.
_CORNER_CUT_IN_TWO = """Edge1 + ~ Edge0 + ~ Edge0 + ~ Edge0
Edge0 > Edge0 -> Edge0 Edge1 Edge2
Edge0 -> Edge1
Edge1 -> & Edge0 [ [ [ [ + Edge2 ] + + Edge2 ] - Edge2 ] - - Edge2 ] Edge0 ^
Edge2 -> & Edge0 [ [ + + Edge2 ] - - Edge2 ] Edge2 ^
Angle 30
Sync
BranchAngle 30
"""


def test_meshing_8_splits_the_longer_side_of_a_corner_cut_in_two(bench_module):
    """Meshing 8's last try splits the corner's longer side (0.0117) at the shorter one's length
    (0.0061) from the corner: one triangle then spans the corner's 29.6 degrees. The mesh stays
    watertight, keeps the surface's vertices and every region's outline."""
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, parse

    _mended_in_sound_regions(grow(parse(_CORNER_CUT_IN_TWO), Environment()).surface, bench_module, 7, 1)


def test_meshing_8_mends_a_thin_triangle_boxed_in_by_two_steps():
    """A triangle of 8.7 degrees among triangles of 15.0 to 15.6 (tests/data/mending-boxed-in.npz):
    every single operation takes one of them under 15, so meshing 7 keeps it; meshing 8 flips an
    edge round it first, whatever that does, then mends what that left. No thin triangle is left in
    a region whose corners are all at least 15 degrees; the patch's outline and surface vertices
    stay; the same bytes twice."""
    from genr8_dist.hemls.mending import pinched

    data = np.load(Path(__file__).resolve().parents[1] / "data" / "mending-boxed-in.npz")
    points, triangles, regions, fixed = data["points"], data["triangles"], data["regions"], int(data["fixed"])
    free = np.ones(int(regions.max()) + 1, dtype=bool)
    free[sorted(pinched(points, triangles, regions))] = False
    for meshing, left in ((7, 1), (8, 0)):
        out_p, out_t, out_r = mend(points, triangles, regions, fixed, meshing=meshing)
        under = triangle_min_angles(out_p, out_t) < 15.0
        assert int(np.sum(under & free[out_r])) == left
    assert np.array_equal(out_p[:fixed], points[:fixed])
    assert _edges(out_t)[1].max() == 2
    _outlines_kept((points, triangles, regions), (out_p, out_t, out_r))
    again = mend(points, triangles, regions, fixed, meshing=8)
    assert all(np.array_equal(a, b) for a, b in zip(again, (out_p, out_t, out_r), strict=True))
