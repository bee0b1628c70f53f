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
(``commit(..., add=...)``) and lists the entries under a manifest key of its own
(``manifest.add_entries``): unique names, verification, repair and garbage collection then apply to it
unchanged.

One writer per run: the process that runs the evolution (the coordinator) or an edit. Any number of
readers (history queries, DuckDB) may read at the same time.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.store import views
from genr8_dist.store._fs import TMP_PREFIX, RunFS, resolve
from genr8_dist.store.commits import Commits
from genr8_dist.store.compaction import COMPACT_EVERY, COMPACT_TARGET_ROWS, Compaction
from genr8_dist.store.configs import (
    Configs,
    ConfigVersion,
    check_toml,
    config_meshing,
    config_screen,
    phenotype_columns,
)
from genr8_dist.store.garbage import TMP_STALE_SECONDS as TMP_STALE_SECONDS
from genr8_dist.store.garbage import Garbage
from genr8_dist.store.live import LIVE_DIR
from genr8_dist.store.manifest import (
    FORMAT,
    KEEP_MANIFESTS,
    LAYOUT_FOLDERS,
    MANIFEST_DIR,
    Manifest,
    load_state,
    utc_now,
)
from genr8_dist.store.pending import LOCK_NAME, QUEUE_DIR, LockAndQueue
from genr8_dist.store.reads import Reads
from genr8_dist.store.repair import Repair
from genr8_dist.store.schema import SCHEMA_VERSION, run_columns

if TYPE_CHECKING:
    import pyarrow.fs as pafs

__all__ = [
    "COMPACT_EVERY",
    "COMPACT_TARGET_ROWS",
    "KEEP_MANIFESTS",
    "ConfigVersion",
    "RunStore",
    "half_created",
]

_RUN_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")
# what a run directory holds
_NAMES = LAYOUT_FOLDERS | {views.FILES, views.STAGING, views.VIEWS, views.CURRENT}


class RunStore(Reads, Configs, Commits, Repair, Compaction, Garbage, LockAndQueue):
    """One run directory: its configuration versions, its individuals and its events.

    Build with ``RunStore.create`` (a new run) or ``RunStore.open`` (an existing one). Reads use the
    snapshot loaded at open or last commit; ``refresh()`` loads the newest. Each concept is a class of
    its own module: ``snapshot`` (the state and what the run is), ``checks``, ``transactions`` (the
    commit protocol), ``commits``, ``reads``, ``configs``, ``repair`` (with ``verify``),
    ``compaction``, ``garbage``, and ``pending`` (the run's lock and queue).
    """

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
                existing, _ = load_state(rfs)
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
            for folder in (MANIFEST_DIR, "configs", *views.DATA_FOLDERS):  # a creation that stopped half-way
                if rfs.local_root is not None and os.path.islink(rfs._local(folder)):
                    continue
                for name in rfs.listdir(folder):
                    if rfs.kind(f"{folder}/{name}") == "file":
                        rfs.delete(f"{folder}/{name}")
        check_toml(config_toml, "configuration version 1")
        if run_id is None:
            base = rfs.root.rstrip("/").rsplit("/", 1)[-1]
            run_id = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip("._-") or "run"
            run_id = run_id[:128]
        if not isinstance(run_id, str) or not _RUN_ID.match(run_id):
            raise StoreError(
                f"run_id {run_id!r} is not allowed: use 1-128 letters, digits, '.', '_' or '-', "
                "starting with a letter or digit"
            )
        meshing = config_meshing(config_toml)
        screen = config_screen(config_toml)
        if criteria is None or sizes is None:
            own_criteria, own_sizes = phenotype_columns(config_toml)
            criteria = own_criteria if criteria is None else criteria
            sizes = own_sizes if sizes is None else sizes
        names, sized = list(criteria), list(sizes)
        columns: list[list[str | bool]] = [[n, kind, null]
                                           for n, kind, null in run_columns(names, sizes=sized)]
        for folder in (MANIFEST_DIR, "configs", f"{views.FILES}/individuals", f"{views.FILES}/events"):
            rfs.makedirs(folder)
        created = utc_now().isoformat()
        manifest: Manifest = {
            "format": FORMAT,
            "schema_version": SCHEMA_VERSION,
            "layout": views.LAYOUT,
            "run_id": run_id,
            "criteria": names,
            "sizes": sized,
            "columns": columns,
            "meshing": meshing,
            "screen": screen,
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
        manifest, stale = load_state(rfs)
        if manifest is None:
            state = half_created(rfs)
            if state == "half-created":
                raise StoreError(
                    f"{rfs.show()}: a run whose creation did not finish (no commit yet); start it again "
                    f"with `genr8 run CONFIG --run-dir {rfs.show()}` (it reuses the directory) or remove it"
                )
            raise StoreError(f"{rfs.show()}: not a run directory (no intact manifest in {MANIFEST_DIR}/)")
        return cls(rfs, manifest, compact_every=compact_every, stale=stale)

    def upgrade(self) -> bool:
        """Convert a run of layout 1 in place to layout 2 (``store/upgrade.py``); whether it did."""
        from genr8_dist.store.upgrade import upgrade

        return upgrade(self)


def half_created(rfs: RunFS) -> str:
    """What a directory holds: ``"empty"``, ``"half-created"`` (a creation that stopped before its
    first manifest: only layout folders, no data), ``"run"``, ``"damaged"`` (data files but no intact
    manifest) or ``"foreign"`` (anything else)."""
    names = rfs.listdir()
    if not names:
        return "empty"
    manifest, _ = load_state(rfs)
    if manifest is not None:
        return "run"
    if [n for n in names if n not in _NAMES | {LOCK_NAME, QUEUE_DIR, LIVE_DIR}]:
        return "foreign"
    data = [n for f in views.DATA_FOLDERS for n in rfs.listdir(f) if not n.startswith(TMP_PREFIX)]
    return "damaged" if data else "half-created"
