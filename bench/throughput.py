"""Evaluations per core-second, the tail of the cost of one individual, and how soon a run starts.

    python bench/throughput.py                         # everything (about 10 minutes on 2 cores)
    python bench/throughput.py --only islands          # the island configurations only
    python bench/throughput.py --only islands --steady # the same, each timed in a warmed-up process
    python bench/throughput.py --only genomes --genomes 300
    python bench/throughput.py --only genomes --genomes 300 --max-work 15000 8000 5000 3000   # caps
    python bench/throughput.py --only genomes --env max_work=0 --universe default   # no work cap
    python bench/throughput.py --only startup

Three parts, each a table:

- islands: one island (plain Python, no Ray) of bench/island.py's default configuration (default
  universe, 50 individuals, generations 0..3, seed 1, 4 and 5 derivation steps) and of the run
  configurations of bench/islands.py and bench/search.py (examples/quick.toml, examples/subdivide.toml);
  individuals per core-second (per second of this process's CPU time, so a shared machine's load
  changes it less) and per wall second, evaluations (genomes mapped, the discarded redraws and
  re-variations included) per core-second, and the median surface (vertices) of the individuals.
- genomes: ``--genomes`` random genomes of every universe (100 codons, default mapping, the default
  environment at ``--steps`` derivation steps), each mapped, parsed, grown and (unless a cap cut its
  growth short) scored on its own (no cache): the median, 99th percentile and maximum CPU seconds per
  individual, how many growth caps cut short, individuals per core-second, and the 99th percentile and
  maximum of the two parts of that cost: map + parse + grow, and scoring (the criteria, with the
  triangulation ``slivers`` measures), so a tail says where it comes from; in a process's steady state
  (the compiled kernels loaded before timing: ``GENR8_COMPILED=1`` unless set). ``--max-work N [N ...]``
  measures the table once per work cap and ends with p99/median and the share of genomes capped per
  universe and cap: what choosing the default ``max_work`` weighs.
- startup: ``genr8 run examples/quick.toml`` in a subprocess: seconds to its first line, to the first
  generation's progress line (``gen 0/...``) and to its end; and ``ray.init`` of a local Ray alone
  (what Ray itself needs: subtract it to get the time that is this program's own).

It uses only APIs that every version of genr8_dist has had, so the same command measures an older
checkout (``PYTHONPATH=/path/to/checkout python bench/throughput.py``): compare before and after in one
sitting, on a shared machine, and read the ratios. Numpy runs single-threaded here (one core per
process, as on an island host). ``--env KEY=VALUE`` (a TOML value, repeatable) sets an environment
field of the islands' and the genomes' configurations.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    k = min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))
    return ordered[k]


# -- islands ------------------------------------------------------------------------------------------

def _island_configs(steps: list[int], env: dict[str, object]) -> list[tuple[str, object]]:
    from genr8_dist.config import RunConfig, load_config

    out: list[tuple[str, object]] = []
    for s in steps:   # bench/island.py's default: default universe, 50 x generations 0..3, seed 1
        out.append((f"island.py {s} steps", RunConfig(universe="default", seed=1,
                                                      ea={"population": 50, "generations": 3},
                                                      environment={"steps": s, **env})))
    out.append(("islands.py RunConfig()", RunConfig(ea={"generations": 3}, environment=dict(env))))
    for name in ("quick", "subdivide"):   # bench/search.py's configurations
        try:
            config = load_config(ROOT / "examples" / f"{name}.toml")
            if env:
                config = config.replace(environment=env)
            out.append((f"examples/{name}.toml", config))
        except Exception as exc:   # an older checkout that does not know a key of today's file
            print(f"examples/{name}.toml: not measured, this checkout cannot load it "
                  f"({str(exc).splitlines()[0][-80:]})")
    return out


def _vertices(ind) -> int:
    """An individual's vertex count, under any checkout's name for it."""
    sizes = getattr(ind, "sizes", None)
    if isinstance(sizes, dict):
        return int(sizes.get("vertices", 0))
    return int(getattr(ind, "n_vertices", 0) or 0)


def islands(steps: list[int], env: dict[str, object], steady: bool = False) -> None:
    import dataclasses

    from genr8_dist.evolution import Island

    print("\nislands: one island, generations 0..3, no Ray" + (f"; environment {env}" if env else "")
          + ("; steady state: each timed after the same configuration ran untimed with seed + 1"
             if steady else ""))
    print(f"{'configuration':<26} {'indiv':>6} {'evals':>6} {'cpu s':>7} {'wall s':>7} {'ind/core-s':>11} "
          f"{'eval/core-s':>12} {'ind/wall-s':>11} {'valid':>6} {'capped':>6} {'med V':>6}")
    for name, config in _island_configs(steps, env):
        if steady:   # as in a long-lived island host: imports, tables and compiled kernels loaded
            Island(dataclasses.replace(config, seed=config.seed + 1), 0).run(3)
        island = Island(config, 0)
        c0, w0 = time.process_time(), time.perf_counter()
        history = island.run(3)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        everyone = [ind for pop in history for ind in pop]
        valid = sum(ind.valid for ind in everyone)
        capped = sum(1 for ind in everyone if ind.capped)
        evaluator = getattr(island, "evaluator", None)
        evals = int(getattr(evaluator, "evaluations", 0))   # genomes mapped, discarded draws included
        median_v = statistics.median(_vertices(ind) for ind in everyone if ind.valid) if valid else 0
        print(f"{name:<26} {len(everyone):>6} {evals:>6} {cpu:>7.2f} {wall:>7.2f} "
              f"{len(everyone) / cpu:>11.1f} {evals / cpu:>12.1f} {len(everyone) / wall:>11.1f} "
              f"{valid / len(everyone):>6.0%} {capped:>6} {median_v:>6.0f}")
        sys.stdout.flush()
    print("indiv: individuals kept (generations 0..3); evals: genomes mapped for them, founders redrawn "
          "and offspring varied again included; med V: the median vertices of the valid ones")


# -- random genomes ----------------------------------------------------------------------------------

def _one(universe, genome, config) -> tuple[float, float, str | None, bool]:
    """CPU seconds to map, parse, grow and score ``genome`` and of those to score it (the criteria,
    the triangulation ``slivers`` asks for included); the cap that cut growth short; valid."""
    from genr8_dist.fitness import score_surface
    from genr8_dist.hemls import grow, parse

    t0 = time.thread_time()
    mapped = universe.map(list(genome), max_depth=config.genome.max_depth,
                          max_wraps=config.genome.max_wraps)
    capped, valid, scoring = None, False, 0.0
    if mapped.valid:
        try:
            result = grow(parse(mapped.text), config.environment)
            capped = result.capped
            if not capped:   # a capped individual is invalid and, since round 4, never measured
                t1 = time.thread_time()
                score_surface(result.surface, config.environment)
                scoring = time.thread_time() - t1
                valid = True
        except Exception:  # failure is data, as in evaluation
            pass
    return time.thread_time() - t0, scoring, capped, valid


def _grows_surfaces(name: str) -> bool:
    """Whether universe ``name`` writes HEMLS rewrite systems (a plugin may bring its own phenotype)."""
    try:
        from genr8_dist.phenotype import SURFACES, phenotype_of
    except ImportError:   # a checkout from before phenotypes: every universe grows surfaces
        return True
    from genr8_dist.grammar import load_universe

    return phenotype_of(load_universe(name)) is SURFACES


def genomes(n: int, steps: int, universes: list[str] | None,
            env: dict[str, object]) -> dict[str, tuple[float, float]]:
    """The table of ``n`` random genomes per universe under ``env``; per universe, p99/median and the
    share of genomes that a growth cap cut short. Measured in a process's steady state: the compiled
    growth and triangulation kernels (the ``fast`` extra) in use from the first genome, loaded before
    timing (``GENR8_COMPILED=1`` unless set; a run's process switches to them after its first few
    hundred thousand edge-steps, and loading them is start-up, not one individual's cost)."""
    before = os.environ.get("GENR8_COMPILED")
    os.environ["GENR8_COMPILED"] = before if before is not None else "1"
    try:
        return _genomes(n, steps, universes, env)
    finally:
        if before is None:
            os.environ.pop("GENR8_COMPILED", None)


def _genomes(n: int, steps: int, universes: list[str] | None,
             env: dict[str, object]) -> dict[str, tuple[float, float]]:
    from genr8_dist.config import RunConfig
    from genr8_dist.environment import Environment
    from genr8_dist.evolution.operators import random_genome
    from genr8_dist.fitness import score_surface
    from genr8_dist.grammar import list_universes, load_universe
    from genr8_dist.hemls import grow, load_system
    from genr8_dist.rng import stream

    names = universes or [u.name for u in list_universes() if _grows_surfaces(u.name)]
    summary: dict[str, tuple[float, float]] = {}
    warm = grow(load_system("four_sided_tiles"), Environment(), steps=3)   # loads the kernels
    score_surface(warm.surface, Environment())
    print(f"\ngenomes: {n} random genomes per universe (100 codons), {steps} derivation steps, each "
          "evaluated on its own; CPU seconds per individual" + (f"; environment {env}" if env else ""))
    print(f"{'universe':<14} {'n':>5} {'valid':>6} {'capped':>6} {'median s':>9} {'p99 s':>8} "
          f"{'max s':>8} {'p99/med':>8} {'ind/core-s':>11} {'grow p99':>9} {'grow max':>9} "
          f"{'score p99':>9} {'score max':>9}")
    for name in names:
        config = RunConfig(universe=name, environment={"steps": steps, **env})
        universe = load_universe(name)
        rng = stream(0, "bench", "throughput", name)
        costs, growing, scoring, caps, valid = [], [], [], 0, 0
        _one(universe, random_genome(rng, 100, 255), config)   # warm imports and compiled tables
        for _ in range(n):
            seconds, scored, capped, ok = _one(universe, random_genome(rng, 100, 255), config)
            costs.append(seconds)
            growing.append(seconds - scored)
            scoring.append(scored)
            caps += bool(capped)
            valid += ok
        med, p99 = statistics.median(costs), _percentile(costs, 0.99)
        print(f"{name:<14} {n:>5} {valid / n:>6.0%} {caps:>6} {med:>9.4f} {p99:>8.3f} {max(costs):>8.3f} "
              f"{p99 / med if med > 0 else float('inf'):>8.1f} {n / sum(costs):>11.1f} "
              f"{_percentile(growing, 0.99):>9.3f} {max(growing):>9.3f} "
              f"{_percentile(scoring, 0.99):>9.3f} {max(scoring):>9.3f}")
        sys.stdout.flush()
        summary[name] = (p99 / med if med > 0 else float("inf"), caps / n)
    return summary


def cap_summary(by_cap: dict[int, dict[str, tuple[float, float]]]) -> None:
    """p99/median per universe (rows) and work cap (columns), and the share of genomes each cap cut."""
    caps = list(by_cap)
    names = list(dict.fromkeys(name for table in by_cap.values() for name in table))
    print("\nwork caps: p99/median per individual (share of random genomes capped)")
    print(f"{'universe':<18}" + "".join(f"{f'max_work {c}':>22}" for c in caps))
    for name in names:
        cells = (by_cap[c].get(name) for c in caps)
        print(f"{name:<18}" + "".join(f"{f'{cell[0]:.1f} ({cell[1]:.1%})' if cell else '-':>22}"
                                      for cell in cells))


# -- start-up -----------------------------------------------------------------------------------------

def _timed_lines(cmd: list[str], env: dict[str, str], cwd: Path) -> tuple[dict[str, float], int]:
    start = time.perf_counter()
    marks: dict[str, float] = {}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            cwd=cwd)
    assert proc.stdout is not None
    for line in proc.stdout:
        now = time.perf_counter() - start
        marks.setdefault("first line", now)
        if line.startswith("gen "):
            marks.setdefault("first gen line", now)
    rc = proc.wait()
    marks["exit"] = time.perf_counter() - start
    return marks, rc


