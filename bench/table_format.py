"""Commit latency of the run store against Delta Lake (the `deltalake` package), and what a plain
Parquet reader sees in each: the measurement behind docs/run-store.md's choice of table format.

    OMP_NUM_THREADS=1 nice -n 5 python bench/table_format.py [--commits 8] [--out /tmp/x]

For 1,000 and 100,000 rows a commit (one epoch of synthetic individuals and its migration event), it
commits ``--commits`` epochs to a new run store and to a new Delta table pair (individuals and events:
Delta commits one table at a time), and prints each one's median CPU time (``process_time``) and wall
time per commit. Then it compacts both and counts the rows a glob of ``individuals/*.parquet`` (the
store) or of the table's Parquet files (Delta) returns, against the rows each table holds.
Without `deltalake` installed only the store is measured.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import tempfile
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from genr8_dist.store import RunStore
from genr8_dist.store.schema import Event, events_table
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch

SHAPES = {1_000: (10, 1, 100), 100_000: (10, 10, 1_000)}   # rows: (islands, generations, population)
CONFIG = 'universe = "default"\nseed = 1\n'


def _timed(fn) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def _epochs(store: RunStore, rows: int, commits: int) -> list[pa.Table]:
    islands, gens, pop = SHAPES[rows]
    texts = _text_pool(1)
    return [synthetic_epoch(store, 1, k, k * gens, (k + 1) * gens - 1, islands, pop, (16, 128), texts)
            for k in range(commits)]


def bench_store(root: Path, rows: int, commits: int) -> dict[str, float]:
    store = RunStore.create(root / f"store-{rows}", CONFIG, compact_every=None)
    tables = _epochs(store, rows, commits)
    cpu, wall = [], []
    for k, table in enumerate(tables):
        ev = [Event("migration", int(table.column("generation")[-1].as_py()), None, {"epoch": k})]
        c, w = _timed(lambda t=table, e=ev: store.commit_table(t, e))
        cpu.append(c)
        wall.append(w)
    store.compact(target_rows=10 * rows)
    globbed = sum(pq.read_metadata(f).num_rows
                  for f in glob.glob(os.path.join(store.path, "individuals", "*.parquet")))
    return {"cpu": statistics.median(cpu), "wall": statistics.median(wall),
            "rows": store.individuals(columns=["id"]).num_rows, "glob": globbed}


def bench_delta(root: Path, rows: int, commits: int, store_for_schema: RunStore) -> dict[str, float]:
    from deltalake import DeltaTable, write_deltalake

    ind, evs = root / f"delta-{rows}" / "individuals", root / f"delta-{rows}" / "events"
    tables = _epochs(store_for_schema, rows, commits)
    cpu, wall = [], []
    for k, table in enumerate(tables):
        gen = int(table.column("generation")[-1].as_py())
        events = events_table([Event("migration", gen, None, {"epoch": k})], "r", k, 0)

        def commit(t: pa.Table = table, e: pa.Table = events) -> None:
            write_deltalake(str(ind), t, mode="append")   # two tables: two commits, not one
            write_deltalake(str(evs), e, mode="append")

        c, w = _timed(commit)
        cpu.append(c)
        wall.append(w)
    dt = DeltaTable(str(ind))
    dt.optimize.compact()
    held = dt.to_pyarrow_dataset().count_rows()
    globbed = sum(pq.read_metadata(f).num_rows for f in glob.glob(str(ind / "*.parquet")))
    return {"cpu": statistics.median(cpu), "wall": statistics.median(wall), "rows": held, "glob": globbed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--commits", type=int, default=8)
    ap.add_argument("--out", default=None, help="folder for the tables (default: a temporary one)")
    args = ap.parse_args()
    try:
        import deltalake
        have_delta = f"deltalake {deltalake.__version__}"
    except ImportError:
        have_delta = ""
    with tempfile.TemporaryDirectory(dir=args.out) as tmp:
        root = Path(tmp)
        print(f"{'rows/commit':>11}  {'format':<16} {'cpu s':>7} {'wall s':>7}  rows held  glob sees")
        for rows in SHAPES:
            s = bench_store(root, rows, args.commits)
            print(f"{rows:>11}  {'run store':<16} {s['cpu']:7.3f} {s['wall']:7.3f}  "
                  f"{s['rows']:>9}  {s['glob']:>9}")
            if have_delta:
                d = bench_delta(root, rows, args.commits, RunStore.open(root / f"store-{rows}"))
                print(f"{rows:>11}  {have_delta:<16} {d['cpu']:7.3f} {d['wall']:7.3f}  "
                      f"{d['rows']:>9}  {d['glob']:>9}")
            else:
                print(f"{rows:>11}  {'deltalake':<16} not installed (pip install deltalake to compare)")


if __name__ == "__main__":
    main()
