"""The explicit Arrow schemas of a run's tables, and the conversion between rows and ``Individual``.

Every Parquet file of a run is written with one of these schemas; the schema version is in each
file's metadata (``genr8.schema_version``) and in the manifest, so a reader knows what it holds.
Criteria are flat ``crit_<name>`` columns (one per criterion, null when not scored) and the
phenotype's sizes flat ``size_<name>`` columns, because flat columns are what SQL and column projection
want. Schemas 1 and 2 named the digest and the sizes after surfaces (``surface_digest``,
``n_vertices``, ``n_edges``, ``n_regions``: ``SCHEMA_2_NAMES``); such a run keeps them, readers see them
under the current names (``current_names``).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import (
    CRITERIA_KIND,
    SCHEMA_2_NAMES,
    SIZES_KIND,
    Column,
    Individual,
    stored_columns,
    timing_columns,
)

if TYPE_CHECKING:
    import numpy as np
    import pyarrow as pa

__all__ = [
    "EVENT_KINDS",
    "SCHEMA_VERSION",
    "TIMING_COLUMNS",
    "Event",
    "criteria_names",
    "criterion_column",
    "current_names",
    "events_schema",
    "events_table",
    "individuals_from_table",
    "individuals_schema",
    "individuals_table",
    "island_generations",
    "listed_columns",
    "run_columns",
    "size_column",
    "size_of",
    "sizes_of",
]

ROW_GROUP_ROWS = 32_768      # Parquet row group size: statistics let readers skip row groups
COMPRESSION = "snappy"       # twice as fast to write as zstd here, files about 12% larger

# Bump when a column is added, removed or changes meaning; readers refuse newer versions and read
# older ones with the columns of their version. 2: the manifest records the run's columns. 3: the
# digest and the sizes are the phenotype's (``phenotype_digest``, ``size_<name>``), not named after
# surfaces; the manifest records the run's sizes.
SCHEMA_VERSION = 3
SIZES_SINCE = 3

# What happened in a run, besides individuals (the ``kind`` column of the events table).
EVENT_KINDS: tuple[str, ...] = (
    "start",         # the run began (generation 0)
    "migration",     # migrants moved between islands after a generation
    "intervention",  # a user edit took effect (a new configuration version)
    "interrupt",     # the run was stopped (Ctrl-C, SIGTERM) after committing what was complete
    "resume",        # the run went on from its last committed generation
    "recovery",      # an island was rebuilt, or a corrupt file was dropped (store.repair)
    "complete",      # the run reached its last generation
    "pause",         # the designer paused a running run between epochs (studio); Ray stays up
    "continue",      # a paused run went on
    "refused",       # a queued intervention could not be recorded when its epoch came (says why)
)

# Measurements: excluded from determinism checks (an interrupted run differs only here).
TIMING_COLUMNS: tuple[str, ...] = timing_columns()

_CRIT = "crit_"
_SIZE = "size_"
_FIELDS = frozenset(Individual.__dataclass_fields__)

# A stored column as the manifest records it: name, Arrow type name, nullable.
ColumnSpec = tuple[str, str, bool]


def criteria_names() -> tuple[str, ...]:
    """The criteria of the built-in phenotype, HEMLS surfaces (imported lazily: the store does not
    need them to read)."""
    from genr8_dist.fitness import criterion_names

    return criterion_names()


def builtin_sizes() -> tuple[str, ...]:
    """The sizes of the built-in phenotype, HEMLS surfaces (what schemas 1 and 2 stored)."""
    from genr8_dist.phenotype import SURFACES

    return tuple(SURFACES.sizes)


def criterion_column(name: str) -> str:
    """The column holding criterion ``name``: ``crit_<name>``."""
    return f"{_CRIT}{name}"


def criterion_of(column: str) -> str | None:
    """The criterion a ``crit_<name>`` column holds, else ``None``."""
    return column[len(_CRIT):] if column.startswith(_CRIT) else None


def size_column(name: str) -> str:
    """The column holding the phenotype's size ``name``: ``size_<name>``."""
    return f"{_SIZE}{name}"


def size_of(column: str) -> str | None:
    """The size a ``size_<name>`` column holds, else ``None``."""
    return column[len(_SIZE):] if column.startswith(_SIZE) else None


def sizes_of(names: Sequence[str]) -> list[str]:
    """The sizes whose ``size_<name>`` columns are among ``names`` (a schema's), in column order."""
    return [s for name in names if (s := size_of(name)) is not None]


