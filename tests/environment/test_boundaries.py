"""Boundaries: slide, cut-off and reflect are never crossed; soft ones are crossed and counted."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.environment import (
    BoxBoundary,
    Environment,
    MeshBoundary,
    PlaneBoundary,
    PointForce,
    SphereBoundary,
)
from genr8_dist.errors import ConfigError, GrowthError
from genr8_dist.rng import stream

_NO_EDGES = np.zeros((0, 2), dtype=np.int64)


def step_once(env: Environment, p: np.ndarray, stopped=None, step: int = 1):
    n = len(p)
    stopped = np.zeros(n, dtype=bool) if stopped is None else stopped
    return env.increase_size(p, step=step, masses=np.ones(n), stopped=stopped, perimeter=np.zeros(n, bool),
                             edges=_NO_EDGES, rng=stream(0, "growth"))


def disc(n: int = 200, radius: float = 1.0, z: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(7)  # test data only
    r = radius * np.sqrt(rng.random(n))
    t = rng.random(n) * 2 * np.pi
    return np.column_stack([r * np.cos(t), r * np.sin(t), np.full(n, z)])


def test_allowed_side_is_where_the_seed_starts_unless_given():
    above = Environment(start_position=(0, 0, 1), boundaries=(PlaneBoundary(point=(0, 0, 0)),))
    below = Environment(start_position=(0, 0, -1), boundaries=(PlaneBoundary(point=(0, 0, 0)),))
    forced = Environment(start_position=(0, 0, 1), boundaries=(PlaneBoundary(inside=True),))
    assert above.boundaries[0].allowed_inside is False
    assert below.boundaries[0].allowed_inside is True
    assert forced.boundaries[0].allowed_inside is True
    ball = Environment(boundaries=(SphereBoundary(centre=(0, 0, -3), radius=2.0),))
    room = Environment(boundaries=(BoxBoundary(min=(-5, -5, -5), max=(5, 5, 5)),))
    assert ball.boundaries[0].allowed_inside is False and room.boundaries[0].allowed_inside is True
    polygon = Environment(seed_polygon=((0, 0, 3), (1, 0, 3), (0, 1, 3)),
                          boundaries=(SphereBoundary(centre=(0, 0, 3), radius=2.0),))
    assert polygon.boundaries[0].allowed_inside is True


def test_slide_drapes_a_sphere_under_gravity():
    ball = SphereBoundary(centre=(0, 0, -2.0), radius=1.5)
    env = Environment(scale=1.2, gravity=(0, 0, -0.5), boundaries=(ball,))
    p = disc()
    stopped = np.zeros(len(p), dtype=bool)
    for step in range(1, 8):
        p, stopped = step_once(env, p, stopped, step)
        assert np.all(np.linalg.norm(p - [0, 0, -2.0], axis=1) >= 1.5)
    assert not stopped.any()
    # the centre rests on the sphere's top, the rim has fallen below it: a drape
    top = np.argmin(np.linalg.norm(p[:, :2], axis=1))
    assert np.linalg.norm(p[top] - [0, 0, -2.0]) == pytest.approx(1.5, abs=1e-6)
    assert p[top, 2] > -1.0
    assert p[:, 2].min() < -1.5


def test_slide_keeps_the_move_along_the_wall():
    env = Environment(scale=1.0, gravity=(1.0, 0.0, -1.0), boundaries=(PlaneBoundary(point=(0, 0, 0)),),
                      start_position=(0, 0, 0.5))
    out, stopped = step_once(env, np.array([[0.0, 0.0, 0.5]]))
    np.testing.assert_allclose(out[0], [1.0, 0.0, 0.0], atol=1e-8)
    assert out[0, 2] >= 0.0 and not stopped[0]


def test_cut_off_stops_vertices_for_good():
    box = BoxBoundary(min=(-2, -2, -1), max=(2, 2, 1), behaviour="cut-off")
    env = Environment(scale=1.5, gravity=(0.3, 0.2, 0.0), boundaries=(box,))
    p = disc()
    stopped = np.zeros(len(p), dtype=bool)
    frozen_at: dict[int, np.ndarray] = {}
    for step in range(1, 7):
        p, new = step_once(env, p, stopped, step)
        assert np.all(new >= stopped), "the stop mask is cumulative"
        for i, where in frozen_at.items():
            assert np.array_equal(p[i], where), "a cut-off vertex moved again"
        for i in np.flatnonzero(new & ~stopped):
            frozen_at[int(i)] = p[i].copy()
        stopped = new
        assert np.all(np.abs(p[:, :2]) <= 2.0)
    assert stopped.sum() > len(p) // 2
    # stopped where they hit the wall, not before it
    hit = p[stopped]
    assert np.all(np.max(np.abs(hit[:, :2]), axis=1) > 2.0 - 1e-6)


def test_reflect_mirrors_the_penetration():
    env = Environment(scale=1.0, gravity=(0.0, 0.0, -1.5), start_position=(0, 0, 1),
                      boundaries=(PlaneBoundary(behaviour="reflect"),))
    out, stopped = step_once(env, np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 3.0]]))
    np.testing.assert_allclose(out, [[0.0, 0.0, 0.5], [2.0, 0.0, 1.5]])
    assert not stopped.any()


def test_reflect_inside_a_sphere_is_never_crossed():
    env = Environment(scale=1.6, boundaries=(SphereBoundary(radius=3.0, behaviour="reflect"),))
    p = disc(radius=1.0)
    for step in range(1, 8):
        p, _ = step_once(env, p, None, step)
        assert np.all(np.linalg.norm(p, axis=1) <= 3.0)


def test_soft_boundaries_let_vertices_through_and_count_them():
    env = Environment(scale=1.0, gravity=(0, 0, -1.0), start_position=(0, 0, 1),
                      boundaries=(PlaneBoundary(behaviour="soft"),))
    p = np.column_stack([np.zeros(10), np.zeros(10), np.linspace(0.1, 2.0, 10)])
    out, stopped = step_once(env, p)
    np.testing.assert_allclose(out[:, 2], p[:, 2] - 1.0)
    assert env.count_soft_violations(out) == int(np.sum(out[:, 2] < 0)) == 5
    assert env.count_soft_violations(p) == 0
    assert not stopped.any()


def test_only_soft_boundaries_count():
    env = Environment(boundaries=(PlaneBoundary(inside=True), SphereBoundary(radius=1.0, behaviour="soft",
                                                                            inside=True)))
    p = np.array([[0, 0, 0.5], [0, 0, 2.0], [0, 0, -3.0]])
    assert env.count_soft_violations(p) == 2


def _icosphere_file(tmp_path, radius=1.5, centre=(0.0, 0.0, -2.0), name="ball.obj"):
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    mesh.apply_translation(centre)
    path = tmp_path / name
    mesh.export(path)
    return path


def test_mesh_boundary_behaves_like_the_sphere_it_approximates(tmp_path):
    path = _icosphere_file(tmp_path)
    env = Environment(scale=1.2, gravity=(0, 0, -0.5), boundaries=(MeshBoundary(path=str(path)),))
    assert env.boundaries[0].watertight and env.boundaries[0].allowed_inside is False
    p = disc(60)
    for step in range(1, 6):
        p, _ = step_once(env, p, None, step)
        assert np.all(env.boundaries[0].violation(p) <= 0)
    # an icosphere lies inside its sphere: nobody is deeper than the facets allow
    assert np.all(np.linalg.norm(p - [0, 0, -2.0], axis=1) >= 1.5 * 0.95)
    top = np.argmin(np.linalg.norm(p[:, :2], axis=1))
    assert p[top, 2] > -1.0


def test_open_mesh_uses_its_face_normals(tmp_path):
    import trimesh

    floor = trimesh.Trimesh(vertices=[[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]],
                            faces=[[0, 1, 2], [0, 2, 3]])
    path = tmp_path / "floor.ply"
    floor.export(path)
    env = Environment(scale=1.0, gravity=(0, 0, -2.0), start_position=(0, 0, 1),
                      boundaries=(MeshBoundary(path=str(path)),))
    assert not env.boundaries[0].watertight
    out, _ = step_once(env, np.array([[0.5, 0.5, 1.0], [1.0, -1.0, 3.0]]))
    assert np.all(out[:, 2] >= 0.0)
    np.testing.assert_allclose(out[:, 2], [0.0, 1.0], atol=1e-6)


def test_unreadable_mesh_names_the_file(tmp_path):
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"this is not a mesh")
    with pytest.raises(GrowthError, match=r"broken\.stl"):
        MeshBoundary(path=str(bad))
    with pytest.raises(GrowthError, match=r"missing\.obj"):
        MeshBoundary(path=str(tmp_path / "missing.obj"))


def test_bad_boundary_values_are_config_errors():
    with pytest.raises(ConfigError, match="behaviour"):
        PlaneBoundary(behaviour="bounce")
    with pytest.raises(ConfigError, match="normal"):
        PlaneBoundary(normal=(0, 0, 0))
    with pytest.raises(ConfigError, match="max"):
        BoxBoundary(min=(0, 0, 0), max=(1, -1, 1))


_HARD = st.sampled_from(["slide", "cut-off", "reflect"])


@st.composite
def _boundary(draw):
    behaviour = draw(_HARD)
    kind = draw(st.sampled_from(["plane", "box", "sphere"]))
    coord = st.floats(-3, 3, allow_nan=False)
    if kind == "plane":
        normal = draw(st.tuples(coord, coord, coord).filter(lambda v: sum(x * x for x in v) > 0.01))
        return PlaneBoundary(point=(0, 0, draw(st.floats(-2, -0.1))), normal=normal, behaviour=behaviour)
    if kind == "box":
        half = draw(st.floats(0.5, 4))
        return BoxBoundary(min=(-half, -half, -half), max=(half, half, half), behaviour=behaviour,
                           inside=draw(st.booleans()))
    return SphereBoundary(centre=draw(st.tuples(coord, coord, coord)), radius=draw(st.floats(0.3, 3)),
                          behaviour=behaviour, inside=draw(st.booleans()))


@given(boundaries=st.lists(_boundary(), min_size=1, max_size=3),
       gravity=st.tuples(*[st.floats(-2, 2, allow_nan=False)] * 3),
       scale=st.floats(0.5, 2.0),
       steps=st.integers(1, 4))
def test_hard_boundaries_are_never_crossed(boundaries, gravity, scale, steps):
    env = Environment(scale=scale, gravity=gravity, boundaries=tuple(boundaries),
                      repellers=(PointForce(position=(0.3, 0.1, -0.4), constant=0.2),))
    p = disc(40, radius=0.6)
    allowed_at_start = np.ones(len(p), dtype=bool)
    for b in env.boundaries:
        allowed_at_start &= b.violation(p) <= 0
    stopped = np.zeros(len(p), dtype=bool)
    for step in range(1, steps + 1):
        p, stopped = step_once(env, p, stopped, step)
        for b in env.boundaries:
            assert np.all(b.violation(p[allowed_at_start]) <= 0), b


def _brute_closest(points, triangles):
    """Closest distance to a triangle soup, by dense sampling-free brute force over every triangle."""
    from genr8_dist.environment._meshgeom import _closest_pairs

    n, t = len(points), len(triangles)
    p = np.repeat(points, t, axis=0)
    tri = np.tile(triangles, (n, 1, 1))
    closest, _ = _closest_pairs(p, tri[:, 0], tri[:, 1], tri[:, 2])
    return np.linalg.norm(closest - p, axis=1).reshape(n, t).min(axis=1)


@pytest.mark.parametrize("shape", ["box", "torus", "inverted box"])
def test_mesh_queries_are_exact_on_sharp_and_concave_meshes(tmp_path, shape):
    import trimesh

    from genr8_dist.environment._meshgeom import TriangleMesh

    rng = np.random.default_rng(3)  # test data only
    points = rng.uniform(-2.5, 2.5, size=(400, 3))
    if shape == "torus":
        mesh = trimesh.creation.torus(major_radius=1.5, minor_radius=0.6, major_sections=48,
                                      minor_sections=24)
        ring = np.hypot(points[:, 0], points[:, 1]) - 1.5
        truth = ring ** 2 + points[:, 2] ** 2 < 0.6 ** 2
        clear = np.abs(np.sqrt(ring ** 2 + points[:, 2] ** 2) - 0.6) > 0.05  # away from the facets' sag
    else:
        mesh = trimesh.creation.box(extents=(2, 3, 1.5))
        if shape == "inverted box":
            mesh.invert()
        truth = np.all(np.abs(points) < [1.0, 1.5, 0.75], axis=1)
        clear = np.ones(len(points), dtype=bool)
    path = tmp_path / "shape.stl"
    mesh.export(path)
    env = Environment(start_position=(0, 0, 10), boundaries=(MeshBoundary(path=str(path)),))
    boundary = env.boundaries[0]
    assert boundary.watertight and boundary.allowed_inside is False
    inside = boundary.outside_distance(points) < 0
    assert np.array_equal(inside[clear], truth[clear])
    geometry = TriangleMesh(mesh.vertices, mesh.faces)
    _, distance, _ = geometry.query(points)
    np.testing.assert_allclose(distance, _brute_closest(points, geometry.triangles), atol=1e-12)


@pytest.fixture(scope="module")
def crate(tmp_path_factory):
    """Two closed, disjoint shells as one boundary file: a slab and a block hovering over one corner,
    so the allowed space (outside both) is not convex."""
    import trimesh

    box = trimesh.creation.box(extents=(6, 6, 3))
    box.apply_translation((0, 0, -2.0))
    block = trimesh.creation.box(extents=(1, 1, 1))
    block.apply_translation((1.0, 1.0, 0.3))
    vertices = np.vstack([box.vertices, block.vertices])
    faces = np.vstack([box.faces, block.faces + len(box.vertices)])
    path = tmp_path_factory.mktemp("mesh") / "crate.ply"
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return path


@settings(max_examples=25)
@given(behaviour=_HARD, gravity=st.tuples(*[st.floats(-1.5, 1.5, allow_nan=False)] * 3),
       scale=st.floats(0.7, 1.8), start_z=st.floats(1.0, 2.0))
def test_mesh_boundaries_are_never_crossed(crate, behaviour, gravity, scale, start_z):
    env = Environment(scale=scale, gravity=gravity, start_position=(0, 0, start_z),
                      boundaries=(MeshBoundary(path=str(crate), behaviour=behaviour),))
    b = env.boundaries[0]
    p = disc(30, radius=0.8, z=start_z)
    stopped = np.zeros(len(p), dtype=bool)
    for step in range(1, 4):
        before = p
        p, new = step_once(env, p, stopped, step)
        assert np.all(b.violation(p) <= 0)
        assert np.array_equal(p[stopped], before[stopped])
        stopped = new


def test_a_behaviour_is_one_registry_entry(monkeypatch):
    """A new behaviour needs only its entry: here one that keeps a violating vertex where it was."""
    from genr8_dist.environment import BEHAVIOURS, Behaviour

    assert {name: (b.hard, b.stops) for name, b in BEHAVIOURS.items()} == {
        "slide": (True, False), "cut-off": (True, True), "reflect": (True, False), "soft": (False, False)}
    monkeypatch.setitem(BEHAVIOURS, "hold", Behaviour("hold", hard=True, resolve=lambda b, p, q, e: p))
    env = Environment(scale=1.0, gravity=(0.0, 0.0, -1.5), start_position=(0, 0, 1),
                      boundaries=(PlaneBoundary(behaviour="hold"),))
    out, stopped = step_once(env, np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 3.0]]))
    np.testing.assert_allclose(out, [[0.0, 0.0, 1.0], [2.0, 0.0, 1.5]])
    assert not stopped.any() and env.count_soft_violations(out) == 0


def test_every_kind_draws_and_bounds_itself(tmp_path):
    """Each boundary kind gives its wireframe, the points a picture holds and the studio's JSON; no
    module outside boundaries.py asks which kind a boundary is (a new kind touches that file only)."""
    import ast
    import json
    from pathlib import Path

    from genr8_dist.environment import boundaries as module

    built = {"plane": PlaneBoundary(point=(0, 0, -1)), "box": BoxBoundary(),
             "sphere": SphereBoundary(radius=2), "mesh": MeshBoundary(path=str(_icosphere_file(tmp_path)))}
    assert set(built) == set(module._KINDS)
    for kind, b in built.items():
        segments = b.outline(np.zeros(3), 2.0)
        assert segments.shape[1:] == (2, 3) and len(segments) and np.isfinite(segments).all()
        sketch = json.loads(json.dumps(b.sketch()))
        assert sketch["kind"] == kind and len(sketch["segments"]) == len(segments)
        assert ("anchor" in sketch) == b.unbounded
    assert np.allclose(built["sphere"].reach(), [[-2, -2, -2], [2, 2, 2]])
    assert len(built["plane"].reach()) == 0
    names = {cls.__name__ for cls in module._KINDS.values()}
    package = Path(module.__file__).resolve().parents[1]
    asking = sorted(f"{path.relative_to(package)}:{node.lineno}" for path in package.rglob("*.py")
                    if path.parent.name != "environment"
                    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                    if isinstance(node, ast.Name) and node.id in names)
    assert not asking, f"a boundary kind named outside environment/: {asking}"
