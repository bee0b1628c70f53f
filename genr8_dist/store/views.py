"""The run directory's glob views: what a plain Parquet reader sees is always exactly one commit.

A run of layout 2 (every run created since; ``genr8 repair --upgrade`` converts older ones) keeps its
data files in ``_files/individuals/`` and ``_files/events/``, where no reader of the tables looks.
After each commit's manifest is linked (the commit point), the writer publishes that commit's *view*:

    _views/<commit>/individuals/<name>.parquet   a hard link to every individuals file the commit names
    _views/<commit>/events/<name>.parquet        likewise for events
    _current -> _views/<commit>                  one symlink, replaced atomically (rename over it)
    individuals -> _current/individuals          fixed symlinks, made once
    events -> _current/events

so ``individuals/*.parquet`` lists exactly the files of one commit: a new part appears, and the files a
compaction superseded disappear, in the one rename that moves ``_current``. A view is built whole
(and its folders fsynced) before ``_current`` points at it, and is never changed afterwards; the last
``KEEP_MANIFESTS`` commits' views are kept (time travel for any reader: ``_views/<commit>/...``).
Views are derived from manifests: a lost or partial one is rebuilt, and publishing one never fails a
commit. Only local filesystems have views (no symlinks or hard links on object stores: readers there
take the manifest's file list).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import secrets
import shutil
from typing import Literal

from genr8_dist.files import replace_atomically, sync_folder, temp_beside
from genr8_dist.store._fs import TMP_PREFIX, RunFS
from genr8_dist.store.manifest import Manifest

__all__ = [
    "CURRENT",
    "FILES",
    "LAYOUT",
    "STAGING",
    "TABLES",
    "VIEWS",
    "current_view",
    "prune_views",
    "publish_view",
    "view_rel",
]

LAYOUT = 2              # the manifest's "layout": data files in _files/, glob views (absent: layout 1)
FILES = "_files"        # where committed data files (and a commit's files before its commit point) lie
STAGING = "_staging"    # parts written by other processes (island hosts) before a commit takes them
VIEWS = "_views"
CURRENT = "_current"
Table = Literal["individuals", "events"]
TABLES: tuple[Table, ...] = ("individuals", "events")
DATA_FOLDERS = (*TABLES, f"{FILES}/individuals", f"{FILES}/events")   # data files, either layout


def view_rel(version: int) -> str:
    """The view folder of commit ``version``, relative to the run directory."""
    return f"{VIEWS}/{version:010d}"


def current_view(rfs: RunFS) -> int | None:
    """The commit whose view ``individuals/`` and ``events/`` show, or None (no view)."""
    if rfs.local_root is None:
        return None
    try:
        target = os.readlink(os.path.join(rfs.local_root, CURRENT))
    except OSError:
        return None
    name = target.rstrip("/").rsplit("/", 1)[-1].split(".")[0]   # (a rebuilt view: <commit>.<token>)
    return int(name) if name.isdigit() else None


def publish_view(rfs: RunFS, manifest: Manifest) -> bool:
    """Make ``individuals/`` and ``events/`` show exactly the files ``manifest`` names (a layout 2 run
    on a local filesystem); whether it did. Idempotent: a writer calls it after every commit point, and
    ``repair``/``resume`` after a crash left the view one commit behind."""
    if rfs.local_root is None or manifest.get("layout") != LAYOUT:
        return False
    root = rfs.local_root
    version = int(manifest["version"])
    rel = view_rel(version)
    folder = os.path.join(root, *rel.split("/"))
    if current_view(rfs) != version:
        if os.path.lexists(folder):   # a build a crash cut short: nobody points at it
            shutil.rmtree(folder, ignore_errors=True)
        _build(rfs, manifest, folder)
        _ensure_link(root, CURRENT, rel)
    for table in TABLES:
        _ensure_link(root, table, f"{CURRENT}/{table}")
    return True


def _target(rfs: RunFS) -> str | None:
    assert rfs.local_root is not None
    try:
        return os.readlink(os.path.join(rfs.local_root, CURRENT)).rstrip("/")
    except OSError:
        return None


def view_problems(rfs: RunFS, manifest: Manifest) -> list[str]:
    """What is wrong with the glob view of ``manifest`` (a layout 2 run on a local filesystem): it
    shows another commit, or a table's folder does not list exactly its files; empty when right."""
    if rfs.local_root is None or manifest.get("layout") != LAYOUT:
        return []
    version = int(manifest["version"])
    shown = current_view(rfs)
    copied = os.path.isdir(os.path.join(rfs.local_root, CURRENT)) and shown is None   # cp -r: no links
    if shown is not None and shown > version:
        return []   # the view of a newer commit: this is an older snapshot, not a problem
    if shown != version and not copied:
        seen = f"commit {shown}" if shown is not None else "no commit"
        return [f"{rfs.show(CURRENT)}: the glob view shows {seen}, the run is at commit {version} (a crash "
                "between a commit and its view); repair publishes it"]
    out = []
    for table in TABLES:
        folder = os.path.join(rfs.local_root, table)
        want = {e["path"].rsplit("/", 1)[-1]: e["path"] for e in manifest.get(table, [])}
        try:
            have = {n for n in os.listdir(folder) if not n.startswith(".")}
        except OSError:
            have = set()
        wrong = sorted(set(want) ^ have)
        wrong += sorted(n for n in set(want) & have if not _same(os.path.join(folder, n),
                                                                 os.path.join(rfs.local_root, want[n])))
        if wrong:   # (a copy of the run made with cp -r holds copies, not links: as right)
            out.append(f"{rfs.show(table)}/: the glob view is altered ({wrong[0]!r} is not commit "
                       f"{version}'s); repair rebuilds it")
    return out


