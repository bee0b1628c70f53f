"""The run store: a run directory of configuration versions, individuals and events, committed atomically.

Layout of a run directory (see docs/run-store.md)::

    _manifest/0000000001.json   numbered manifests; the highest intact one is the run's state
    configs/v0001.toml          configuration versions, in force from a recorded generation
    individuals/part-<commit>.parquet          one Parquet file per commit (an epoch)
    individuals/compact-<first>-<last>.parquet many commits merged by compact()
    events/events-<commit>.parquet, events/compact-<first>-<last>.parquet

A commit writes its data files (temporary name, fsync, rename), then publishes manifest ``N+1``, a
complete snapshot naming every committed file with its row count, size and sha256. Readers read only
files a manifest names, so a crash at any moment leaves the whole commit or none of it; files no
manifest names are garbage and are ignored (and removed by ``compact``, ``repair`` and
``collect_garbage``). The last ``KEEP_MANIFESTS`` manifests are kept so that a reader holding an older
snapshot can still read it, and so that ``repair`` can fall back to an older intact state.

One writer per run: the process that runs the evolution (the coordinator) or an edit. Any number of
readers (history queries, DuckDB) may read at the same time.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import ConfigError, StoreError
from genr8_dist.evolution.individual import Individual
from genr8_dist.store._fs import TMP_PREFIX, RunFS, resolve
from genr8_dist.store.pending import Queued, RunLock, dequeue, enqueue, lock_holder, queued
from genr8_dist.store.schema import (
    SCHEMA_VERSION,
    Event,
    events_schema,
    events_table,
    individuals_from_table,
    individuals_schema,
    individuals_table,
    reading_schema,
    run_columns,
)

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.dataset as ds
    import pyarrow.fs as pafs

    from genr8_dist.config import RunConfig
    from genr8_dist.fitness import FitnessSpec

__all__ = [
    "COMPACT_EVERY",
    "COMPACT_TARGET_ROWS",
    "KEEP_MANIFESTS",
    "ConfigVersion",
    "RunStore",
]

FORMAT = "genr8-run"
MANIFEST_DIR = "_manifest"
KEEP_MANIFESTS = 16          # manifests kept for concurrent readers and for repair()
COMPACT_TARGET_ROWS = 100_000  # compact() merges small files into files of about this many rows
COMPACT_EVERY = 32           # commit() compacts when this many small individuals files have built up
ROW_GROUP_ROWS = 32_768      # Parquet row group size: statistics let readers skip row groups
COMPRESSION = "snappy"       # twice as fast to write as zstd here, files about 12% larger
_MANIFEST_NAME = re.compile(r"^(\d{10})\.json$")
_RUN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")
_LAYOUT = {MANIFEST_DIR, "configs", "individuals", "events"}


@dataclass(frozen=True, slots=True)
class ConfigVersion:
    """One configuration of a run, in force from ``effective_generation`` until the next version's."""

    version: int
    effective_generation: int
    toml: str
    created: datetime


def _now() -> datetime:
    return datetime.now(UTC)


def _check_toml(text: str, what: str) -> None:
    if not isinstance(text, str):
        raise ConfigError(f"{what}: a configuration is TOML text, got {type(text).__name__}")
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{what}: not valid TOML: {exc}") from None


def _body_digest(body: dict[str, Any]) -> str:
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _encode_manifest(m: dict[str, Any]) -> bytes:
    body = {k: v for k, v in m.items() if k != "checksum"}
    out = dict(body, checksum=_body_digest(body))
    return (json.dumps(out, sort_keys=True, indent=1) + "\n").encode()


def _decode_manifest(data: bytes) -> dict[str, Any] | None:
    """The manifest in ``data``, or None when it is torn, altered or not a run manifest."""
    try:
        m = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        return None
    body = {k: v for k, v in m.items() if k != "checksum"}
    if m.get("checksum") != _body_digest(body):
        return None
    return m


