"""How fast the run history answers on a large run: 1,000,000 synthetic individuals.

Writes the synthetic history once with the store's own writer (cached in the temp folder; pass
``--fresh`` to rewrite it), then times what a user types, as separate ``genr8`` processes (start-up
included), and the same questions through the Python API in one process:

- ``genr8 top RUN -k 10``
- ``genr8 history RUN`` (every generation and island)
- ``genr8 query RUN "<group-by over generations>"``
- ``genr8 lineage RUN ID`` (not a target; for reference)

Target (issue 6): top, history and the group-by query each under 2 s.

    python bench/history.py [--islands 8 --generations 250 --pop 500] [--repeat 3] [--fresh]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

GROUP_BY = ("select generation, count(*) as n, min(fitness) as best, median(fitness) as median "
            "from individuals where valid group by generation order by generation")


def _cached_run(islands: int, generations: int, pop: int, fresh: bool) -> Path:
    from genr8_dist.store import RunStore, write_synthetic_run

    path = Path(tempfile.gettempdir()) / f"genr8-history-bench-{islands}x{generations}x{pop}"
    if path.exists() and not fresh:
        try:
            store = RunStore.open(path)
            if store.dataset().count_rows() == islands * generations * pop:
                return path
        except Exception as exc:  # a broken cache is rewritten
            print(f"cached run unusable ({exc}); rewriting it")
    shutil.rmtree(path, ignore_errors=True)
    start = time.perf_counter()
    write_synthetic_run(path, islands, generations, pop, seed=1, generations_per_commit=25)
    print(f"wrote {islands * generations * pop:,} synthetic individuals to {path} "
          f"in {time.perf_counter() - start:.1f} s")
    return path


def _best_of(repeat: int, fn) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _cli(args: list[str]) -> None:
    exe = shutil.which("genr8") or str(Path(sys.executable).with_name("genr8"))
    subprocess.run([exe, *args], check=True, stdout=subprocess.DEVNULL)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--islands", type=int, default=8)
    parser.add_argument("--generations", type=int, default=250)
    parser.add_argument("--pop", type=int, default=500)
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs (default 3)")
    parser.add_argument("--fresh", action="store_true", help="rewrite the cached synthetic run")
    args = parser.parse_args()

    from genr8_dist import history

    run = _cached_run(args.islands, args.generations, args.pop, args.fresh)
    last = args.generations - 1
    some = f"{args.islands // 2}-{last}-{args.pop // 3}"
    n = args.islands * args.generations * args.pop
    print(f"run: {run} ({n:,} individuals; {args.islands} islands x {args.generations} generations "
          f"x {args.pop})")
    rows = [
        ("top -k 10", ["top", str(run), "-k", "10"], lambda: history.top(run, 10)),
        ("history", ["history", str(run)], lambda: history.per_generation(run)),
        ("query group-by", ["query", str(run), GROUP_BY], lambda: history.query(run, GROUP_BY)),
        ("top --criterion size", ["top", str(run), "--criterion", "size"],
         lambda: history.top(run, 10, criterion="size")),
        ("lineage (reference)", ["lineage", str(run), some], lambda: history.lineage(run, some)),
    ]
    print(f"{'command':<24}{'genr8 process (s)':>20}{'python API (s)':>17}   target")
    for label, argv, fn in rows:
        cli_s = _best_of(args.repeat, lambda argv=argv: _cli(argv))
        api_s = _best_of(args.repeat, fn)
        target = "< 2 s" if "reference" not in label and "criterion" not in label else ""
        verdict = ("ok" if cli_s < 2.0 else "SLOW") if target else ""
        print(f"{label:<24}{cli_s:>20.3f}{api_s:>17.3f}   {target} {verdict}".rstrip())
    return 0


if __name__ == "__main__":
    sys.exit(main())
