"""What ``RunStore.verify`` checks in ``_manifest/`` beyond each manifest's own bytes.

A writer prunes the oldest manifests first (``KEEP_MANIFESTS`` are kept), so the manifests of a run
are always a contiguous run of numbers up to the newest: a number missing in between was deleted by
someone else. ``HEAD`` is always written whole as ``N\\n`` (atomically), so a ``HEAD`` that is not
digits and a newline is torn or altered, even when what is left still reads as a number. Garbage
collection after ``repair`` removes the manifests below a gap (older snapshots, no longer whole),
which mends it.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from genr8_dist.store._fs import RunFS

__all__ = ["below_gap", "describe_missing", "head_damaged", "missing_manifests"]

_HEAD_BYTES = re.compile(rb"^[0-9]{1,10}\n$")


def head_damaged(rfs: RunFS, head: str) -> bool:
    """Whether the file ``head`` exists and is not what a writer writes (``N\\n``)."""
    if rfs.kind(head) != "file":
        return False
    try:
        data = rfs.read_bytes(head)
    except OSError:
        return True
    return _HEAD_BYTES.match(data) is None


def missing_manifests(listed: list[int], newest: int) -> list[int]:
    """The numbers between the oldest listed manifest and ``newest`` that have no manifest."""
    present = {v for v in listed if v <= newest}
    if not present:
        return []
    return [v for v in range(min(present), newest + 1) if v not in present]


def below_gap(listed: list[int], newest: int) -> list[int]:
    """The listed manifests older than the newest missing one (what garbage collection removes)."""
    gaps = missing_manifests(listed, newest)
    return [v for v in listed if gaps and v < gaps[-1]]


def describe_missing(versions: list[int], show: Callable[[int], str]) -> list[str]:
    """One problem line per missing manifest (``show(v)``: its path as the user sees it)."""
    return [f"{show(v)}: an older manifest is missing (deleted by hand?); repair drops the snapshots "
            "older than it" for v in versions]
