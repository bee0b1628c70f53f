"""Growth benchmark: time per derivation step and edges per second.

    /work/venv/bin/python bench/growth.py            # tiles to 8 steps, 5 individuals per universe
    /work/venv/bin/python bench/growth.py --quick    # tiles to 7 steps, 2 individuals per universe

Prints one table per tile system (step, V, E, regions, seconds, edges/s, ratio of this step's time
per edge to the previous step's: about 1 or below means cost linear in edges), then random
individuals of every universe grown 4, 5 and 6 steps in a capped environment.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.hemls import grow, load_system
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


def universes(per_universe: int) -> None:
    env = Environment(max_edges=200_000, max_work=0, max_seconds=60)
    print(f"\nrandom individuals ({per_universe} valid per universe; genome 50-150 codons, seed 0)")
    print(f"{'universe':>14} {'steps':>5} {'mean s':>8} {'max s':>8} {'mean E':>9} {'max E':>9} "
          f"{'edges/s':>11} {'capped':>6}")
    for info in list_universes():
        universe = load_universe(info.name)
        rng = stream(0, "bench", info.name)
        systems = []
        tries = 0
        while len(systems) < per_universe and tries < 50 * per_universe:
            tries += 1
            mapped = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
            if mapped.valid:
                from genr8_dist.hemls import parse

                systems.append(parse(mapped.text))
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and individuals")
    args = parser.parse_args()
    steps = 7 if args.quick else 8
    for name in ("four_sided_tiles", "three_sided_tiles", "square"):
        tiles(name, steps, repeats=1 if args.quick else 3)
    universes(2 if args.quick else 5)


if __name__ == "__main__":
    main()
