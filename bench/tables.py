"""Hornby & Pollack's comparison (GECCO 2001, section 3), scaled to minutes: does the generative
encoding (the ``tables`` universe: P0L-systems with block replication) reach fitter tables sooner
than the direct one (``tables_direct``: one command string, no replication, no productions)?

Both encodings run the same EA, the one every genr8 island runs (generational, tournament selection,
one-point crossover, int-flip mutation) with the paper's elitism of 2, the same genome length, the
same population and generations, over the same seeds; the only difference is the universe. The
paper ran 100 individuals for 1,000 generations over 100 trials on a 40^3 grid; the defaults here
(30 individuals, 40 generations, 10 seeds) fit a small shared machine.

Prints, per encoding and for every few generations, the median and quartiles of the best fitness
(the paper's height x surface x stability / excess, maximised) over the seeds; the final best
tables' voxel counts and reuse (commands run per token of the text: the paper's "compression
factor"); a Mann-Whitney U test on the final best fitness; and a one-line verdict on the paper's
claim.

    python bench/tables.py                      # 10 seeds, 30 x 40 (about 5 minutes on 2 cores)
    python bench/tables.py --seeds 20 --generations 60 --population 50 --workers 4
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ENCODINGS = ("tables", "tables_direct")


def one_run(job: tuple[str, int, int, int, int]) -> dict:
    """Evolve one seed of one encoding on one island; the best paper fitness of every generation."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.evaluate import universe_for
    from genr8_dist.evolution.island import Island

    universe, seed, population, generations, length = job
    config = RunConfig.from_dict({
        "universe": universe, "seed": seed,
        "genome": {"length": length, "codon_max": 255, "max_depth": 5, "max_wraps": 2},
        "ea": {"population": population, "generations": generations, "tournament": 3, "elites": 2,
               "crossover_rate": 0.9, "mutation_rate": 0.02},
        "islands": {"count": 1, "migrants": 0},
    })
    island = Island(config, 0)
    start = time.perf_counter()
    population_now = island.initial()
    best_per_generation = []
    for generation in range(generations + 1):
        if generation:
            population_now = island.step(population_now, generation)
        best = min(population_now, key=lambda ind: ind.fitness)
        best_per_generation.append(-best.fitness if best.valid else 0.0)
    best = min(population_now, key=lambda ind: ind.fitness)
    phenotype = universe_for(config).hooks.PHENOTYPE
    table = phenotype.develop(best.text, config).value if best.valid else None
    return {"universe": universe, "seed": seed, "best": best_per_generation,
            "voxels": table.n_voxels if table is not None else 0,
            "reuse": table.commands / max(1, len(best.text.split())) if table is not None else 0.0,
            "criteria": dict(best.criteria), "text": best.text, "seconds": time.perf_counter() - start}


def _quartiles(values: list[float]) -> tuple[float, float, float]:
    if len(values) < 2:
        v = values[0] if values else float("nan")
        return v, v, v
    q = statistics.quantiles(values, n=4, method="inclusive")
    return q[0], statistics.median(values), q[2]