def current_names(names: Sequence[str]) -> list[str]:
    """Column ``names`` as readers see them: a schema 1 or 2 run's surface-named columns renamed."""
    return [SCHEMA_2_NAMES.get(name, name) for name in names]


def _check_names(names: tuple[str, ...], what: str) -> None:
    for name in names:
        if not name.isidentifier():
            raise StoreError(f"{what} name {name!r} is not an identifier; it cannot be a column")
    if len(set(names)) != len(names):
        raise StoreError(f"{what} names repeat: {list(names)}")


def run_columns(criteria: Sequence[str], *, sizes: Sequence[str] = (),
                version: int | None = None) -> list[ColumnSpec]:
    """The columns of a run storing ``criteria`` and the phenotype's ``sizes``: every column declared
    now (``version=None``, what a new run records in its manifest), or those a run of schema
    ``version`` has (declared by then; before schema 3 the surface-named ones, whatever ``sizes``)."""
    names, sized = tuple(criteria), tuple(sizes)
    _check_names(names, "criterion")
    _check_names(sized, "size")
    old = version is not None and version < SIZES_SINCE
    renamed = {new: old_name for old_name, new in SCHEMA_2_NAMES.items()}
    out: list[ColumnSpec] = []
    for column in stored_columns():
        if version is not None and not 1 <= column.since <= version:
            continue
        if column.arrow == CRITERIA_KIND:
            out += [(criterion_column(name), "float64", True) for name in names]
        elif column.arrow == SIZES_KIND:
            out += ([(renamed[size_column(s)], "int32", False) for s in builtin_sizes()] if old
                    else [(size_column(s), "int64", False) for s in sized])
        else:
            out.append((renamed.get(column.name, column.name) if old else column.name, column.arrow,
                        column.nullable))
    return out


def listed_columns(criteria: Sequence[str], *, sizes: Sequence[str] = (), shown: bool = False,
                   available: Sequence[str] | None = None) -> list[str]:
    """The columns ``history.top`` returns (``shown``: those ``genr8 top`` prints), in their declared
    places, the criteria's ``crit_<name>`` columns where the ``criteria`` field stands and the
    ``size_<name>`` columns of ``sizes`` where the ``sizes`` field does; only those in ``available``
    when given."""
    def place(column: Column) -> int:
        return column.shown if shown else column.top

    out: list[str] = []
    for column in sorted((c for c in stored_columns() if place(c)), key=place):
        if column.arrow == CRITERIA_KIND:
            out += [criterion_column(name) for name in criteria]
        elif column.arrow == SIZES_KIND:
            out += [size_column(name) for name in sizes]
        else:
            out.append(column.name)
    return out if available is None else [name for name in out if name in set(available)]


def column_heading(name: str) -> str:
    """The short heading of stored column ``name`` in text tables (``generation`` -> ``gen``,
    ``crit_smoothness`` -> ``smooth``)."""
    crit = criterion_of(name)
    if crit is not None:
        from genr8_dist.fitness import criterion_heading

        return criterion_heading(crit)
    return next((c.heading for c in stored_columns() if c.name == name), name)


def _arrow(name: str) -> pa.DataType:
    import pyarrow as pa

    if name.startswith("list<"):
        return pa.list_(_arrow(name[5:-1]))
    return {"bool": pa.bool_(), "int32": pa.int32(), "int64": pa.int64(), "float64": pa.float64(),
            "string": pa.string()}[name]


def _metadata(table: str, version: int = SCHEMA_VERSION) -> dict[bytes, bytes]:
    return {b"genr8.schema_version": str(version).encode(), b"genr8.table": table.encode()}


@lru_cache(maxsize=32)
def _schema_of(columns: tuple[ColumnSpec, ...], version: int) -> pa.Schema:
    import pyarrow as pa

    return pa.schema([pa.field(name, _arrow(kind), nullable=nullable) for name, kind, nullable in columns],
                     metadata=_metadata("individuals", version))


