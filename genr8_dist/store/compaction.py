"""Compaction: runs of small committed files merged into files of about ``COMPACT_TARGET_ROWS`` rows,
in one atomic commit; rows and their order unchanged.
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.store import views
from genr8_dist.store.manifest import Entry, first_commit
from genr8_dist.store.transactions import Transactions

__all__ = ["COMPACT_EVERY", "COMPACT_TARGET_ROWS", "Compaction"]
COMPACT_TARGET_ROWS = 100_000  # compact() merges small files into files of about this many rows
COMPACT_EVERY = 32           # commit() compacts when this many small individuals files have built up


class Compaction(Transactions):
    """A store's ``compact``."""

    if TYPE_CHECKING:
        def collect_garbage(self) -> int: ...   # store/garbage.py
    def compact(self, target_rows: int = COMPACT_TARGET_ROWS) -> int:
        """Merge runs of small committed files into files of about ``target_rows`` rows, in one
        atomic commit (readers see the old files or the merged ones, never both or neither). Rows and
        their order are unchanged. Returns how many fewer files the run has."""
        import pyarrow as pa

        if target_rows < 1:
            raise StoreError(f"target_rows must be >= 1, got {target_rows}")
        manifest = copy.deepcopy(self._m)
        before = len(manifest["individuals"]) + len(manifest["events"])
        version = None
        with self._transaction():
            for key in views.TABLES:
                prefix = f"{key}/compact"
                merged: list[Entry] = []
                for group in _plan_compaction(manifest[key], target_rows):
                    if len(group) == 1:
                        merged.append(group[0])
                        continue
                    if version is None:
                        version = self._next_version()
                    tables = [self._read_whole(e) for e in group]
                    if key == "individuals":  # files written before a resume may order columns otherwise
                        schema = self.schema
                        tables = [t.select(schema.names).cast(schema) for t in tables]
                    table = pa.concat_tables(tables)
                    first, last = first_commit(group[0]), group[-1]["commits"][1]
                    entry = self._write_parquet(f"{prefix}-{first:010d}-{last:010d}", table)
                    entry["commits"] = [first, last]
                    if key == "individuals":
                        islands: dict[str, list[int]] = {}
                        for e in group:
                            for island, (lo, hi) in e["islands"].items():
                                have = islands.get(island)
                                islands[island] = [min(have[0], lo), max(have[1], hi)] if have else [lo, hi]
                        entry["islands"] = dict(sorted(islands.items(), key=lambda kv: int(kv[0])))
                    else:
                        entry["seq"] = [group[0]["seq"][0], group[-1]["seq"][1]]
                    merged.append(entry)
                manifest[key] = merged
            if version is None:
                return 0
            self._publish(manifest, version)
        self.collect_garbage()
        return before - len(manifest["individuals"]) - len(manifest["events"])


def _plan_compaction(entries: list[Entry], target_rows: int) -> list[list[Entry]]:
    """Groups of consecutive entries, each a file to keep (one entry) or to merge (several)."""
    groups: list[list[Entry]] = []
    run: list[Entry] = []
    rows = 0
    for e in entries:
        if e["rows"] >= target_rows:
            if run:
                groups.append(run)
            groups.append([e])
            run, rows = [], 0
            continue
        run.append(e)
        rows += e["rows"]
        if rows >= target_rows:
            groups.append(run)
            run, rows = [], 0
    if run:
        groups.append(run)
    return groups
