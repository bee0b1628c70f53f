"""The turtle: successors drawn once into templates fitted to the unit chord."""

from __future__ import annotations

import math

import numpy as np

from genr8_dist.hemls import parse
from genr8_dist.hemls.turtle import AT_END, LEFT, NO_SIDE, RIGHT, draw, rotation_between


def _template(successor: str, angle: float = 90.0):
    system = parse(f"Edge0 + Edge1 + Edge2\nEdge0 -> {successor}\nAngle {angle:g}\n")
    return draw(system.rules[0].successors[0], system.turn_angle, system.label_ids())


def test_koch_successor_is_fitted_to_the_unit_chord_with_its_bump_to_the_right():
    t = _template("Edge0 - Edge0 + + Edge0 - Edge0", 60)
    third = 1.0 / 3.0
    expected = [(0, 0), (third, 0), (0.5, -math.sqrt(3) / 6), (2 * third, 0), (1, 0)]
    assert np.allclose(t.points[:, :2], expected)
    assert t.n_segments == 4 and t.n_branches == 0


def test_plus_turns_left_and_branches_take_the_side_they_point_to():
    t = _template("Edge0 [ [ + Edge1 ] - Edge2 ] Edge0")
    assert np.allclose(t.points, [(0, 0, 0), (0.5, 0, 0), (1, 0, 0)])
    assert np.allclose(t.branch_heading, [(0, 1, 0), (0, -1, 0)])
    assert t.branch_labels.tolist() == [1, 2]
    assert t.branch_side.tolist() == [LEFT, RIGHT]
    assert t.branch_vertex.tolist() == [1, 1]


def test_branch_is_one_segment_and_anything_after_it_is_ignored():
    t = _template("Edge0 [ + Edge1 Edge2 [ - Edge2 ] ] Edge0")
    assert t.n_branches == 1 and t.branch_labels.tolist() == [1]


def test_branches_at_the_ends_and_along_the_line():
    t = _template("[ + Edge1 ] Edge0 [ Edge2 ]")
    assert t.branch_side.tolist() == [AT_END, AT_END]
    t = _template("Edge0 [ Edge1 ] Edge0")
    assert t.branch_side.tolist() == [NO_SIDE]


def test_reverse_marks_the_next_edge_only():
    t = _template("Edge0 ~ Edge0 Edge0 [ ~ + Edge1 ] Edge0")
    assert t.main_reversed.tolist() == [False, True, False, False]
    assert t.branch_reversed.tolist() == [True]


def test_pitch_and_roll_leave_the_plane_and_the_chord_is_still_unit():
    t = _template("Edge0 & Edge0 ^ ^ Edge0 & Edge0", 45)
    assert np.allclose(t.points[-1], (1, 0, 0))
    assert np.ptp(t.points[:, 2]) > 0.1
    t = _template("/ + Edge0 - \\\\ Edge0", 90)  # roll then turn: the first segment goes up or down
    assert np.allclose(t.points[-1], (1, 0, 0))


def test_timed_segments_keep_their_offsets():
    t = _template("Edge0_i+1 [ [ + Edge1_i ] - Edge1 ] Edge0_i-1")
    assert t.main_timed.tolist() == [True, True] and t.main_ages.tolist() == [1, -1]
    assert t.branch_timed.tolist() == [True, False]


def test_rotation_between_is_a_proper_rotation():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=3), rng.normal(size=3)
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        r = rotation_between(a, b)
        assert np.allclose(r @ a, b) and np.allclose(r @ r.T, np.eye(3))
        assert np.isclose(np.linalg.det(r), 1.0)
    r = rotation_between(np.array([1.0, 0, 0]), np.array([-1.0, 0, 0]))
    assert np.allclose(r @ [1, 0, 0], [-1, 0, 0]) and np.isclose(np.linalg.det(r), 1.0)
