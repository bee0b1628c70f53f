"""Checking committed files against their manifest entries (size, sha256, Parquet rows) before
trusting them: once per file and store, and again when its size or time changes; and rows against
the run's schema before they are written (a commit's, or a part's by any process).
"""

from __future__ import annotations

import hashlib
import os
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.store.manifest import Entry, Manifest, file_entries
from genr8_dist.store.snapshot import Snapshot

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = ["FileChecks"]


class FileChecks(Snapshot):
    """A store's checks of the files its manifest names."""

    def read_file(self, entry: Entry) -> bytes:
        """The bytes of a file a manifest entry names, checked against its size and sha256 first
        (``StoreError`` naming it when they differ)."""
        self._require_current()
        data = self._fs.read_bytes(entry["path"]) if self._fs.size(entry["path"]) is not None else None
        if data is None or hashlib.sha256(data).hexdigest() != entry["sha256"]:
            problem = self._check_entry(entry, deep=True) or f"{self._fs.show(entry['path'])}: changed"
            raise StoreError(f"{problem}; {self._repair_hint()}")
        self._verified[(entry["path"], entry["sha256"])] = self._stamp(entry["path"])
        return data

    def _verify_files(self, entries: list[Entry]) -> None:
        """Check each file against its manifest entry (size, sha256, Parquet rows) the first time
        this store reads it; ``StoreError`` naming the first damaged one."""
        todo = []
        for e in entries:
            key = (e["path"], e["sha256"])
            stamp = self._stamp(e["path"])
            if self._verified.get(key) == stamp and stamp[0] is not None:
                continue  # checked before, and neither its size nor its time has changed since
            todo.append((e, key, stamp))
        if len(todo) > 1:  # hashing releases the GIL: several files at once on several cores
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=min(len(todo), os.cpu_count() or 1, 8)) as pool:
                problems = list(pool.map(lambda t: self._check_entry(t[0], deep=True), todo))
        else:
            problems = [self._check_entry(t[0], deep=True) for t in todo]
        for (_, key, stamp), problem in zip(todo, problems, strict=True):
            if problem is not None:
                raise StoreError(f"{problem}; {self._repair_hint()}")
            self._verified[key] = stamp

    def _stamp(self, rel: str) -> tuple[int | None, float | None]:
        try:
            return self._fs.size(rel), self._fs.mtime(rel)
        except OSError:
            return None, None

    def _read_whole(self, entry: Entry) -> pa.Table:
        import pyarrow as pa
        import pyarrow.parquet as pq

        problem = self._check_entry(entry, deep=True)
        if problem is not None:
            raise StoreError(f"{problem}; {self._repair_hint()}")
        data = self._fs.read_bytes(entry["path"])
        return pq.read_table(pa.BufferReader(data))

    def _read_error(self, entry: Entry, exc: BaseException) -> StoreError:
        problem = self._check_entry(entry, deep=True) or f"{self._fs.show(entry['path'])}: unreadable ({exc})"
        return StoreError(f"{problem}; {self._repair_hint()}")

    def _check_entry(self, entry: Entry, *, deep: bool) -> str | None:
        """What is wrong with a committed file, or None. ``deep`` also checks its sha256."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        rel = entry["path"]
        where = self._fs.show(rel)
        try:
            size = self._fs.size(rel)
        except OSError as exc:
            return f"{where}: cannot be read ({exc})"
        if size is None:
            return f"{where}: missing (the manifest names it)"
        if size != entry["bytes"]:
            return f"{where}: truncated or altered: {size} bytes, the manifest recorded {entry['bytes']}"
        parquet = rel.endswith(".parquet") and "rows" in entry
        if not deep and not parquet:
            return None
        try:
            if deep:
                data = self._fs.read_bytes(rel)
                if hashlib.sha256(data).hexdigest() != entry["sha256"]:
                    return f"{where}: corrupt: its sha256 differs from the one the manifest recorded"
                if not parquet:
                    return None
                meta = pq.ParquetFile(pa.BufferReader(data)).metadata
            else:
                with self._fs.fs.open_input_file(self._fs.full(rel)) as fh:
                    meta = pq.ParquetFile(fh).metadata
        except (pa.ArrowException, OSError) as exc:
            return f"{where}: not a readable Parquet file ({exc})"
        if meta.num_rows != entry["rows"]:
            return f"{where}: holds {meta.num_rows} rows, the manifest recorded {entry['rows']}"
        return None

    def _bad_entries(self, manifest: Manifest, cache: dict[tuple[str, str], str | None]
                     ) -> list[tuple[str, Entry, str]]:
        bad = []
        for kind, e in file_entries(manifest):
            k = (e["path"], e["sha256"])
            if k not in cache:
                cache[k] = self._check_entry(e, deep=True)
            problem = cache[k]
            if problem is not None:
                bad.append((kind, e, problem))
        return bad

    def _checked_rows(self, table: pa.Table) -> pa.Table:
        """``table`` cast to the run's schema, or a ``StoreError`` saying how its rows do not fit (a
        column, a null, another run's id, a negative place, an id not ``island-generation-index``)."""
        import pyarrow as pa
        import pyarrow.compute as pc

        schema = self.schema
        if table.column_names != schema.names:
            missing = [n for n in schema.names if n not in table.column_names]
            extra = [n for n in table.column_names if n not in schema.names]
            what = f"lacks column {missing[0]!r}" if missing else (
                f"has unknown column {extra[0]!r}" if extra else "has its columns in another order")
            raise StoreError(f"{self._fs.show()}: the rows to commit do not fit the schema: the table {what}")
        try:
            table = table.cast(schema)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError, pa.ArrowTypeError) as exc:
            raise StoreError(f"{self._fs.show()}: the rows to commit do not fit the schema: {exc}") from None
        if table.num_rows == 0:
            return table
        for f in schema:
            if not f.nullable and table.column(f.name).null_count:
                raise StoreError(f"column {f.name!r} holds a null; it is required")
        if not pc.all(pc.equal(table.column("run_id"), self.run_id)).as_py():
            raise StoreError(f"the rows to commit belong to another run (run_id is not {self.run_id!r})")
        for name in ("island", "generation", "index"):
            if pc.min(table.column(name)).as_py() < 0:
                raise StoreError(f"column {name!r} holds a negative value")
        strings = [pc.cast(table.column(n), pa.string()) for n in ("island", "generation", "index")]
        expected = pc.binary_join_element_wise(*strings, "-")
        if not pc.all(pc.equal(expected, table.column("id"))).as_py():
            raise StoreError("column 'id' must be \"island-generation-index\" on every row")
        return table
