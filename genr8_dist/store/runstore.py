"""The run store: a run directory of configuration versions, individuals and events, committed atomically.

Layout of a run directory (see docs/run-store.md)::

    _manifest/0000000001.json   numbered manifests; the highest intact one is the run's state
    _manifest/HEAD              the newest commit's number
    configs/v0001-<token>.toml  configuration versions, in force from a recorded generation
    individuals/part-<commit>-<token>.parquet          one Parquet file per commit (an epoch)
    individuals/compact-<first>-<last>-<token>.parquet many commits merged by compact()
    events/events-<commit>-<token>.parquet, events/compact-<first>-<last>-<token>.parquet

A commit writes its data files, each under a name no other writer can use (its stem, then a random
writer token: ``part-0000000003-9f2c4e1ab07d5e36.parquet``), never replacing a file, then publishes
manifest ``N+1``, a complete snapshot naming every committed file with its row count, size and
sha256, by *linking* it into place: whoever links ``N+1`` first has committed, and a writer that loses
deletes only the files it wrote. So a losing writer can never touch the winner's bytes. Readers read
only files a manifest names and check each file's sha256 against it before trusting it (once per
file and store), so a crash at any moment leaves the whole commit or none of it, and damage is named,
never read as data; files no manifest names are garbage and are ignored (and removed by ``compact``,
``repair`` and ``collect_garbage``). ``_manifest/HEAD`` holds the newest commit's number, so the loss
of the newest manifest is seen rather than silently serving the one before. The last
``KEEP_MANIFESTS`` manifests are kept so that a reader holding an older snapshot can still read it,
and so that ``repair`` can replace a damaged compacted file by the files it was merged from.

Any feature that stores a new kind of file does it through ``RunStore.write_file`` inside a commit
(``commit(..., add=...)``) and lists the entries under a manifest key of its own: unique names,
verification, repair and garbage collection then apply to it unchanged.

One writer per run: the process that runs the evolution (the coordinator) or an edit. Any number of
readers (history queries, DuckDB) may read at the same time.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import os
import re
import secrets
import tomllib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import ConfigError, StoreError
from genr8_dist.evolution.individual import SCHEMA_2_NAMES, Individual
from genr8_dist.store import views
from genr8_dist.store._fs import TMP_PREFIX, RunFS, resolve
from genr8_dist.store.audit import below_gap, describe_missing, head_damaged, missing_manifests
from genr8_dist.store.foreign import is_store_name, set_aside
from genr8_dist.store.live import LIVE_DIR
from genr8_dist.store.pending import (
    LOCK_NAME,
    QUEUE_DIR,
    Queued,
    RunLock,
    dequeue,
    enqueue,
    lock_holder,
    queued,
)
from genr8_dist.store.schema import (
    COMPRESSION,
    ROW_GROUP_ROWS,
    SCHEMA_VERSION,
    Event,
    events_schema,
    events_table,
    individuals_from_table,
    individuals_schema,
    individuals_table,
    island_generations,
    reading_schema,
    run_columns,
    sizes_of,
    stored_schema,
)

if TYPE_CHECKING:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.dataset as ds
    import pyarrow.fs as pafs

    from genr8_dist.config import RunConfig
    from genr8_dist.fitness import FitnessSpec
    from genr8_dist.store.parts import Part

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
HEAD = f"{MANIFEST_DIR}/HEAD"   # the newest commit's number, written after its manifest is linked
TMP_STALE_SECONDS = 3600     # a temporary file this old is a crash's leftover, whoever wrote it
_MANIFEST_NAME = re.compile(r"^(\d{10})\.json$")
_TMP_PID = re.compile(r"-(\d+)-[0-9a-f]{8}$")
_REL_PATH = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9._-]{0,200}(/[A-Za-z0-9_][A-Za-z0-9._-]{0,200}){1,3}$")
_SHA256 = re.compile(r"^[0-9a-f]{64}$")
_RUN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")
_LAYOUT = {MANIFEST_DIR, "configs", "individuals", "events"}
_NAMES = _LAYOUT | {views.FILES, views.STAGING, views.VIEWS, views.CURRENT}   # what a run directory holds
_DATA = ("individuals", "events", f"{views.FILES}/individuals", f"{views.FILES}/events")


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
    try:
        _check_manifest(m)
    except (ValueError, TypeError, KeyError, AttributeError):
        return None
    return m


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check_range(value: Any) -> None:
    if not (isinstance(value, list) and len(value) == 2 and all(_is_int(v) for v in value)
            and value[0] <= value[1]):
        raise ValueError(f"not a range: {value!r}")


def file_entries(manifest: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """Every file a manifest names, as ``(kind, entry)``: the kind is the manifest key listing it
    (``configs``, ``individuals``, ``events``, or any list a later feature adds the same way)."""
    out: list[tuple[str, dict[str, Any]]] = []
    for key, value in manifest.items():
        if isinstance(value, list) and value and all(isinstance(e, dict) and "path" in e for e in value):
            out.extend((key, e) for e in value)
    return out


def _check_manifest(m: dict[str, Any]) -> None:
    """Raise ``ValueError`` unless ``m`` is well formed and names only files inside the run."""
    if not _is_int(m["version"]) or not _is_int(m["next_seq"]) or not isinstance(m["run_id"], str):
        raise ValueError("header")
    if not (isinstance(m["criteria"], list) and all(isinstance(c, str) for c in m["criteria"])):
        raise ValueError("criteria")
    for key in ("configs", "individuals", "events"):
        if not isinstance(m[key], list):
            raise ValueError(key)
    for kind, e in file_entries(m):
        path = e["path"]
        if (not isinstance(path, str) or not _REL_PATH.match(path) or path.startswith(MANIFEST_DIR + "/")
                or not _is_int(e["bytes"]) or e["bytes"] < 0 or not isinstance(e["sha256"], str)
                or not _SHA256.match(e["sha256"])):
            raise ValueError(f"{kind} entry {path!r}")
        if kind == "configs":
            if not (_is_int(e["version"]) and _is_int(e["effective_generation"]) and _is_int(e["commit"])
                    and isinstance(e["created"], str)):
                raise ValueError("config entry")
        elif kind in ("individuals", "events"):
            if not _is_int(e["rows"]):
                raise ValueError("rows")
            _check_range(e["commits"])
            if kind == "events":
                _check_range(e["seq"])
            else:
                if not isinstance(e["islands"], dict):
                    raise ValueError("islands")
                for island, span in e["islands"].items():
                    int(island)
                    _check_range(span)
    if not isinstance(m["generations"], dict):
        raise ValueError("generations")
    for island, g in m["generations"].items():
        int(island)
        if not _is_int(g):
            raise ValueError("generations")


def _phenotype_columns(config_toml: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The criteria and the sizes a run of ``config_toml`` stores: those of its universe's phenotype,
    or the built-in surface phenotype's when the text is not a run configuration (a bare store)."""
    from genr8_dist.config import RunConfig, run_phenotype
    from genr8_dist.errors import Genr8Error
    from genr8_dist.store.schema import builtin_sizes, criteria_names

    try:
        config = RunConfig.from_toml(config_toml)
    except Genr8Error:
        return criteria_names(), builtin_sizes()
    return tuple(config.fitness.names), tuple(run_phenotype(config.universe_source).sizes)


