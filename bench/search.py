"""How well evolution searches: live founders, wasted offspring, evolved best against random sampling.

    python bench/search.py                                   # the shipped examples, 5 seeds
    python bench/search.py --configs examples/quick.toml --seeds 3 --founders 200
    python bench/search.py --skip founders islands --configs examples/long.toml \\
        --population 12 --generations 16                     # a long example, scaled-down EA budget
    python bench/search.py --skip founders islands --configs examples/quick.toml --env max_work=5000

Everything runs in plain Python (islands in lockstep with the run's own migration plan, no Ray), so the
figures are the engine's, not the cluster's. Sections:

1. *founders*: per built-in universe, the share of generation 0 (``--founders`` individuals, the
   environment of the first configuration) that is trivial (invalid, or a surface of one region:
   the axiom polygon left as it was or grown without subdivision), and the founder redraws it cost
   (each one an evaluation).
2. *per configuration* (each over ``--seeds`` run seeds): per generation the trivial share, the share
   of distinct surfaces, the share of offspring equal to a parent (same text or same surface); the
   best fitness against evaluations; the best of a random sample of the same number of evaluations
   (one generation of that size, same seed), and the evolved best's margin over it; the evaluations
   until the best reaches the ``four_sided_tiles`` score on that fitness. Each mode is also judged on
   what it optimises, against the same random sample: ``pareto`` on the hypervolume of the run's
   non-dominated front over its objectives (``front_volumes``), ``map-elites`` on the coverage and
   QD-score of the archive the run filled on its grid (``archive_figures``).
3. *islands*: the configuration's islands against one population of the same total size: evaluations
   until the best reaches the single population's median final best, and how many islands' best
   surfaces are distinct at the end.

An *evaluation* is a genome the run evaluated (mapped and, if new text, grown): every founder redrawn
and offspring re-varied counts, elites, migrants and cache hits do not; a genome drawn or varied
again because its text alone shows it trivial or a copy (``IslandStats.screened``: mapped and
parsed, never grown; under ``ea.screen = 2`` also the replay of its growth's topology,
``hemls.splitting.can_join``, measured at 0.2-0.4 ms a text against 12-33 ms for a growth, about
1%) does not. The random sample gets as many plain random genomes; the
founder-machinery sample a generation 0 of the run's own initialisation bought with as many
evaluations (the run's generation 0 cost per founder), so what evolution adds is measured apart
from what initialisation adds. Evaluations per stored individual: the run's evaluations over the
individuals its generations hold (elites and migrants are stored without an evaluation); growths per
stored individual: the texts it grew over them (a genome whose text grew before costs no growth).
Medians are over seeds, with [min, max] beside them.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
import tomllib
from collections.abc import Sequence
from typing import Any

COPIES = ("elite", "migrant")
DEFAULT_CONFIGS = ("examples/quick.toml", "examples/subdivide.toml")


def trivial(ind: Any, phenotype: Any = None) -> bool:
    """Invalid, or trivial as the universe's phenotype says (surfaces: at most one region)."""
    from genr8_dist.evolution.island import is_trivial

    return is_trivial(ind, phenotype)


def phenotype_of_config(config: Any) -> Any:
    """The phenotype that ``config``'s universe develops (surfaces, or a plugin's own)."""
    from genr8_dist.grammar import load_universe
    from genr8_dist.phenotype import phenotype_of

    return phenotype_of(load_universe(config.universe))


Run = tuple[list[list[list[Any]]], list[int], int]


def run_islands(config: Any, generations: int) -> Run:
    """Generations 0..``generations`` of every island of ``config``, migrating as a run does:
    ``history[g][i]`` is island i's generation g; ``spent[g]`` the genomes evaluated up to it (every
    founder redraw and re-variation included, cache hits not); then the texts grown in all (a genome
    whose text grew before is evaluated from the grown surface, with no growth)."""
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
    return history, spent, sum(isl.evaluator.growths for isl in islands)


