"""Files in a run directory that the store did not write: set aside, never deleted.

Garbage collection (``RunStore.collect_garbage``, run by ``resume``, ``edit``'s commits and
``repair``) deletes the store's own files that no kept manifest names: what a crashed writer left.
Every file the store writes is named ``stem-<16 hex digits><suffix>`` (``RunStore.write_file``) or is
a temporary (``.tmp-``); anything else under ``configs/``, ``individuals/``, ``events/`` or a plugin's
folder (a note, a copy a user dropped there) is the user's, so it is moved to ``_foreign/<folder>/``
instead, and the command says so in one line (:func:`describe`).
"""

from __future__ import annotations

import re

from genr8_dist.store._fs import RunFS

__all__ = ["FOREIGN_DIR", "describe", "is_store_name", "set_aside"]

FOREIGN_DIR = "_foreign"
_STORE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*-[0-9a-f]{16}\.[A-Za-z0-9]+$")


def is_store_name(name: str) -> bool:
    """Whether ``name`` is one the store gives its own files (``stem-<16 hex><suffix>``)."""
    return _STORE_NAME.match(name) is not None


def set_aside(rfs: RunFS, rel: str) -> str:
    """Move ``rel`` (``folder/name``) to ``_foreign/folder/name`` (``name.1``, ``name.2``... when that
    is taken) and return where it went; the copy is written before the original is deleted."""
    data = rfs.read_bytes(rel)
    folder, _, name = rel.rpartition("/")
    rfs.makedirs(f"{FOREIGN_DIR}/{folder}")
    target = f"{FOREIGN_DIR}/{folder}/{name}"
    for n in range(1, 10_000):
        try:
            rfs.write_exclusive(target, data)
            break
        except FileExistsError:
            target = f"{FOREIGN_DIR}/{folder}/{name}.{n}"
    rfs.delete(rel)
    return target


def describe(moves: list[tuple[str, str]], where: str) -> str:
    """One line naming the files set aside (``(from, to)`` pairs) in the run ``where``."""
    shown = ", ".join(src for src, _ in moves[:3]) + (f" and {len(moves) - 3} more" if len(moves) > 3 else "")
    return (f"{where}: set aside {len(moves)} file(s) the run did not write ({shown}) in "
            f"{where.rstrip('/')}/{FOREIGN_DIR}/")