def _config_meshing(config_toml: str) -> int:
    """The meshing a new run of ``config_toml`` records: the one it names, else the current one."""
    from genr8_dist.hemls.meshing import MESHING, check_meshing

    try:
        named = tomllib.loads(config_toml).get("meshing")
    except tomllib.TOMLDecodeError:
        return MESHING
    return MESHING if named is None else check_meshing(named, "configuration version 1: meshing")


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

    def get_fragments(self, filter: pc.Expression | None = None) -> Iterator[Any]:
        return iter(self.stored.get_fragments(filter=filter))


def _manifest_rel(version: int) -> str:
    return f"{MANIFEST_DIR}/{version:010d}.json"


def _checked_events(events: Sequence[Event]) -> list[Event]:
    """``events`` as a list; ``StoreError`` if one is not an ``Event`` record."""
    out = list(events)
    for event in out:
        if not isinstance(event, Event):
            raise StoreError(f"events must be Event records, got {type(event).__name__}")
    return out


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

    def __init__(self, rfs: RunFS, manifest: dict[str, Any], *, compact_every: int | None,
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

    # --- building ----------------------------------------------------------------------------
    @classmethod
    def create(
        cls,
        path_or_uri: str | os.PathLike[str],
        config_toml: str,
        *,
        run_id: str | None = None,
        criteria: Sequence[str] | None = None,
        sizes: Sequence[str] | None = None,
        filesystem: pafs.FileSystem | None = None,
        compact_every: int | None = COMPACT_EVERY,
    ) -> RunStore:
        """A new run at ``path_or_uri`` whose configuration version 1 is ``config_toml`` (generation 0).

        The directory becomes a run in one step, when manifest 1 is linked into place; a creation that
        stopped before that (a crash, a full disk) left only a half-created directory, which this
        finishes. Refuses a directory that is already a run, or that holds anything else, and leaves it
        as it was. ``run_id`` defaults to the directory's name. The run stores the criteria and the
        sizes of its configuration's phenotype (``genr8_dist.phenotype``: its universe's; the built-in
        surface phenotype's when ``config_toml`` is not a run configuration); ``criteria`` and
        ``sizes`` override them. They and the columns declared now are the run's for good (its
        manifest keeps them).
        """
        rfs = resolve(path_or_uri, filesystem)
        kind = rfs.kind()
        if kind == "file":
            raise StoreError(f"{rfs.show()}: is a file; a run needs a directory")
        if kind == "dir":
            state = half_created(rfs)
            if state == "run":
                existing, _ = _load_state(rfs)
                assert existing is not None
                raise StoreError(
                    f"{rfs.show()}: already holds run {existing['run_id']!r}; "
                    "choose a new directory, or resume that run"
                )
            if state == "foreign":
                foreign = [n for n in rfs.listdir() if n not in _NAMES | {LOCK_NAME, QUEUE_DIR, LIVE_DIR}]
                raise StoreError(
                    f"{rfs.show()}: exists and is not empty (holds {foreign[0]!r}); "
                    "a new run needs a new or empty directory"
                )
            if state == "damaged":
                raise StoreError(
                    f"{rfs.show()}: holds a damaged run (data files but no intact manifest in "
                    f"{MANIFEST_DIR}/); a new run needs a new or empty directory"
                )
            for folder in (MANIFEST_DIR, "configs", *_DATA):  # a creation that stopped half-way
                if rfs.local_root is not None and os.path.islink(rfs._local(folder)):
                    continue
                for name in rfs.listdir(folder):
                    if rfs.kind(f"{folder}/{name}") == "file":
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
        meshing = _config_meshing(config_toml)
        if criteria is None or sizes is None:
            own_criteria, own_sizes = _phenotype_columns(config_toml)
            criteria = own_criteria if criteria is None else criteria
            sizes = own_sizes if sizes is None else sizes
        names, sized = list(criteria), list(sizes)
        columns = [list(c) for c in run_columns(names, sizes=sized)]
        for folder in (MANIFEST_DIR, "configs", f"{views.FILES}/individuals", f"{views.FILES}/events"):
            rfs.makedirs(folder)
        created = _now().isoformat()
        manifest: dict[str, Any] = {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "layout": views.LAYOUT,
            "run_id": run_id,
            "criteria": names,
            "sizes": sized,
            "columns": columns,
            "meshing": meshing,
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
        """The run at ``path_or_uri``; ``StoreError`` naming the path if it is missing or not a run.

        A run whose newest manifest is lost or damaged opens (so that ``verify`` and ``repair`` can
        name and mend it), but its data reads raise a ``StoreError`` naming that manifest rather
        than silently answering from the commit before."""
        rfs = resolve(path_or_uri, filesystem)
        kind = rfs.kind()
        if kind == "missing":
            raise StoreError(f"{rfs.show()}: no such run directory")
        if kind == "file":
            raise StoreError(f"{rfs.show()}: is a file, not a run directory")
        manifest, stale = _load_state(rfs)
        if manifest is None:
            state = half_created(rfs)
            if state == "half-created":
                raise StoreError(
                    f"{rfs.show()}: a run whose creation did not finish (no commit yet); start it again "
                    f"with `genr8 run CONFIG --run-dir {rfs.show()}` (it reuses the directory) or remove it"
                )
            raise StoreError(f"{rfs.show()}: not a run directory (no intact manifest in {MANIFEST_DIR}/)")
        return cls(rfs, manifest, compact_every=compact_every, stale=stale)

    def refresh(self) -> RunStore:
        """Load the newest committed state (another process may have committed since open)."""
        manifest, stale = _load_state(self._fs)
        if manifest is None:
            raise StoreError(f"{self._fs.show()}: no intact manifest left in {MANIFEST_DIR}/")
        self._m, self._stale = manifest, stale
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

    # --- commits -----------------------------------------------------------------------------
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

        def written(version: int) -> list[dict[str, Any]]:
            if not table.num_rows:
                return []
            entry = self._write_parquet(f"individuals/part-{version:010d}", table)
            entry.update(commits=[version, version], islands=islands)
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
        return self._commit_entries(lambda version: take_parts(self, list(parts), version), events, add)

    def _commit_entries(self, entries: Callable[[int], list[dict[str, Any]]], events: list[Event],
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
            manifest["generations"] = _generations(manifest["individuals"])
            self._publish(manifest, version)
        if self.compact_every and self._small_files() >= self.compact_every:
            self.compact()
        return version

    def upgrade(self) -> bool:
        """Convert a run of layout 1 in place to layout 2 (``store/upgrade.py``); whether it did."""
        from genr8_dist.store.upgrade import upgrade

        return upgrade(self)

    def write_file(self, stem: str, suffix: str, data: bytes | memoryview) -> dict[str, Any]:
        """Write one data file of the commit being made and return its manifest entry (``path``,
        ``bytes``, ``sha256``); add it to a list in the manifest (``add`` of ``commit``) and readers,
        ``verify``, ``repair`` and garbage collection know it. The file is named ``stem``, a random
        writer token, then ``suffix`` (``stem`` is ``folder/name``, e.g. ``archive/epoch-0000000007``):
        no other writer can use that name, and nothing is ever overwritten. If the commit fails or
        another writer commits first, the file is deleted again; nobody else's file is touched."""
        folder = stem.rpartition("/")[0]
        nested = folder.removeprefix(f"{views.FILES}/")
        if (not folder or "/" in nested or folder in (MANIFEST_DIR, views.FILES)
                or not _REL_PATH.match(f"{stem}{suffix}")):
            raise StoreError(f"write_file: {stem + suffix!r} is not 'folder/name' inside the run")
        rel = f"{stem}-{secrets.token_hex(8)}{suffix}"
        if folder not in _LAYOUT or folder != nested:
            self._fs.makedirs(folder)
        self._pending.append(rel)
        self._fs.write_new(rel, data)
        digest = hashlib.sha256(data).hexdigest()
        self._verified[(rel, digest)] = self._stamp(rel)
        return {"path": rel, "bytes": memoryview(data).nbytes, "sha256": digest}

    def read_file(self, entry: dict[str, Any]) -> bytes:
        """The bytes of a file a manifest entry names, checked against its size and sha256 first
        (``StoreError`` naming it when they differ)."""
        self._require_current()
        data = self._fs.read_bytes(entry["path"]) if self._fs.size(entry["path"]) is not None else None
        if data is None or hashlib.sha256(data).hexdigest() != entry["sha256"]:
            problem = self._check_entry(entry, deep=True) or f"{self._fs.show(entry['path'])}: changed"
            raise StoreError(f"{problem}; {self._repair_hint()}")
        self._verified[(entry["path"], entry["sha256"])] = self._stamp(entry["path"])
        return data

    @property
    def manifest(self) -> dict[str, Any]:
        """A copy of the manifest this store reads (the committed state)."""
        return copy.deepcopy(self._m)

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
        """The run's lock for ``role`` (``"run"``: the evolution's driver; ``"edit"``: one edit); this
        store's commits check it first (on S3, that its lease is still theirs)."""
        self.writer_lock = RunLock(self._fs, role, wait=wait)
        return self.writer_lock

    def running(self) -> dict[str, Any] | None:
        """Who runs the run now (role, pid, host, since), or None when no process holds its lock."""
        return lock_holder(self._fs)

    def enqueue(self, request: dict[str, Any]) -> Queued:
        """Queue an intervention for the running run's next epoch (plain JSON data)."""
        return enqueue(self._fs, request)

    def live(self) -> Any:
        """The live view of the running run (``store/live.py``): what it has completed, not committed."""
        from genr8_dist.store import live

        return live.LiveView(self._fs)

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

    def _refreshed(self) -> bool:
        """Load the newest manifest if there is a newer one than this store's; whether there was."""
        newest, stale = _load_state(self._fs)
        if newest is None or newest["version"] <= self.version:
            return False
        self._m, self._stale = newest, stale
        return True

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

    def _entries_between(self, lo: int, hi: int) -> list[dict[str, Any]]:
        """The individuals files holding some island's generation in ``lo..hi``."""
        return [e for e in self._m["individuals"]
                if any(a <= hi and b >= lo for a, b in e["islands"].values())]

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
            parsed = RunConfig.from_toml(cv.toml, source=source, criteria=self.criteria,
                                         meshing=self.meshing)
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

    # --- integrity ---------------------------------------------------------------------------
    def verify(self) -> list[str]:
        """Problems with the committed files (missing, truncated, altered, unreadable) and with the
        manifests (the newest lost or damaged, an older one damaged), each naming its file; empty when
        the run is intact. Reads every committed byte."""
        return ([p for _, _, p in self._bad_entries(self._m, {})] + self._manifest_problems()
                + ([] if self._stale else views.view_problems(self._fs, self._m)))

    def _manifest_problems(self) -> list[str]:
        out = [self._stale] if self._stale else []
        if head_damaged(self._fs, HEAD):   # unreadable, or truncated to what still reads as a number
            out.append(f"{self._fs.show(HEAD)}: damaged (it should hold the newest commit's number)")
        listed = _list_manifests(self._fs)
        out += describe_missing(missing_manifests(listed, self.version),
                                lambda v: self._fs.show(_manifest_rel(v)))
        for version in listed:
            if version >= self.version:
                continue  # a newer one torn or altered is the stale newest manifest, above
            rel = _manifest_rel(version)
            if _read_manifest(self._fs, version) is None and self._fs.size(rel) is not None:
                out.append(f"{self._fs.show(_manifest_rel(version))}: an older manifest is torn or altered "
                           "(a snapshot no longer in use; repair removes it)")
        return out

    def repair(self) -> list[str]:
        """Mend what ``verify`` finds, keeping every intact commit: a damaged configuration file is
        rewritten from the manifest's copy; a damaged individuals or events file is replaced by intact
        files an older manifest names holding the same commits, or else dropped alone (later commits
        stay); a lost or damaged newest manifest gives way to the newest intact one. What was dropped
        is said in one line (``last_repair``) and recorded with the problems in a "recovery" event.
        Returns the problems repaired (empty: nothing to do)."""
        cache: dict[tuple[str, str], str | None] = {}
        bad = self._bad_entries(self._m, cache)
        problems = [p for _, _, p in bad] + self._manifest_problems()
        view = [] if self._stale else views.view_problems(self._fs, self._m)
        if view and not problems:   # only the glob view: published again, no commit needed
            views.rebuild_view(self._fs, self._m)
            self.last_repair = f"rebuilt the glob view of commit {self.version}"
            return view
        if not problems:
            self.last_repair = ""
            return []
        with self._transaction():
            manifest, dropped, restored = self._mended(bad, cache)
            manifest["next_seq"] = self._m["next_seq"]
            manifest["generations"] = _generations(manifest["individuals"])
            version = self._next_version(repairing=True)
            if self._stale:
                dropped.append(f"commit {version - 1}'s manifest (lost or damaged; its files are no "
                               "longer named)")
            line = "dropped " + "; ".join(dropped) if dropped else "dropped nothing"
            if restored:
                line += "; restored " + "; ".join(restored)
            last = max((int(g) for g in manifest["generations"].values()), default=0)
            detail = {
                "problems": problems,
                "dropped": line,
                "kept_commits_through": self.version,
                "generations": manifest["generations"],
            }
            self._add_events(manifest, [Event("recovery", last, None, detail)], version)
            self._publish(manifest, version)
        self.last_repair = line
        self.collect_garbage()
        return problems

    def _mended(self, bad: list[tuple[str, dict[str, Any], str]], cache: dict[tuple[str, str], str | None]
                ) -> tuple[dict[str, Any], list[str], list[str]]:
        """The manifest with every damaged file restored, replaced or dropped; what was dropped and
        what was restored, each as short phrases."""
        m = copy.deepcopy(self._m)
        dropped: list[str] = []
        restored: list[str] = []
        damaged = {(e["path"], e["sha256"]) for _, e, _ in bad}
        older = []
        for version in sorted(_list_manifests(self._fs), reverse=True):
            if version < self.version and (om := _read_manifest(self._fs, version)) is not None:
                older.append(om)
        # configurations: rewritten from the manifest's copy; a run written before copies were kept
        # falls back to the state before the damaged version (the old rule)
        for e in list(m["configs"]):
            if (e["path"], e["sha256"]) not in damaged:
                continue
            text = e.get("toml")
            if isinstance(text, str) and hashlib.sha256(text.encode()).hexdigest() == e["sha256"]:
                new = self.write_file(f"configs/v{e['version']:04d}", ".toml", text.encode())
                e["path"] = new["path"]
                restored.append(f"configuration version {e['version']} (from the manifest's copy)")
                continue
            if e["commit"] <= m["configs"][0]["commit"]:
                problem = next(p for _, b, p in bad if b["path"] == e["path"])
                raise StoreError(f"{problem}; it belongs to the run's creation and the manifest "
                                 "holds no copy, so it cannot be repaired")
            cut = int(e["commit"])
            for kind, entry in file_entries(m):
                if _first_commit(entry) >= cut:
                    dropped.append(_describe(kind, entry))
            m = _prefix(m, cut)
            break
        for kind in [k for k, v in m.items() if isinstance(v, list) and k != "configs"]:
            kept = []
            for e in m[kind]:
                if not isinstance(e, dict) or (e.get("path"), e.get("sha256")) not in damaged:
                    kept.append(e)
                    continue
                pieces = self._replacement(kind, e, older, cache)
                if pieces:
                    kept.extend(pieces)
                    restored.append(f"{e['path']} (from the {len(pieces)} file(s) it was compacted from)")
                else:
                    dropped.append(_describe(kind, e))
                    if kind == "individuals":
                        m.setdefault("_tails", []).append(e)
            m[kind] = kept
        # events of a commit whose individuals were the newest of their islands describe generations
        # the run will make again: dropped with them, or a resumed run would record them twice
        for e in m.pop("_tails", []):
            newer = any(k["islands"][i][1] > span[1] for k in m["individuals"]
                        for i, span in e["islands"].items() if i in k["islands"])
            if newer:
                continue
            lo, hi = e["commits"]
            gone = [x for x in m["events"] if lo <= x["commits"][0] and x["commits"][1] <= hi]
            m["events"] = [x for x in m["events"] if x not in gone]
            dropped.extend(_describe("events", x) for x in gone)
        return m, dropped, restored

    def _replacement(self, kind: str, entry: dict[str, Any], older: list[dict[str, Any]],
                     cache: dict[tuple[str, str], str | None]) -> list[dict[str, Any]]:
        """Intact files older manifests name that hold exactly ``entry``'s commits, or []."""
        if "commits" not in entry or "rows" not in entry:
            return []
        lo, hi = entry["commits"]
        candidates: dict[str, dict[str, Any]] = {}
        for om in older:
            for e in om.get(kind, []):
                if (isinstance(e, dict) and e.get("path") != entry["path"] and "commits" in e
                        and lo <= e["commits"][0] and e["commits"][1] <= hi
                        and _within(e.get("islands", {}), entry.get("islands", {}))):
                    candidates.setdefault(e["path"], e)
        chosen, end = [], lo - 1
        for e in sorted(candidates.values(), key=lambda x: (x["commits"][0], -x["commits"][1])):
            if e["commits"][0] <= end:
                continue
            k = (e["path"], e["sha256"])
            if k not in cache:
                cache[k] = self._check_entry(e, deep=True)
            if cache[k] is None:
                chosen.append(e)
                end = e["commits"][1]
        if not chosen or sum(e["rows"] for e in chosen) != entry["rows"]:
            return []
        return chosen

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
        with self._transaction():
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
                    entry = self._write_parquet(f"{prefix}-{first:010d}-{last:010d}", table)
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
        """Delete files no kept manifest names (left by crashes, compaction and repair), torn older
        manifests and temporary files left by crashed writers (their process is gone, or they are
        over an hour old). Only the run's writer may call it. Returns how many it deleted."""
        from genr8_dist.store.parts import clear_stale_parts

        referenced: set[str] = set()
        folders = {"configs", *_DATA}
        deleted = 0
        for version in _list_manifests(self._fs):
            m = _read_manifest(self._fs, version)
            if m is None:
                if version < self.version:
                    self._fs.delete(_manifest_rel(version))
                    deleted += 1
                continue
            for _, e in file_entries(m):
                referenced.add(e["path"])
                folders.add(e["path"].rsplit("/", 1)[0])
        for version in below_gap(_list_manifests(self._fs), self.version):   # older than a missing one
            self._fs.delete(_manifest_rel(version))
            deleted += 1
        for _, e in file_entries(self._m):
            referenced.add(e["path"])
            folders.add(e["path"].rsplit("/", 1)[0])
        if self._fs.local_root is not None:  # a view's links are not the run's files: never collected
            folders = {f for f in folders if not os.path.islink(self._fs._local(f))}
        deleted += clear_stale_parts(self, TMP_STALE_SECONDS) + views.clear_stale_links(self._fs)
        for folder in [*sorted(folders), MANIFEST_DIR]:
            for name in self._fs.listdir(folder):
                rel = f"{folder}/{name}"
                if name.startswith(TMP_PREFIX):
                    if self._stale_tmp(rel, name):
                        self._fs.delete(rel)
                        deleted += 1
                elif (folder != MANIFEST_DIR and rel not in referenced and rel not in self._pending
                      and self._fs.kind(rel) == "file"):
                    if is_store_name(name):
                        self._fs.delete(rel)
                        deleted += 1
                    else:   # a user's file: moved aside, never deleted
                        self.set_aside.append((rel, set_aside(self._fs, rel)))
        deleted += self._collect_in_views(referenced)
        return deleted

    def _collect_in_views(self, referenced: set[str]) -> int:
        """Files dropped into the published view (``individuals/``, ``events/``: links to the commit's
        files) that are not the commit's: the store's own names deleted, a user's moved aside."""
        deleted = 0
        if self._fs.local_root is None:
            return deleted
        for table in views.TABLES:
            if not os.path.islink(self._fs._local(table)):
                continue
            for name in self._fs.listdir(table):
                rel = f"{table}/{name}"
                if (f"{views.FILES}/{rel}" in referenced or name.startswith(TMP_PREFIX)
                        or self._fs.kind(rel) != "file"):
                    continue
                if is_store_name(name):
                    self._fs.delete(rel)
                    deleted += 1
                else:
                    self.set_aside.append((rel, set_aside(self._fs, rel)))
        return deleted

    def _stale_tmp(self, rel: str, name: str) -> bool:
        match = _TMP_PID.search(name)
        if match and int(match.group(1)) != os.getpid():
            try:
                os.kill(int(match.group(1)), 0)
            except ProcessLookupError:
                return True
            except OSError:
                pass
        mtime = self._fs.mtime(rel)
        return mtime is not None and _now().timestamp() - mtime > TMP_STALE_SECONDS

    # --- internals ---------------------------------------------------------------------------
    @contextlib.contextmanager
    def _transaction(self) -> Iterator[None]:
        """Files written inside are this commit's: deleted again if it fails before its manifest is
        linked (another writer won, the disk filled...). Only files this store wrote are touched."""
        outer = self._pending
        self._pending = []
        try:
            yield
        except BaseException:
            for rel in self._pending:
                with contextlib.suppress(OSError):
                    self._fs.delete(rel)
            raise
        finally:
            self._pending = outer

    def _require_current(self) -> None:
        if self._stale:
            raise StoreError(f"{self._stale}; {self._repair_hint()}")

    def _repair_hint(self) -> str:
        return (f"`genr8 repair {self._fs.show()}` mends the run (it keeps every intact commit and names "
                "what it drops)")

    def _next_version(self, *, repairing: bool = False) -> int:
        if self._stale and not repairing:
            raise StoreError(f"{self._stale}; repair the run before writing to it")
        listed = _list_manifests(self._fs)
        for version in sorted(listed, reverse=True):
            if version <= self.version:
                break
            if _read_manifest(self._fs, version) is not None:
                raise StoreError(
                    f"{self._fs.show()}: another process committed to this run (manifest {version}) "
                    "since it was opened here; only one writer may commit"
                )
        head = _read_head(self._fs) or 0
        return max([self.version, head, *listed]) + 1

    def _publish(self, manifest: dict[str, Any], version: int) -> None:
        manifest["version"] = version
        manifest["written"] = _now().isoformat()
        if self.writer_lock is not None:
            self.writer_lock.check()
        try:
            self._fs.write_exclusive(_manifest_rel(version), _encode_manifest(manifest))
        except FileExistsError:
            raise StoreError(
                f"{self._fs.show()}: another process committed manifest {version} at the same time; "
                "only one writer may commit (this commit's files were removed, nothing else)"
            ) from None
        self._pending = []  # committed: no longer this writer's to remove
        self._m = manifest
        self._stale = None
        with contextlib.suppress(OSError):  # the glob view only lags (a crash): rebuilt by the next writer
            views.publish_view(self._fs, manifest)
            views.prune_views(self._fs, version - KEEP_MANIFESTS + 1)
        with contextlib.suppress(OSError):  # HEAD only lags (a full disk): never a false alarm
            if (_read_head(self._fs) or 0) < version:
                self._fs.write_atomic(HEAD, f"{version}\n".encode())
        for old in _list_manifests(self._fs):
            if old <= version - KEEP_MANIFESTS:
                self._fs.delete(_manifest_rel(old))

    def _publish_config(self, toml_text: str, effective_generation: int, events: Sequence[Event]) -> int:
        number = len(self._m["configs"]) + 1
        with self._transaction():
            version = self._next_version()
            data = toml_text.encode()
            entry = self.write_file(f"configs/v{number:04d}", ".toml", data)
            manifest = copy.deepcopy(self._m)
            manifest["configs"].append({
                "version": number,
                "effective_generation": effective_generation,
                **entry,
                "created": _now().isoformat(),
                "commit": version,
                "toml": toml_text,  # the copy repair() restores the file from
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
        entry = self._write_parquet(f"events/events-{version:010d}", table)
        entry.update(commits=[version, version], seq=[first, first + len(events) - 1])
        manifest["events"].append(entry)
        manifest["next_seq"] = first + len(events)

    def _write_parquet(self, stem: str, table: pa.Table) -> dict[str, Any]:
        import pyarrow as pa
        import pyarrow.parquet as pq

        buf = pa.BufferOutputStream()
        pq.write_table(table, buf, compression=COMPRESSION, row_group_size=ROW_GROUP_ROWS)
        data = buf.getvalue()
        if self.manifest_layout == views.LAYOUT:
            stem = f"{views.FILES}/{stem}"
        entry = self.write_file(stem, ".parquet", memoryview(data))
        return {"path": entry["path"], "rows": table.num_rows, "bytes": entry["bytes"],
                "sha256": entry["sha256"]}

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

    def _read_entries(self, entries: list[dict[str, Any]], *, columns: Sequence[str] | None,
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

    def _verify_files(self, entries: list[dict[str, Any]]) -> None:
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

    def _read_whole(self, entry: dict[str, Any]) -> pa.Table:
        import pyarrow as pa
        import pyarrow.parquet as pq

        problem = self._check_entry(entry, deep=True)
        if problem is not None:
            raise StoreError(f"{problem}; {self._repair_hint()}")
        data = self._fs.read_bytes(entry["path"])
        return pq.read_table(pa.BufferReader(data))

    def _read_error(self, entry: dict[str, Any], exc: BaseException) -> StoreError:
        problem = self._check_entry(entry, deep=True) or f"{self._fs.show(entry['path'])}: unreadable ({exc})"
        return StoreError(f"{problem}; {self._repair_hint()}")

    def _check_entry(self, entry: dict[str, Any], *, deep: bool) -> str | None:
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

    def _bad_entries(self, manifest: dict[str, Any], cache: dict[tuple[str, str], str | None]
                     ) -> list[tuple[str, dict[str, Any], str]]:
        bad = []
        for kind, e in file_entries(manifest):
            k = (e["path"], e["sha256"])
            if k not in cache:
                cache[k] = self._check_entry(e, deep=True)
            problem = cache[k]
            if problem is not None:
                bad.append((kind, e, problem))
        return bad

    def _config(self, entry: dict[str, Any]) -> ConfigVersion:
        number = entry["version"]
        text = self._config_cache.get(number)
        if text is None:
            problem = self._check_entry(entry, deep=True)
            if problem is not None:
                raise StoreError(f"{problem}; {self._repair_hint()}")
            try:
                text = self._fs.read_bytes(entry["path"]).decode()
            except UnicodeDecodeError:
                raise StoreError(f"{self._fs.show(entry['path'])}: not UTF-8 text") from None
            self._config_cache[number] = text
        return ConfigVersion(number, entry["effective_generation"], text,
                             datetime.fromisoformat(entry["created"]))


AddFiles = Callable[[dict[str, Any], int], None]
"""``add(manifest, version)``: writes files with ``RunStore.write_file`` and lists their entries in
``manifest`` (a list under a key of its own), as part of commit ``version``."""

_LAYOUT_STATES = ("empty", "half-created", "run", "damaged", "foreign")


def half_created(rfs: RunFS) -> str:
    """What a directory holds: ``"empty"``, ``"half-created"`` (a creation that stopped before its
    first manifest: only layout folders, no data), ``"run"``, ``"damaged"`` (data files but no intact
    manifest) or ``"foreign"`` (anything else)."""
    names = rfs.listdir()
    if not names:
        return "empty"
    manifest, _ = _load_state(rfs)
    if manifest is not None:
        return "run"
    if [n for n in names if n not in _NAMES | {LOCK_NAME, QUEUE_DIR, LIVE_DIR}]:
        return "foreign"
    data = [n for f in _DATA for n in rfs.listdir(f) if not n.startswith(TMP_PREFIX)]
    return "damaged" if data else "half-created"


def _describe(kind: str, entry: dict[str, Any]) -> str:
    """A dropped file in a few words: which commits, islands, generations, rows or events it held."""
    path = entry["path"]
    if kind == "individuals":
        spans = entry["islands"].values()
        lo = min(s[0] for s in spans) if spans else 0
        hi = max(s[1] for s in spans) if spans else 0
        isl = sorted(int(i) for i in entry["islands"])
        islands = f"island {isl[0]}" if len(isl) == 1 else f"islands {isl[0]}-{isl[-1]}"
        return f"{path} ({entry['rows']} individuals: {islands}, generations {lo}..{hi})"
    if kind == "events":
        return f"{path} ({entry['rows']} event(s), seq {entry['seq'][0]}..{entry['seq'][1]})"
    if kind == "configs":
        return f"{path} (configuration version {entry['version']})"
    return f"{path} ({kind})"


def _within(islands: dict[str, list[int]], outer: dict[str, list[int]]) -> bool:
    """Whether every island's generations in ``islands`` lie in ``outer``'s (a commit holds one part
    per island when the hosts write them: a replacement must be of the same islands)."""
    return all(i in outer and outer[i][0] <= lo and hi <= outer[i][1] for i, (lo, hi) in islands.items())


def _islands_of(entry: dict[str, Any]) -> set[int]:
    return {int(i) for i in entry.get("islands", {})}


def _first_commit(entry: dict[str, Any]) -> int:
    return int(entry["commits"][0]) if "commits" in entry else int(entry["commit"])


def _prefix(manifest: dict[str, Any], first_bad: int) -> dict[str, Any]:
    """The state of ``manifest`` before commit ``first_bad`` (commits only append, so it is a prefix)."""
    out = copy.deepcopy(manifest)
    for key, value in manifest.items():
        if isinstance(value, list) and value and all(isinstance(e, dict) and "path" in e for e in value):
            out[key] = [e for e in out[key] if _first_commit(e) < first_bad]
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


def _read_head(rfs: RunFS) -> int | None:
    """The commit number ``_manifest/HEAD`` records, or None (absent: a run written before it was
    kept; unreadable: damaged, which ``verify`` reports)."""
    try:
        text = rfs.read_bytes(HEAD).decode().strip()
    except (OSError, UnicodeDecodeError):
        return None
    return int(text) if text.isdigit() and len(text) <= 10 else None


def _load_state(rfs: RunFS) -> tuple[dict[str, Any] | None, str | None]:
    """The highest-numbered intact manifest (None when there is none) and, when the newest manifest
    is lost or damaged, a line saying so. Refuses runs written by a newer schema."""
    head = _read_head(rfs)  # read before listing: a writer links its manifest before writing HEAD
    skipped: list[int] = []
    for version in sorted(_list_manifests(rfs), reverse=True):
        manifest = _read_manifest(rfs, version)
        if manifest is None:
            if rfs.size(_manifest_rel(version)) is not None:  # not merely pruned by a writer
                skipped.append(version)
            continue
        found = manifest.get("schema_version")
        if not isinstance(found, int) or not _is_int(found) or found > SCHEMA_VERSION:
            raise StoreError(
                f"{rfs.show(_manifest_rel(version))}: schema version {found!r} is newer than this "
                f"genr8_dist reads ({SCHEMA_VERSION}); upgrade genr8_dist"
            )
        if skipped:
            return manifest, (f"{rfs.show(_manifest_rel(max(skipped)))}: the newest manifest is torn or "
                              f"altered; the run would read as commit {version}")
        if head is not None and head > version:
            return manifest, (f"{rfs.show(_manifest_rel(head))}: the newest manifest (commit {head}, "
                              f"recorded in {HEAD}) is missing; the run would read as commit {version}")
        return manifest, None
    return None, None


def _latest_manifest(rfs: RunFS) -> dict[str, Any] | None:
    """The highest-numbered intact manifest, or None."""
    return _load_state(rfs)[0]