def describe(run: Run, tiles: float, phenotype: Any = None) -> dict[str, Any]:
    """The per-run figures of one run's history (``phenotype``: what trivial means, default surfaces)."""
    history, spent, growths = run
    by_id = {}
    trivial_share, distinct_share, copy_share = [], [], []
    curve = []   # (evaluations so far, best so far)
    evaluations, best = 0, math.inf
    reach = None
    for g, gen in enumerate(history):
        pops = [ind for pop in gen for ind in pop]
        trivial_share.append(sum(trivial(ind, phenotype) for ind in pops) / len(pops))
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
    everyone = [ind for gen in history for pop in gen for ind in pop]
    top = min(everyone, key=lambda ind: ind.fitness)   # the run's best (its vertices are printed)
    last = history[-1]
    bests = []
    for pop in last:
        island_best = min(pop, key=lambda ind: ind.fitness)
        bests.append(island_best.phenotype_digest if island_best.valid else None)
    return {"trivial": trivial_share, "distinct": distinct_share, "copies": copy_share, "curve": curve,
            "evaluations": evaluations, "best": best, "reach": reach,
            "distinct_island_bests": len(set(bests)), "islands": len(last),
            "best_vertices": int(top.sizes.get("vertices", 0)),
            "capped": sum(1 for ind in everyone if ind.capped) / len(everyone), "everyone": everyone,
            "per_stored": evaluations / len(everyone), "grown_per_stored": growths / len(everyone),
            "founder_cost": spent[0] / sum(len(pop) for pop in history[0])}


def random_sample(config: Any, evaluations: int) -> list[Any]:
    """``evaluations`` random genomes, evaluated (one generation 0 of that size, no founder redrawn:
    every evaluation a random genome)."""
    from genr8_dist.evolution import Island

    ea = {"population": max(2, evaluations), "elites": 0, "tournament": 1}
    if "founder_retries" in getattr(config.ea, "__dataclass_fields__", {}):
        ea |= {"founder_retries": 0, "init": "random"}
    one = config.replace(ea=ea, islands={"count": 1, "migrants": 0})
    return Island(one, 0).initial()


def founder_sample(config: Any, evaluations: int, cost: float) -> tuple[list[Any], int]:
    """A generation 0 drawn by the founder machinery (``ea.init``, ``ea.founder_retries``: redraws,
    bushy trees, text screening) on one island, as many founders as ``evaluations`` buy at the run's
    own cost per founder (``cost``: its generation 0's evaluations per founder), and the
    evaluations it spent: what initialisation alone reaches for that budget."""
    from genr8_dist.evolution import Island

    count = max(2, round(evaluations / max(cost, 1.0)))
    one = config.replace(ea={"population": count, "elites": 0, "tournament": 1},
                         islands={"count": 1, "migrants": 0})
    island = Island(one, 0)
    return island.initial(), island.evaluator.evaluations


def mode_of(config: Any) -> str:
    return getattr(getattr(config, "search", None), "mode", "weighted")


def front_volumes(config: Any, evolved: Sequence[Any], sampled: Sequence[Any]) -> tuple[float, float]:
    """The hypervolumes of the evolved run's front and of the random sample's, over the Pareto
    objectives (their weighted deviations), both normalised by the ideal and nadir points of the two
    fronts together, the reference point 1.1 in each objective: the share of the box between the
    best and worst front values that each front dominates (ideal 1.1^k)."""
    import numpy as np

    from genr8_dist.evolution.island import pareto_objectives
    from genr8_dist.evolution.pareto import hypervolume, non_dominated, objectives_of

    names = pareto_objectives(config)

    def front(individuals: Sequence[Any]) -> Any:
        valid = [ind for ind in individuals if ind.valid]
        f = objectives_of([ind.criteria for ind in valid], [True] * len(valid), config.fitness, names)
        f = f[np.isfinite(f).all(axis=1)]
        return f[non_dominated(f)] if len(f) else f.reshape(0, len(names))

    a, b = front(evolved), front(sampled)
    both = np.vstack([a, b])
    ideal, nadir = both.min(axis=0), both.max(axis=0)
    span = np.where(nadir > ideal, nadir - ideal, 1.0)
    ref = np.full(len(names), 1.1)
    return (hypervolume((a - ideal) / span, ref), hypervolume((b - ideal) / span, ref))


def archive_figures(config: Any, individuals: Sequence[Any]) -> tuple[float, float]:
    """(coverage, QD-score) of the MAP-Elites archive that ``individuals`` fill on the configuration's
    grid: the share of cells held, and the sum over held cells of 1 / (1 + the cell's best fitness)
    (fitness is a sum of non-negative deviations, so a perfect surface counts 1 and a cell counts
    more the better its elite: the score grows with coverage and quality, with no offset to choose)."""
    from genr8_dist.evolution.archive import Grid

    grid = Grid.from_settings(config.search)
    held = grid.archive(individuals)
    return len(held) / grid.size, math.fsum(1.0 / (1.0 + ind.fitness) for ind in held.values())


def tiles_score(config: Any) -> float:
    from genr8_dist.evolution.evaluate import evaluate_text
    from genr8_dist.resources import systems_dir

    return evaluate_text((systems_dir() / "four_sided_tiles.hemls").read_text(), config).fitness


