"""How well evolution searches: live founders, wasted offspring, evolved best against random sampling.

    python bench/search.py                                   # the shipped examples, 5 seeds
    python bench/search.py --configs examples/quick.toml --seeds 3 --founders 200

Everything runs in plain Python (islands in lockstep with the run's own migration plan, no Ray), so the
figures are the engine's, not the cluster's. Sections:

1. *founders*: per built-in universe, the share of generation 0 (``--founders`` individuals, the
   environment of the first configuration) that is trivial (invalid, or a surface of one region:
   the axiom polygon left as it was or grown without subdivision).
2. *per configuration* (each over ``--seeds`` run seeds): per generation the trivial share, the share
   of distinct surfaces, the share of offspring equal to a parent (same text or same surface); the
   best fitness against evaluations; the best of a random sample of the same number of evaluations
   (one generation of that size, same seed), and the evolved best's margin over it; the evaluations
   until the best reaches the ``four_sided_tiles`` score on that fitness; MAP-Elites archive coverage
   where the configuration's mode is ``map-elites``.
3. *islands*: the configuration's islands against one population of the same total size: evaluations
   until the best reaches the single population's median final best, and how many islands' best
   surfaces are distinct at the end.

An *evaluation* is a genome the run evaluated (mapped and, if new text, grown): every founder redrawn
and offspring re-varied counts, elites, migrants and cache hits do not. The random sample gets as
many plain random genomes.
Medians are over seeds, with [min, max] beside them.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

COPIES = ("elite", "migrant")
DEFAULT_CONFIGS = ("examples/quick.toml", "examples/subdivide.toml")


def trivial(ind: Any) -> bool:
    """Invalid, or a surface of at most one region."""
    return not ind.valid or ind.sizes.get("regions", 0) <= 1


def run_islands(config: Any, generations: int) -> tuple[list[list[list[Any]]], list[int]]:
    """Generations 0..``generations`` of every island of ``config``, migrating as a run does:
    ``history[g][i]`` is island i's generation g; ``spent[g]`` the genomes evaluated up to it (every
    founder redraw and re-variation included, cache hits not)."""
    from genr8_dist.distributed.migration import is_migration_generation, plan_migration
    from genr8_dist.evolution import Island

    n = config.islands.count
    islands = [Island(config, i) for i in range(n)]
    history = [[isl.initial() for isl in islands]]
    spent = [sum(isl.evaluator.evaluations for isl in islands)]
    for g in range(1, generations + 1):
        previous = history[-1]
        migrants: dict[int, list[Any]] = {i: [] for i in range(n)}
        if n > 1 and is_migration_generation(g - 1, config.islands.migration_interval):
            choice = getattr(config.islands, "emigrants", None)
            migrants = plan_migration(dict(enumerate(previous)), config.islands.topology,
                                      config.islands.migrants, config.seed, g - 1,
                                      *((choice,) if choice else ()))
        history.append([isl.step(previous[i], g, migrants[i]) for i, isl in enumerate(islands)])
        spent.append(sum(isl.evaluator.evaluations for isl in islands))
    return history, spent


def describe(run: tuple[list[list[list[Any]]], list[int]], tiles: float) -> dict[str, Any]:
    """The per-run figures of one run's history."""
    history, spent = run
    by_id = {}
    trivial_share, distinct_share, copy_share = [], [], []
    curve = []   # (evaluations so far, best so far)
    evaluations, best = 0, math.inf
    reach = None
    for g, gen in enumerate(history):
        pops = [ind for pop in gen for ind in pop]
        trivial_share.append(sum(map(trivial, pops)) / len(pops))
        distinct = [len({ind.phenotype_digest for ind in pop if ind.valid}) / len(pop) for pop in gen]
        distinct_share.append(statistics.fmean(distinct))
        offspring = [ind for ind in pops if ind.origin not in COPIES and ind.generation > 0]
        copies = 0
        for ind in offspring:
            parents = [by_id[p] for p in ind.parents if p in by_id]
            if any(p.text == ind.text or (ind.valid and p.phenotype_digest == ind.phenotype_digest)
                   for p in parents):
                copies += 1
        if offspring:
            copy_share.append(copies / len(offspring))
        best = min(best, min(ind.fitness for ind in pops))
        evaluations = spent[g]
        if reach is None and best <= tiles + 1e-12:
            reach = evaluations
        curve.append((evaluations, best))
        by_id.update({ind.id: ind for ind in pops})
    last = history[-1]
    bests = []
    for pop in last:
        top = min(pop, key=lambda ind: ind.fitness)
        bests.append(top.phenotype_digest if top.valid else None)
    return {"trivial": trivial_share, "distinct": distinct_share, "copies": copy_share, "curve": curve,
            "evaluations": evaluations, "best": best, "reach": reach,
            "distinct_island_bests": len(set(bests)), "islands": len(last),
            "everyone": [ind for gen in history for pop in gen for ind in pop]}


