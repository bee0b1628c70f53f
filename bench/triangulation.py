"""Exported triangles (issue 10, item 7): how thin they are, and how long triangulating and exporting take.

    python bench/triangulation.py                          # 40 founders of examples/subdivide.toml
    python bench/triangulation.py --founders 40 --config examples/subdivide.toml --run runs/quick

1. *founders*: the ``--founders`` generation-0 individuals of ``--config`` (one island, its universe
   and environment; trivial founders are redrawn as in a run), each grown and triangulated
   (``Surface.triangles``). Printed: regions, their vertices (median, 90th percentile, largest),
   triangles, the share of *slivers* (smallest angle below 10 degrees, the ``slivers`` criterion), the
   share of *zero-area* triangles (twice the area below 1e-9 x the longest side squared) and the
   share of those that lie in regions with no area themselves (grown flat onto a line or folded back
   on themselves: degenerate growth, not triangulation), the median smallest angle, and the CPU seconds of
   ``Surface.triangles`` over all of them.
2. *run best* (with ``--run DIR``): the same figures for the run's best individual, regrown.
3. *export*: CPU seconds to triangulate (a fresh ``Surface``, nothing cached) and to write an OBJ and a
   PLY of four_sided_tiles at 5 steps (1,024 regions) and of the founder with the most regions.
4. *kernels* (a checkout with the compiled kernels and numba installed): CPU seconds to triangulate
   the founders and every surface bench/island.py's default run scores (4 steps), with the
   numpy/Python reference code and with the compiled kernels, and on how many the triangles are
   identical; and the CPU seconds a new process spends on its first triangulation (numba's import
   and compiling, or loading the compiled code) with an empty cache (cold) and again (warm).

CPU seconds (``time.process_time``), the median of ``--repeat`` tries, so other work on the machine
counts less. Run it on an older checkout (PYTHONPATH) for the figures before a change.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from genr8_dist.config import load_config
from genr8_dist.export import export_mesh
from genr8_dist.fitness import SLIVER_DEGREES, triangle_min_angles
from genr8_dist.hemls import Surface, grow, load_system, parse


def fresh(surface: Any) -> Surface:
    """A copy of ``surface`` with nothing cached."""
    return Surface(surface.vertices, surface.edges, surface.labels, surface.ages, surface.region_offsets,
                   surface.region_vertices, surface.perimeter(), surface.masses, surface.stopped)


def cpu(work: Any, repeat: int) -> float:
    """The median CPU seconds of ``repeat`` calls of ``work``."""
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        work()
        times.append(time.process_time() - t0)
    return statistics.median(times)


def _degenerate(v: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(T,) True for triangles of zero area: twice the area below 1e-9 x the longest side squared."""
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    twice = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.sum((b - a) ** 2, 1), np.sum((c - a) ** 2, 1), np.sum((c - b) ** 2, 1)], 0)
    return twice <= 1e-9 * longest


def figures(surfaces: Sequence[Any]) -> dict[str, float]:
    """Region and triangle figures over ``surfaces`` (see the module docstring)."""
    sizes = np.concatenate([s.region_sizes for s in surfaces])
    angles, zero, flat = [], 0, 0
    for s in surfaces:
        tri = np.asarray(s.triangles()).reshape(-1, 3)
        v = s.vertices
        degenerate = _degenerate(v, tri)
        zero += int(degenerate.sum())
        # regions without area (their Newell normal, twice the area vector, vanishes: grown flat onto
        # a line or folded back on themselves), each triangulated alone: their degenerate triangles
        rv, offs = s.region_vertices, s.region_offsets
        nxt = np.arange(len(rv)) + 1
        nxt[offs[1:] - 1] = offs[:-1]
        cross = np.cross(v[rv], v[rv[nxt]])
        region_of = np.repeat(np.arange(s.n_regions), s.region_sizes)
        normal = np.stack([np.bincount(region_of, cross[:, k], s.n_regions) for k in range(3)], 1)
        extent = np.array([np.ptp(v[r], axis=0).max() for r in s.regions])
        for f in np.flatnonzero(np.linalg.norm(normal, axis=1) <= 1e-9 * extent ** 2):
            alone = type(s)(v, s.edges, s.labels, s.ages, np.array([0, s.region_sizes[f]]), s.regions[f],
                            s.perimeter()).triangles()
            flat += int(np.sum(_degenerate(v, np.asarray(alone).reshape(-1, 3))))
        angles.append(triangle_min_angles(v, tri))
    angle = np.concatenate(angles) if angles else np.zeros(0)
    n = max(len(angle), 1)
    return {"surfaces": len(surfaces), "regions": len(sizes), "size_median": float(np.median(sizes)),
            "size_p90": float(np.percentile(sizes, 90)), "size_max": int(sizes.max()),
            "triangles": len(angle), "slivers": float(np.mean(angle < SLIVER_DEGREES)),
            "zero": zero / n, "zero_flat": flat / n, "median_angle": float(np.median(angle))}


def show(title: str, f: dict[str, float], seconds: float | None = None) -> None:
    print(f"\n## {title}\n")
    print(f"surfaces {f['surfaces']}, regions {f['regions']} (vertices per region: median "
          f"{f['size_median']:.0f}, 90th percentile {f['size_p90']:.0f}, largest {f['size_max']})")
    print(f"triangles {f['triangles']}: slivers (< {SLIVER_DEGREES:.0f} deg) {f['slivers']:.3f}, "
          f"zero-area {f['zero']:.4f} (in regions without area {f['zero_flat']:.4f}), "
          f"median smallest angle {f['median_angle']:.2f} deg")
    if seconds is not None:
        print(f"Surface.triangles over all: {seconds:.3f} s CPU")