def spread(values: Sequence[float], fmt: str = "{:.3f}") -> str:
    values = [v for v in values if v is not None]
    if not values:
        return "-"
    return f"{fmt.format(statistics.median(values))} [{fmt.format(min(values))}, {fmt.format(max(values))}]"


def against_random(measure: str, margins: Sequence[float]) -> None:
    """One line: the evolved run's margin over the random sample on ``measure`` (a share of the
    random sample's figure, positive when evolution is better), per seed and whether it meets the
    target (better in every seed, by at least 20% in the median)."""
    met = all(m > 0 for m in margins) and statistics.median(margins) >= 0.2
    print(f"- margin over random on {measure}: {spread(margins)}; evolved better in "
          f"{sum(m > 0 for m in margins)} of {len(margins)} seeds; per seed "
          f"{', '.join(f'{m:+.3f}' for m in margins)}; {'MEETS' if met else 'MISSES'} the target "
          f"(every seed better, median >= 0.20)")


def founders(universes: Sequence[str], count: int, base: Any) -> None:
    from genr8_dist.evolution import Island

    print(f"\n## founders: trivial share of generation 0 ({count} individuals, seed {base.seed})\n")
    print("| universe | trivial | distinct surfaces | redraws per founder | seconds |")
    print("| --- | --- | --- | --- | --- |")
    for name in universes:
        config = base.replace(universe=name, ea={"population": count, "elites": 0, "tournament": 1},
                              islands={"count": 1, "migrants": 0})
        t0 = time.perf_counter()
        island = Island(config, 0)
        pop = island.initial()
        seconds = time.perf_counter() - t0
        distinct = len({ind.phenotype_digest for ind in pop if ind.valid}) / len(pop)
        redraws = island.stats.founders_redrawn / len(pop)
        share = sum(trivial(ind, island.phenotype) for ind in pop) / len(pop)
        print(f"| {name} | {share:.3f} | {distinct:.3f} | {redraws:.2f} | "
              f"{seconds:.1f} |")


def scaled(config: Any, population: int | None) -> Any:
    """``config`` with ``population`` individuals per island (``None``: as it is), its elites and
    migrants kept below that size: a smaller EA budget on the same fitness, environment, universe and
    genome settings."""
    if population is None:
        return config
    return config.replace(ea={"population": population, "elites": min(config.ea.elites, population - 1)},
                          islands={"migrants": min(config.islands.migrants, population - 1)})


