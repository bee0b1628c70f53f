"""Parts: individuals files written by any process that reaches the run directory, committed by its writer.

``write_part(store, table)`` checks the rows against the run's schema and writes them as one Parquet
file in ``_staging/`` (where no table reader looks, and which no writer's garbage collection touches
while it is fresh), returning a small ``Part`` descriptor: its name, digest, rows, bytes and the
generations of each island it holds. An island host calls it for its own generations and sends the
descriptor to the coordinator, whose ``RunStore.commit_parts(parts, events)`` takes the files into
``_files/individuals/`` and names them in the next manifest, atomically with the epoch's events. A
part no commit takes (its host crashed, or the commit lost a race) is removed by the writer's garbage
collection once it is an hour old.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import secrets
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.store.views import FILES, LAYOUT, STAGING

if TYPE_CHECKING:
    import pyarrow as pa

    from genr8_dist.store._fs import RunFS
    from genr8_dist.store.checks import FileChecks
    from genr8_dist.store.manifest import Entry
    from genr8_dist.store.transactions import Transactions

__all__ = ["Part", "write_part"]


@dataclass(frozen=True, slots=True)
class Part:
    """An individuals file written by ``write_part`` and not yet committed: what a commit takes."""

    name: str                       # the file's name (``part-<stem>-<token>.parquet``)
    sha256: str
    rows: int
    bytes: int
    islands: dict[str, list[int]] = field(default_factory=dict)   # island -> [first, last] generation

    @property
    def staged(self) -> str:
        """Where the part lies until it is committed, relative to the run directory."""
        return f"{STAGING}/{self.name}"


def write_part(store: FileChecks, table: pa.Table, *, stem: str = "part") -> Part:
    """Write ``table`` (rows of the run's schema: one or more islands' consecutive generations, each id
    once) as a part of the run (an open store: ``RunStore.open(path)`` in another process) and return its
    descriptor for ``RunStore.commit_parts``. Safe from any process: the name holds a random token,
    and nothing is committed until the run's writer commits it."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from genr8_dist.store.schema import COMPRESSION, ROW_GROUP_ROWS

    if not stem.replace("-", "").replace("_", "").isalnum():
        raise StoreError(f"write_part: stem {stem!r} must be letters, digits, '-' or '_'")
    table = store._checked_rows(table)
    if table.num_rows == 0:
        raise StoreError("write_part: the part holds no rows")
    islands = island_spans(table)
    buf = pa.BufferOutputStream()
    pq.write_table(table, buf, compression=COMPRESSION, row_group_size=ROW_GROUP_ROWS)
    data = buf.getvalue()
    name = f"{stem}-{secrets.token_hex(8)}.parquet"
    rfs = store._fs
    rfs.makedirs(STAGING)
    rfs.write_new(f"{STAGING}/{name}", memoryview(data))
    return Part(name, hashlib.sha256(memoryview(data)).hexdigest(), table.num_rows, data.size, islands)


def island_spans(table: pa.Table) -> dict[str, list[int]]:
    """Each island's first and last generation in ``table``; ``StoreError`` if an id appears twice or an
    island's generations do not follow one another."""
    from genr8_dist.store.schema import island_generations

    spans: dict[str, list[int]] = {}
    for isl, gens in island_generations(table, "one part"):
        if int(gens[-1]) - int(gens[0]) + 1 != len(gens):
            raise StoreError(f"island {isl}: the part's generations {gens.tolist()[:8]} do not follow "
                             "one another")
        spans[str(isl)] = [int(gens[0]), int(gens[-1])]
    return spans


def take_parts(store: Transactions, parts: list[Part], version: int) -> list[Entry]:
    """Check ``parts`` (staged, whole, disjoint, each island following its last committed generation),
    move them into the run's data folder as files of commit ``version`` and return their manifest
    entries. Called inside the commit's transaction: the moved files are the commit's own, removed
    again if it fails."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    rfs = store._fs
    done = store.committed_generations()
    spans: dict[str, list[list[int]]] = {}
    for part in parts:
        if not isinstance(part, Part):
            raise StoreError(f"commit_parts: expected Part descriptors, got {type(part).__name__}")
        where = rfs.show(part.staged)
        size = rfs.size(part.staged)
        if size is None:
            raise StoreError(f"{where}: the part is missing (written by write_part? already committed?)")
        if size != part.bytes:
            raise StoreError(f"{where}: {size} bytes, its descriptor says {part.bytes}")
        with rfs.fs.open_input_file(rfs.full(part.staged)) as fh:
            rows = pq.ParquetFile(fh).metadata.num_rows
        if rows != part.rows:
            raise StoreError(f"{where}: holds {rows} rows, its descriptor says {part.rows}")
        for island, span in part.islands.items():
            spans.setdefault(island, []).append(list(span))
    for island, got in spans.items():
        got.sort()
        expect = done.get(int(island), -1) + 1
        for lo, hi in got:
            if lo != expect:
                raise StoreError(
                    f"island {island}: the parts hold generations from {got[0][0]} to {got[-1][1]} "
                    f"({len(got)} part(s)), but the next one to commit is {done.get(int(island), -1) + 1} "
                    "and a commit's generations must follow one another"
                )
            expect = hi + 1
    folder = f"{FILES}/individuals" if store.manifest_layout == LAYOUT else "individuals"
    entries: list[Entry] = []
    for part in parts:
        rel = f"{folder}/{part.name}"
        store._pending.append(rel)
        try:
            if rfs.local_root is not None:
                os.rename(rfs._local(part.staged), rfs._local(rel))
            else:
                rfs.fs.move(rfs.full(part.staged), rfs.full(rel))
        except (OSError, pa.ArrowException) as exc:
            raise StoreError(f"{rfs.show(part.staged)}: cannot take the part into the run ({exc})") from None
        entries.append({"path": rel, "rows": part.rows, "bytes": part.bytes, "sha256": part.sha256,
                        "commits": [version, version],
                        "islands": dict(sorted(part.islands.items(), key=lambda kv: int(kv[0])))})
    return entries


def clear_stale_parts(rfs: RunFS, stale_after: float) -> int:
    """Delete the run's staged parts older than ``stale_after`` seconds (no commit took them); how many."""
    import time

    deleted = 0
    for name in rfs.listdir(STAGING):
        mtime = rfs.mtime(f"{STAGING}/{name}")
        if mtime is not None and time.time() - mtime > stale_after:
            with contextlib.suppress(OSError):
                rfs.delete(f"{STAGING}/{name}")
                deleted += 1
    return deleted
