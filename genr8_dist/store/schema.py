"""The explicit Arrow schemas of a run's tables, and the conversion between rows and ``Individual``.

Every Parquet file of a run is written with one of these schemas; the schema version is in each
file's metadata (``genr8.schema_version``) and in the manifest, so a reader knows what it holds.
Criteria are flat ``crit_<name>`` columns (one per criterion, null when not scored) because flat
columns are what SQL and column projection want.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import Individual

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = [
    "EVENT_KINDS",
    "SCHEMA_VERSION",
    "TIMING_COLUMNS",
    "Event",
    "criteria_names",
    "criterion_column",
    "events_schema",
    "events_table",
    "individuals_from_table",
    "individuals_schema",
    "individuals_table",
]

# Bump when a column is added, removed or changes meaning; readers refuse newer versions.
SCHEMA_VERSION = 1

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
TIMING_COLUMNS: tuple[str, ...] = ("eval_seconds", "map_seconds", "grow_seconds", "score_seconds")

_INT_FIELDS = ("codons_used", "wraps", "n_vertices", "n_edges", "n_regions", "steps_done")
# Individual fields stored unchanged in a column of the same name (genome, parents and criteria are
# converted; run_id and id are the run's and derived).
_PLAIN_FIELDS = tuple(f.name for f in fields(Individual) if f.name not in ("genome", "parents", "criteria"))


def criteria_names() -> tuple[str, ...]:
    """The criteria of the fitness module (imported lazily: the store does not need it to read)."""
    from genr8_dist.fitness import CRITERIA

    return tuple(CRITERIA)


def criterion_column(name: str) -> str:
    """The column holding criterion ``name``: ``crit_<name>``."""
    return f"crit_{name}"


def _metadata(table: str) -> dict[bytes, bytes]:
    return {b"genr8.schema_version": str(SCHEMA_VERSION).encode(), b"genr8.table": table.encode()}


@lru_cache(maxsize=8)
def _individuals_schema(criteria: tuple[str, ...]) -> pa.Schema:
    import pyarrow as pa

    fields = [
        pa.field("run_id", pa.string(), nullable=False),
        pa.field("id", pa.string(), nullable=False),
        pa.field("island", pa.int32(), nullable=False),
        pa.field("generation", pa.int32(), nullable=False),
        pa.field("index", pa.int32(), nullable=False),
        pa.field("genome", pa.list_(pa.int32()), nullable=False),
        pa.field("text", pa.string()),
        pa.field("valid", pa.bool_(), nullable=False),
        pa.field("stage", pa.string()),
        pa.field("error", pa.string()),
        pa.field("fitness", pa.float64(), nullable=False),
    ]
    fields += [pa.field(criterion_column(name), pa.float64()) for name in criteria]
    fields += [
        pa.field("origin", pa.string(), nullable=False),
        pa.field("parents", pa.list_(pa.string()), nullable=False),
        pa.field("config_version", pa.int32(), nullable=False),
    ]
    fields += [pa.field(name, pa.int32(), nullable=False) for name in _INT_FIELDS]
    fields += [
        pa.field("capped", pa.string()),
        pa.field("surface_digest", pa.string()),
    ]
    fields += [pa.field(name, pa.float64(), nullable=False) for name in TIMING_COLUMNS]
    return pa.schema(fields, metadata=_metadata("individuals"))


def individuals_schema(criteria: Sequence[str] | None = None) -> pa.Schema:
    """The schema of the individuals table, one ``crit_<name>`` column per criterion.

    ``criteria`` defaults to ``genr8_dist.fitness.CRITERIA``; a run keeps the list it was created
    with in its manifest, so old runs stay readable if criteria are added later.
    """
    names = tuple(criteria) if criteria is not None else criteria_names()
    for name in names:
        if not name.isidentifier():
            raise StoreError(f"criterion name {name!r} is not an identifier; it cannot be a column")
    if len(set(names)) != len(names):
        raise StoreError(f"criterion names repeat: {list(names)}")
    return _individuals_schema(names)


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


def individuals_table(individuals: Iterable[Individual], run_id: str, criteria: Sequence[str]) -> pa.Table:
    """The rows of ``individuals`` as a table of ``individuals_schema(criteria)``."""
    import pyarrow as pa

    schema = individuals_schema(criteria)
    crit_set = set(criteria)
    cols: dict[str, list[Any]] = {f.name: [] for f in schema}
    crit_cols = [(name, cols[criterion_column(name)]) for name in criteria]
    for ind in individuals:
        if not isinstance(ind, Individual):
            raise StoreError(f"the store keeps Individual records, got {type(ind).__name__}")
        unknown = set(ind.criteria) - crit_set
        if unknown:
            raise StoreError(
                f"individual {ind.id}: unknown criterion {sorted(unknown)[0]!r} "
                f"(this run stores {', '.join(criteria)})"
            )
        cols["run_id"].append(run_id)
        cols["id"].append(ind.id)
        cols["genome"].append(ind.genome)
        cols["parents"].append(ind.parents)
        for name, col in crit_cols:
            col.append(ind.criteria.get(name))
        for name in _PLAIN_FIELDS:
            cols[name].append(getattr(ind, name))
    arrays = []
    for f in schema:
        try:
            arrays.append(pa.array(cols[f.name], type=f.type))
        except (pa.ArrowInvalid, pa.ArrowTypeError, OverflowError) as exc:
            raise StoreError(f"column {f.name!r}: a value does not fit {f.type}: {exc}") from None
    return pa.Table.from_arrays(arrays, schema=schema)


def individuals_from_table(table: pa.Table) -> list[Individual]:
    """``Individual`` records from rows of the individuals table (the inverse of ``individuals_table``)."""
    names = table.column_names
    criteria = [n[len("crit_"):] for n in names if n.startswith("crit_")]
    py = {name: table.column(name).to_pylist() for name in names}
    out = []
    for i in range(table.num_rows):
        crit = {}
        for name in criteria:
            value = py[criterion_column(name)][i]
            if value is not None:
                crit[name] = value
        out.append(
            Individual(
                genome=tuple(py["genome"][i]),
                parents=tuple(py["parents"][i]),
                criteria=crit,
                **{name: py[name][i] for name in _PLAIN_FIELDS},
            )
        )
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
