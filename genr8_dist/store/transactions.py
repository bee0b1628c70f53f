"""The commit protocol: files written under names no other writer can use, then manifest ``N+1``
linked into place (whoever links it first has committed), then ``HEAD`` and the glob view; a commit
that fails removes only the files it wrote (see ``store/runstore.py``'s docstring).
"""

from __future__ import annotations

import contextlib
import hashlib
import secrets
from collections.abc import Iterator
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.store import views
from genr8_dist.store.checks import FileChecks
from genr8_dist.store.manifest import (
    HEAD,
    KEEP_MANIFESTS,
    LAYOUT_FOLDERS,
    MANIFEST_DIR,
    REL_PATH,
    Entry,
    Manifest,
    encode_manifest,
    list_manifests,
    manifest_rel,
    read_head,
    read_manifest,
    utc_now,
)
from genr8_dist.store.schema import COMPRESSION, ROW_GROUP_ROWS, Event, events_table

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = ["Transactions"]


class Transactions(FileChecks):
    """Writing a commit's files and publishing its manifest."""

    def write_file(self, stem: str, suffix: str, data: bytes | memoryview) -> Entry:
        """Write one data file of the commit being made and return its manifest entry (``path``,
        ``bytes``, ``sha256``); add it to a list in the manifest (``add`` of ``commit``) and readers,
        ``verify``, ``repair`` and garbage collection know it. The file is named ``stem``, a random
        writer token, then ``suffix`` (``stem`` is ``folder/name``, e.g. ``archive/epoch-0000000007``):
        no other writer can use that name, and nothing is ever overwritten. If the commit fails or
        another writer commits first, the file is deleted again; nobody else's file is touched."""
        folder = stem.rpartition("/")[0]
        nested = folder.removeprefix(f"{views.FILES}/")
        if (not folder or "/" in nested or folder in (MANIFEST_DIR, views.FILES)
                or not REL_PATH.match(f"{stem}{suffix}")):
            raise StoreError(f"write_file: {stem + suffix!r} is not 'folder/name' inside the run")
        rel = f"{stem}-{secrets.token_hex(8)}{suffix}"
        if folder not in LAYOUT_FOLDERS or folder != nested:
            self._fs.makedirs(folder)
        self._pending.append(rel)
        self._fs.write_new(rel, data)
        digest = hashlib.sha256(data).hexdigest()
        self._verified[(rel, digest)] = self._stamp(rel)
        return {"path": rel, "bytes": memoryview(data).nbytes, "sha256": digest}

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

    def _next_version(self, *, repairing: bool = False) -> int:
        if self._stale and not repairing:
            raise StoreError(f"{self._stale}; repair the run before writing to it")
        listed = list_manifests(self._fs)
        for version in sorted(listed, reverse=True):
            if version <= self.version:
                break
            if read_manifest(self._fs, version) is not None:
                raise StoreError(
                    f"{self._fs.show()}: another process committed to this run (manifest {version}) "
                    "since it was opened here; only one writer may commit"
                )
        head = read_head(self._fs) or 0
        return max([self.version, head, *listed]) + 1

    def _publish(self, manifest: Manifest, version: int) -> None:
        manifest["version"] = version
        manifest["written"] = utc_now().isoformat()
        if self.writer_lock is not None:
            self.writer_lock.check()
        try:
            self._fs.write_exclusive(manifest_rel(version), encode_manifest(manifest))
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
            if (read_head(self._fs) or 0) < version:
                self._fs.write_atomic(HEAD, f"{version}\n".encode())
        for old in list_manifests(self._fs):
            if old <= version - KEEP_MANIFESTS:
                self._fs.delete(manifest_rel(old))

    def _add_events(self, manifest: Manifest, events: list[Event], version: int) -> None:
        if not events:
            return
        first = manifest["next_seq"]
        now = utc_now()
        time_us = int(now.timestamp()) * 1_000_000 + now.microsecond
        table = events_table(events, self.run_id, first, time_us)
        entry = self._write_parquet(f"events/events-{version:010d}", table)
        entry["commits"], entry["seq"] = [version, version], [first, first + len(events) - 1]
        manifest["events"].append(entry)
        manifest["next_seq"] = first + len(events)

    def _write_parquet(self, stem: str, table: pa.Table) -> Entry:
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