def random_best(config: Any, evaluations: int) -> float:
    """The best fitness among ``evaluations`` random genomes (one generation 0 of that size, no
    founder redrawn: every evaluation a random genome)."""
    from genr8_dist.evolution import Island

    ea = {"population": max(2, evaluations), "elites": 0, "tournament": 1}
    if "founder_retries" in getattr(config.ea, "__dataclass_fields__", {}):
        ea |= {"founder_retries": 0, "init": "random"}
    one = config.replace(ea=ea, islands={"count": 1, "migrants": 0})
    return min(ind.fitness for ind in Island(one, 0).initial())


def tiles_score(config: Any) -> float:
    from genr8_dist.evolution.evaluate import evaluate_text
    from genr8_dist.resources import systems_dir

    return evaluate_text((systems_dir() / "four_sided_tiles.hemls").read_text(), config).fitness


def coverage(config: Any, everyone: Sequence[Any]) -> float | None:
    """Share of the MAP-Elites grid's cells held at the end (``None`` outside that mode)."""
    search = getattr(config, "search", None)
    if search is None or getattr(search, "mode", "weighted") != "map-elites":
        return None
    from genr8_dist.evolution.archive import Grid

    grid = Grid.from_settings(search)
    cells = {grid.cell(ind) for ind in everyone if ind.valid}
    cells.discard(None)
    return len(cells) / grid.size


def spread(values: Sequence[float], fmt: str = "{:.3f}") -> str:
    values = [v for v in values if v is not None]
    if not values:
        return "-"
    return f"{fmt.format(statistics.median(values))} [{fmt.format(min(values))}, {fmt.format(max(values))}]"


def founders(universes: Sequence[str], count: int, base: Any) -> None:
    from genr8_dist.evolution import Island

    print(f"\n## founders: trivial share of generation 0 ({count} individuals, seed {base.seed})\n")
    print("| universe | trivial | distinct surfaces | seconds |")
    print("| --- | --- | --- | --- |")
    for name in universes:
        config = base.replace(universe=name, ea={"population": count, "elites": 0, "tournament": 1},
                              islands={"count": 1, "migrants": 0})
        t0 = time.perf_counter()
        pop = Island(config, 0).initial()
        seconds = time.perf_counter() - t0
        distinct = len({ind.phenotype_digest for ind in pop if ind.valid}) / len(pop)
        print(f"| {name} | {sum(map(trivial, pop)) / len(pop):.3f} | {distinct:.3f} | {seconds:.1f} |")


def per_config(path: str, seeds: Sequence[int], generations: int | None) -> list[dict[str, Any]]:
    from genr8_dist.config import load_config

    base = load_config(path)
    last = base.ea.generations if generations is None else generations
    tiles = tiles_score(base)
    runs = []
    for seed in seeds:
        config = base.replace(seed=seed)
        t0 = time.perf_counter()
        figures = describe(run_islands(config, last), tiles)
        figures["seconds"] = time.perf_counter() - t0
        figures["random"] = random_best(config, figures["evaluations"])
        figures["coverage"] = coverage(config, figures["everyone"])
        runs.append(figures)
    mode = getattr(getattr(base, "search", None), "mode", "weighted")
    print(f"\n## {path} (mode {mode}, {base.islands.count} island(s) x {base.ea.population}, "
          f"{last} generations, {len(seeds)} seeds; four_sided_tiles scores {tiles:.4f})\n")
    print("| generation | trivial | distinct surfaces | offspring equal to a parent | best (median) |")
    print("| --- | --- | --- | --- | --- |")
    for g in range(last + 1):
        copies = [r["copies"][g - 1] for r in runs if g >= 1 and len(r["copies"]) >= g]
        print(f"| {g} | {statistics.median(r['trivial'][g] for r in runs):.3f} | "
              f"{statistics.median(r['distinct'][g] for r in runs):.3f} | "
              f"{statistics.median(copies):.3f} | " if copies else
              f"| {g} | {statistics.median(r['trivial'][g] for r in runs):.3f} | "
              f"{statistics.median(r['distinct'][g] for r in runs):.3f} | - | ", end="")
        print(f"{statistics.median(r['curve'][g][1] for r in runs):.4f} |")
    margins = [(r["random"] - r["best"]) / r["random"] if r["random"] > 0 else 0.0 for r in runs]
    print()
    print(f"- evaluations per run: {runs[0]['evaluations']}")
    print(f"- evolved best: {spread([r['best'] for r in runs], '{:.4f}')}")
    print(f"- random best, same evaluations: {spread([r['random'] for r in runs], '{:.4f}')}")
    print(f"- margin of evolved over random (share of the random best): {spread(margins)}; "
          f"evolved better in {sum(m > 0 for m in margins)} of {len(runs)} seeds")
    reached = [r["reach"] for r in runs if r["reach"] is not None]
    print(f"- evaluations to reach the four_sided_tiles score: reached in {len(reached)} of {len(runs)}"
          f"; {spread(reached, '{:.0f}')}")
    print(f"- trivial share, all generations after 0: "
          f"{spread([statistics.fmean(r['trivial'][1:]) for r in runs if len(r['trivial']) > 1])}")
    print(f"- distinct surfaces, all generations: {spread([min(r['distinct']) for r in runs])} (lowest "
          f"generation), {spread([statistics.fmean(r['distinct']) for r in runs])} (mean)")
    copies = [statistics.fmean(r["copies"]) for r in runs if r["copies"]]
    print(f"- offspring equal to a parent: {spread(copies)}")
    if runs[0]["coverage"] is not None:
        print(f"- MAP-Elites coverage at the end: {spread([r['coverage'] for r in runs])}")
    print(f"- seconds per run: {spread([r['seconds'] for r in runs], '{:.1f}')}")
    return runs


