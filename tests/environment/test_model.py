"""The Environment value: Genr8's defaults, validation, TOML files and the dict round trip."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from genr8_dist.environment import (
    BoxBoundary,
    Environment,
    MeshBoundary,
    PlaneBoundary,
    PointForce,
    SphereBoundary,
    load_environment,
)
from genr8_dist.errors import ConfigError, GrowthError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "environments"


def test_defaults_are_genr8s():
    env = Environment()
    assert env.steps == 4
    assert env.scale == (1.5, 1.5, 1.5)
    assert env.start_length == 1.0 and env.start_position == (0.0, 0.0, 0.0)
    assert env.branch_length == -1.0 and env.max_branch_distance(3) == math.inf
    assert env.seed_polygon is None and env.vertex_mass == 1.0
    assert not (env.fixed_perimeter or env.fixed_centre or env.uniform_cells)
    assert env.gravity == (0.0, 0.0, 0.0) and env.boundaries == () and env.is_empty
    assert env.max_edges == 200_000 and env.max_seconds == 60.0


def test_characteristic_length_and_branch_distance():
    env = Environment(start_length=2.0, scale=(1.5, 1.5, 1.5), branch_length=0.5)
    assert env.characteristic_length(0) == 2.0
    assert env.characteristic_length(2) == pytest.approx(2.0 * 2.25)
    assert env.max_branch_distance(2) == pytest.approx(0.5 * 4.5)


def test_scalar_scale_is_per_axis_and_numbers_normalise():
    assert Environment(scale=1.2).scale == (1.2, 1.2, 1.2)
    env = Environment(scale=np.array([1.0, 2.0, 3.0]), start_position=[1, 2, 3])
    assert env.scale == (1.0, 2.0, 3.0) and env.start_position == (1.0, 2.0, 3.0)
    assert hash(env) == hash(Environment(scale=(1, 2, 3), start_position=(1, 2, 3)))


@pytest.mark.parametrize(("field", "value", "message"), [
    ("steps", -1, "steps"),
    ("steps", 2.5, "steps"),
    ("steps", True, "steps"),
    ("scale", 0.0, "scale"),
    ("scale", [1, 2], "scale"),
    ("scale", "big", "scale"),
    ("start_length", -1.0, "start_length"),
    ("branch_length", 0.0, "branch_length"),
    ("label_noise", 1.5, "label_noise"),
    ("position_noise", -0.1, "position_noise"),
    ("vertex_mass", 0, "vertex_mass"),
    ("max_edges", 0, "max_edges"),
    ("fixed_centre", 1, "fixed_centre"),
    ("seed", -3, "seed"),
    ("seed_polygon", [[0, 0, 0], [1, 0, 0]], "seed_polygon"),
    ("gravity", {"direction": "w"}, "gravity.direction"),
    ("gravity", [0, 0, float("nan")], "gravity"),
    ("repellers", [{"position": [0, 0], "constant": 1}], r"repellers\[0\].position"),
    ("attractors", [{"law": "cubic"}], r"attractors\[0\].law"),
    ("attractors", [{"charge": 1}], r"attractors\[0\].charge"),
    ("boundaries", [{"kind": "cylinder"}], r"boundaries\[0\].kind"),
    ("boundaries", [{"radius": 1}], r"boundaries\[0\].kind"),
    ("boundaries", [{"kind": "sphere", "radius": -2}], r"boundaries\[0\].radius"),
    ("boundaries", [{"kind": "plane", "behavior": "slide"}], r"boundaries\[0\].behavior"),
    ("boundaries", [{"kind": "box", "behaviour": "stop"}], "behaviour"),
])
def test_bad_fields_name_the_file_and_field(field, value, message):
    with pytest.raises(ConfigError, match=message) as info:
        Environment.from_dict({field: value}, source="env.toml")
    assert str(info.value).startswith("env.toml")


def test_seed_masses_need_a_matching_polygon():
    triangle = ((0, 0, 0), (1, 0, 0), (0, 1, 0))
    env = Environment(seed_polygon=triangle, seed_masses=(1, 2, 3))
    assert env.seed_masses == (1.0, 2.0, 3.0)
    assert env.seed_centre == pytest.approx((1 / 3, 1 / 3, 0))
    with pytest.raises(ConfigError, match="seed_masses"):
        Environment(seed_polygon=triangle, seed_masses=(1, 2))
    with pytest.raises(ConfigError, match="seed_masses"):
        Environment(seed_masses=(1, 2, 3))


def test_unknown_top_level_key(tmp_path):
    path = tmp_path / "env.toml"
    path.write_text("steps = 3\nstep_count = 4\n")
    with pytest.raises(ConfigError, match=r"env.toml: field 'step_count': unknown field"):
        load_environment(path)


def test_wrong_type_in_file(tmp_path):
    path = tmp_path / "env.toml"
    path.write_text('steps = "four"\n')
    with pytest.raises(ConfigError, match=r"env.toml: field 'steps': must be an integer"):
        load_environment(path)


def test_malformed_toml_and_missing_file(tmp_path):
    path = tmp_path / "env.toml"
    path.write_text("steps = = 3\n")
    with pytest.raises(ConfigError, match=r"env.toml: not valid TOML.*line 1"):
        load_environment(path)
    with pytest.raises(ConfigError, match=r"nothere\.toml"):
        load_environment(tmp_path / "nothere.toml")


def test_full_file_round_trip(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(1, 1, 1)).export(tmp_path / "crate.stl")
    text = """
