"""Reading a run's committed individuals and events: by generation, as a table, as a dataset."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import Individual
from genr8_dist.store.checks import FileChecks
from genr8_dist.store.manifest import Entry
from genr8_dist.store.schema import events_schema, individuals_from_table, reading_schema, stored_schema

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.dataset as ds

__all__ = ["Reads", "RenamedDataset"]


class RenamedDataset:
    """The individuals files of a run of schema 1 or 2 read as a dataset whose columns carry their
    current names (``SCHEMA_2_NAMES``: ``surface_digest`` is ``phenotype_digest``, ``n_regions`` is
    ``size_regions``...): what ``RunStore.dataset`` gives for such a run. It answers what readers ask
    of a ``pyarrow.dataset.Dataset``: ``schema``, ``to_table``, ``count_rows``, ``get_fragments``; a
    ``filter`` expression names columns as they are stored. ``stored`` is the dataset itself (SQL
    scans it, see ``history.query``), ``renamed`` maps stored names to current ones."""

    def __init__(self, stored: ds.Dataset, renamed: dict[str, str]) -> None:
        self.stored = stored
        self.renamed = dict(renamed)
        self._back = {new: old for old, new in self.renamed.items()}

    @property
    def schema(self) -> pa.Schema:
        return reading_schema(self.stored.schema)

    def to_table(self, columns: Sequence[str] | None = None, filter: pc.Expression | None = None) -> pa.Table:
        """The rows (matching ``filter``), the ``columns`` asked for (current names), as a table."""
        cols = [self._back.get(c, c) for c in columns] if columns is not None else None
        table = self.stored.to_table(columns=cols, filter=filter)
        return table.rename_columns([self.renamed.get(c, c) for c in table.column_names])

    def count_rows(self, filter: pc.Expression | None = None) -> int:
        return int(self.stored.count_rows(filter=filter))

    def get_fragments(self, filter: pc.Expression | None = None) -> Iterator[ds.Fragment]:
        return iter(self.stored.get_fragments(filter=filter))


class Reads(FileChecks):
    """A store's reads; each file is checked against the manifest before it is read."""

    def generation_table(
        self, island: int, generation: int, columns: Sequence[str] | None = None
    ) -> pa.Table:
        """The rows of ``island``'s ``generation``, ordered by index. A generation committed after
        this store's snapshot was loaded (by another process) is found too: the snapshot is refreshed."""
        import pyarrow.compute as pc

        self._require_current()
        key = str(island)
        entries = self._entries_holding(key, generation)
        if not entries and generation > self._m["generations"].get(key, -1) and self._refreshed():
            entries = self._entries_holding(key, generation)
        if not entries:
            done = self._m["generations"].get(key)
            held = f"its last committed generation is {done}" if done is not None else "it has none"
            raise StoreError(
                f"{self._fs.show()}: island {island} generation {generation} is not committed ({held})"
            )
        cols = list(columns) if columns is not None else None
        if cols is not None and "index" not in cols:
            cols.append("index")
        flt = (pc.field("island") == island) & (pc.field("generation") == generation)
        try:
            table = self._read_entries(entries, columns=cols, filter=flt)
        except StoreError:
            if not self._refreshed():  # an old snapshot whose files compaction has since removed
                raise
            return self.generation_table(island, generation, columns)
        table = table.sort_by("index")
        if columns is not None and "index" not in columns:
            table = table.drop_columns(["index"])
        return table

    def _entries_holding(self, island: str, generation: int) -> list[Entry]:
        return [
            e for e in self._m["individuals"]
            if island in e["islands"] and e["islands"][island][0] <= generation <= e["islands"][island][1]
        ]

    def load_generation(self, island: int, generation: int) -> list[Individual]:
        """Every individual of ``island``'s ``generation``, exactly as committed, ordered by index."""
        return individuals_from_table(self.generation_table(island, generation))

    def individuals(
        self, columns: Sequence[str] | None = None, filter: pc.Expression | None = None
    ) -> pa.Table:
        """Every committed individual (in commit order), or only ``columns`` and rows matching ``filter``;
        columns declared since the run was written read as nulls.
        Each file is checked against the manifest's sha256 before it is read (once per store)."""
        self._require_current()
        schema = self.reading_schema
        if columns is not None:
            for name in columns:
                if name not in schema.names:
                    raise StoreError(f"{self._fs.show()}: no column {name!r} in individuals")
        try:
            return self._read_entries(self._m["individuals"], columns=columns, filter=filter)
        except StoreError:
            if not self._refreshed():
                raise
            return self.individuals(columns, filter)

    def dataset(self, generations: tuple[int, int] | None = None) -> ds.Dataset | RenamedDataset:
        """The committed individuals files as one pyarrow dataset (DuckDB can scan it), each file
        checked against the manifest's sha256 first. With ``generations=(lo, hi)`` only the files
        holding a generation in that range (any island) are in it, and only they are checked: a
        reader of a few generations of a long run hashes a few files, not the run. A run of schema 1
        or 2 gives a ``RenamedDataset``: the same, its columns under their current names."""
        import pyarrow.dataset as ds

        self._require_current()
        entries = self._m["individuals"] if generations is None else self._entries_between(*generations)
        try:
            self._verify_files(entries)
        except StoreError:
            if self._refreshed():
                return self.dataset(generations)
            raise
        try:
            data = ds.dataset([self._fs.full(e["path"]) for e in entries],
                              schema=stored_schema(self.schema), format="parquet", filesystem=self._fs.fs)
        except OSError as exc:
            if self._refreshed():
                return self.dataset(generations)
            raise StoreError(f"{self._fs.show()}: cannot read individuals: {exc}") from None
        renamed = self.renamed
        return RenamedDataset(data, renamed) if renamed else data

    def _entries_between(self, lo: int, hi: int) -> list[Entry]:
        """The individuals files holding some island's generation in ``lo..hi``."""
        return [e for e in self._m["individuals"]
                if any(a <= hi and b >= lo for a, b in e["islands"].values())]

    def individual_files(self) -> list[str]:
        """The committed individuals files, as paths inside ``self.filesystem`` (local: absolute paths)."""
        return [self._fs.full(e["path"]) for e in self._m["individuals"]]

    def events(self) -> pa.Table:
        """Every event, in order of ``seq``; each file checked against the manifest's sha256 first."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._require_current()
        tables = []
        for e in self._m["events"]:
            self._verify_files([e])
            try:
                tables.append(pq.read_table(self._fs.full(e["path"]), filesystem=self._fs.fs,
                                            schema=events_schema()))
            except (pa.ArrowException, OSError) as exc:
                raise self._read_error(e, exc) from None
        if not tables:
            return events_schema().empty_table()
        return pa.concat_tables(tables).sort_by("seq")

    def _read_entries(self, entries: list[Entry], *, columns: Sequence[str] | None,
                      filter: pc.Expression | None) -> pa.Table:
        import pyarrow as pa
        import pyarrow.dataset as ds

        self._verify_files(entries)
        renamed = self.renamed
        stored = {new: old for old, new in renamed.items()}
        try:
            dataset = ds.dataset([self._fs.full(e["path"]) for e in entries],
                                 schema=stored_schema(self.schema), format="parquet", filesystem=self._fs.fs)
            table = dataset.to_table(columns=[stored.get(c, c) for c in columns] if columns is not None
                                     else None, filter=filter)
            return table.rename_columns([renamed.get(c, c) for c in table.column_names]) if renamed else table
        except (pa.ArrowException, OSError) as exc:
            for e in entries:
                if self._check_entry(e, deep=False) is not None:
                    raise self._read_error(e, exc) from None
            raise StoreError(f"{self._fs.show()}: cannot read individuals: {exc}") from None
