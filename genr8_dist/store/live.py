"""The live view of a running run: each island's generation as it completes, before its commit.

The coordinator commits an epoch at once (``distributed/coordinator.py``); the studio would otherwise
see nothing until the first epoch's commit, minutes into a run. So each island's host writes every
completed generation here (``live/<generation>-<island>.json``, written atomically but not fsynced:
plain JSON rows as the studio's generation view lists them, with each design's rewrite system), and
the driver deletes them once they are committed or the run ends. Nothing here is durable or part of
the run: a reader marks what it shows from here as not yet committed, and the run store never reads
it (``verify`` and garbage collection leave the folder to its writer). Local run directories only;
elsewhere nothing is written.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from genr8_dist.store._fs import RunFS

if TYPE_CHECKING:
    from genr8_dist.evolution.individual import Individual

__all__ = ["LIVE_DIR", "LiveView", "clear", "drop_committed", "live_row", "read", "write_generation"]

LIVE_DIR = "live"
_NAME = re.compile(r"^(\d+)-(\d+)\.json$")


def _finite(value: float | None) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def live_row(ind: Individual) -> dict[str, Any]:
    """An individual as the studio lists it (its criteria and sizes by column name, its text)."""
    from genr8_dist.store.schema import criterion_column, size_column

    return {"id": ind.id, "island": int(ind.island), "generation": int(ind.generation),
            "index": int(ind.index), "fitness": _finite(ind.fitness), "valid": bool(ind.valid),
            "origin": ind.origin, "parents": list(ind.parents), "config_version": int(ind.config_version),
            "text": ind.text, "phenotype_digest": ind.phenotype_digest, "stage": ind.stage,
            "error": ind.error, "steps_done": int(ind.steps_done),
            **{criterion_column(k): _finite(v) for k, v in ind.criteria.items()},
            **{size_column(k): int(v) for k, v in ind.sizes.items()}}


def write_generation(rfs: RunFS, island: int, generation: int, population: Sequence[Individual]) -> None:
    """Island ``island``'s completed ``generation``, for readers of the live view."""
    if rfs.local_root is None:
        return
    rfs.makedirs(LIVE_DIR)
    data = json.dumps([live_row(ind) for ind in population]).encode()
    rfs.write_atomic(f"{LIVE_DIR}/{generation}-{island}.json", data, durable=False)


def read(rfs: RunFS) -> dict[int, dict[int, list[dict[str, Any]]]]:
    """generation -> island -> rows, of what the running run has completed and not committed (a file
    deleted or torn meanwhile is skipped)."""
    out: dict[int, dict[int, list[dict[str, Any]]]] = {}
    if rfs.local_root is None:
        return out
    for name in rfs.listdir(LIVE_DIR):
        match = _NAME.match(name)
        if not match:
            continue
        try:
            rows = json.loads(rfs.read_bytes(f"{LIVE_DIR}/{name}").decode())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        if isinstance(rows, list):
            out.setdefault(int(match.group(1)), {})[int(match.group(2))] = rows
    return out


def drop_committed(rfs: RunFS, committed: Mapping[int, int]) -> None:
    """Delete the live files of generations now committed (island -> its last committed one)."""
    if rfs.local_root is None:
        return
    for name in rfs.listdir(LIVE_DIR):
        match = _NAME.match(name)
        if match and int(match.group(1)) <= committed.get(int(match.group(2)), -1):
            with contextlib.suppress(OSError):
                rfs.delete(f"{LIVE_DIR}/{name}")


def clear(rfs: RunFS) -> None:
    """Delete the live view (the run has ended: what was not committed is not the run's)."""
    if rfs.local_root is None:
        return
    for name in rfs.listdir(LIVE_DIR):
        with contextlib.suppress(OSError):
            rfs.delete(f"{LIVE_DIR}/{name}")
    with contextlib.suppress(OSError):
        import os

        os.rmdir(rfs.full(LIVE_DIR))


class LiveView:
    """The functions above bound to one run directory (``RunStore.live()``)."""

    def __init__(self, rfs: RunFS) -> None:
        self._rfs = rfs

    def write(self, island: int, generation: int, population: Sequence[Individual]) -> None:
        write_generation(self._rfs, island, generation, population)

    def read(self) -> dict[int, dict[int, list[dict[str, Any]]]]:
        return read(self._rfs)

    def drop_committed(self, committed: Mapping[int, int]) -> None:
        drop_committed(self._rfs, committed)

    def clear(self) -> None:
        clear(self._rfs)