def _manifest_rel(version: int) -> str:
    return f"{MANIFEST_DIR}/{version:010d}.json"


def _generations(entries: list[dict[str, Any]]) -> dict[str, int]:
    last: dict[str, int] = {}
    for e in entries:
        for island, (_, gmax) in e["islands"].items():
            last[island] = max(last.get(island, -1), gmax)
    return dict(sorted(last.items(), key=lambda kv: int(kv[0])))


class RunStore:
    """One run directory: its configuration versions, its individuals and its events.

    Build with ``RunStore.create`` (a new run) or ``RunStore.open`` (an existing one). Reads use the
    snapshot loaded at open or last commit; ``refresh()`` loads the newest.
    """

    def __init__(self, rfs: RunFS, manifest: dict[str, Any], *, compact_every: int | None) -> None:
        self._fs = rfs
        self._m = manifest
        self.compact_every = compact_every
        self._config_cache: dict[int, str] = {}
        self._parsed: dict[tuple[int, str], RunConfig] = {}

    # --- building ----------------------------------------------------------------------------
    @classmethod
    def create(
        cls,
        path_or_uri: str | os.PathLike[str],
        config_toml: str,
        *,
        run_id: str | None = None,
        criteria: Sequence[str] | None = None,
        filesystem: pafs.FileSystem | None = None,
        compact_every: int | None = COMPACT_EVERY,
    ) -> RunStore:
        """A new run at ``path_or_uri`` whose configuration version 1 is ``config_toml`` (generation 0).

        Refuses a directory that is already a run, or that holds anything else, and leaves it as it was.
        ``run_id`` defaults to the directory's name; ``criteria`` (default: every registered surface
        criterion) and the columns declared now are the run's for good (its manifest keeps them).
        """
        rfs = resolve(path_or_uri, filesystem)
        kind = rfs.kind()
        if kind == "file":
            raise StoreError(f"{rfs.show()}: is a file; a run needs a directory")
        if kind == "dir":
            existing = _latest_manifest(rfs)
            if existing is not None:
                raise StoreError(
                    f"{rfs.show()}: already holds run {existing['run_id']!r}; "
                    "choose a new directory, or resume that run"
                )
            foreign = [n for n in rfs.listdir() if n not in _LAYOUT]
            if foreign:
                raise StoreError(
                    f"{rfs.show()}: exists and is not empty (holds {foreign[0]!r}); "
                    "a new run needs a new or empty directory"
                )
            if rfs.listdir("individuals") or rfs.listdir("events"):
                raise StoreError(
                    f"{rfs.show()}: holds a damaged run (data files but no intact manifest in "
                    f"{MANIFEST_DIR}/); a new run needs a new or empty directory"
                )
            for folder in sorted(_LAYOUT & set(rfs.listdir())):  # a creation that crashed half-way
                for name in rfs.listdir(folder):
                    rfs.delete(f"{folder}/{name}")
        _check_toml(config_toml, "configuration version 1")
        if run_id is None:
            base = rfs.root.rstrip("/").rsplit("/", 1)[-1]
            run_id = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip("._-") or "run"
            run_id = run_id[:128]
        if not isinstance(run_id, str) or not _RUN_ID.match(run_id):
            raise StoreError(
                f"run_id {run_id!r} is not allowed: use 1-128 letters, digits, '.', '_' or '-', "
                "starting with a letter or digit"
            )
        from genr8_dist.store.schema import criteria_names

        names = list(criteria_names() if criteria is None else criteria)
        columns = [list(c) for c in run_columns(names)]
        for folder in sorted(_LAYOUT):
            rfs.makedirs(folder)
        created = _now().isoformat()
        manifest: dict[str, Any] = {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "run_id": run_id,
            "criteria": names,
            "columns": columns,
            "created": created,
            "version": 0,
            "configs": [],
            "individuals": [],
            "events": [],
            "generations": {},
            "next_seq": 0,
        }
        store = cls(rfs, manifest, compact_every=compact_every)
        store._publish_config(config_toml, 0, ())
        return store

    @classmethod
    def open(
        cls,
        path_or_uri: str | os.PathLike[str],
        *,
        filesystem: pafs.FileSystem | None = None,
        compact_every: int | None = COMPACT_EVERY,
    ) -> RunStore:
        """The run at ``path_or_uri``; ``StoreError`` naming the path if it is missing or not a run."""
        rfs = resolve(path_or_uri, filesystem)
        kind = rfs.kind()
        if kind == "missing":
            raise StoreError(f"{rfs.show()}: no such run directory")
        if kind == "file":
            raise StoreError(f"{rfs.show()}: is a file, not a run directory")
        manifest = _latest_manifest(rfs)
        if manifest is None:
            raise StoreError(f"{rfs.show()}: not a run directory (no intact manifest in {MANIFEST_DIR}/)")
        return cls(rfs, manifest, compact_every=compact_every)

    def refresh(self) -> RunStore:
        """Load the newest committed state (another process may have committed since open)."""
        manifest = _latest_manifest(self._fs)
        if manifest is None:
            raise StoreError(f"{self._fs.show()}: no intact manifest left in {MANIFEST_DIR}/")
        self._m = manifest
        return self

    # --- identity ----------------------------------------------------------------------------
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
    def schema_version(self) -> int:
        """The store schema version this run was created with (it keeps it for good)."""
        return int(self._m["schema_version"])

    @property
    def schema(self) -> pa.Schema:
        """The individuals table's schema for this run: the columns its manifest records, or (a run of
        schema version 1) the columns of that version."""
        columns = self._m.get("columns")
        if columns is None:
            columns = run_columns(self.criteria, version=self.schema_version)
        return individuals_schema(columns=columns, version=self.schema_version)

    @property
    def reading_schema(self) -> pa.Schema:
        """What readers see: this run's schema, and every column declared since as nulls."""
        return reading_schema(self.schema)

    @property
    def version(self) -> int:
        """The number of the manifest this store reads (one per commit)."""
        return int(self._m["version"])

    def __repr__(self) -> str:
        return f"RunStore({self.path!r}, run_id={self.run_id!r}, version={self.version})"

    # --- commits -----------------------------------------------------------------------------
    def commit(self, individuals: Sequence[Individual], events: Sequence[Event] = ()) -> int:
        """Commit ``individuals`` and ``events`` atomically: afterwards all are there, or (after a
        crash) none. Each island's generations in a commit must follow its last committed one.
        Returns the commit number (the manifest version)."""
        if not individuals and not events:
            return self.version
        table = individuals_table(individuals, self.run_id, self.criteria, self.schema)
        return self.commit_table(table, events)

    def commit_table(self, table: pa.Table, events: Sequence[Event] = ()) -> int:
        """``commit`` for rows already in an Arrow table of ``self.schema`` (bulk writers)."""
        table = self._checked_rows(table)
        islands = self._island_ranges(table)
        events = list(events)
        for event in events:
            if not isinstance(event, Event):
                raise StoreError(f"events must be Event records, got {type(event).__name__}")
        if table.num_rows == 0 and not events:
            return self.version
        version = self._next_version()
        manifest = copy.deepcopy(self._m)
        if table.num_rows:
            entry = self._write_parquet(f"individuals/part-{version:010d}.parquet", table)
            entry.update(commits=[version, version], islands=islands)
            manifest["individuals"].append(entry)
        self._add_events(manifest, events, version)
        manifest["generations"] = _generations(manifest["individuals"])
        self._publish(manifest, version)
        if self.compact_every and self._small_files() >= self.compact_every:
            self.compact()
        return version

    def record_event(
        self, kind: str, *, generation: int, island: int | None = None, detail: dict[str, Any] | None = None
    ) -> None:
        """Record one event atomically (its own commit)."""
        self.commit([], [Event(kind, generation, island, dict(detail or {}))])

    def add_config(self, toml_text: str, effective_generation: int, *, events: Sequence[Event] = ()) -> int:
        """Record a new configuration version in force from ``effective_generation``, atomically with
        ``events`` (e.g. the intervention that made it). Returns the new version number (1-based)."""
        if isinstance(effective_generation, bool) or not isinstance(effective_generation, int):
            raise StoreError(f"effective_generation must be an integer, got {effective_generation!r}")
        last = self._m["configs"][-1]
        if effective_generation < last["effective_generation"]:
            raise StoreError(
                f"effective_generation {effective_generation} is before configuration version "
                f"{last['version']}'s ({last['effective_generation']}); versions take effect in order"
            )
        done = max((int(g) for g in self._m["generations"].values()), default=-1)
        if effective_generation <= done:
            raise StoreError(
                f"effective_generation {effective_generation} is already committed (up to generation "
                f"{done}); an edit takes effect from generation {done + 1} or later"
            )
        version = len(self._m["configs"]) + 1
        _check_toml(toml_text, f"configuration version {version}")
        return self._publish_config(toml_text, effective_generation, events)

    # --- the run's lock and its queue of pending interventions (store/pending.py) ------------
    def lock(self, role: str, *, wait: float = 10.0) -> RunLock:
        """The run's lock for ``role`` (``"run"``: the evolution's driver; ``"edit"``: one edit)."""
        return RunLock(self._fs, role, wait=wait)

    def running(self) -> dict[str, Any] | None:
        """Who runs the run now (role, pid, host, since), or None when no process holds its lock."""
        return lock_holder(self._fs)

    def enqueue(self, request: dict[str, Any]) -> Queued:
        """Queue an intervention for the running run's next epoch (plain JSON data)."""
        return enqueue(self._fs, request)

    def queued(self) -> list[Queued]:
        """The pending interventions, in the order the coordinator takes them."""
        return queued(self._fs)

    def dequeue(self, item: Queued) -> None:
        """Remove a pending intervention that has been recorded (only the run's writer does this)."""
        dequeue(self._fs, item)

    # --- reads -------------------------------------------------------------------------------
    def committed_generations(self) -> dict[int, int]:
        """Each island's last committed generation."""
        return {int(k): int(v) for k, v in self._m["generations"].items()}

    def generation_table(
        self, island: int, generation: int, columns: Sequence[str] | None = None
    ) -> pa.Table:
        """The rows of ``island``'s ``generation``, ordered by index. A generation committed after
        this store's snapshot was loaded (by another process) is found too: the snapshot is refreshed."""
        import pyarrow.compute as pc

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

    def _entries_holding(self, island: str, generation: int) -> list[dict[str, Any]]:
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
        columns declared since the run was written read as nulls."""
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

    def _refreshed(self) -> bool:
        """Load the newest manifest if there is a newer one than this store's; whether there was."""
        newest = _latest_manifest(self._fs)
        if newest is None or newest["version"] <= self.version:
            return False
        self._m = newest
        return True

    def dataset(self) -> ds.Dataset:
        """The committed individuals files as one pyarrow dataset (DuckDB can scan it)."""
        import pyarrow.dataset as ds

        try:
            return ds.dataset(self.individual_files(), schema=self.reading_schema, format="parquet",
                              filesystem=self._fs.fs)
        except OSError as exc:
            if self._refreshed():
                return self.dataset()
            for e in self._m["individuals"]:
                if self._check_entry(e, deep=False) is not None:
                    raise self._read_error(e, exc) from None
            raise StoreError(f"{self._fs.show()}: cannot read individuals: {exc}") from None

    def individual_files(self) -> list[str]:
        """The committed individuals files, as paths inside ``self.filesystem`` (local: absolute paths)."""
        return [self._fs.full(e["path"]) for e in self._m["individuals"]]

    def configs(self) -> list[ConfigVersion]:
        """Every configuration version, oldest first."""
        return [self._config(e) for e in self._m["configs"]]

    def config(self, version: int | ConfigVersion) -> RunConfig:
        """Configuration ``version`` (a number, or one of ``configs()``) as a ``RunConfig``, its fitness
        over the criteria this run stores: the one place a stored configuration is parsed. A
        configuration that no longer validates is a ``ConfigError`` naming the run and the version."""
        cv = version if isinstance(version, ConfigVersion) else self._config_version(version)
        key = (cv.version, cv.toml)
        parsed = self._parsed.get(key)
        if parsed is None:
            from genr8_dist.config import RunConfig

            source = f"{self.path} configuration v{cv.version}"
            parsed = RunConfig.from_toml(cv.toml, source=source, criteria=self.criteria)
            self._parsed[key] = parsed
        return parsed

    def fitness(self, version: int | ConfigVersion) -> FitnessSpec:
        """The fitness specification of configuration ``version`` alone (what history queries need;
        cheaper than ``config``: no environment or universe is built)."""
        cv = version if isinstance(version, ConfigVersion) else self._config_version(version)
        from genr8_dist.fitness import FitnessSpec

        data = tomllib.loads(cv.toml)
        return FitnessSpec.from_dict(data.get("fitness"), names=self.criteria,
                                     source=f"{self.path} configuration v{cv.version}")

    def _config_version(self, version: int) -> ConfigVersion:
        for e in self._m["configs"]:
            if int(e["version"]) == int(version):
                return self._config(e)
        raise StoreError(f"{self._fs.show()}: no configuration version {version}")

    def config_for(self, generation: int) -> ConfigVersion:
        """The configuration version in force at ``generation``."""
        chosen = None
        for e in self._m["configs"]:
            if e["effective_generation"] <= generation:
                chosen = e
        if chosen is None:
            raise StoreError(f"{self._fs.show()}: no configuration is in force at generation {generation}")
        return self._config(chosen)

    def events(self) -> pa.Table:
        """Every event, in order of ``seq``."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        tables = []
        for e in self._m["events"]:
            try:
                tables.append(pq.read_table(self._fs.full(e["path"]), filesystem=self._fs.fs,
                                            schema=events_schema()))
            except (pa.ArrowException, OSError) as exc:
                raise self._read_error(e, exc) from None
        if not tables:
            return events_schema().empty_table()
        return pa.concat_tables(tables).sort_by("seq")

    # --- integrity ---------------------------------------------------------------------------
    def verify(self) -> list[str]:
        """Problems with the committed files (missing, truncated, altered, unreadable), each naming
        its file; empty when the run is intact. Reads every committed byte."""
        return [p for _, p in self._bad_entries(self._m, {})] + self._manifest_problems()

    def _manifest_problems(self) -> list[str]:
        return [
            f"{self._fs.show(_manifest_rel(version))}: manifest is torn or altered; "
            f"the run is read from manifest {self.version}"
            for version in _list_manifests(self._fs)
            if version > self.version and _read_manifest(self._fs, version) is None
        ]

    def repair(self) -> list[str]:
        """Fall back to the last intact commit when ``verify`` finds problems, and record a
        "recovery" event saying what was lost. Returns the problems repaired (empty: nothing to do)."""
        cache: dict[tuple[str, str], str | None] = {}
        bad = self._bad_entries(self._m, cache)
        problems = [p for _, p in bad] + self._manifest_problems()
        if not problems:
            return []
        state = self._m
        kept_to = self.version
        if bad:
            first_bad = min(_first_commit(e) for e, _ in bad)
            if first_bad <= self._m["configs"][0]["commit"]:
                raise StoreError(
                    f"{problems[0]}; it belongs to the run's creation, so there is no intact "
                    "state to fall back to"
                )
            state = _prefix(self._m, first_bad)
            kept_to = first_bad - 1
            for version in sorted(_list_manifests(self._fs), reverse=True):
                if version <= kept_to:
                    break
                older = _read_manifest(self._fs, version)
                if older is None or version >= self.version:
                    continue
                if not self._bad_entries(older, cache):
                    state, kept_to = older, version
                    break
        manifest = copy.deepcopy(state)
        manifest["next_seq"] = self._m["next_seq"]
        manifest["generations"] = _generations(manifest["individuals"])
        version = self._next_version()
        last = max((int(g) for g in manifest["generations"].values()), default=0)
        detail = {
            "problems": problems,
            "kept_commits_through": kept_to,
            "lost_commits": self.version - kept_to,
            "generations": manifest["generations"],
        }
        self._add_events(manifest, [Event("recovery", last, None, detail)], version)
        self._publish(manifest, version)
        self.collect_garbage()
        return problems

    # --- compaction and garbage --------------------------------------------------------------
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
        for key, prefix in (("individuals", "individuals/compact"), ("events", "events/compact")):
            merged: list[dict[str, Any]] = []
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
                first, last = _first_commit(group[0]), group[-1]["commits"][1]
                entry = self._write_parquet(f"{prefix}-{first:010d}-{last:010d}.parquet", table)
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

    def collect_garbage(self) -> int:
        """Delete files no kept manifest names (left by crashes, compaction and repair), torn
        manifests and temporary files. Only the run's writer may call it. Returns how many it deleted."""
        referenced: set[str] = set()
        deleted = 0
        for version in _list_manifests(self._fs):
            m = _read_manifest(self._fs, version)
            if m is None:
                self._fs.delete(_manifest_rel(version))
                deleted += 1
                continue
            for key in ("configs", "individuals", "events"):
                referenced.update(e["path"] for e in m[key])
        for folder in ("configs", "individuals", "events", MANIFEST_DIR):
            for name in self._fs.listdir(folder):
                rel = f"{folder}/{name}"
                if name.startswith(TMP_PREFIX) or (folder != MANIFEST_DIR and rel not in referenced):
                    self._fs.delete(rel)
                    deleted += 1
        return deleted

    # --- internals ---------------------------------------------------------------------------
    def _next_version(self) -> int:
        listed = _list_manifests(self._fs)
        for version in sorted(listed, reverse=True):
            if version <= self.version:
                break
            if _read_manifest(self._fs, version) is not None:
                raise StoreError(
                    f"{self._fs.show()}: another process committed to this run (manifest {version}) "
                    "since it was opened here; only one writer may commit"
                )
        return max([self.version, *listed]) + 1

    def _publish(self, manifest: dict[str, Any], version: int) -> None:
        manifest["version"] = version
        manifest["written"] = _now().isoformat()
        try:
            self._fs.write_exclusive(_manifest_rel(version), _encode_manifest(manifest))
        except FileExistsError:
            raise StoreError(
                f"{self._fs.show()}: another process committed manifest {version} at the same time; "
                "only one writer may commit"
            ) from None
        self._m = manifest
        for old in _list_manifests(self._fs):
            if old <= version - KEEP_MANIFESTS:
                self._fs.delete(_manifest_rel(old))

    def _publish_config(self, toml_text: str, effective_generation: int, events: Sequence[Event]) -> int:
        number = len(self._m["configs"]) + 1
        version = self._next_version()
        rel = f"configs/v{number:04d}.toml"
        data = toml_text.encode()
        self._fs.write_atomic(rel, data)
        manifest = copy.deepcopy(self._m)
        manifest["configs"].append({
            "version": number,
            "effective_generation": effective_generation,
            "path": rel,
            "bytes": len(data),
            "sha256": hashlib.sha256(data).hexdigest(),
            "created": _now().isoformat(),
            "commit": version,
        })
        self._add_events(manifest, list(events), version)
        self._publish(manifest, version)
        self._config_cache[number] = toml_text
        return number

    def _add_events(self, manifest: dict[str, Any], events: list[Event], version: int) -> None:
        if not events:
            return
        first = manifest["next_seq"]
        now = _now()
        time_us = int(now.timestamp()) * 1_000_000 + now.microsecond
        table = events_table(events, self.run_id, first, time_us)
        entry = self._write_parquet(f"events/events-{version:010d}.parquet", table)
        entry.update(commits=[version, version], seq=[first, first + len(events) - 1])
        manifest["events"].append(entry)
        manifest["next_seq"] = first + len(events)

    def _write_parquet(self, rel: str, table: pa.Table) -> dict[str, Any]:
        import pyarrow as pa
        import pyarrow.parquet as pq

        buf = pa.BufferOutputStream()
        pq.write_table(table, buf, compression=COMPRESSION, row_group_size=ROW_GROUP_ROWS)
        data = buf.getvalue()
        self._fs.write_atomic(rel, memoryview(data))
        return {"path": rel, "rows": table.num_rows, "bytes": data.size,
                "sha256": hashlib.sha256(memoryview(data)).hexdigest()}

    def _checked_rows(self, table: pa.Table) -> pa.Table:
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

    def _island_ranges(self, table: pa.Table) -> dict[str, list[int]]:
        import numpy as np

        if table.num_rows == 0:
            return {}
        island = table.column("island").to_numpy()
        gen = table.column("generation").to_numpy()
        index = table.column("index").to_numpy()
        order = np.lexsort((index, gen, island))
        si, sg, sx = island[order], gen[order], index[order]
        dup = (si[1:] == si[:-1]) & (sg[1:] == sg[:-1]) & (sx[1:] == sx[:-1])
        if dup.any():
            k = int(np.argmax(dup))
            raise StoreError(f"individual {si[k]}-{sg[k]}-{sx[k]} appears twice in one commit")
        done = self.committed_generations()
        ranges: dict[str, list[int]] = {}
        for isl in np.unique(si):
            gens = np.unique(sg[si == isl])
            start = done.get(int(isl), -1) + 1
            if gens[0] != start or int(gens[-1]) - int(gens[0]) + 1 != len(gens):
                raise StoreError(
                    f"island {isl}: the commit holds generations {gens.tolist()[:8]}, but the next one "
                    f"to commit is {start} and a commit's generations must follow one another"
                )
            ranges[str(int(isl))] = [int(gens[0]), int(gens[-1])]
        return ranges

    def _small_files(self) -> int:
        return sum(1 for e in self._m["individuals"] if e["rows"] < COMPACT_TARGET_ROWS)

    def _read_entries(self, entries: list[dict[str, Any]], *, columns: Sequence[str] | None,
                      filter: pc.Expression | None) -> pa.Table:
        import pyarrow as pa
        import pyarrow.dataset as ds

        try:
            dataset = ds.dataset([self._fs.full(e["path"]) for e in entries], schema=self.reading_schema,
                                 format="parquet", filesystem=self._fs.fs)
            return dataset.to_table(columns=list(columns) if columns is not None else None, filter=filter)
        except (pa.ArrowException, OSError) as exc:
            for e in entries:
                if self._check_entry(e, deep=False) is not None:
                    raise self._read_error(e, exc) from None
            raise StoreError(f"{self._fs.show()}: cannot read individuals: {exc}") from None

    def _read_whole(self, entry: dict[str, Any]) -> pa.Table:
        import pyarrow as pa
        import pyarrow.parquet as pq

        problem = self._check_entry(entry, deep=True)
        if problem is not None:
            raise StoreError(f"{problem}; run repair to fall back to the last intact commit")
        data = self._fs.read_bytes(entry["path"])
        return pq.read_table(pa.BufferReader(data))

    def _read_error(self, entry: dict[str, Any], exc: BaseException) -> StoreError:
        problem = self._check_entry(entry, deep=True) or f"{self._fs.show(entry['path'])}: unreadable ({exc})"
        return StoreError(f"{problem}; run repair to fall back to the last intact commit")

    def _check_entry(self, entry: dict[str, Any], *, deep: bool) -> str | None:
        """What is wrong with a committed file, or None. ``deep`` also checks its sha256."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        rel = entry["path"]
        where = self._fs.show(rel)
        size = self._fs.size(rel)
        if size is None:
            return f"{where}: missing (the manifest names it)"
        if size != entry["bytes"]:
            return f"{where}: truncated or altered: {size} bytes, the manifest recorded {entry['bytes']}"
        if not deep and rel.endswith(".toml"):
            return None
        try:
            if deep:
                data = self._fs.read_bytes(rel)
                if hashlib.sha256(data).hexdigest() != entry["sha256"]:
                    return f"{where}: corrupt: its sha256 differs from the one the manifest recorded"
                if rel.endswith(".toml"):
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

    def _bad_entries(self, manifest: dict[str, Any], cache: dict[tuple[str, str], str | None]
                     ) -> list[tuple[dict[str, Any], str]]:
        bad = []
        for key in ("configs", "individuals", "events"):
            for e in manifest[key]:
                k = (e["path"], e["sha256"])
                if k not in cache:
                    cache[k] = self._check_entry(e, deep=True)
                if cache[k] is not None:
                    bad.append((e, cache[k]))
        return bad

    def _config(self, entry: dict[str, Any]) -> ConfigVersion:
        number = entry["version"]
        text = self._config_cache.get(number)
        if text is None:
            problem = self._check_entry(entry, deep=True)
            if problem is not None:
                raise StoreError(f"{problem}; run repair to fall back to the last intact commit")
            text = self._fs.read_bytes(entry["path"]).decode()
            self._config_cache[number] = text
        return ConfigVersion(number, entry["effective_generation"], text,
                             datetime.fromisoformat(entry["created"]))


def _first_commit(entry: dict[str, Any]) -> int:
    return int(entry["commits"][0]) if "commits" in entry else int(entry["commit"])


def _prefix(manifest: dict[str, Any], first_bad: int) -> dict[str, Any]:
    """The state of ``manifest`` before commit ``first_bad`` (commits only append, so it is a prefix)."""
    out = copy.deepcopy(manifest)
    out["configs"] = [e for e in out["configs"] if e["commit"] < first_bad]
    out["individuals"] = [e for e in out["individuals"] if e["commits"][1] < first_bad]
    out["events"] = [e for e in out["events"] if e["commits"][1] < first_bad]
    return out


def _plan_compaction(entries: list[dict[str, Any]], target_rows: int) -> list[list[dict[str, Any]]]:
    """Groups of consecutive entries, each a file to keep (one entry) or to merge (several)."""
    groups: list[list[dict[str, Any]]] = []
    run: list[dict[str, Any]] = []
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


def _list_manifests(rfs: RunFS) -> list[int]:
    return sorted(int(m.group(1)) for n in rfs.listdir(MANIFEST_DIR) if (m := _MANIFEST_NAME.match(n)))


def _read_manifest(rfs: RunFS, version: int) -> dict[str, Any] | None:
    try:
        data = rfs.read_bytes(_manifest_rel(version))
    except OSError:
        return None
    manifest = _decode_manifest(data)
    if manifest is not None and manifest.get("version") != version:
        return None
    return manifest


def _latest_manifest(rfs: RunFS) -> dict[str, Any] | None:
    """The highest-numbered intact manifest, or None. Refuses runs written by a newer schema."""
    for version in sorted(_list_manifests(rfs), reverse=True):
        manifest = _read_manifest(rfs, version)
        if manifest is None:
            continue
        found = manifest.get("schema_version")
        if not isinstance(found, int) or found > SCHEMA_VERSION:
            raise StoreError(
                f"{rfs.show(_manifest_rel(version))}: schema version {found!r} is newer than this "
                f"genr8_dist reads ({SCHEMA_VERSION}); upgrade genr8_dist"
            )
        return manifest
    return None
