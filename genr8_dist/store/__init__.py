"""The run store: a run's configuration versions, individuals and events, committed atomically.

``RunStore.create(path, config_toml)`` starts a run directory, ``RunStore.open(path)`` reads one;
``commit`` adds generations (all or nothing), ``individuals``/``dataset``/``events`` read them back.
See docs/run-store.md for the layout and every column.
"""

from __future__ import annotations

from genr8_dist.store.parts import Part, write_part
from genr8_dist.store.runstore import (
    COMPACT_EVERY,
    COMPACT_TARGET_ROWS,
    KEEP_MANIFESTS,
    ConfigVersion,
    RunStore,
)
from genr8_dist.store.schema import (
    EVENT_KINDS,
    SCHEMA_VERSION,
    TIMING_COLUMNS,
    Event,
    criterion_column,
    events_schema,
    individuals_schema,
)
from genr8_dist.store.synthetic import write_synthetic_run

__all__ = [
    "COMPACT_EVERY",
    "COMPACT_TARGET_ROWS",
    "EVENT_KINDS",
    "KEEP_MANIFESTS",
    "SCHEMA_VERSION",
    "TIMING_COLUMNS",
    "ConfigVersion",
    "Event",
    "Part",
    "RunStore",
    "criterion_column",
    "events_schema",
    "individuals_schema",
    "write_part",
    "write_synthetic_run",
]
