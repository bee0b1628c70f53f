"""Barnes–Hut all-pairs repelling points (thesis 2.7.2: every vertex pushes every other one)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from genr8_dist.environment import Environment
from genr8_dist.environment.barnes_hut import inverse_square_field
from genr8_dist.environment.forces import repelling_displacement
from genr8_dist.errors import ConfigError


def _exact(points: np.ndarray) -> np.ndarray:
    delta = points[:, None, :] - points[None, :, :]
    d2 = np.einsum("ijk,ijk->ij", delta, delta)
    d2[d2 == 0.0] = np.inf
    return np.einsum("ij,ijk->ik", d2 ** -1.5, delta)


def _dome(side: int) -> np.ndarray:
    """A side x side grid of unit spacing bent into a spherical cap, like a grown surface."""
    x, y = np.meshgrid(np.arange(side, dtype=float), np.arange(side, dtype=float))
    x, y = x.ravel() - side / 2, y.ravel() - side / 2
    return np.column_stack([x, y, np.sqrt(side * side - x * x - y * y)])


def test_opening_angle_zero_is_the_exact_sum():
    points = np.random.default_rng(3).random((300, 3)) * [4.0, 4.0, 0.5]
    np.testing.assert_allclose(inverse_square_field(points, 0.0), _exact(points), rtol=1e-10, atol=1e-9)


def test_opening_angle_one_half_is_within_a_few_percent_of_every_pair():
    """bench/repelling.py's figure on four_sided_tiles: about 1% of the root mean square, 3% at worst."""
    points = _dome(40)   # 1,600 vertices: the octree has many levels
    exact = _exact(points)
    scale = math.sqrt(float(np.mean(np.sum(exact ** 2, axis=1))))
    err = np.linalg.norm(inverse_square_field(points, 0.5) - exact, axis=1) / scale
    assert float(np.median(err)) < 0.02 and float(err.max()) < 0.05
    tighter = np.linalg.norm(inverse_square_field(points, 0.3) - exact, axis=1) / scale
    assert float(tighter.max()) < float(err.max())


def test_same_points_same_bytes_and_coincident_points_do_not_push_each_other():
    points = _dome(20)
    points = np.vstack([points, points[:5]])   # five vertices twice
    a, b = inverse_square_field(points, 0.5), inverse_square_field(points.copy(), 0.5)
    assert a.tobytes() == b.tobytes()
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(a[:5], a[-5:])
    assert inverse_square_field(points[:1], 0.5).tolist() == [[0.0, 0.0, 0.0]]


def test_every_pair_is_the_default_and_reaches_far_vertices():
    env = Environment(repelling_points=0.5)
    assert env.repelling_radius == -1 and env.repelling_theta == 0.5
    points = _dome(30)
    masses = np.full(len(points), 2.0)
    expected = 0.5 * 1.0 ** 3 * inverse_square_field(points, 0.5) / 2.0
    np.testing.assert_array_equal(env.repelling(points, masses, 1.0), expected)
    exact = repelling_displacement(points, masses, 0.5, math.inf, 1.0)   # theta 0: every pair exactly
    exact_env = Environment(repelling_points=0.5, repelling_theta=0)
    np.testing.assert_allclose(exact_env.repelling(points, masses, 1.0), exact)
    # the corner vertex is pushed by the whole surface, far beyond one edge length
    near = repelling_displacement(points, masses, 0.5, 1.5, 1.0)
    assert np.linalg.norm(exact[0]) > 3 * np.linalg.norm(near[0])


@pytest.mark.parametrize("bad", [-0.1, 1.5, "wide"])
def test_an_opening_angle_outside_0_to_1_is_a_config_error(bad):
    with pytest.raises(ConfigError, match="repelling_theta"):
        Environment(repelling_theta=bad)
