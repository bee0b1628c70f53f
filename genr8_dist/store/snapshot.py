"""What one ``RunStore`` holds: the manifest it reads (its snapshot of the run), the run's
filesystem, its caches, and what the manifest says the run is (identity, columns, schema, layout).
Every other part of the store (``checks``, ``transactions``, ``commits``, ``reads``, ``configs``,
``repair``, ``compaction``, ``garbage``) is a class built on this one; ``RunStore`` joins them.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import TYPE_CHECKING, Self

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import SCHEMA_2_NAMES
from genr8_dist.store._fs import RunFS
from genr8_dist.store.manifest import MANIFEST_DIR, Manifest, load_state
from genr8_dist.store.schema import individuals_schema, reading_schema, run_columns, sizes_of

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.fs as pafs

    from genr8_dist.config import RunConfig
    from genr8_dist.store.pending import RunLock

__all__ = ["Snapshot"]


class Snapshot:
    """A run's committed state as one store reads it; reads use this snapshot, ``refresh()`` loads the
    newest."""

    def __init__(self, rfs: RunFS, manifest: Manifest, *, compact_every: int | None,
                 stale: str | None = None) -> None:
        self._fs = rfs
        self._m = manifest
        self.compact_every = compact_every
        self._config_cache: dict[int, str] = {}
        self._parsed: dict[tuple[int, str], RunConfig] = {}
        # files this store checked against their sha256: (path, sha256) -> (size, mtime) seen then
        self._verified: dict[tuple[str, str], tuple[int | None, float | None]] = {}
        self._pending: list[str] = []                  # files written by the commit being made
        self._stale = stale                            # the newest manifest is lost or damaged
        self.last_repair = ""                          # what the last repair() dropped, in one line
        self.set_aside: list[tuple[str, str]] = []     # users' files moved by collect_garbage (foreign.py)
        self.writer_lock: RunLock | None = None        # checked before each manifest (a lease on S3)

    def refresh(self) -> Self:
        """Load the newest committed state (another process may have committed since open)."""
        manifest, stale = load_state(self._fs)
        if manifest is None:
            raise StoreError(f"{self._fs.show()}: no intact manifest left in {MANIFEST_DIR}/")
        self._m, self._stale = manifest, stale
        return self

    @property
    def run_id(self) -> str:
        return str(self._m["run_id"])

    @property
    def path(self) -> str:
        """The run directory: an absolute local path, or the URI it was opened with."""
        return self._fs.local_root or self._fs.display

    @property
    def filesystem(self) -> pafs.FileSystem:
        return self._fs.fs

    @property
    def criteria(self) -> tuple[str, ...]:
        """The criteria this run stores (its ``crit_<name>`` columns), fixed when it was created."""
        return tuple(self._m["criteria"])

    @property
    def sizes(self) -> tuple[str, ...]:
        """The phenotype's sizes this run stores (its ``size_<name>`` columns; a run of schema 1 or 2:
        a surface's vertices, edges and regions, stored as ``n_<name>``), fixed when it was created."""
        if "sizes" in self._m:
            return tuple(self._m["sizes"])
        return tuple(sizes_of(self.reading_schema.names))

    @property
    def meshing(self) -> int:
        """The meshing version (``hemls.meshing``) this run was created with: what its configurations
        use unless they name one. 1 for a run created before meshing was recorded (it keeps cutting
        its surfaces, and measuring its ``slivers``, as it did)."""
        return int(self._m.get("meshing", 1))

    @property
    def screen(self) -> int:
        """The screen before growth (``ea.screen``) this run was created with: what its
        configurations use unless they name one. 1 for a run created before it was recorded (its
        islands breed, and a resumed run goes on, as they did)."""
        return int(self._m.get("screen", 1))

    @property
    def schema_version(self) -> int:
        """The store schema version this run was created with (it keeps it for good)."""
        return int(self._m["schema_version"])

    @property
    def schema(self) -> pa.Schema:
        """The individuals table's schema for this run: the columns its manifest records, or (a run of
        schema version 1) the columns of that version."""
        columns: Sequence[Sequence[str | bool]] | None = self._m.get("columns")
        if columns is None:
            columns = run_columns(self.criteria, version=self.schema_version)
        return individuals_schema(columns=columns, version=self.schema_version)

    @property
    def reading_schema(self) -> pa.Schema:
        """What readers see: this run's schema, every column declared since as nulls, and a schema 1
        or 2 run's surface-named columns under their current names (``SCHEMA_2_NAMES``)."""
        return reading_schema(self.schema)

    @property
    def renamed(self) -> dict[str, str]:
        """The columns this run stores under another name than readers see (a run of schema 1 or 2):
        ``{stored name: current name}``; empty for a run of the current schema."""
        return {old: new for old, new in SCHEMA_2_NAMES.items() if old in self.schema.names}

    @property
    def version(self) -> int:
        """The number of the manifest this store reads (one per commit)."""
        return int(self._m["version"])

    @property
    def manifest_layout(self) -> int:
        """The run directory's layout: 2, data files in ``_files/`` and glob views (docs/run-store.md);
        1, a run written before (its data files where its tables' readers glob: ``repair --upgrade``)."""
        return int(self._m.get("layout", 1))

    def __repr__(self) -> str:
        return f"RunStore({self.path!r}, run_id={self.run_id!r}, version={self.version})"

    @property
    def manifest(self) -> Manifest:
        """A copy of the manifest this store reads (the committed state)."""
        return copy.deepcopy(self._m)

    def committed_generations(self) -> dict[int, int]:
        """Each island's last committed generation."""
        return {int(k): int(v) for k, v in self._m["generations"].items()}

    def _refreshed(self) -> bool:
        """Load the newest manifest if there is a newer one than this store's; whether there was."""
        newest, stale = load_state(self._fs)
        if newest is None or newest["version"] <= self.version:
            return False
        self._m, self._stale = newest, stale
        return True

    def _require_current(self) -> None:
        if self._stale:
            raise StoreError(f"{self._stale}; {self._repair_hint()}")

    def _repair_hint(self) -> str:
        return (f"`genr8 repair {self._fs.show()}` mends the run (it keeps every intact commit and names "
                "what it drops)")