def startup(repeat: int) -> None:
    import genr8_dist

    env = dict(os.environ)   # the subprocesses import the genr8_dist this process imported
    here = str(Path(genr8_dist.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (here, env.get("PYTHONPATH", "")) if p)
    print("\nstartup: genr8 run examples/quick.toml (local Ray of 2 CPUs); ray.init alone")
    print(f"{'what':<30} {'first line s':>12} {'gen 0 line s':>12} {'exit s':>8}")
    probe = ("import time; t = time.perf_counter(); import ray; "
             "ray.init(address='local', num_cpus=2, include_dashboard=False, log_to_driver=False); "
             "t1 = time.perf_counter(); print(f'{t1 - t:.3f}'); ray.shutdown()")
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env)
        total = time.perf_counter() - t0
        inside = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else "?"
        print(f"{'import ray + ray.init':<30} {inside:>12} {'':>12} {total:>8.2f}")
        with tempfile.TemporaryDirectory() as tmp:
            marks, rc = _timed_lines([sys.executable, "-m", "genr8_dist.cli", "run",
                                      str(ROOT / "examples" / "quick.toml"), "--run-dir",
                                      str(Path(tmp) / "run"), "--cpus", "2"], env, ROOT)
        what = "genr8 run quick.toml" + ("" if rc == 0 else f" (exit {rc})")
        print(f"{what:<30} {marks.get('first line', float('nan')):>12.2f} "
              f"{marks.get('first gen line', float('nan')):>12.2f} {marks['exit']:>8.2f}")
        sys.stdout.flush()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", choices=["islands", "genomes", "startup"], action="append",
                        help="run only this part (repeatable)")
    parser.add_argument("--steps", type=int, default=4, help="derivation steps of the random genomes")
    parser.add_argument("--island-steps", type=int, nargs="+", default=[4, 5])
    parser.add_argument("--steady", action="store_true",
                        help="islands: time each configuration in a process that has just run it with "
                             "seed + 1 (the steady state of an island host)")
    parser.add_argument("--genomes", type=int, default=1000, help="random genomes per universe")
    parser.add_argument("--universe", action="append", help="only this universe (repeatable)")
    parser.add_argument("--repeat", type=int, default=2, help="start-up measurements")
    parser.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                        help="an environment field (TOML value) of the islands and genomes (repeatable)")
    parser.add_argument("--max-work", type=int, nargs="+", metavar="N",
                        help="the genomes table once per work cap, then p99/median per universe and cap")
    args = parser.parse_args(argv)
    env: dict[str, object] = {}
    for item in args.env:
        key, _, value = item.partition("=")
        env[key.strip()] = tomllib.loads(f"v = {value}")["v"]
    parts = args.only or ["islands", "genomes", "startup"]
    import genr8_dist

    print(f"genr8_dist from {Path(genr8_dist.__file__).parent.parent}")
    if "islands" in parts:
        islands(args.island_steps, env, args.steady)
    if "genomes" in parts:
        if args.max_work:
            cap_summary({cap: genomes(args.genomes, args.steps, args.universe, {**env, "max_work": cap})
                         for cap in args.max_work})
        else:
            genomes(args.genomes, args.steps, args.universe, env)
    if "startup" in parts:
        startup(args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
