"""The square rewrite system (journal Table 2) grown by genr8_dist.hemls.grow in real environments."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest

from genr8_dist.environment import (
    BoxBoundary,
    Environment,
    PlaneBoundary,
    PointForce,
    SphereBoundary,
    load_environment,
)
from genr8_dist.hemls import grow, load_system

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "environments"


@pytest.fixture(scope="module")
def square():
    return load_system("square")


def test_gravity_lowers_the_grown_surface(square):
    flat = grow(square, Environment(steps=4)).surface
    heavy = grow(square, Environment(steps=4, gravity=(0.0, 0.0, -0.5))).surface
    assert np.all(flat.vertices[:, 2] == 0.0)
    assert heavy.vertices[:, 2].mean() < -1.0
    assert heavy.n_regions == flat.n_regions == 256
    assert heavy.validate() == []


def test_repeller_keeps_the_grown_surface_away(square):
    where = np.array([0.2, 0.1, -0.3])
    env = Environment(steps=4, repellers=(PointForce(position=tuple(where), constant=1.0),))
    plain = grow(square, Environment(steps=4)).surface
    pushed = grow(square, env).surface
    assert (np.linalg.norm(pushed.vertices - where, axis=1).min()
            > np.linalg.norm(plain.vertices - where, axis=1).min() + 0.1)


def _stepwise(system, env):
    result = grow(system, env, keep_steps=True)
    return result, result.history


def test_slide_sphere_is_never_crossed_by_moved_vertices(square):
    ball = SphereBoundary(centre=(0.0, 0.0, -3.0), radius=3.5)
    env = Environment(steps=5, scale=(1.5, 1.5, 1.0), start_position=(0, 0, 0.5), gravity=1.5,
                      boundaries=(ball,))
    result, history = _stepwise(square, env)
    for before, after in pairwise(history):
        # the vertices that existed before the step were moved by increase_size: all outside the sphere
        old = after.vertices[: before.n_vertices]
        assert np.all(np.linalg.norm(old - [0, 0, -3.0], axis=1) >= 3.5)
    # new vertices on chords of the sphere are brought out at the end of the step: none is inside
    final = result.surface
    assert np.all(np.linalg.norm(final.vertices - [0, 0, -3.0], axis=1) >= 3.5)
    fixed, _ = env.constrain(final.vertices, stopped=final.stopped)
    assert np.array_equal(fixed, final.vertices)
    # it drapes: the top rests on the sphere and the rim hangs below the sphere's equator
    assert final.vertices[:, 2].max() == pytest.approx(0.5, abs=1e-6)
    assert final.vertices[:, 2].min() < -3.0


def test_cut_off_vertices_of_a_grown_surface_never_move_again(square):
    box = BoxBoundary(min=(-3, -3, -3), max=(3, 3, 3), behaviour="cut-off")
    env = Environment(steps=6, gravity=(0.2, 0.1, 0.0), boundaries=(box,))
    _, history = _stepwise(square, env)
    assert history[-1].stopped.sum() > 0
    for before, after in pairwise(history):
        stopped = np.flatnonzero(before.stopped)
        assert np.array_equal(after.vertices[stopped], before.vertices[stopped])
        assert after.stopped[: before.n_vertices][before.stopped].all()
        old = after.vertices[: before.n_vertices]
        assert np.all(np.abs(old) <= 3.0)


def test_reflect_box_is_never_crossed(square):
    box = BoxBoundary(min=(-4, -4, -1), max=(4, 4, 1), behaviour="reflect")
    env = Environment(steps=5, gravity=(0.0, 0.0, 0.7), boundaries=(box,))
    _, history = _stepwise(square, env)
    for before, after in pairwise(history):
        assert np.all(np.abs(after.vertices[: before.n_vertices]) <= [4, 4, 1])


def test_soft_floor_is_crossed_and_counted(square):
    floor = PlaneBoundary(behaviour="soft")
    env = Environment(steps=4, start_position=(0, 0, 1), gravity=0.6, boundaries=(floor,))
    surface = grow(square, env).surface
    below = int(np.sum(surface.vertices[:, 2] < 0))
    assert below > 0
    assert env.count_soft_violations(surface.vertices) == below


def test_fixed_perimeter_keeps_the_seed_corners(square):
    env = Environment(steps=4, fixed_perimeter=True, gravity=(0, 0, -0.3),
                      repellers=(PointForce(position=(0, 0, -1), law="bounded"),))
    seed = grow(square, Environment(steps=0)).surface
    surface = grow(square, env).surface
    np.testing.assert_array_equal(surface.vertices[:4], seed.vertices)
    rim = surface.perimeter()
    assert np.all(surface.vertices[rim, 2] == 0.0)
    assert np.abs(surface.vertices[:, 2]).max() > 0.1


def test_fixed_centre_cancels_uniform_gravity(square):
    surface = grow(square, Environment(steps=4, fixed_centre=True, gravity=(0.3, 0.0, -1.0))).surface
    np.testing.assert_allclose(surface.vertices.mean(axis=0), [0, 0, 0], atol=1e-9)
    assert np.abs(surface.vertices[:, 2]).max() < 1e-9


def test_same_environment_and_seed_give_the_same_bytes(square):
    env = Environment(steps=4, position_noise=0.1, uniform_cells=True, repelling_points=0.05, seed=9)
    a = grow(square, env).surface.vertices
    b = grow(square, env).surface.vertices
    c = grow(square, Environment(steps=4, position_noise=0.1, uniform_cells=True, repelling_points=0.05,
                                 seed=10)).surface.vertices
    assert a.tobytes() == b.tobytes() and a.tobytes() != c.tobytes()


@pytest.mark.parametrize("example", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_examples_grow_valid_maps(square, example):
    env = load_environment(example)
    result = grow(square, Environment.from_dict({**env.to_dict(), "steps": min(env.steps, 4)}))
    assert result.capped is None
    assert result.surface.validate() == []
    assert np.isfinite(result.surface.vertices).all()


def test_uniform_cells_relax_after_the_step_so_the_new_cells_are_even_too():
    """Thesis 2.7.2: after each growth step the perimeter is fixed and the other vertices move to even
    out the cells; the interior vertices that one step's joins make end at their neighbours' mean."""
    from genr8_dist.hemls import parse

    thirds = parse("Edge0 + ~ Edge1 + ~ Edge0 + Edge1\n"
                   "Edge0 -> Edge0 [ [ + Edge1 ] - Edge1 ] Edge0 Edge0\n"
                   "Edge1 -> Edge1 [ [ + Edge0 ] - Edge0 ] Edge1 Edge1\nAngle 90\n")
    for uniform in (True, False):
        surface = grow(thirds, Environment(uniform_cells=uniform, steps=1, scale=1.0)).surface
        inner = np.flatnonzero(~surface.perimeter_mask)
        assert len(inner) == 2
        gap = max(np.linalg.norm(surface.vertices[surface.neighbours(v)].mean(axis=0) - surface.vertices[v])
                  for v in inner)
        assert (gap < 1e-3) == uniform, (uniform, gap)