def islands_vs_one(path: str, seeds: Sequence[int], count: int, generations: int | None) -> None:
    from genr8_dist.config import load_config

    base = load_config(path)
    last = base.ea.generations if generations is None else generations
    total = base.ea.population * base.islands.count
    per = total // count
    variants = {
        f"{count} islands x {per}": base.replace(
            ea={"population": per, "elites": min(base.ea.elites, per - 1)},
            islands={"count": count, "migrants": min(base.islands.migrants, per - 1)}),
        f"1 population x {per * count}": base.replace(ea={"population": per * count},
                                                      islands={"count": 1, "migrants": 0}),
    }
    tiles = tiles_score(base)
    results: dict[str, list[dict[str, Any]]] = {}
    for name, config in variants.items():
        results[name] = [describe(run_islands(config.replace(seed=s), last), tiles) for s in seeds]
    single = list(results)[1]
    goal = statistics.median(r["best"] for r in results[single])
    print(f"\n## islands against one population ({path}, {last} generations, {len(seeds)} seeds)\n")
    print(f"Goal: the one population's median final best, {goal:.4f}.\n")
    print("| variant | final best | evaluations to the goal | runs reaching it | distinct island bests |")
    print("| --- | --- | --- | --- | --- |")
    for name, runs in results.items():
        reach = []
        for r in runs:
            hit = next((e for e, b in r["curve"] if b <= goal + 1e-12), None)
            reach.append(hit)
        distinct = [r["distinct_island_bests"] for r in runs]
        print(f"| {name} | {spread([r['best'] for r in runs], '{:.4f}')} | "
              f"{spread([x for x in reach if x is not None], '{:.0f}')} | "
              f"{sum(x is not None for x in reach)}/{len(runs)} | "
              f"{spread(distinct, '{:.0f}')} of {runs[0]['islands']} |")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="*", default=list(DEFAULT_CONFIGS))
    parser.add_argument("--seeds", type=int, default=5, help="run seeds 1..N (default 5)")
    parser.add_argument("--generations", type=int, default=None, help="override ea.generations")
    parser.add_argument("--founders", type=int, default=200, help="generation-0 size per universe")
    parser.add_argument("--universes", nargs="*", default=None, help="default: every built-in")
    parser.add_argument("--islands", type=int, default=4, help="islands in the islands comparison")
    parser.add_argument("--skip", nargs="*", default=[], choices=["founders", "configs", "islands"])
    args = parser.parse_args(argv)
    from genr8_dist import grammar
    from genr8_dist.config import load_config

    seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    if "founders" not in args.skip:
        names = args.universes or [u.name for u in grammar.list_universes() if u.origin == "built-in"]
        founders(names, args.founders, load_config(args.configs[0]))
    if "configs" not in args.skip:
        for path in args.configs:
            per_config(path, seeds, args.generations)
    if "islands" not in args.skip:
        islands_vs_one(args.configs[0], seeds, args.islands, args.generations)
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
