"""Growth benchmark: time per derivation step and edges per second.

    /work/venv/bin/python bench/growth.py            # tiles to 8 steps, 5 individuals per universe
    /work/venv/bin/python bench/growth.py --quick    # tiles to 7 steps, 2 individuals per universe

Prints one table per tile system (step, V, E, regions, seconds, edges/s, ratio of this step's time
per edge to the previous step's: about 1 or below means cost linear in edges), then random
individuals of every universe with surfaces grown 4, 5 and 6 steps in a capped environment, then the
CPU per text of parsing and growing random texts of each universe at 4 steps (the default environment)
with the numpy reference code and with the compiled kernels (the ``fast`` extra), and whether both
grew the same surfaces (vertices, edges, labels, regions, work, cap: bit for bit).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.errors import ParseError
from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.hemls import grow, growth, load_system, parse
from genr8_dist.rng import stream


def tiles(name: str, steps: int, repeats: int) -> None:
    system = load_system(name)
    grow(system, steps=2)  # warm caches (compiled system, imports)
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = grow(system, Environment(max_edges=2_000_000, max_work=0, max_seconds=600), steps=steps)
        total = time.perf_counter() - t0
        if best is None or total < best[0]:
            best = (total, result)
    total, result = best
    print(f"\n{name}: {steps} steps in {total:.3f} s (best of {repeats}, including the final Surface)")
    print(f"{'step':>4} {'V':>8} {'E':>8} {'regions':>8} {'seconds':>9} {'edges/s':>11} {'s/edge ratio':>12}")
    prev = None
    for s in result.steps:
        rate = s.n_edges / s.seconds if s.seconds > 0 else float("inf")
        per_edge = s.seconds / s.n_edges
        ratio = f"{per_edge / prev:.2f}" if prev else "-"
        prev = per_edge
        print(f"{s.step:>4} {s.n_vertices:>8} {s.n_edges:>8} {s.n_regions:>8} {s.seconds:>9.4f} "
              f"{rate:>11,.0f} {ratio:>12}")


def _texts(name: str, count: int, seed: int) -> list[str]:
    """Up to ``count`` texts of random valid genomes of universe ``name`` that parse as rewrite
    systems (none for a universe of another phenotype)."""
    universe = load_universe(name)
    rng = stream(seed, "bench", name)
    texts: list[str] = []
    tries = 0
    while len(texts) < count and tries < 50 * count:
        tries += 1
        mapped = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
        if mapped.valid:
            try:
                parse(mapped.text)
            except ParseError:
                return []
            texts.append(mapped.text)
    return texts


def universes(per_universe: int) -> None:
    env = Environment(max_edges=200_000, max_work=0, max_seconds=60)
    print(f"\nrandom individuals ({per_universe} valid per universe; genome 50-150 codons, seed 0)")
    print(f"{'universe':>14} {'steps':>5} {'mean s':>8} {'max s':>8} {'mean E':>9} {'max E':>9} "
          f"{'edges/s':>11} {'capped':>6}")
    for info in list_universes():
        systems = [parse(text) for text in _texts(info.name, per_universe, 0)]
        if not systems:
            print(f"{info.name:>14} (its texts are not rewrite systems)")
            continue
        for steps in (4, 5, 6):
            times, edges, capped = [], [], 0
            for i, system in enumerate(systems):
                t0 = time.perf_counter()
                result = grow(system, env, steps=steps, seed=i)
                times.append(time.perf_counter() - t0)
                edges.append(result.surface.n_edges)
                capped += result.capped is not None
            rate = sum(edges) / sum(times)
            print(f"{info.name:>14} {steps:>5} {np.mean(times):>8.3f} {np.max(times):>8.3f} "
                  f"{np.mean(edges):>9,.0f} {np.max(edges):>9,} {rate:>11,.0f} {capped:>6}")


def _grown(texts: list[str], env: Environment) -> tuple[float, list[tuple]]:
    """CPU seconds to parse and grow ``texts`` (best of two), and what each growth gave."""
    best, out = float("inf"), []
    for _ in range(2):
        t0 = time.process_time()
        results = [grow(parse(text), env) for text in texts]
        best = min(best, time.process_time() - t0)
        out = [(r.surface.vertices.tobytes(), r.surface.edges.tobytes(), r.surface.labels.tobytes(),
                r.surface.region_vertices.tobytes(), r.work, r.capped) for r in results]
    return best, out


def kernels(per_universe: int) -> None:
    compiled = growth._load_kernels()
    print(f"\nparse + grow, 4 steps, default environment ({per_universe} random texts per universe, seed 1): "
          "CPU ms per text")
    if compiled is None:
        print("  the compiled kernels are off (no numba: the `fast` extra; or GENR8_COMPILED=0)")
        return
    print(f"{'universe':>16} {'reference':>10} {'compiled':>9} {'speed-up':>9} {'same surfaces':>14}")
    env = Environment(steps=4)
    saved = growth._kernels
    for info in list_universes():
        texts = _texts(info.name, per_universe, 1)
        if not texts:
            continue
        try:
            growth._kernels = lambda: None
            slow, expected = _grown(texts, env)
            growth._kernels = lambda: compiled
            fast, got = _grown(texts, env)
        finally:
            growth._kernels = saved
        print(f"{info.name:>16} {1e3 * slow / len(texts):>10.2f} {1e3 * fast / len(texts):>9.2f} "
              f"{slow / fast:>8.2f}x {'yes' if got == expected else 'NO':>14}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and individuals")
    args = parser.parse_args()
    steps = 7 if args.quick else 8
    for name in ("four_sided_tiles", "three_sided_tiles", "square"):
        tiles(name, steps, repeats=1 if args.quick else 3)
    universes(2 if args.quick else 5)
    kernels(20 if args.quick else 100)


if __name__ == "__main__":
    main()