steps = 5
scale = [1.4, 1.4, 1.1]
start_position = [0, 0, 2]
seed = 42
branch_length = 1.5
label_noise = 0.05
position_noise = 0.02
fixed_centre = true
repelling_points = 0.1
gravity = {direction = "-z", magnitude = 0.3}

[[repellers]]
position = [0, 0, -1]
constant = 2.0
exponent = 2

[[attractors]]
position = [3, 0, 2]
law = "bounded"

[[boundaries]]
kind = "sphere"
centre = [0, 0, -2]
radius = 1.5

[[boundaries]]
kind = "box"
min = [-6, -6, -6]
max = [6, 6, 6]
behaviour = "cut-off"

[[boundaries]]
kind = "plane"
point = [0, 0, 10]
normal = [0, 0, 1]
behaviour = "soft"
inside = true

[[boundaries]]
kind = "mesh"
path = "crate.stl"
translate = [4, 4, 0]
"""
    path = tmp_path / "env.toml"
    path.write_text(text)
    env = load_environment(path)
    assert env.steps == 5 and env.scale == (1.4, 1.4, 1.1) and env.gravity == (0.0, 0.0, -0.3)
    assert env.repellers == (PointForce(position=(0, 0, -1), constant=2.0, exponent=2.0),)
    assert env.attractors[0].law == "bounded"
    kinds = [type(b) for b in env.boundaries]
    assert kinds == [SphereBoundary, BoxBoundary, PlaneBoundary, MeshBoundary]
    assert [b.allowed_inside for b in env.boundaries] == [False, True, True, False]
    assert env.boundaries[3].path == str(tmp_path / "crate.stl")
    assert Environment.from_dict(env.to_dict()) == env
    again = tmp_path / "again.toml"
    again.write_text(tomli_w.dumps(env.to_dict()))
    assert load_environment(again) == env


def test_mesh_path_error_names_the_file(tmp_path):
    path = tmp_path / "env.toml"
    path.write_text('[[boundaries]]\nkind = "mesh"\npath = "nope.obj"\n')
    with pytest.raises(GrowthError, match=r"nope\.obj"):
        load_environment(path)


@pytest.mark.parametrize("example", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.name)
def test_shipped_examples_load(example):
    env = load_environment(example)
    assert not env.is_empty
    assert Environment.from_dict(env.to_dict()) == env


def test_pickles_with_a_mesh_boundary_for_ray_workers(tmp_path):
    import dataclasses
    import pickle

    import trimesh

    trimesh.creation.icosphere().export(tmp_path / "ball.obj")
    env = Environment(start_position=(0, 0, 2), boundaries=(MeshBoundary(path=str(tmp_path / "ball.obj")),))
    copy = pickle.loads(pickle.dumps(env))
    assert copy == env and copy.boundaries[0].allowed_inside is False
    probe = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]])
    np.testing.assert_array_equal(copy.boundaries[0].violation(probe), env.boundaries[0].violation(probe))
    assert dataclasses.replace(env, steps=2).boundaries[0].mesh is env.boundaries[0].mesh


def test_docs_describe_every_field():
    import dataclasses
    import re

    from genr8_dist.environment.boundaries import BoxBoundary, MeshBoundary, PlaneBoundary, SphereBoundary

    doc = (Path(__file__).resolve().parents[2] / "docs" / "environment.md").read_text()
    documented = set(re.findall(r"^\| `([a-z_]+)`", doc, flags=re.M))
    fields = {f.name for f in dataclasses.fields(Environment) if f.name not in ("source",)}
    assert fields - {"attractors", "repellers", "boundaries"} <= documented
    for cls in (PlaneBoundary, BoxBoundary, SphereBoundary, MeshBoundary):
        for f in dataclasses.fields(cls):
            if f.init and f.name not in ("allowed_inside",):
                assert f"`{f.name}`" in doc, f"{cls.__name__}.{f.name} is not in docs/environment.md"
