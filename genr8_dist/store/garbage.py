"""Garbage collection: files no kept manifest names, torn older manifests, and temporary files left by
crashed writers; a user's file found among the run's is moved aside, never deleted (``foreign.py``).
"""

from __future__ import annotations

import os
import re

from genr8_dist.store import views
from genr8_dist.store._fs import TMP_PREFIX
from genr8_dist.store.audit import below_gap
from genr8_dist.store.foreign import is_store_name, set_aside
from genr8_dist.store.manifest import (
    MANIFEST_DIR,
    file_entries,
    list_manifests,
    manifest_rel,
    read_manifest,
    utc_now,
)
from genr8_dist.store.snapshot import Snapshot

__all__ = ["TMP_STALE_SECONDS", "Garbage"]
TMP_STALE_SECONDS = 3600     # a temporary file this old is a crash's leftover, whoever wrote it
_TMP_PID = re.compile(r"-(\d+)-[0-9a-f]{8}$")


class Garbage(Snapshot):
    """A store's ``collect_garbage``."""

    def collect_garbage(self) -> int:
        """Delete files no kept manifest names (left by crashes, compaction and repair), torn older
        manifests and temporary files left by crashed writers (their process is gone, or they are
        over an hour old). Only the run's writer may call it. Returns how many it deleted."""
        from genr8_dist.store.parts import clear_stale_parts

        referenced: set[str] = set()
        folders = {"configs", *views.DATA_FOLDERS}
        deleted = 0
        for version in list_manifests(self._fs):
            m = read_manifest(self._fs, version)
            if m is None:
                if version < self.version:
                    self._fs.delete(manifest_rel(version))
                    deleted += 1
                continue
            for _, e in file_entries(m):
                referenced.add(e["path"])
                folders.add(e["path"].rsplit("/", 1)[0])
        for version in below_gap(list_manifests(self._fs), self.version):   # older than a missing one
            self._fs.delete(manifest_rel(version))
            deleted += 1
        for _, e in file_entries(self._m):
            referenced.add(e["path"])
            folders.add(e["path"].rsplit("/", 1)[0])
        if self._fs.local_root is not None:  # a view's links are not the run's files: never collected
            folders = {f for f in folders if not os.path.islink(self._fs._local(f))}
        deleted += clear_stale_parts(self._fs, TMP_STALE_SECONDS)
        deleted += views.clear_stale_links(self._fs)
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
        return mtime is not None and utc_now().timestamp() - mtime > TMP_STALE_SECONDS
