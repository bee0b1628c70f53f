"""Commits of individuals (rows, or parts written by island hosts) and events, all or nothing."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import Individual
from genr8_dist.store.compaction import COMPACT_TARGET_ROWS
from genr8_dist.store.manifest import Entry, Manifest, last_generations
from genr8_dist.store.schema import Event, individuals_table, island_generations
from genr8_dist.store.transactions import Transactions

if TYPE_CHECKING:
    import pyarrow as pa

    from genr8_dist.store.parts import Part

__all__ = ["AddFiles", "Commits"]
AddFiles = Callable[[Manifest, int], None]
"""``add(manifest, version)``: writes files with ``RunStore.write_file`` and lists their entries in
``manifest`` (a list under a key of its own), as part of commit ``version``."""


def _checked_events(events: Sequence[Event]) -> list[Event]:
    """``events`` as a list; ``StoreError`` if one is not an ``Event`` record."""
    out = list(events)
    for event in out:
        if not isinstance(event, Event):
            raise StoreError(f"events must be Event records, got {type(event).__name__}")
    return out


class Commits(Transactions):
    """A store's commits; each one compacts the run when enough small files have gathered."""

    if TYPE_CHECKING:
        def compact(self, target_rows: int = COMPACT_TARGET_ROWS) -> int: ...   # store/compaction.py
    def commit(self, individuals: Sequence[Individual], events: Sequence[Event] = (),
               *, add: AddFiles | None = None) -> int:
        """Commit ``individuals`` and ``events`` atomically: afterwards all are there, or (after a
        crash) none. Each island's generations in a commit must follow its last committed one.
        ``add(manifest, version)`` may put more files in the same commit (see ``write_file``).
        Returns the commit number (the manifest version)."""
        if not individuals and not events and add is None:
            return self.version
        table = individuals_table(individuals, self.run_id, self.criteria, self.schema)
        return self.commit_table(table, events, add=add)

    def commit_table(self, table: pa.Table, events: Sequence[Event] = (),
                     *, add: AddFiles | None = None) -> int:
        """``commit`` for rows already in an Arrow table of ``self.schema`` (bulk writers)."""
        table = self._checked_rows(table)
        islands = self._island_ranges(table)
        events = _checked_events(events)
        if table.num_rows == 0 and not events and add is None:
            return self.version

        def written(version: int) -> list[Entry]:
            if not table.num_rows:
                return []
            entry = self._write_parquet(f"individuals/part-{version:010d}", table)
            entry["commits"], entry["islands"] = [version, version], islands
            return [entry]

        return self._commit_entries(written, events, add)

    def commit_parts(self, parts: Sequence[Part], events: Sequence[Event] = (),
                     *, add: AddFiles | None = None) -> int:
        """Commit parts written by ``write_part`` (in this process or any other: an island host) with
        ``events``, atomically: one manifest names them all. Each island's generations across the
        parts must follow its last committed one. Returns the commit number."""
        from genr8_dist.store.parts import take_parts

        events = _checked_events(events)
        if not parts and not events and add is None:
            return self.version
        def taken(version: int) -> list[Entry]:
            return take_parts(self, list(parts), version)

        return self._commit_entries(taken, events, add)

    def _commit_entries(self, entries: Callable[[int], list[Entry]], events: list[Event],
                        add: AddFiles | None) -> int:
        """One commit: the individuals files ``entries(version)`` writes or takes in (inside the
        commit's transaction, so a failure removes them), ``events`` and what ``add`` adds, in one
        new manifest; then compaction when enough small files have gathered."""
        with self._transaction():
            version = self._next_version()
            manifest = copy.deepcopy(self._m)
            manifest["individuals"].extend(entries(version))
            self._add_events(manifest, events, version)
            if add is not None:
                add(manifest, version)
            manifest["generations"] = last_generations(manifest["individuals"])
            self._publish(manifest, version)
        if self.compact_every and self._small_files() >= self.compact_every:
            self.compact()
        return version

    def record_event(
        self, kind: str, *, generation: int, island: int | None = None, detail: dict[str, Any] | None = None
    ) -> None:
        """Record one event atomically (its own commit)."""
        self.commit([], [Event(kind, generation, island, dict(detail or {}))])

    def _island_ranges(self, table: pa.Table) -> dict[str, list[int]]:
        if table.num_rows == 0:
            return {}
        spans = island_generations(table, "one commit")
        done = self.committed_generations()
        ranges: dict[str, list[int]] = {}
        for isl, gens in spans:
            start = done.get(isl, -1) + 1
            if gens[0] != start or int(gens[-1]) - int(gens[0]) + 1 != len(gens):
                raise StoreError(
                    f"island {isl}: the commit holds generations {gens.tolist()[:8]}, but the next one "
                    f"to commit is {start} and a commit's generations must follow one another"
                )
            ranges[str(isl)] = [int(gens[0]), int(gens[-1])]
        return ranges

    def _small_files(self) -> int:
        return sum(1 for e in self._m["individuals"] if e["rows"] < COMPACT_TARGET_ROWS)
