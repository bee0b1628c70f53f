"""Physics of Environment.increase_size on synthetic surfaces: forces, constraints, internal forces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from genr8_dist.environment import Environment, PointForce
from genr8_dist.errors import ConfigError
from genr8_dist.rng import stream


def grid(n: int = 9, size: float = 2.0, z: float = 0.0):
    """An n x n grid of vertices in the plane z, its edges and its perimeter mask."""
    xs = np.linspace(-size / 2, size / 2, n)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    positions = np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])
    index = np.arange(n * n).reshape(n, n)
    edges = np.concatenate([
        np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()]),
        np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()]),
    ])
    perimeter = np.zeros((n, n), dtype=bool)
    perimeter[0, :] = perimeter[-1, :] = perimeter[:, 0] = perimeter[:, -1] = True
    return positions, edges, perimeter.ravel()


def grow(env: Environment, positions, edges, perimeter, steps: int = 1, masses=None, stopped=None, seed=0):
    """Apply increase_size ``steps`` times; returns (positions, stopped) and the per-step history."""
    n = len(positions)
    masses = np.ones(n) if masses is None else masses
    stopped = np.zeros(n, dtype=bool) if stopped is None else stopped
    rng = stream(seed, "growth")
    history = [(positions, stopped)]
    for step in range(1, steps + 1):
        positions, stopped = env.increase_size(positions, step=step, masses=masses, stopped=stopped,
                                               perimeter=perimeter, edges=edges, rng=rng)
        history.append((positions, stopped))
    return positions, stopped, history


def test_empty_environment_scales_about_the_centre():
    p, e, per = grid()
    p = p + np.array([3.0, -1.0, 2.0])
    out, stopped, _ = grow(Environment(), p, e, per)
    centre = p.mean(axis=0)
    np.testing.assert_allclose(out, centre + (p - centre) * 1.5)
    assert not stopped.any()


def test_per_axis_scale_and_shrinking():
    p, e, per = grid()
    p[:, 2] = np.linspace(-1, 1, len(p))
    out, _, _ = grow(Environment(scale=(2.0, 0.5, 1.0)), p, e, per)
    centre = p.mean(axis=0)
    np.testing.assert_allclose(out - centre, (p - centre) * np.array([2.0, 0.5, 1.0]))


def test_inputs_are_not_modified():
    p, e, per = grid()
    copy = p.copy()
    stopped = np.zeros(len(p), dtype=bool)
    Environment(gravity=(0, 0, -1)).increase_size(p, step=1, masses=np.ones(len(p)), stopped=stopped,
                                                  perimeter=per, edges=e, rng=stream(0))
    assert np.array_equal(p, copy) and not stopped.any()


def test_gravity_lowers_the_mean_z_by_its_magnitude_each_step():
    p, e, per = grid()
    empty, _, _ = grow(Environment(), p, e, per, steps=3)
    heavy, _, _ = grow(Environment.from_dict({"gravity": 0.25}), p, e, per, steps=3)
    assert heavy[:, 2].mean() < empty[:, 2].mean()
    np.testing.assert_allclose(heavy[:, 2].mean(), empty[:, 2].mean() - 0.75)
    sideways, _, _ = grow(Environment.from_dict({"gravity": {"direction": "x", "magnitude": 2.0}}), p, e, per)
    np.testing.assert_allclose(sideways[:, 0].mean() - p[:, 0].mean(), 2.0)


def test_repeller_raises_the_minimum_distance_to_it():
    p, e, per = grid()
    where = np.array([0.1, 0.2, -0.5])
    env = Environment(repellers=(PointForce(position=tuple(where), constant=0.5),))
    plain, _, _ = grow(Environment(), p, e, per, steps=2)
    pushed, _, _ = grow(env, p, e, per, steps=2)
    gap = np.linalg.norm(pushed - where, axis=1).min()
    assert gap > np.linalg.norm(plain - where, axis=1).min() + 0.05


def test_attractor_pulls_with_the_inverse_power_law_over_mass():
    p = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 3.0]])
    masses = np.array([2.0, 1.0])
    attractor = PointForce(position=(0.0, 0.0, 0.0), constant=4.0, exponent=2.0)
    env = Environment(scale=1.0, attractors=(attractor,))
    out, _ = env.increase_size(p, step=1, masses=masses, stopped=np.zeros(2, bool),
                               perimeter=np.zeros(2, bool), edges=np.zeros((0, 2), np.int64), rng=stream(0))
    # f = c d^-e / m towards the attractor: 4 / 4 / 2 = 0.5 and 4 / 9 / 1
    np.testing.assert_allclose(out[0], [1.5, 0.0, 0.0])
    np.testing.assert_allclose(out[1], [0.0, 0.0, 3.0 - 4.0 / 9.0])


def test_bounded_law_has_no_singularity():
    inverse = PointForce(constant=1.0, exponent=2.0)
    bounded = PointForce(constant=1.0, exponent=2.0, law="bounded")
    d = np.array([0.0, 0.01, 0.5, 1.0, 2.0])
    m = np.ones_like(d)
    np.testing.assert_allclose(bounded.magnitude(d, m), [0.0, 0.01, 0.5, 1.0, 0.25])
    assert inverse.magnitude(np.array([0.01]), np.ones(1))[0] == pytest.approx(1e4)
    np.testing.assert_allclose(bounded.magnitude(d[3:], m[3:]), inverse.magnitude(d[3:], m[3:]))


def test_bounded_law_near_part_is_c_times_d_whatever_the_mass():
    # thesis 2.7.1: f = c / (m d^e) for d > 1, c · d for d <= 1
    bounded = PointForce(constant=3.0, exponent=2.0, law="bounded")
    d = np.array([0.5, 1.0, 2.0])
    np.testing.assert_allclose(bounded.magnitude(d, np.full(3, 2.0)), [1.5, 3.0, 3.0 / (2.0 * 4.0)])


def test_fixed_perimeter_keeps_perimeter_vertices_in_place():
    p, e, per = grid()
    env = Environment(fixed_perimeter=True, gravity=(0.0, 0.0, -0.3),
                      repellers=(PointForce(position=(0.0, 0.0, -1.0)),))
    out, _, _ = grow(env, p, e, per, steps=3)
    assert np.array_equal(out[per], p[per])
    assert np.all(np.linalg.norm(out[~per] - p[~per], axis=1) > 0.01)


def test_fixed_centre_keeps_the_centre_where_it_was():
    p, e, per = grid()
    env = Environment(fixed_centre=True, gravity=(0.0, 0.0, -0.5),
                      attractors=(PointForce(position=(3.0, 0.0, 1.0), constant=2.0),))
    out, _, _ = grow(env, p, e, per, steps=3)
    np.testing.assert_allclose(out.mean(axis=0), p.mean(axis=0), atol=1e-12)
    free, _, _ = grow(Environment(gravity=(0.0, 0.0, -0.5)), p, e, per, steps=3)
    assert free[:, 2].mean() < -1.0
    # stretched towards the attractor rather than moved: the near side is pulled further than the far side
    assert out[:, 0].max() - out[:, 0].min() > free[:, 0].max() - free[:, 0].min()


def test_heavier_vertices_move_less_under_point_forces():
    p = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    env = Environment(scale=1.0, repellers=(PointForce(position=(0.0, 0.0, 0.0)),))
    out, _ = env.increase_size(p, step=1, masses=np.array([1.0, 4.0]), stopped=np.zeros(2, bool),
                               perimeter=np.zeros(2, bool), edges=np.zeros((0, 2), np.int64), rng=stream(0))
    np.testing.assert_allclose(out[:, 0] - 1.0, [1.0, 0.25])


def test_repelling_points_spread_crowded_vertices():
    rng = np.random.default_rng(1)  # test data only
    p = rng.normal(0.0, 0.3, size=(200, 3))
    e = np.column_stack([np.arange(199), np.arange(1, 200)])
    per = np.zeros(200, dtype=bool)

    def min_gap(x):
        d = np.linalg.norm(x[:, None] - x[None], axis=2)
        d[np.diag_indices(len(x))] = np.inf
        return d.min()

    env = Environment(scale=1.0, repelling_points=0.5, repelling_radius=1.0)
    out, _, _ = grow(env, p, e, per, steps=3)
    assert min_gap(out) > 2 * min_gap(p)
    assert np.isfinite(out).all()


def test_uniform_cells_even_out_edge_lengths_and_hold_the_perimeter():
    p, e, per = grid(n=11)
    warp = p.copy()
    warp[:, 0] = np.sign(p[:, 0]) * np.abs(p[:, 0]) ** 2  # cells crowd at the centre
    plain = warp
    even = Environment(uniform_cells=True).relax_cells(warp, edges=e, perimeter=per,
                                                       stopped=np.zeros(len(warp), dtype=bool))
    # uniform cells act after the step, not in the size increase
    np.testing.assert_array_equal(grow(Environment(uniform_cells=True), warp, e, per)[0],
                                  grow(Environment(), warp, e, per)[0])

    inner = ~(per[e[:, 0]] & per[e[:, 1]])

    def spread(x):
        lengths = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)[inner]
        return lengths.std() / lengths.mean()

    assert spread(even) < 0.6 * spread(plain)
    assert np.array_equal(even[per], plain[per])


def test_position_noise_is_seeded_and_scaled_to_the_edges():
    p, e, per = grid()
    env = Environment(position_noise=0.1)
    a, _, _ = grow(env, p, e, per, seed=3)
    b, _, _ = grow(env, p, e, per, seed=3)
    c, _, _ = grow(env, p, e, per, seed=4)
    clean, _, _ = grow(Environment(), p, e, per)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    noise = (a - clean).std()
    edge = 2.0 / 8
    assert 0.05 * edge < noise < 0.2 * edge


def test_stopped_vertices_never_move():
    p, e, per = grid()
    stopped = np.zeros(len(p), dtype=bool)
    stopped[:5] = True
    out, stop, _ = grow(Environment(gravity=(0, 0, -1)), p, e, per, steps=2, stopped=stopped)
    assert np.array_equal(out[:5], p[:5])
    assert stop[:5].all() and not stop[5:].any()


def test_shape_mismatch_is_a_growth_error():
    from genr8_dist.errors import GrowthError

    p, e, per = grid()
    with pytest.raises(GrowthError, match="masses"):
        Environment().increase_size(p, step=1, masses=np.ones(3), stopped=np.zeros(len(p), bool),
                                    perimeter=per, edges=e, rng=stream(0))


def test_repelling_points_reach_every_vertex_with_radius_minus_one():
    from genr8_dist.environment.forces import repelling_displacement

    points = np.array([[0.0, 0, 0], [1.0, 0, 0], [10.0, 0, 0]])
    masses = np.array([1.0, 1.0, 2.0])
    every = repelling_displacement(points, masses, 0.5, math.inf, 1.0)
    # thesis 2.7.2: each vertex pushes all the others, (L/d)^2 with L = 1
    np.testing.assert_allclose(every[2], [0.5 * (1 / 100 + 1 / 81) / 2.0, 0, 0])
    np.testing.assert_allclose(every[0], [-0.5 * (1 + 1 / 100), 0, 0])
    near = repelling_displacement(points, masses, 0.5, 2.0, 1.0)
    np.testing.assert_allclose(near[2], 0.0)
    np.testing.assert_allclose(near[0], [-0.5 * (1 - 1 / 4), 0, 0])  # shifted to 0 at R = 2
    env = Environment(repelling_points=0.5, repelling_radius=-1)
    np.testing.assert_allclose(env.repelling(points, masses, 1.0), every)
    for bad in (0, -2):
        with pytest.raises(ConfigError, match=r"repelling_radius.*-1 \(every vertex, the thesis\) or > 0"):
            Environment(repelling_radius=bad)