def _pictures(by: dict[str, list[dict]], folder: Path, args: argparse.Namespace) -> None:
    """The final best table of each encoding's median seed, drawn by the tables phenotype."""
    from genr8_dist.grammar import load_universe

    phenotype = load_universe("tables").hooks.PHENOTYPE
    folder.mkdir(parents=True, exist_ok=True)
    for u, runs in by.items():
        ranked = sorted(runs, key=lambda r: r["best"][-1])
        r = ranked[len(ranked) // 2]
        path = folder / f"{u}.png"
        phenotype.preview(phenotype.develop(r["text"], None), path, config=None,
                          title=f"{u}: seed {r['seed']}'s best after {args.generations} generations")
        print(f"  wrote {path} (seed {r['seed']}, fitness {r['best'][-1]:.4g})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--population", type=int, default=30)
    parser.add_argument("--generations", type=int, default=40)
    parser.add_argument("--length", type=int, default=300, help="codons per genome (both encodings)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--every", type=int, default=5, help="print every N-th generation")
    parser.add_argument("--pictures", metavar="DIR", help="draw each encoding's final best table of "
                        "the seed with the median final fitness into DIR/<universe>.png")
    args = parser.parse_args(argv)

    jobs = [(u, seed, args.population, args.generations, args.length)
            for seed in range(1, args.seeds + 1) for u in ENCODINGS]
    start = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        results = pool.map(one_run, jobs)
    wall = time.perf_counter() - start
    by = {u: [r for r in results if r["universe"] == u] for u in ENCODINGS}

    print(f"Hornby & Pollack's comparison: {args.seeds} seeds per encoding, population {args.population}, "
          f"{args.generations} generations, elitism 2, genome {args.length} codons; {wall:.0f} s on "
          f"{args.workers} workers")
    print("best fitness (height x surface x stability / excess), median [quartiles] over the seeds")
    print(f"{'gen':>4}  " + "  ".join(f"{u:>36}" for u in ENCODINGS))
    for g in list(range(0, args.generations + 1, args.every)) + (
            [args.generations] if args.generations % args.every else []):
        cells = []
        for u in ENCODINGS:
            lo, mid, hi = _quartiles([r["best"][g] for r in by[u]])
            cells.append(f"{mid:>12.4g} [{lo:>9.4g} .. {hi:>9.4g}]")
        print(f"{g:>4}  " + "  ".join(f"{c:>36}" for c in cells))

    print("final best tables: voxels, reuse (commands run per text token), seconds per run")
    for u in ENCODINGS:
        vox = sorted(r["voxels"] for r in by[u])
        reuse = [r["reuse"] for r in by[u]]
        secs = [r["seconds"] for r in by[u]]
        print(f"  {u:<14} voxels median {statistics.median(vox):.0f} (range {vox[0]}..{vox[-1]}), "
              f"reuse median {statistics.median(reuse):.1f}, {statistics.median(secs):.1f} s/run")

    if args.pictures:
        _pictures(by, Path(args.pictures), args)

    gen_final = [r["best"][-1] for r in by["tables"]]
    dir_final = [r["best"][-1] for r in by["tables_direct"]]
    wins = sum(g > d for g, d in zip(gen_final, dir_final, strict=True))
    print(f"seeds where the generative encoding ends fitter than the direct one: {wins}/{args.seeds}")
    first = {}
    threshold = statistics.median(dir_final)
    for u in ENCODINGS:
        reach = [next((g for g, v in enumerate(r["best"]) if v >= threshold), None) for r in by[u]]
        done = [g for g in reach if g is not None]
        first[u] = (len(done), statistics.median(done) if done else None)
        print(f"  {u:<14} reaches the direct encoding's median final fitness ({threshold:.4g}) in "
              f"{len(done)}/{args.seeds} seeds" + (f", median generation {first[u][1]:g}" if done else ""))
    try:
        from scipy.stats import mannwhitneyu

        p = float(mannwhitneyu(gen_final, dir_final, alternative="greater").pvalue)
        print(f"Mann-Whitney U, generative > direct on the final best fitness: p = {p:.3g}")
    except ImportError:  # scipy is a test extra
        p = float("nan")
    higher = statistics.median(gen_final) > statistics.median(dir_final)
    sooner = first["tables"][0] >= first["tables_direct"][0] and (
        first["tables"][1] is not None and (first["tables_direct"][1] is None
                                            or first["tables"][1] <= first["tables_direct"][1]))
    agree = higher and sooner and (p != p or p < 0.05)
    print("verdict: " + ("our runs agree with the paper: the generative encoding reaches higher fitness, "
                         "sooner" if agree else
                         "our runs do not clearly agree with the paper (higher: "
                         f"{'yes' if higher else 'no'}, sooner: {'yes' if sooner else 'no'}, p = {p:.3g})"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
