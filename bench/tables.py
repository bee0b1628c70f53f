"""Hornby & Pollack's comparison (GECCO 2001, section 3): does the generative encoding (the ``tables``
universe: P0L-systems of 20 productions with block replication) evolve fitter tables, sooner, than
the direct one (``tables_direct``: one string of up to 20,000 build commands, no replication, no
productions)?

Both encodings evolve as the paper's did: their own genomes and the paper's operators (the plugins'
``hooks.VARIATION``: random systems or strings, structural mutation and recombination, half and
half), elitism 2, tournaments of 3, the same population, generations and seeds; the only difference
is the encoding. The paper ran 100 individuals for 1,000 generations, 100 trials per encoding
(``--paper``, for a cluster or a lent machine: 100-250 CPU-hours, docs/fidelity.md); the default
fits a small shared machine. Each run prints a line to stderr as it ends.

Reported per encoding, over the seeds (median [quartiles]): the best fitness (height x surface x
stability / excess, maximised) every few generations; generation 0's and the final best, and the
improvement evolution made (final / generation 0, per seed); the final best tables' voxels, the
filled share of their top layer (its voxels / the area of its convex hull: 1 is a solid top, a
lattice of bars is far below), commands run, the paper's compression (commands run / specification
length, counted as the paper counts table 4.d: a production head 1, a condition 2, each command,
call, bracket or block in a successor 1 each per symbol: 45x there) and the repetition of the
command string the turtle ran (its length / its zlib-compressed length); a Mann-Whitney U test on
the final best fitness; and a plain verdict on the paper's claim. ``--json FILE`` writes it all.

    python bench/tables.py                      # 10 seeds, 20 x 60 (about 800 CPU-s: 6-7 minutes on 2 cores)
    python bench/tables.py --seeds 20 --population 50 --generations 100 --workers 4
    python bench/tables.py --paper --workers 64 # 100 trials of 100 x 1,000 per encoding
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import sys
import time
import zlib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ENCODINGS = ("tables", "tables_direct")


def specification_length(text: str) -> int:
    """The paper's specification length (table 4.d, 123 for its table): over the productions the axiom
    reaches, 1 per production head, 2 per condition, and in every successor 1 per command or call and
    2 per bracket or block (its two symbols); a direct string: 1 per command, 2 per bracket pair."""
    from genr8_dist.grammar import load_universe

    hooks = load_universe("tables").hooks
    system = hooks.voxels.parse(text)

    def size(items) -> int:
        n = 0
        for item in items:
            if item[0] == "[":
                n += 2 + size(item[1])
            elif item[0] == "{":
                n += 2 + size(item[2])
            else:
                n += 1
        return n

    if not system.productions:
        return size(system.axiom)
    rules = hooks.variation._Rules(system)
    total = 0
    for name in rules.used():
        production = system.productions[name]
        total += 1 + sum(2 + size(items) for _, _, items in production.pairs)
    return max(1, total)


def regularity(text: str) -> dict:
    """The best table's measures besides its fitness: voxels, the top layer's filled share, commands
    run, the paper's compression (commands / specification length), the command string's repetition
    (its length / its zlib-compressed length)."""
    from genr8_dist.grammar import load_universe

    voxels = load_universe("tables").hooks.voxels
    table = voxels.develop(text)
    word = voxels.derive(voxels.parse(text))[0]
    commands = voxels.command_string(word, calls=False).encode()
    return {"voxels": table.n_voxels, "top_filled": voxels.top_filled_share(table.voxels),
            "commands": table.commands, "specification": specification_length(text),
            "compression": table.commands / specification_length(text),
            "repetition": len(commands) / max(1, len(zlib.compress(commands, 9)))}


def one_run(job: tuple[str, int, int, int]) -> dict:
    """Evolve one seed of one encoding on one island; the best paper fitness of every generation."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.island import Island

    universe, seed, population, generations = job
    config = RunConfig.from_dict({
        "universe": universe, "seed": seed,
        "ea": {"population": population, "generations": generations, "tournament": 3, "elites": 2,
               "crossover_rate": 0.5},
        "islands": {"count": 1, "migrants": 0},
    })
    island = Island(config, 0)
    start = time.process_time()
    now = island.initial()
    best_per_generation = []
    for generation in range(generations + 1):
        if generation:
            now = island.step(now, generation)
        best = min(now, key=lambda ind: ind.fitness)
        best_per_generation.append(-best.fitness if best.valid else 0.0)
    best = min(now, key=lambda ind: ind.fitness)
    return {"universe": universe, "seed": seed, "best": best_per_generation, "text": best.text,
            "cpu_seconds": time.process_time() - start, **regularity(str(best.text))}


