"""Distributed runs: island hosts on Ray, migration, the epoch coordinator, interrupts and recovery.

``start_run`` / ``resume_run`` (what ``genr8 run`` / ``genr8 resume`` call) connect to Ray, start the
island hosts and drive the ``Coordinator``; ``apply_edit`` records an intervention (``genr8 edit``).
Ray is imported only when a run starts.
"""

from __future__ import annotations

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
