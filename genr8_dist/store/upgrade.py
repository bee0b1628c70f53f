"""Converting a run of layout 1 (data files in ``individuals/`` and ``events/``) to layout 2 in place.

``genr8 repair --upgrade`` and the first ``genr8 resume`` do it. One commit, like any other:

1. every individuals and events file the newest manifest names is hard-linked (copied, on a filesystem
   without links) to ``_files/<folder>/<name>``, the same bytes under the name layout 2 keeps them;
2. manifest ``N+1`` is published: the same run, its paths in ``_files/``, ``"layout": 2`` (the commit
   point: from here the store reads ``_files/``);
3. the glob view of commit ``N+1`` is published, and the real folders ``individuals/`` and ``events/``
   are swapped for their symlinks into it (in one step on Linux: ``renameat2`` exchange).

A crash before 2 leaves the old layout (the new links are garbage, collected by the next writer); after
2 the old folders still hold exactly the files of the commit (an upgrade changes no row), so a glob
reads the same rows through either layout, and the next writer finishes step 3. Rows, ids, events and
configurations are unchanged; the manifest records when the run was upgraded.
"""

from __future__ import annotations

import contextlib
import copy
import os
from typing import TYPE_CHECKING

from genr8_dist.store import views

if TYPE_CHECKING:
    from genr8_dist.store.transactions import Transactions

__all__ = ["upgrade"]


def upgrade(store: Transactions) -> bool:
    """Convert ``store``'s run to layout 2 in one commit (a run already there: finish its glob view,
    in case a crash cut it short). Whether a conversion was committed."""
    rfs = store._fs
    if store.manifest_layout == views.LAYOUT:
        with contextlib.suppress(OSError):
            views.publish_view(rfs, store._m)
        return False
    store._require_current()
    with store._transaction():
        version = store._next_version()
        manifest = copy.deepcopy(store._m)
        for table in views.TABLES:
            rfs.makedirs(f"{views.FILES}/{table}")
            for entry in manifest[table]:
                old = entry["path"]
                new = f"{views.FILES}/{table}/{old.rsplit('/', 1)[-1]}"
                store._pending.append(new)
                _link(store, old, new)
                entry["path"] = new
        manifest["layout"] = views.LAYOUT
        manifest["upgraded"] = {"from_layout": 1, "at_commit": version}
        store._publish(manifest, version)
    return True


def _link(store: Transactions, old: str, new: str) -> None:
    """``new`` the same file as ``old`` (a hard link; a copy where links are not possible)."""
    rfs = store._fs
    if rfs.kind(new) == "file":   # left by an upgrade a crash cut short
        rfs.delete(new)
    if rfs.local_root is not None:
        try:
            os.link(rfs._local(old), rfs._local(new))
            return
        except OSError:
            pass
    rfs.fs.copy_file(rfs.full(old), rfs.full(new))
