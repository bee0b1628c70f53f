"""The criteria on surfaces whose answers are known by hand, and the fitness specification."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from genr8_dist.errors import ConfigError
from genr8_dist.fitness import (
    CRITERIA,
    DEFAULT_CRITERIA,
    Criterion,
    FitnessSpec,
    score_surface,
    smoothness,
    symmetry,
)


def grid(n: int, side: float = 1.0, z=None) -> SimpleNamespace:
    """The four-sided tiles after ``n`` steps, by hand: an (m+1) x (m+1) lattice, m = 2^n, of ``side``."""
    m = 2**n
    xs = np.linspace(-side / 2, side / 2, m + 1)
    xx, yy = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    if z is not None:
        vertices[:, 2] = z(vertices[:, 0], vertices[:, 1])
    idx = np.arange((m + 1) ** 2).reshape(m + 1, m + 1)
    horizontal = np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()])
    vertical = np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])
    return SimpleNamespace(vertices=vertices, edges=np.vstack([horizontal, vertical]))


class SoftPlane:
    """A soft boundary z <= level: vertices above it are on the wrong side."""

    def __init__(self, level: float) -> None:
        self.level = level

    def count_soft_violations(self, positions) -> int:
        return int(np.count_nonzero(np.asarray(positions)[:, 2] > self.level))


def test_criteria_are_the_thesis_six_then_cells_and_slivers_in_order():
    assert CRITERIA == ("size", "smoothness", "undulation", "subdivisions", "symmetry", "soft_boundary",
                        "cells", "slivers")
    assert tuple(FitnessSpec().to_dict()) == CRITERIA
    # the two added ones weigh nothing unless a configuration says so: old fitnesses are unchanged
    assert FitnessSpec()["cells"].weight == FitnessSpec()["slivers"].weight == 0.0


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4])
def test_flat_four_sided_tiles(n):
    side = 1.5**n
    s = grid(n, side)
    m = 2**n
    assert len(s.vertices) == (m + 1) ** 2 and len(s.edges) == 2 * m * (m + 1)
    raw = score_surface(s, None)
    assert list(raw) == list(CRITERIA)
    assert raw["size"] == pytest.approx(2 * side)
    assert raw["smoothness"] == 0.0
    assert raw["undulation"] == 0.0
    assert raw["subdivisions"] == pytest.approx((m + 1) ** 2 / (2 * m * (m + 1)))
    assert raw["symmetry"] == 1.0
    assert raw["soft_boundary"] == 0.0


def test_surface_pulled_down_has_undulation_and_roughness():
    # A sag like gravity's: z = -(1 - r^2), lowest in the middle, perimeter at 0.
    s = grid(3, 2.0, z=lambda x, y: -(1 - np.minimum(1, x**2 + y**2)))
    raw = score_surface(s)
    assert raw["undulation"] == pytest.approx(1.0)  # the centre vertex (0, 0) sits at z = -1
    assert raw["smoothness"] > 0
    assert raw["symmetry"] == 1.0  # still balanced in x and y


def test_smoothness_counts_each_neighbour_pair_once():
    vertices = np.array([[0, 0, 0.0], [1, 0, 2.0], [0, 1, -1.0]])
    edges = np.array([[0, 1], [1, 0], [0, 2], [2, 2]])  # a parallel edge and a self-loop
    # 1/2 sum_i sum_{j in N(i)} |zi - zj| with N(0) = {1, 2}, N(1) = {0}, N(2) = {0}
    assert smoothness(vertices, edges) == pytest.approx(0.5 * ((2 + 1) + 2 + 1))


def test_half_through_a_soft_boundary_counts_the_vertices_through_it():
    s = grid(2, 4.0, z=lambda x, y: x)  # tilted: z = x, 5 columns of 5 vertices at x = -2..2
    raw = score_surface(s, SoftPlane(0.5))
    assert raw["soft_boundary"] == 10.0  # the columns x = 1 and x = 2


def test_symmetry_is_the_ratio_of_counts_either_side():
    # Three vertices left of the centre line x = 0, one right; all on y = 0 except a balanced pair.
    vertices = np.array([[-2, 0, 0], [-1, 1, 0], [-1, -1, 0], [2, 0, 0.0]])
    # sym(x): the line y = 0 -> one above, one below (those on it count for neither) -> 1
    # sym(y): the line x = 0 (bbox centre) -> 3 left, 1 right -> 1/3
    assert symmetry(vertices) == pytest.approx((1 + 1 / 3) / 2)


def test_a_polygon_has_subdivisions_one():
    angles = np.arange(5) * 2 * np.pi / 5
    vertices = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(5)])
    edges = np.column_stack([np.arange(5), (np.arange(5) + 1) % 5])
    assert score_surface(SimpleNamespace(vertices=vertices, edges=edges))["subdivisions"] == 1.0


def test_degenerate_surface_gives_nan_not_an_exception():
    raw = score_surface(SimpleNamespace(vertices=np.zeros((0, 3)), edges=np.zeros((0, 2), int)))
    assert math.isnan(raw["subdivisions"]) and math.isnan(raw["symmetry"])
    assert FitnessSpec().evaluate(raw) == math.inf


def test_total_is_the_weighted_sum_of_normalised_deviations():
    spec = FitnessSpec.from_dict({
        "size": {"target": 10, "weight": 2},
        "smoothness": {"target": 0, "weight": 1},
        "undulation": {"target": 0, "weight": 0},
        "subdivisions": {"target": 0.5, "weight": 3},
        "symmetry": {"target": 1, "weight": 1, "scale": 0.5},
        "soft_boundary": {"target": 0, "weight": 1},
    })
    raw = {"size": 12, "smoothness": 0.25, "undulation": 99, "subdivisions": 0.75, "symmetry": 0.9,
           "soft_boundary": 2, "cells": 40, "slivers": 0.5}
    dev = spec.deviations(raw)
    assert dev == pytest.approx({"size": 2 * 2 / 10, "smoothness": 0.25, "undulation": 0.0,
                                 "subdivisions": 3 * 0.25, "symmetry": 0.1 / 0.5, "soft_boundary": 2.0,
                                 "cells": 0.0, "slivers": 0.0})
    assert spec.evaluate(raw) == pytest.approx(sum(dev.values()))
    met = {name: spec[name].target for name in CRITERIA}
    assert spec.evaluate(met) == 0.0


def test_defaults_and_partial_tables():
    spec = FitnessSpec.from_dict({"size": {"weight": 5}})
    assert spec.size == Criterion(DEFAULT_CRITERIA["size"]["target"], 5.0)
    assert spec.symmetry == FitnessSpec().symmetry
    assert FitnessSpec.from_dict(spec.to_dict()) == spec


@pytest.mark.parametrize(
    ("table", "field"),
    [
        ({"sizes": {"target": 1}}, "fitness.sizes"),
        ({"size": {"target": 1, "wieght": 2}}, "fitness.size.wieght"),
        ({"size": {"weight": -1}}, "fitness.size.weight"),
        ({"size": {"target": "big"}}, "fitness.size.target"),
        ({"size": {"target": True}}, "fitness.size.target"),
        ({"symmetry": {"scale": 0}}, "fitness.symmetry.scale"),
        ({"smoothness": 3}, "fitness.smoothness"),
    ],
)
def test_bad_fitness_tables_name_the_field(table, field):
    with pytest.raises(ConfigError, match=f"'{field}'"):
        FitnessSpec.from_dict(table, source="run.toml")
    with pytest.raises(ConfigError, match=r"^run\.toml: "):
        FitnessSpec.from_dict(table, source="run.toml")


def test_replace_changes_one_criterion():
    spec = FitnessSpec().replace({"subdivisions": {"target": 0.3}})
    assert spec.subdivisions.target == 0.3 and spec.subdivisions.weight == 1.0
    assert spec.size == FitnessSpec().size


@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-50, 50)), min_size=1,
                max_size=40))
def test_criteria_are_invariant_under_translation(points):
    pts = np.array(points)
    edges = np.column_stack([np.arange(len(pts)), (np.arange(len(pts)) + 1) % len(pts)])
    a = score_surface(SimpleNamespace(vertices=pts, edges=edges))
    b = score_surface(SimpleNamespace(vertices=pts + np.array([3.0, -7.0, 11.0]), edges=edges))
    for name in ("size", "smoothness", "undulation", "subdivisions"):
        assert a[name] == pytest.approx(b[name], rel=1e-9, abs=1e-9)
    assert 0.0 <= a["symmetry"] <= 1.0


# --------------------------------------------------------------------------------------------------
# The same criteria on surfaces grown by the growth engine.


def grown(system: str, **env_fields):
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, load_system

    env = Environment.from_dict(env_fields)
    result = grow(load_system(system), env)
    assert result.capped is None
    return result.surface, env


@pytest.mark.parametrize("n", [1, 2, 3])
def test_grown_four_sided_tiles_match_the_closed_forms(n):
    surface, env = grown("four-sided-tiles", steps=n)
    m = 2**n
    raw = score_surface(surface, env)
    assert raw["subdivisions"] == pytest.approx((m + 1) ** 2 / (2 * m * (m + 1)))
    assert raw["size"] == pytest.approx(2 * 1.0 * 1.5**n)  # start length 1, scale 1.5 per step, x + y
    assert raw["smoothness"] == 0.0 and raw["undulation"] == 0.0
    assert raw["symmetry"] == 1.0 and raw["soft_boundary"] == 0.0


def test_grown_surface_under_gravity_undulates():
    flat, _ = grown("four-sided-tiles", steps=3, fixed_perimeter=True)
    sagged, env = grown("four-sided-tiles", steps=3, fixed_perimeter=True, gravity=0.2)
    raw = score_surface(sagged, env)
    assert score_surface(flat)["undulation"] == 0.0
    assert raw["undulation"] > 0.1 and raw["smoothness"] > 0.0
    z = sagged.vertices[:, 2]
    assert raw["undulation"] == pytest.approx(z.max() - z.min())
    assert raw["symmetry"] == 1.0  # gravity pulls straight down: still balanced


def test_grown_surface_half_through_a_soft_boundary():
    plane = {"kind": "plane", "point": [0.013, 0.0, 0.0], "normal": [1.0, 0.0, 0.0], "behaviour": "soft"}
    surface, env = grown("four-sided-tiles", steps=3, boundaries=[plane])
    x = surface.vertices[:, 0]
    through = int(np.count_nonzero(x > 0.013))
    assert 0 < through < len(x)  # the surface grew half through the plane, unhindered
    assert score_surface(surface, env)["soft_boundary"] == through == 36


finite = st.floats(-1e6, 1e6, allow_nan=False)
criterion_tables = st.fixed_dictionaries(
    {"target": finite, "weight": st.floats(0, 1e3)}, optional={"scale": st.floats(1e-3, 1e3)})


@given(st.dictionaries(st.sampled_from(CRITERIA), criterion_tables))
def test_spec_round_trips_and_total_is_never_negative(tables):
    spec = FitnessSpec.from_dict(tables)
    assert FitnessSpec.from_dict(spec.to_dict()) == spec
    raw = {name: spec[name].target + 1.0 for name in CRITERIA}
    total = spec.evaluate(raw)
    assert total >= 0.0
    assert total == pytest.approx(sum(spec[n].weight / spec[n].unit for n in CRITERIA))


def test_cells_count_regions_and_slivers_the_thin_triangles():
    from types import SimpleNamespace

    from genr8_dist.fitness import cells, slivers, triangle_min_angles

    vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [10, 0.1, 0]]
    square = SimpleNamespace(vertices=vertices, n_regions=1, triangles=lambda: [[0, 1, 2], [0, 2, 3]])
    sliver = SimpleNamespace(vertices=vertices, n_regions=2,
                             triangles=lambda: [[0, 1, 2], [0, 4, 1]])
    assert cells(square) == 1.0 and cells(sliver) == 2.0
    assert triangle_min_angles(vertices, [[0, 1, 2]]) == pytest.approx([45.0])
    assert slivers(square) == 0.0
    assert slivers(sliver) == 0.5          # [0, 4, 1] has an angle of about 0.6 degrees
