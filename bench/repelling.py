"""Repelling points: every pair (the thesis), exactly and by Barnes–Hut, against a cut-off radius.

    python bench/repelling.py                 # four_sided_tiles, steps 5 to 7 (1,089 to 16,641 V)
    python bench/repelling.py --steps 6 --theta 0.3 0.5 0.7

For each step of four_sided_tiles (V vertices, the surface flat, then the same surface bent into a
dome) prints the seconds a whole derivation step takes without repelling points (the growth time
budget the force has to fit in; a growth's ``max_seconds`` defaults to 60), and the seconds the
repelling-points displacement takes: every pair exactly (``repelling_theta = 0``; above 5,000
vertices estimated from a sample of target vertices), by Barnes–Hut at each opening angle θ, and
within radii of 1 and 3 mean edge lengths. The Barnes–Hut error is measured against the exact sum on
(a sample of) the vertices: the norm of the difference over the root mean square of the exact
displacement, as a median and a maximum over the vertices.
"""

from __future__ import annotations

import argparse
import functools
import math
import time

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.environment.barnes_hut import inverse_square_field
from genr8_dist.environment.forces import repelling_displacement
from genr8_dist.environment.physics import mean_edge_length
from genr8_dist.hemls import grow, load_system

SAMPLE = 400   # target vertices the exact sum is computed for on large surfaces


def best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def exact_at(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """The exact field Σ_j (p_i - p_j)/|p_i - p_j|^3 at ``targets`` (indices), all pairs."""
    out = np.zeros((len(targets), 3))
    for r0 in range(0, len(targets), 200):
        rows = targets[r0:r0 + 200]
        delta = points[rows, None, :] - points[None, :, :]
        d2 = np.einsum("ijk,ijk->ij", delta, delta)
        d2[d2 == 0.0] = np.inf
        out[r0:r0 + 200] = np.einsum("ij,ijk->ik", d2 ** -1.5, delta)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=7, help="last derivation step to measure")
    parser.add_argument("--theta", type=float, nargs="+", default=[0.3, 0.5, 0.7],
                        help="Barnes-Hut opening angles")
    args = parser.parse_args()
    system = load_system("four_sided_tiles")
    result = grow(system, Environment(max_edges=2_000_000, max_seconds=600, max_work=0), steps=args.steps,
                  keep_steps=True)
    rng = np.random.default_rng(0)
    head = f"{'step':>4} {'shape':>5} {'V':>6} {'step s':>7} {'exact s':>8}"
    for theta in args.theta:
        head += f" {f'θ={theta} s':>9} {'err med':>8} {'err max':>8}"
    print(head + f" {'R=3 s':>7} {'R=1 s':>7}")
    for step in range(max(1, args.steps - 2), args.steps + 1):
        flat = np.asarray(result.history[step].vertices, dtype=np.float64)
        radius2 = float(np.max(np.sum(flat[:, :2] ** 2, axis=1)))
        dome = flat.copy()
        dome[:, 2] = np.sqrt(np.maximum(1.5 * radius2 - np.sum(flat[:, :2] ** 2, axis=1), 0.0))
        edges = np.asarray(result.history[step].edges)
        seconds = result.steps[step - 1].seconds
        for shape, points in (("flat", flat), ("dome", dome)):
            n = len(points)
            masses = np.ones(n)
            length = mean_edge_length(points, edges, 1.0)
            repeats = 3 if n < 5_000 else 1
            targets = np.arange(n) if n <= 5_000 else np.sort(rng.choice(n, SAMPLE, replace=False))
            t0 = time.perf_counter()
            exact = exact_at(points, targets)
            exact_s = (time.perf_counter() - t0) * n / len(targets)
            scale = math.sqrt(float(np.mean(np.sum(exact ** 2, axis=1))))
            row = f"{step:>4} {shape:>5} {n:>6} {seconds:>7.3f} {'~' if n > 5_000 else ''}{exact_s:>7.2f}"
            for theta in args.theta:
                bh_s = best(functools.partial(inverse_square_field, points, theta), repeats)
                err = np.linalg.norm(inverse_square_field(points, theta)[targets] - exact, axis=1) / scale
                row += f" {bh_s:>9.3f} {float(np.median(err)):>8.1e} {float(err.max()):>8.1e}"
            three, one = (best(functools.partial(repelling_displacement, points, masses, 0.05, r, length),
                               repeats) for r in (3 * length, length))
            print(row + f" {three:>7.3f} {one:>7.3f}")


if __name__ == "__main__":
    main()