def individuals_schema(criteria: Sequence[str] | None = None,
                       columns: Sequence[Sequence[Any]] | None = None,
                       version: int = SCHEMA_VERSION, *, sizes: Sequence[str] | None = None) -> pa.Schema:
    """The schema of the individuals table: ``columns`` (a run's, as its manifest records them), or
    every declared column with one ``crit_<name>`` column per criterion of ``criteria`` and one
    ``size_<name>`` column per size of ``sizes`` (default: the built-in surface phenotype's);
    ``version`` is the schema version written into its metadata."""
    if columns is None:
        columns = run_columns(tuple(criteria) if criteria is not None else criteria_names(),
                              sizes=tuple(sizes) if sizes is not None else builtin_sizes())
    return _schema_of(tuple((str(n), str(k), bool(b)) for n, k, b in columns), version)


def stored_schema(schema: pa.Schema) -> pa.Schema:
    """``schema`` (a run's, as stored) with every column declared now that it lacks appended as
    nullable: what its files are read with, so a column added since the run was written reads as
    nulls (a column renamed since is not added: it is there under its old name)."""
    import pyarrow as pa

    have = set(current_names(schema.names))
    missing = [pa.field(name, _arrow(kind), nullable=True) for name, kind, _ in run_columns(())
               if name not in have]
    return pa.schema([*schema, *missing], metadata=schema.metadata) if missing else schema


def reading_schema(schema: pa.Schema) -> pa.Schema:
    """What readers see of a run of ``schema``: ``stored_schema(schema)`` with the columns of schemas
    1 and 2 named after surfaces under their current names (``SCHEMA_2_NAMES``)."""
    import pyarrow as pa

    full = stored_schema(schema)
    if not any(name in SCHEMA_2_NAMES for name in full.names):
        return full
    return pa.schema([f.with_name(SCHEMA_2_NAMES.get(f.name, f.name)) for f in full],
                     metadata=full.metadata)


@lru_cache(maxsize=1)
def events_schema() -> pa.Schema:
    """The schema of the events table: one row per thing that happened to the run."""
    import pyarrow as pa

    return pa.schema(
        [
            pa.field("run_id", pa.string(), nullable=False),
            pa.field("seq", pa.int64(), nullable=False),
            pa.field("kind", pa.string(), nullable=False),
            pa.field("generation", pa.int32(), nullable=False),
            pa.field("island", pa.int32()),
            pa.field("detail", pa.string(), nullable=False),
            pa.field("time", pa.timestamp("us", tz="UTC"), nullable=False),
        ],
        metadata=_metadata("events"),
    )