def per_config(path: str, seeds: Sequence[int], generations: int | None,
               population: int | None = None, env: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    from genr8_dist.config import load_config

    base = scaled(load_config(path), population)
    if env:
        base = base.replace(environment=env)
    last = base.ea.generations if generations is None else generations
    tiles = tiles_score(base)
    runs = []
    for seed in seeds:
        config = base.replace(seed=seed)
        t0 = time.perf_counter()
        figures = describe(run_islands(config, last), tiles, phenotype_of_config(config))
        figures["seconds"] = time.perf_counter() - t0
        sample = random_sample(config, figures["evaluations"])
        figures["random"] = min(ind.fitness for ind in sample)
        founded, figures["founder_evaluations"] = founder_sample(config, figures["evaluations"],
                                                                 figures["founder_cost"])
        figures["founders"] = min(ind.fitness for ind in founded)
        mode = mode_of(config)
        if mode == "pareto":
            figures["volumes"] = front_volumes(config, figures["everyone"], sample)
        if mode == "map-elites":
            figures["archive"] = archive_figures(config, figures["everyone"])
            figures["random_archive"] = archive_figures(config, sample)
        del figures["everyone"]
        runs.append(figures)
    mode = mode_of(base)
    print(f"\n## {path} (mode {mode}, {base.islands.count} island(s) x {base.ea.population}, "
          f"{last} generations, {len(seeds)} seeds; four_sided_tiles scores {tiles:.4f}"
          + (f"; environment {env}" if env else "") + ")\n")
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
    print()
    print(f"- evaluations per run: {spread([r['evaluations'] for r in runs], '{:.0f}')}")
    print(f"- evolved best: {spread([r['best'] for r in runs], '{:.4f}')}; its vertices "
          f"{spread([r['best_vertices'] for r in runs], '{:.0f}')}")
    print(f"- random best, same evaluations: {spread([r['random'] for r in runs], '{:.4f}')}")
    against_random("best fitness (lower is better)",
                   [(r["random"] - r["best"]) / abs(r["random"]) if r["random"] else 0.0 for r in runs])
    print(f"- founder-machinery best (one generation 0 of "
          f"{spread([r['founder_evaluations'] for r in runs], '{:.0f}')} evaluations): "
          f"{spread([r['founders'] for r in runs], '{:.4f}')}")
    founder_margins = [(r["founders"] - r["best"]) / abs(r["founders"]) if r["founders"] else 0.0
                       for r in runs]
    met = sum(m > 0 for m in founder_margins) >= math.ceil(0.8 * len(runs)) \
        and statistics.median(founder_margins) >= 0.2
    print(f"- margin over the founder machinery (what evolution adds to initialisation): "
          f"{spread(founder_margins)}; evolved better in {sum(m > 0 for m in founder_margins)} of "
          f"{len(runs)} seeds; per seed {', '.join(f'{m:+.3f}' for m in founder_margins)}; "
          f"{'MEETS' if met else 'MISSES'} the target (4 of 5 seeds better, median >= 0.20)")
    print(f"- evaluations per stored individual: {spread([r['per_stored'] for r in runs])} "
          f"(generation 0: {spread([r['founder_cost'] for r in runs])} per founder); growths per "
          f"stored individual: {spread([r['grown_per_stored'] for r in runs])}")
    if mode == "pareto":
        print(f"- hypervolume of the run's front (normalised, reference 1.1): "
              f"{spread([r['volumes'][0] for r in runs])}; of the random sample's front: "
              f"{spread([r['volumes'][1] for r in runs])}")
        against_random("hypervolume", [(e - r) / r if r > 0 else math.inf for e, r in
                                       (x["volumes"] for x in runs)])
    if mode == "map-elites":
        for i, name in enumerate(("coverage", "QD-score")):
            print(f"- archive {name} of the run: {spread([r['archive'][i] for r in runs])}; of the random "
                  f"sample on the same grid: {spread([r['random_archive'][i] for r in runs])}")
            against_random(f"archive {name}", [(r["archive"][i] - r["random_archive"][i])
                                               / r["random_archive"][i] for r in runs])
    reached = [r["reach"] for r in runs if r["reach"] is not None]
    if math.isfinite(tiles):   # a fitness that can score the tiles (a surface universe's)
        print(f"- evaluations to reach the four_sided_tiles score: reached in {len(reached)} of "
              f"{len(runs)}; {spread(reached, '{:.0f}')}")
    print(f"- trivial share, all generations after 0: "
          f"{spread([statistics.fmean(r['trivial'][1:]) for r in runs if len(r['trivial']) > 1])}")
    print(f"- distinct surfaces, all generations: {spread([min(r['distinct']) for r in runs])} (lowest "
          f"generation), {spread([statistics.fmean(r['distinct']) for r in runs])} (mean)")
    copies = [statistics.fmean(r["copies"]) for r in runs if r["copies"]]
    print(f"- offspring equal to a parent: {spread(copies)}")
    print(f"- individuals a growth cap cut short (max_work {base.environment.max_work}, max_edges "
          f"{base.environment.max_edges}): {spread([r['capped'] for r in runs])}")
    print(f"- seconds per run: {spread([r['seconds'] for r in runs], '{:.1f}')}")
    return runs


def islands_vs_one(path: str, seeds: Sequence[int], count: int, generations: int | None,
                   population: int | None = None) -> None:
    from genr8_dist.config import load_config

    base = scaled(load_config(path), population)
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
        results[name] = [describe(run_islands(config.replace(seed=s), last), tiles,
                                    phenotype_of_config(config)) for s in seeds]
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
    parser.add_argument("--population", type=int, default=None,
                        help="override ea.population (per island; elites and migrants kept below it): "
                             "a scaled-down EA budget on a configuration's own fitness and environment")
    parser.add_argument("--founders", type=int, default=200, help="generation-0 size per universe")
    parser.add_argument("--universes", nargs="*", default=None, help="default: every built-in")
    parser.add_argument("--islands", type=int, default=4, help="islands in the islands comparison")
    parser.add_argument("--skip", nargs="*", default=[], choices=["founders", "configs", "islands"])
    parser.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                        help="an environment field (TOML value) of every configuration (repeatable), "
                             "e.g. --env max_work=5000")
    args = parser.parse_args(argv)
    env = {}
    for item in args.env:
        key, _, value = item.partition("=")
        env[key.strip()] = tomllib.loads(f"v = {value}")["v"]
    from genr8_dist import grammar
    from genr8_dist.config import load_config

    seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    if "founders" not in args.skip:
        names = args.universes or [u.name for u in grammar.list_universes() if u.origin == "built-in"]
        founders(names, args.founders, load_config(args.configs[0]))
    if "configs" not in args.skip:
        for path in args.configs:
            per_config(path, seeds, args.generations, args.population, env)
    if "islands" not in args.skip:
        islands_vs_one(args.configs[0], seeds, args.islands, args.generations, args.population)
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
