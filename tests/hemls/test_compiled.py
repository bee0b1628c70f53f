"""The compiled triangulation kernels give the reference code's triangles bit for bit (same arrays,
same order, same dtype) on simple and non-simple polygons, straight runs, degenerate polygons, padded
groups of many polygons, large regions and grown surfaces."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.hemls import surface as module

pytest.importorskip("numba", reason="numba is not installed: the compiled kernels (extra `fast`) are off")

if module._load_kernels() is None:   # numba is installed, so only GENR8_COMPILED=0 turns them off
    pytest.skip("GENR8_COMPILED=0: the compiled kernels are off", allow_module_level=True)


@pytest.fixture(autouse=True, scope="module")
def _compiled_at_once():
    """The kernels from the first triangulation on (a process loads them only after some work)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(module.KERNELS, "load_after", 0)
        yield


def _both(vertices, offsets, cycles) -> np.ndarray:
    """The compiled path's triangles, after asserting that the reference path gives the same."""
    compiled = module.triangulate_polygons(vertices, offsets, cycles)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(module, "_kernels", lambda: None)
        reference = module.triangulate_polygons(vertices, offsets, cycles)
    assert compiled.dtype == reference.dtype == np.int64
    assert np.array_equal(compiled, reference)
    return compiled


def _polygons(polygons: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, offsets and cycles of ``polygons`` (each (m, 3)) as one flat input."""
    vertices = np.concatenate(polygons) if polygons else np.zeros((0, 3))
    sizes = [len(p) for p in polygons]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return vertices, offsets, np.arange(len(vertices))


def _star(rng: np.random.Generator, m: int, lift: float) -> np.ndarray:
    """A simple polygon: ``m`` vertices at sorted random angles and random radii, z tilted and bent."""
    angle = np.sort(rng.uniform(0.0, 2.0 * np.pi, m))
    radius = rng.uniform(0.2, 1.0, m)
    x, y = radius * np.cos(angle), radius * np.sin(angle)
    return np.column_stack([x, y, lift * (x + x * y)])


def _with_runs(corners: np.ndarray, per_side: np.ndarray) -> np.ndarray:
    """A polygon through ``corners`` whose side s carries ``per_side[s] - 1`` evenly spaced vertices."""
    out = []
    for a, b, n in zip(corners, np.roll(corners, -1, axis=0), per_side, strict=True):
        t = np.arange(n)[:, None] / n
        out.append(a + t * (b - a))
    return np.concatenate(out)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(3, 80), lift=st.sampled_from([0.0, 0.3, 2.0]))
def test_random_simple_polygons(seed, m, lift):
    rng = np.random.default_rng(seed)
    tri = _both(*_polygons([_star(rng, m, lift)]))
    assert tri.shape == (m - 2, 3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(3, 90), flat=st.booleans())
def test_random_non_simple_polygons(seed, m, flat):
    """Vertices anywhere: self-crossing cycles, which the programme and ear clipping leave partly
    outside (the fallback fan) the same way in both paths."""
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(m, 3))
    if flat:
        points[:, 2] = 0.0
    _both(*_polygons([points]))


@pytest.mark.parametrize("lift", [0.0, 0.4])
def test_straight_runs_small_and_large(lift):
    """Polygons whose sides carry collinear runs (what growth leaves), small ones for the programme
    and large ones (up to 900 vertices) for true corners, fans, strips and flips; star-shaped corner
    sets of 3 to 90 true corners."""
    rng = np.random.default_rng(7)
    polygons = []
    for corners in (3, 4, 5, 8, 12, 30, 70, 90):
        for runs in ((1, 2), (1, 6), (3, 12), (8, 30)):
            c = _star(rng, corners, 0.0)
            points = _with_runs(c, rng.integers(*runs, size=corners))
            points[:, 2] = lift * points[:, 0] * points[:, 1]
            polygons.append(points)
    vertices, offsets, cycles = _polygons(polygons)
    assert np.diff(offsets).max() > module._EXACT_MAX
    _both(vertices, offsets, cycles)


@pytest.mark.parametrize("lift", [0.0, 0.3])
def test_evenly_split_sides_tie_in_strips(lift):
    """Large regions whose sides all carry the same number of evenly spaced vertices: the strips
    between two such sides meet exact ties (which diagonal is shorter) that must break alike."""
    shapes = [[(0, 0), (1, 0), (1, 1), (0, 1)], [(0, 0), (3, 0), (3, 1), (0, 1)], [(0, 0), (2, 0), (0, 2)],
              [(0, 0), (1, 0), (1.5, 1), (0, 1)]]
    polygons = []
    for corners in shapes:
        for per in (17, 20, 33, 40):
            points = _with_runs(np.column_stack([corners, np.zeros(len(corners))]),
                                np.full(len(corners), per))
            points[:, 2] = lift * points[:, 0] * points[:, 1]
            polygons.append(points)
    _both(*_polygons(polygons))


def test_strips_square_like_python():
    """A grown region whose strips meet near-ties that ``x * x`` breaks unlike Python's ``x ** 2``
    (``pow``): the compiled cut squares as Python does (tests/data/README.md)."""
    points = np.loadtxt(Path(__file__).parents[1] / "data" / "strip-tie-region.txt")
    assert points.shape == (81, 3)
    _both(*_polygons([points]))


def test_degenerate_polygons():
    """Collinear vertices (no area), repeated vertices, one point, zigzags, polygons of 1 and 2
    vertices (no triangles) and a large collinear one."""
    line = np.column_stack([np.linspace(0, 1, 9), np.linspace(0, 2, 9), np.zeros(9)])
    back = np.concatenate([line, line[::-1][1:-1]])
    point = np.zeros((6, 3))
    twice = np.repeat(_star(np.random.default_rng(1), 7, 0.2), 2, axis=0)
    zigzag = np.column_stack([np.arange(40.0), np.arange(40) % 2 * 1e-12, np.zeros(40)])
    big_line = np.column_stack([np.arange(150.0), np.zeros(150), np.zeros(150)])
    tiny = _star(np.random.default_rng(2), 30, 0.0) * 1e-200
    polygons = [line, back, point, twice, zigzag, big_line, tiny, np.zeros((1, 3)), np.ones((2, 3)),
                np.concatenate([twice, twice[::-1]])]
    _both(*_polygons(polygons))
    for p in polygons:
        _both(*_polygons([p]))


def test_padded_groups_of_many_sizes():
    """Hundreds of polygons of 3 to 64 vertices in one call: solved in groups padded to their largest
    (which moves their centres and so their costs' rounding), in the order they came."""
    rng = np.random.default_rng(11)
    sizes = rng.integers(3, 65, size=400)
    polygons = [_star(rng, int(m), 0.3) if m % 3 else rng.normal(size=(int(m), 3)) for m in sizes]
    vertices, offsets, cycles = _polygons(polygons)
    perm = rng.permutation(len(vertices))            # the cycles index a shuffled vertex array
    inverse = np.argsort(perm)
    tri = _both(vertices[perm], offsets, inverse[cycles])
    assert len(tri) == int(np.sum(sizes - 2))


def test_empty_input():
    assert _both(*_polygons([])).shape == (0, 3)


def test_grown_surfaces_of_random_genomes():
    """Thirty random default-universe genomes grown at 4 steps, and two predefined systems."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.operators import random_genome
    from genr8_dist.grammar import load_universe
    from genr8_dist.hemls import grow, load_system, parse
    from genr8_dist.rng import stream

    config = RunConfig(environment={"steps": 4})
    universe = load_universe("default")
    rng = stream(3, "test", "compiled")
    surfaces = [grow(load_system("koch"), steps=4).surface,
                grow(load_system("four_sided_tiles"), steps=4).surface]
    while len(surfaces) < 32:
        mapped = universe.map(list(random_genome(rng, 100, 255)), max_depth=config.genome.max_depth,
                              max_wraps=config.genome.max_wraps)
        if not mapped.valid:
            continue
        try:
            result = grow(parse(mapped.text), config.environment)
        except Exception:  # a genome that fails to grow is no surface to compare
            continue
        if result.surface.n_vertices <= 5_000:
            surfaces.append(result.surface)
    assert sum(s.n_regions for s in surfaces) > 100
    for s in surfaces:
        _both(s.vertices, s.region_offsets, s.region_vertices)


def test_kernels_are_off_when_asked(monkeypatch):
    monkeypatch.setenv("GENR8_COMPILED", "0")
    module._load_kernels.cache_clear()
    try:
        assert module._kernels() is None
    finally:
        module._load_kernels.cache_clear()


def test_a_process_loads_the_kernels_after_some_reference_work(monkeypatch):
    """Below ``KERNELS.load_after`` region vertices the reference code runs (a short run pays nothing for
    numba); the call that passes it still does, the next one is compiled; GENR8_COMPILED=1 loads the
    kernels at once."""
    paths = []
    real = module.KERNELS.load

    def spy():
        paths.append("compiled")
        return real()

    monkeypatch.setattr(module.KERNELS, "load", spy)
    monkeypatch.setattr(module.KERNELS, "load_after", 100)
    monkeypatch.setattr(module.KERNELS, "reference_work", 0)
    monkeypatch.delenv("GENR8_COMPILED", raising=False)
    square = _polygons([_with_runs(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                                   np.full(4, 20))])                  # 80 vertices, a large region
    first = module.triangulate_polygons(*square)
    assert paths == [] and module.KERNELS.reference_work == 80
    second = module.triangulate_polygons(*square)
    assert paths == [] and module.KERNELS.reference_work == 160
    third = module.triangulate_polygons(*square)
    assert paths and module.KERNELS.reference_work == 160
    assert np.array_equal(first, second) and np.array_equal(first, third)
    monkeypatch.setattr(module.KERNELS, "reference_work", 0)
    monkeypatch.setenv("GENR8_COMPILED", "1")
    paths.clear()
    module.triangulate_polygons(*square)
    assert paths


def test_kernels_compile_in_memory_when_no_cache_directory_is_writable(monkeypatch):
    """numba refuses ``cache=True`` when it finds no writable cache directory: the kernels are then
    compiled in memory instead of failing the run."""
    from genr8_dist.hemls import _compiled

    real = _compiled.numba.njit

    def njit(*args, **kwargs):
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file 'f.py'")
        return real(*args, **kwargs)

    monkeypatch.setattr(_compiled.numba, "njit", njit)

    def square(x: float) -> float:
        return x * x

    kernel = _compiled._jit(square)
    assert kernel(3.0) == 9.0 and type(kernel._cache).__name__ == "NullCache"
