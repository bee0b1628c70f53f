"""Distributed runs: island hosts on Ray, migration, the epoch coordinator, interrupts and recovery.

``start_run`` / ``resume_run`` (what ``genr8 run`` / ``genr8 resume`` call) connect to Ray, start the
island hosts and drive the ``Coordinator``; ``apply_edit`` records an intervention (``genr8 edit``).
Ray is imported only when a run starts.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from genr8_dist.distributed.coordinator import Coordinator, RunSummary, StopRequest
    from genr8_dist.distributed.intervene import Edit, EditResult, apply_edit
    from genr8_dist.distributed.migration import (
        TOPOLOGIES,
        destinations,
        is_migration_generation,
        plan_migration,
        select_emigrants,
    )
    from genr8_dist.distributed.progress import ProgressDisplay
    from genr8_dist.distributed.session import RunOptions, connect_ray, resume_run, start_run

# Where each name lives: imported on first use, so that ``genr8 run`` can start Ray before the
# coordinator and its dependencies are imported (session.connect_ray imports them meanwhile).
_HOMES = {
    "Coordinator": "coordinator", "RunSummary": "coordinator", "StopRequest": "coordinator",
    "Edit": "intervene", "EditResult": "intervene", "apply_edit": "intervene",
    "TOPOLOGIES": "migration", "destinations": "migration", "is_migration_generation": "migration",
    "plan_migration": "migration", "select_emigrants": "migration",
    "ProgressDisplay": "progress",
    "RunOptions": "session", "connect_ray": "session", "resume_run": "session", "start_run": "session",
}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"genr8_dist.distributed.{home}"), name)


__all__ = [
    "TOPOLOGIES",
    "Coordinator",
    "Edit",
    "EditResult",
    "ProgressDisplay",
    "RunOptions",
    "RunSummary",
    "StopRequest",
    "apply_edit",
    "connect_ray",
    "destinations",
    "is_migration_generation",
    "plan_migration",
    "resume_run",
    "select_emigrants",
    "start_run",
]
