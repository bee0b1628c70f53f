"""Repelling points: all pairs (the thesis) against a cut-off radius, in seconds per derivation step.

    python bench/repelling.py            # four_sided_tiles, steps 4 to 7
    python bench/repelling.py --steps 6

For each step of four_sided_tiles (V vertices) prints the seconds the repelling-points displacement
takes with every pair (``repelling_radius = -1``) and with radii of 1 and 3 mean edge lengths, and
the seconds a whole derivation step takes without repelling points: the growth time budget the
force has to fit in (a run's ``max_seconds`` defaults to 60 for a whole growth).
"""

from __future__ import annotations

import argparse
import functools
import math
import time

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.environment.forces import repelling_displacement
from genr8_dist.environment.physics import mean_edge_length
from genr8_dist.hemls import grow, load_system


def best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=7, help="last derivation step to measure")
    args = parser.parse_args()
    system = load_system("four_sided_tiles")
    result = grow(system, Environment(max_edges=2_000_000, max_seconds=600, max_work=0), steps=args.steps,
                  keep_steps=True)
    print(f"{'step':>4} {'V':>7} {'step s':>8} {'all pairs s':>12} {'R=3 s':>8} {'R=1 s':>8} "
          f"{'all / step':>10}")
    for step in range(4, args.steps + 1):
        surface = result.history[step]
        points = np.asarray(surface.vertices)
        masses = np.ones(len(points))
        length = mean_edge_length(points, np.asarray(surface.edges), 1.0)
        repeats = 3 if len(points) < 20_000 else 1
        every, three, one = (
            best(functools.partial(repelling_displacement, points, masses, 0.05, radius, length), repeats)
            for radius in (math.inf, 3 * length, length))
        seconds = result.steps[step - 1].seconds
        print(f"{step:>4} {len(points):>7} {seconds:>8.3f} {every:>12.3f} {three:>8.3f} {one:>8.3f} "
              f"{every / seconds:>10.1f}")


if __name__ == "__main__":
    main()
