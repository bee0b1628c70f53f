"""Hard boundaries hold after every derivation step, for the vertices rewriting makes too (issue 14).

Tolerance: a vertex counts as on the wrong side when its violation exceeds 1e-9 (boundaries leave a
moved vertex a hair of 1e-9 x the scene's extent on the allowed side; the scenes here are < 20 wide).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from genr8_dist.environment import (
    BoxBoundary,
    Environment,
    MeshBoundary,
    PlaneBoundary,
    SphereBoundary,
    load_environment,
)
from genr8_dist.hemls import grow, load_system, parse

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "environments"
TOLERANCE = 1e-9

# every edge becomes a dip that pitches below the surface (against the floor it lies on)
DIP = parse("A + A + A + A\nA -> A & A ^ ^ A & A\nAngle 40\n", name="dip")


def _wrong_side(env, surface) -> int:
    depth = np.zeros(surface.n_vertices)
    for b in env.boundaries:
        if b.behaviour != "soft":
            depth = np.maximum(depth, b.violation(surface.vertices))
    return int(np.count_nonzero(depth > TOLERANCE))


def _boundary(kind, behaviour, tmp_path):
    if kind == "plane":
        return PlaneBoundary(point=(0, 0, -1.0), normal=(0, 0, 1), behaviour=behaviour)
    if kind == "box":
        return BoxBoundary(min=(-4, -4, -1.0), max=(4, 4, 3), behaviour=behaviour)
    if kind == "sphere":
        return SphereBoundary(centre=(0, 0, -3.0), radius=2.5, behaviour=behaviour)
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=2, radius=2.5)
    ball.apply_translation((0, 0, -3.0))
    path = tmp_path / "ball.obj"
    ball.export(path)
    return MeshBoundary(path=str(path), behaviour=behaviour)


@pytest.mark.parametrize("behaviour", ["slide", "cut-off", "reflect"])
@pytest.mark.parametrize("kind", ["plane", "box", "sphere", "mesh"])
@pytest.mark.parametrize("system", ["four_sided_tiles", "dip"])
def test_every_vertex_is_on_the_allowed_side_after_every_step(kind, behaviour, system, tmp_path):
    env = Environment(steps=4, scale=(1.4, 1.4, 1.0), gravity=0.8, boundaries=(_boundary(kind, behaviour,
                                                                                        tmp_path),))
    rules = DIP if system == "dip" else load_system(system)
    history = grow(rules, env, keep_steps=True).history
    assert [_wrong_side(env, s) for s in history] == [0] * 5
    # the wall was reached: some vertex came within a quarter of it
    assert max(env.boundaries[0].violation(s.vertices).max() for s in history) > -0.25


@pytest.mark.parametrize("example", [p for p in sorted(EXAMPLES.glob("*.toml"))
                                     if any(b.behaviour != "soft" for b in load_environment(p).boundaries)],
                         ids=lambda p: p.stem)
@pytest.mark.parametrize("system", ["four_sided_tiles", "dip"])
def test_shipped_environments_are_never_crossed(example, system):
    env = load_environment(example)
    rules = DIP if system == "dip" else load_system(system)
    history = grow(rules, Environment.from_dict({**env.to_dict(), "steps": min(env.steps, 5)}),
                   keep_steps=True).history
    assert [_wrong_side(env, s) for s in history] == [0] * len(history)


def test_the_drape_of_the_journal_figure_keeps_every_vertex_outside_the_sphere():
    env = load_environment(EXAMPLES / "drape_sphere.toml")
    history = grow(load_system("four_sided_tiles"), env, keep_steps=True).history
    centre, radius = np.array([0.0, 0.0, -3.0]), 3.5
    for surface in history:
        assert np.linalg.norm(surface.vertices - centre, axis=1).min() >= radius - TOLERANCE
    assert history[-1].n_vertices == 4225  # every join made: 65 x 65 vertices


def test_slide_cut_off_and_reflect_give_different_surfaces_in_the_box():
    """Thesis Figs 2-13 and 2-14: with slide the rim slides along the walls and climbs them; with
    cut-off the part that hits stops dead and grows no further, so the surface stays flat; reflect
    bounces off and crumples. (docs/boundary_behaviours.png shows them.)"""
    tiles = load_system("four_sided_tiles")
    grown = {name: grow(tiles, load_environment(EXAMPLES / f"{name}.toml")).surface
             for name in ("box_corner", "box_corner_cutoff", "box_corner_reflect")}
    slide, cut, reflect = grown.values()
    assert slide.vertices[:, 2].max() > 1.0 and reflect.vertices[:, 2].max() > 1.0
    assert cut.vertices[:, 2].max() < 0.5
    assert cut.stopped.mean() > 0.5 and not slide.stopped.any() and not reflect.stopped.any()
    assert len({s.digest() for s in grown.values()}) == 3
    assert all(s.validate() == [] for s in grown.values())