def _is_count(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


@dataclass(frozen=True, slots=True)
class Event:
    """One thing that happened to a run: its ``kind``, the generation, the island (if one) and details.

    ``detail`` must be JSON-serialisable; it is stored as a JSON string with sorted keys.
    """

    kind: str
    generation: int
    island: int | None = None
    detail: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise StoreError(f"event kind {self.kind!r} is not one of {', '.join(EVENT_KINDS)}")
        if not _is_count(self.generation):
            raise StoreError(
                f"event {self.kind!r}: generation must be an integer >= 0, got {self.generation!r}"
            )
        if self.island is not None and not _is_count(self.island):
            raise StoreError(
                f"event {self.kind!r}: island must be None or an integer >= 0, got {self.island!r}"
            )
        if not isinstance(self.detail, dict):
            raise StoreError(f"event {self.kind!r}: detail must be a dict, got {type(self.detail).__name__}")

    def detail_json(self) -> str:
        """``detail`` as canonical JSON (sorted keys); raises ``StoreError`` if it cannot be."""
        try:
            return json.dumps(self.detail, sort_keys=True, allow_nan=True, separators=(",", ":"))
        except (TypeError, ValueError) as exc:
            raise StoreError(f"event {self.kind!r}: detail is not JSON-serialisable: {exc}") from None


def individuals_table(individuals: Iterable[Individual], run_id: str, criteria: Sequence[str],
                      schema: pa.Schema | None = None) -> pa.Table:
    """The rows of ``individuals`` as a table of ``schema`` (default ``individuals_schema(criteria)``)."""
    import pyarrow as pa

    schema = schema if schema is not None else individuals_schema(criteria)
    crit_set = set(criteria)
    declared = {c.name: c for c in stored_columns()}
    stored = set(schema.names)
    cols: dict[str, list[object]] = {f.name: [] for f in schema}
    def getter(name: str) -> Callable[[Individual], object]:
        name = SCHEMA_2_NAMES.get(name, name)   # a schema 1 or 2 run's columns, by their current names
        crit = criterion_of(name)
        size = size_of(name)
        if name == "run_id":
            return lambda ind: run_id
        if name == "id":
            return lambda ind: ind.id
        if crit is not None:
            return lambda ind: ind.criteria.get(crit)
        if size is not None:
            return lambda ind: ind.sizes.get(size, 0)
        if name in _FIELDS:
            return lambda ind: getattr(ind, name)
        default = declared[name].default if name in declared else None
        return lambda ind: ind.extra.get(name, default)

    getters = [(cols[f.name], getter(f.name)) for f in schema]
    for ind in individuals:
        if not isinstance(ind, Individual):
            raise StoreError(f"the store keeps Individual records, got {type(ind).__name__}")
        unknown = set(ind.criteria) - crit_set
        if unknown:
            raise StoreError(
                f"individual {ind.id}: unknown criterion {sorted(unknown)[0]!r} "
                f"(this run stores {', '.join(criteria)})"
            )
        strange = [k for k in ind.extra if k not in stored and k not in declared]
        if strange:
            raise StoreError(f"individual {ind.id}: {strange[0]!r} is not a declared column")
        for col, get in getters:
            col.append(get(ind))
    arrays = []
    for f in schema:
        try:
            arrays.append(pa.array(cols[f.name], type=f.type))
        except (pa.ArrowInvalid, pa.ArrowTypeError, OverflowError) as exc:
            raise StoreError(f"column {f.name!r}: a value does not fit {f.type}: {exc}") from None
    return pa.Table.from_arrays(arrays, schema=schema)


def individuals_from_table(table: pa.Table) -> list[Individual]:
    """``Individual`` records from rows of the individuals table (the inverse of ``individuals_table``;
    a schema 1 or 2 run's surface-named columns are read under their current names); columns that are
    not ``Individual`` fields, criteria or sizes go to ``extra`` (nulls left out)."""
    names = current_names(table.column_names)
    py = {name: table.column(i).to_pylist() for i, name in enumerate(names)}
    criteria = [(name, c) for name in names if (c := criterion_of(name)) is not None]
    sized = [(name, s) for name in names if (s := size_of(name)) is not None]
    plain = [n for n in names if n in _FIELDS]
    sequences = [n for n in plain if n in ("genome", "parents")]
    extras = [n for n in names if n not in _FIELDS and n not in ("run_id", "id")
              and criterion_of(n) is None and size_of(n) is None]
    out = []
    for i in range(table.num_rows):
        kwargs = {name: py[name][i] for name in plain}
        for name in sequences:
            kwargs[name] = tuple(kwargs[name])
        kwargs["criteria"] = {c: v for name, c in criteria if (v := py[name][i]) is not None}
        kwargs["sizes"] = {s: v for name, s in sized if (v := py[name][i]) is not None}
        kwargs["extra"] = {n: v for n in extras if (v := py[n][i]) is not None}
        out.append(Individual(**kwargs))
    return out


def events_table(events: Sequence[Event], run_id: str, first_seq: int, time_us: int) -> pa.Table:
    """The rows of ``events`` as a table of ``events_schema()``, numbered from ``first_seq``."""
    import pyarrow as pa

    schema = events_schema()
    n = len(events)
    return pa.Table.from_arrays(
        [
            pa.array([run_id] * n, pa.string()),
            pa.array(range(first_seq, first_seq + n), pa.int64()),
            pa.array([e.kind for e in events], pa.string()),
            pa.array([e.generation for e in events], pa.int32()),
            pa.array([e.island for e in events], pa.int32()),
            pa.array([e.detail_json() for e in events], pa.string()),
            pa.array([time_us] * n, pa.timestamp("us", tz="UTC")),
        ],
        schema=schema,
    )


def island_generations(table: pa.Table, where: str) -> list[tuple[int, np.ndarray]]:
    """Each island of ``table`` with its distinct generations, ascending; ``StoreError`` naming
    ``where`` ("one part", "one commit") if an individual's id appears twice."""
    import numpy as np

    island = table.column("island").to_numpy()
    gen = table.column("generation").to_numpy()
    index = table.column("index").to_numpy()
    order = np.lexsort((index, gen, island))
    si, sg, sx = island[order], gen[order], index[order]
    dup = (si[1:] == si[:-1]) & (sg[1:] == sg[:-1]) & (sx[1:] == sx[:-1])
    if dup.any():
        k = int(np.argmax(dup))
        raise StoreError(f"individual {si[k]}-{sg[k]}-{sx[k]} appears twice in {where}")
    return [(int(isl), np.unique(sg[si == isl])) for isl in np.unique(si)]