def founders(config_path: str, count: int, repeat: int) -> list[Any]:
    from genr8_dist.evolution import Island

    config = load_config(config_path)
    config = config.replace(ea={"population": count, "elites": 0, "tournament": 1},
                            islands={"count": 1, "migrants": 0})
    surfaces = [grow(parse(ind.text), config.environment).surface
                for ind in Island(config, 0).initial() if ind.valid]
    seconds = cpu(lambda: [fresh(s).triangles() for s in surfaces], repeat)
    show(f"founders: {len(surfaces)} valid of {count}, {config_path} (universe {config.universe}, "
         f"{config.environment.steps} steps)", figures(surfaces), seconds)
    return surfaces


def run_best(run: str) -> None:
    from genr8_dist.history import regrow, top

    best = top(run, 1).to_pylist()[0]
    surface = regrow(run, best["id"]).value
    show(f"run best: {run} {best['id']} (fitness {best['fitness']:.4f})", figures([surface]))


def export_times(surfaces: Sequence[Any], repeat: int) -> None:
    tiles = grow(load_system("four_sided_tiles"), steps=5).surface
    cases = [("four_sided_tiles, 5 steps", tiles)]
    if surfaces:
        cases.append(("founder with the most regions", max(surfaces, key=lambda s: s.n_regions)))
    print("\n## export\n")
    print("| surface | regions | triangles | triangulate s | OBJ s | PLY s |")
    print("| --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        for name, surface in cases:
            tri = cpu(lambda: fresh(surface).triangles(), repeat)   # noqa: B023 (called at once)
            obj = cpu(lambda: export_mesh(fresh(surface), Path(tmp) / "s.obj"), repeat)  # noqa: B023
            ply = cpu(lambda: export_mesh(fresh(surface), Path(tmp) / "s.ply"), repeat)  # noqa: B023
            print(f"| {name} | {surface.n_regions} | {len(surface.triangles())} | {tri:.3f} | {obj:.3f} "
                  f"| {ply:.3f} |")


_FIRST = """
import time
from genr8_dist.hemls import grow, load_system
surface = grow(load_system("four_sided_tiles"), steps=3).surface
t = time.process_time()
surface.triangles()
print(time.process_time() - t)
"""


def island_inputs() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The (vertices, offsets, cycles) of every triangulation bench/island.py's default run asks for
    (default universe, 4 steps, 50 x generations 0..3, seed 1): the scoring of ``slivers``."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution import Island
    from genr8_dist.hemls import surface as module

    inputs = []
    original = module.triangulate_polygons

    def record(vertices, offsets, cycles):
        inputs.append((np.array(vertices), np.array(offsets), np.array(cycles)))
        return original(vertices, offsets, cycles)

    module.triangulate_polygons = record
    try:
        config = RunConfig(universe="default", seed=1, ea={"population": 50, "generations": 3},
                           environment={"steps": 4})
        Island(config, 0).run(3)
    finally:
        module.triangulate_polygons = original
    return inputs


def kernels(surfaces: Sequence[Any], repeat: int) -> None:
    import os
    import subprocess

    from genr8_dist.hemls import surface as module

    compiled = getattr(module, "_load_kernels", lambda: None)()
    if compiled is None:
        print("\n## kernels\n\nno compiled kernels here (numba missing, GENR8_COMPILED=0, or an older "
              "checkout)")
        return
    module.KERNELS.load_after = 0     # compiled from the first triangulation on
    print("\n## kernels\n")
    print("| surfaces | triangles | reference s | compiled s | speed-up | identical |")
    print("| --- | --- | --- | --- | --- | --- |")
    cases = [("founders", [(s.vertices, s.region_offsets, s.region_vertices) for s in surfaces]),
             ("bench/island.py's default run (4 steps)", island_inputs())]
    for name, inputs in cases:
        def work(inputs=inputs):
            return [module.triangulate_polygons(*args) for args in inputs]

        fast = work()
        fast_s = cpu(work, repeat)
        original = module._kernels
        module._kernels = lambda: None
        try:
            slow = work()
            slow_s = cpu(work, repeat)
        finally:
            module._kernels = original
        same = sum(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(fast, slow, strict=True))
        print(f"| {name}: {len(inputs)} | {sum(len(t) for t in slow)} | {slow_s:.3f} | {fast_s:.3f} | "
              f"{slow_s / max(fast_s, 1e-9):.1f}x | {same} of {len(inputs)} |")
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "GENR8_COMPILED": "1"}
        first = [float(subprocess.run([sys.executable, "-c", _FIRST], env=env, check=True, text=True,
                                      capture_output=True).stdout) for _ in range(2)]
    print(f"\na new process's first triangulation (numba's import, and compiling or loading the "
          f"kernels): {first[0]:.2f} s CPU cold (empty cache), {first[1]:.2f} s warm")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="examples/subdivide.toml")
    parser.add_argument("--founders", type=int, default=40)
    parser.add_argument("--run", help="a run directory: also measure its best individual")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    surfaces = founders(args.config, args.founders, args.repeat) if args.founders > 0 else []
    if args.run:
        run_best(args.run)
    export_times(surfaces, args.repeat)
    kernels(surfaces, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