def _quartiles(values: list[float]) -> tuple[float, float, float]:
    if len(values) < 2:
        v = values[0] if values else float("nan")
        return v, v, v
    q = statistics.quantiles(values, n=4, method="inclusive")
    return q[0], statistics.median(values), q[2]


def _pictures(by: dict[str, list[dict]], folder: Path, args: argparse.Namespace) -> None:
    """The final best table of each encoding: of its best seed and of its median seed."""
    from genr8_dist.grammar import load_universe

    phenotype = load_universe("tables").hooks.PHENOTYPE
    folder.mkdir(parents=True, exist_ok=True)
    for u, runs in by.items():
        ranked = sorted(runs, key=lambda r: r["best"][-1])
        for label, r in (("median", ranked[len(ranked) // 2]), ("best", ranked[-1])):
            path = folder / f"{u}-{label}.png"
            phenotype.preview(phenotype.develop(r["text"], None), path, config=None,
                              title=f"{u}: seed {r['seed']}'s best after {args.generations} generations")
            print(f"  wrote {path} ({label} seed {r['seed']}, fitness {r['best'][-1]:.4g})")


def summarise(by: dict[str, list[dict]], args: argparse.Namespace) -> dict:
    """The figures the report prints (and ``--json`` writes)."""
    out: dict = {"settings": {k: getattr(args, k) for k in ("seeds", "population", "generations")},
                 "encodings": {}}
    for u, runs in by.items():
        gen0 = [r["best"][0] for r in runs]
        final = [r["best"][-1] for r in runs]
        gains = [f / g0 if g0 > 0 else float("inf") for f, g0 in zip(final, gen0, strict=True)]
        out["encodings"][u] = {
            "generation_0": _quartiles(gen0), "final": _quartiles(final),
            "improvement": _quartiles([g for g in gains if g != float("inf")] or [float("nan")]),
            **{k: _quartiles([float(r[k]) for r in runs]) for k in (
                "voxels", "top_filled", "commands", "specification", "compression", "repetition",
                "cpu_seconds")},
            "runs": runs,
        }
    gen = [r["best"][-1] for r in by["tables"]]
    direct = [r["best"][-1] for r in by["tables_direct"]]
    from scipy.stats import mannwhitneyu

    p = float(mannwhitneyu(gen, direct, alternative="greater").pvalue) if len(gen) > 1 else float("nan")
    threshold = statistics.median(direct)
    reach = {u: [next((g for g, v in enumerate(r["best"]) if v >= threshold), None) for r in by[u]]
             for u in by}
    out["comparison"] = {
        "generation_0_ratio": statistics.median([r["best"][0] for r in by["tables"]]) /
        max(1e-12, statistics.median([r["best"][0] for r in by["tables_direct"]])),
        "final_ratio": statistics.median(gen) / max(1e-12, statistics.median(direct)),
        "mann_whitney_p": p, "wins": sum(g > d for g, d in zip(gen, direct, strict=True)),
        "direct_median_final": threshold,
        "reaches_direct_median": {u: [g for g in reach[u]] for u in reach},
    }
    return out


def _row(name: str, q: tuple[float, float, float], fmt: str = ".4g") -> str:
    return f"{name:>22}  {q[1]:>10{fmt}} [{q[0]:>9{fmt}} .. {q[2]:>9{fmt}}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, help="seeds per encoding (10; --paper: 100)")
    parser.add_argument("--population", type=int, help="individuals (20; --paper: 100)")
    parser.add_argument("--generations", type=int, help="generations (60; --paper: 1,000)")
    parser.add_argument("--paper", action="store_true",
                        help="the paper's size: 100 seeds of 100 individuals for 1,000 generations "
                        "(--seeds, --population or --generations given as well win)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--every", type=int, default=5, help="print every N-th generation")
    parser.add_argument("--json", metavar="FILE", help="write every figure (and each run's) to FILE")
    parser.add_argument("--pictures", metavar="DIR", help="draw each encoding's final best table of "
                        "its best and its median seed into DIR/<universe>-{best,median}.png")
    args = parser.parse_args(argv)
    for key, small, paper in (("seeds", 10, 100), ("population", 20, 100), ("generations", 60, 1000)):
        if getattr(args, key) is None:
            setattr(args, key, paper if args.paper else small)
    if args.paper:
        args.every = max(args.every, 100)

    jobs = [(u, seed, args.population, args.generations)
            for seed in range(1, args.seeds + 1) for u in ENCODINGS]
    start, cpu = time.perf_counter(), time.process_time()
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        results = []
        for done, result in enumerate(pool.imap(one_run, jobs, chunksize=1), 1):
            results.append(result)
            print(f"  run {done}/{len(jobs)}: {result['universe']} seed {result['seed']}: best "
                  f"{result['best'][0]:.4g} at generation 0, {result['best'][-1]:.4g} at the end; "
                  f"{result['voxels']} voxels, top {result['top_filled']:.2f} filled, compression "
                  f"{result['compression']:.3g}; {result['cpu_seconds']:.0f} CPU-s", file=sys.stderr,
                  flush=True)
    wall = time.perf_counter() - start
    by = {u: [r for r in results if r["universe"] == u] for u in ENCODINGS}
    figures = summarise(by, args)
    cpu_total = sum(r["cpu_seconds"] for r in results) + time.process_time() - cpu
    figures["settings"].update(wall_seconds=wall, cpu_seconds=cpu_total, workers=args.workers)

    print(f"Hornby & Pollack's comparison: {args.seeds} seeds per encoding, population {args.population}, "
          f"{args.generations} generations, elitism 2, the paper's operators; {wall:.0f} s wall on "
          f"{args.workers} workers, {cpu_total:.0f} CPU-s")
    print("best fitness (height x surface x stability / excess), median [quartiles] over the seeds")
    print(f"{'gen':>4}  " + "  ".join(f"{u:>36}" for u in ENCODINGS))
    for g in list(range(0, args.generations + 1, args.every)) + (
            [args.generations] if args.generations % args.every else []):
        cells = []
        for u in ENCODINGS:
            lo, mid, hi = _quartiles([r["best"][g] for r in by[u]])
            cells.append(f"{mid:>12.4g} [{lo:>9.4g} .. {hi:>9.4g}]")
        print(f"{g:>4}  " + "  ".join(f"{c:>36}" for c in cells))
    for u in ENCODINGS:
        e = figures["encodings"][u]
        print(f"{u}: final best tables, median [quartiles]")
        for key, label, fmt in (("generation_0", "generation-0 best", ".4g"), ("final", "final best", ".4g"),
                                ("improvement", "final / generation 0", ".3g"),
                                ("voxels", "voxels", ".0f"), ("top_filled", "top layer filled", ".2f"),
                                ("commands", "commands run", ".0f"),
                                ("specification", "specification length", ".0f"),
                                ("compression", "compression", ".3g"),
                                ("repetition", "command repetition", ".3g"),
                                ("cpu_seconds", "CPU-s per run", ".0f")):
            print(_row(label, e[key], fmt))
    c = figures["comparison"]
    print(f"generation-0 median best, generative / direct: {c['generation_0_ratio']:.3g}")
    print(f"final median best, generative / direct: {c['final_ratio']:.3g}; generative ends fitter in "
          f"{c['wins']}/{args.seeds} seeds; Mann-Whitney U (generative > direct): p = "
          f"{c['mann_whitney_p']:.3g}")
    for u in ENCODINGS:
        done = [g for g in c["reaches_direct_median"][u] if g is not None]
        print(f"  {u:<14} reaches the direct encoding's median final best ({c['direct_median_final']:.4g}) "
              f"in {len(done)}/{args.seeds} seeds" +
              (f", median generation {statistics.median(done):g}" if done else ""))
    gen_reach = [g for g in c["reaches_direct_median"]["tables"] if g is not None]
    dir_reach = [g for g in c["reaches_direct_median"]["tables_direct"] if g is not None]
    higher = c["final_ratio"] > 1 and c["mann_whitney_p"] < 0.05
    sooner = bool(gen_reach) and len(gen_reach) >= len(dir_reach) and (
        not dir_reach or statistics.median(gen_reach) <= statistics.median(dir_reach))
    fair = 1 / 3 <= c["generation_0_ratio"] <= 3
    figures["verdict"] = {"higher": higher, "sooner": sooner, "fair_start": fair}
    print("verdict: " + (
        "the paper's claim holds here: from random designs of similar fitness (generation-0 medians "
        "within 3x) the generative encoding evolves fitter tables, sooner" if higher and sooner and fair
        else f"the paper's claim is not shown here (fitter: {'yes' if higher else 'no'}, sooner: "
             f"{'yes' if sooner else 'no'}, similar start: {'yes' if fair else 'no'})"))
    if args.pictures:
        _pictures(by, Path(args.pictures), args)
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1, default=float) + "\n")
        print(f"  wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
