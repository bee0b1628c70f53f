"""Parts: Parquet files of rows written by the island hosts themselves, committed by the driver's manifest.

A host writes the generations it computed into the run store (``write_part``) and hands the driver a
small ``Part`` (its path, sha256, rows, bytes and the island's generations in it); the driver's commit
(``RunStore.commit_parts``) is then the manifest alone, so no row passes through the driver. The
atomicity contract is the store's: a part is data of the run only once a manifest names it; a part no
manifest names (its epoch was lost with the driver, or its host died before the commit) is an orphan
that ``RunStore.collect_garbage`` deletes (``genr8 resume`` calls it before any host starts).

Names are unique without coordination (``individuals/part-<island>-<first>-<last>-<token>.parquet``,
the token random), so a host never overwrites anything, and an island recomputed after a failure
writes a new file beside the orphan.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import Individual

if TYPE_CHECKING:
    from genr8_dist.store.runstore import RunStore

__all__ = ["Part", "check_parts", "write_part"]


@dataclass(frozen=True, slots=True)
class Part:
    """A written, not yet committed, part file: what the driver's manifest commit takes."""

    path: str                  # relative to the run directory
    sha256: str
    rows: int
    bytes: int
    island: int
    first: int                 # the island's first and last generation in the file
    last: int

    def entry(self) -> dict[str, Any]:
        """The manifest entry of this part (the commit adds ``commits``)."""
        return {"path": self.path, "rows": self.rows, "bytes": self.bytes, "sha256": self.sha256,
                "islands": {str(self.island): [self.first, self.last]}}


def write_part(store: RunStore, individuals: Sequence[Individual]) -> Part:
    """Write ``individuals`` (consecutive generations of one island) as a new part file of the run in
    ``store`` and return its ``Part``; nothing is committed (``RunStore.commit_parts`` does that)."""
    from genr8_dist.store.schema import individuals_table

    if not individuals:
        raise StoreError("write_part: no individuals to write")
    islands = {ind.island for ind in individuals}
    if len(islands) != 1:
        raise StoreError(f"write_part: a part holds one island's rows, got islands {sorted(islands)}")
    generations = sorted({ind.generation for ind in individuals})
    first, last = generations[0], generations[-1]
    if last - first + 1 != len(generations):
        raise StoreError(f"write_part: generations {generations[:8]} do not follow one another")
    island = islands.pop()
    table = store._checked_rows(individuals_table(individuals, store.run_id, store.criteria, store.schema))
    entry = store._write_parquet(f"individuals/part-{island:06d}-{first:06d}-{last:06d}", table)
    store._pending.remove(entry["path"])   # a host's file: the driver's commit makes it the run's
    return Part(path=entry["path"], sha256=entry["sha256"], rows=int(entry["rows"]),
                bytes=int(entry["bytes"]), island=island, first=first, last=last)


def check_parts(store: RunStore, parts: Sequence[Part], committed: Mapping[int, int]) -> list[dict[str, Any]]:
    """The manifest entries of ``parts``, after checking that each island's parts follow its last
    ``committed`` generation and one another, and that every file is there with its size (its sha256
    is checked by readers and ``verify``, so the driver reads none of it)."""
    entries = []
    expected = dict(committed)
    for part in sorted(parts, key=lambda p: (p.island, p.first)):
        start = expected.get(part.island, -1) + 1
        if part.first != start or part.last < part.first:
            raise StoreError(f"island {part.island}: a part holds generations {part.first}..{part.last}, but "
                             f"the next one to commit is {start}")
        size = store._fs.size(part.path)
        if size != part.bytes:
            raise StoreError(f"{store._fs.show(part.path)}: the part is missing or not the "
                             f"{part.bytes} bytes its host wrote")
        expected[part.island] = part.last
        entries.append(part.entry())
    return entries
