"""How fast one island evaluates individuals, and where the time goes (map, grow, score).

    python bench/island.py                       # default universe, 4 and 5 steps, 50 x 4 generations
    python bench/island.py --population 60 --generations 4 --steps 3 4 5

For each number of derivation steps it runs one island (plain Python, no Ray) for generation 0 and a
few more, and prints the individuals per second, the distinct genomes mapped and texts grown per
second, the share of evaluation time spent mapping, parsing, growing and scoring, and the median and
largest surface (vertices).
Figures depend on the machine and on how many genomes map to texts that grow into big surfaces.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time


def run(steps: int, population: int, generations: int, seed: int, universe: str) -> dict[str, float]:
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution import Island

    config = RunConfig(universe=universe, seed=seed,
                       ea={"population": population, "generations": generations},
                       environment={"steps": steps})
    island = Island(config, 0)
    start = time.perf_counter()
    history = island.run(generations)
    wall = time.perf_counter() - start
    everyone = [ind for pop in history for ind in pop]
    mapped = sum(ind.map_seconds for ind in everyone)
    grown = sum(ind.grow_seconds for ind in everyone)
    scored = sum(ind.score_seconds for ind in everyone)
    measured = mapped + grown + scored
    ev = island.evaluator
    valid = [ind for ind in everyone if ind.valid]
    # grow_seconds includes parsing the text: parse each distinct text again to split the two
    from genr8_dist.hemls import parse

    texts = {ind.text for ind in everyone if ind.text and ind.stage != "map"}
    t0 = time.perf_counter()
    for text in texts:
        parse(text)
    parsed = min(time.perf_counter() - t0, grown)
    return {
        "steps": steps,
        "individuals": len(everyone),
        "wall_s": wall,
        "individuals_per_s": len(everyone) / wall,
        "mapped_per_s": ev.evaluations / wall,
        "grown_per_s": ev.growths / wall,
        "map_share": mapped / measured if measured else 0.0,
        "parse_share": parsed / measured if measured else 0.0,
        "grow_share": (grown - parsed) / measured if measured else 0.0,
        "score_share": scored / measured if measured else 0.0,
        "other_share": max(0.0, 1.0 - measured / wall),
        "valid_share": len(valid) / len(everyone),
        "median_vertices": statistics.median(ind.sizes.get("vertices", 0) for ind in valid) if valid else 0,
        "max_vertices": max((ind.sizes.get("vertices", 0) for ind in valid), default=0),
        "best_fitness": min((ind.fitness for ind in valid), default=float("inf")),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, nargs="+", default=[4, 5])
    parser.add_argument("--population", type=int, default=50)
    parser.add_argument("--generations", type=int, default=3, help="generations after generation 0")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--universe", default="default")
    args = parser.parse_args(argv)
    print(f"universe {args.universe}, population {args.population}, generations 0..{args.generations}, "
          f"seed {args.seed}")
    header = (f"{'steps':>5} {'indiv':>6} {'wall s':>7} {'indiv/s':>8} {'mapped/s':>9} {'grown/s':>8} "
              f"{'map':>6} {'parse':>6} {'grow':>6} {'score':>6} {'other':>6} {'valid':>6} "
              f"{'med V':>6} {'max V':>6}")
    print(header)
    for steps in args.steps:
        r = run(steps, args.population, args.generations, args.seed, args.universe)
        print(f"{r['steps']:>5} {r['individuals']:>6} {r['wall_s']:>7.2f} {r['individuals_per_s']:>8.1f} "
              f"{r['mapped_per_s']:>9.1f} {r['grown_per_s']:>8.1f} {r['map_share']:>6.1%} "
              f"{r['parse_share']:>6.1%} {r['grow_share']:>6.1%} {r['score_share']:>6.1%} "
              f"{r['other_share']:>6.1%} "
              f"{r['valid_share']:>6.1%} {r['median_vertices']:>6.0f} {r['max_vertices']:>6}")
        sys.stdout.flush()
    print("map/parse/grow/score: shares of the measured evaluation time (parse re-timed on each distinct "
          "text); other: wall time outside it (selection, variation, bookkeeping)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