def rebuild_view(rfs: RunFS, manifest: Manifest) -> None:
    """Publish ``manifest``'s view anew (the current one was altered), under a fresh folder name."""
    assert rfs.local_root is not None
    rel = f"{view_rel(int(manifest['version']))}.{secrets.token_hex(4)}"
    folder = os.path.join(rfs.local_root, *rel.split("/"))
    _build(rfs, manifest, folder)
    _ensure_link(rfs.local_root, CURRENT, rel)
    for table in TABLES:
        _ensure_link(rfs.local_root, table, f"{CURRENT}/{table}")


def _same(a: str, b: str) -> bool:
    """Whether ``a`` is the file ``b`` (a link to it, or a copy of its size)."""
    try:
        return os.path.samefile(a, b) or os.path.getsize(a) == os.path.getsize(b)
    except OSError:
        return False


def _build(rfs: RunFS, manifest: Manifest, folder: str) -> None:
    assert rfs.local_root is not None
    for table in TABLES:
        os.makedirs(os.path.join(folder, table))
        for entry in manifest.get(table, []):
            src = os.path.join(rfs.local_root, *entry["path"].split("/"))
            os.link(src, os.path.join(folder, table, entry["path"].rsplit("/", 1)[-1]))
        sync_folder(os.path.join(folder, table))
    sync_folder(folder)


def prune_views(rfs: RunFS, oldest_kept: int) -> None:
    """Remove the views of commits before ``oldest_kept`` (and half-built ones), never the current."""
    if rfs.local_root is None:
        return
    current = current_view(rfs)
    base = os.path.join(rfs.local_root, VIEWS)
    for name in rfs.listdir(VIEWS):
        number = int(name.split(".")[0]) if name.split(".")[0].isdigit() else -1
        if number == current and os.path.join(VIEWS, name) == _target(rfs):
            continue
        if number < oldest_kept:   # older than every kept manifest, or not a view's name at all
            shutil.rmtree(os.path.join(base, name), ignore_errors=True)


def clear_stale_links(rfs: RunFS) -> int:
    """Remove the temporary symlinks (and moved-aside folders) a crash left at the run's root while
    switching a view: those whose writer process is gone. How many."""
    import re

    if rfs.local_root is None:
        return 0
    removed = 0
    for name in os.listdir(rfs.local_root):
        names = "|".join((CURRENT, *TABLES))
        match = re.match(rf"^{re.escape(TMP_PREFIX)}(?:{names})-(\d+)-[0-9a-f]{{8}}", name)
        if not match or _alive(int(match.group(1))):
            continue
        _remove(os.path.join(rfs.local_root, name))
        removed += 1
    return removed


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _replace_symlink(root: str, name: str, target: str) -> None:
    """Point ``root/name`` at ``target`` in one rename (readers see the old target or the new)."""
    tmp = temp_beside(os.path.join(root, name))
    os.symlink(target, tmp)
    replace_atomically(tmp, os.path.join(root, name), durable=True)


def _ensure_link(root: str, name: str, target: str) -> None:
    """``root/name`` a symlink to ``target``. A real folder there (a run of layout 1 being upgraded,
    or a copy that followed the links) is swapped for the link in one step where the kernel can
    (``renameat2`` exchange, Linux), else moved aside first, then removed."""
    path = os.path.join(root, name)
    if os.path.islink(path):
        if os.readlink(path) != target:
            _replace_symlink(root, name, target)
        return
    if not os.path.lexists(path):
        _replace_symlink(root, name, target)
        return
    tmp = temp_beside(path)
    os.symlink(target, tmp)
    if not _exchange(tmp, path):
        os.rename(path, tmp + "-old")
        os.rename(tmp, path)
        tmp = tmp + "-old"
    sync_folder(root)
    _remove(tmp)


def _remove(path: str) -> None:
    """Remove ``path``, a real folder (with what it holds) or a file or link; gone already is fine."""
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _exchange(a: str, b: str) -> bool:
    """Swap the names ``a`` and ``b`` atomically (Linux ``renameat2(RENAME_EXCHANGE)``); whether it could."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    return int(renameat2(at_fdcwd, a.encode(), at_fdcwd, b.encode(), rename_exchange)) == 0
