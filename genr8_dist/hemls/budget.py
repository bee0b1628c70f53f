"""The caps that stop a growth early: edges (``max_edges``), work (``max_work``), time (``max_seconds``).

Work is counted in edge-steps, a count that is the same on every machine: every edge alive when a
derivation step starts and every edge rewriting makes counts one; each successor placed on a batch
of edges counts ``WORK_BATCH`` more; ``WORK_PAIRS`` branch pairs tested for joining count one.
"""

from __future__ import annotations

import time

__all__ = ["WORK_BATCH", "WORK_PAIRS", "Budget", "Capped"]

#: Branch pairs tested for joining that count as one edge-step of work (the ``max_work`` cap):
#: testing a pair costs about a fortieth of carrying an edge through a derivation step.
WORK_PAIRS = 40
#: Edge-steps one successor's placement on a batch of edges counts for besides its edges (the fixed
#: cost of a pass over the arrays, which dominates on small maps).
WORK_BATCH = 64


class Capped(Exception):
    """Growth reached a cap: ``what`` is ``"edges"``, ``"work"`` or ``"time"``."""

    def __init__(self, what: str) -> None:
        super().__init__(what)
        self.what = what


class Budget:
    """What one growth may still spend; ``spend`` and ``check_time`` raise ``Capped`` past a cap."""

    def __init__(self, max_edges: int, max_work: int, deadline: float) -> None:
        self.max_edges = max_edges
        self.max_work = max_work   # 0: no work cap
        self.deadline = deadline   # a ``time.perf_counter()`` value
        self.work = 0      # edge-steps: the edges alive at the start of each step, and those it makes
        self.pairs = 0     # branch pairs tested and re-tested for joining

    @property
    def spent(self) -> int:
        """The work done so far in edge-steps (see the module docstring)."""
        return self.work + self.pairs // WORK_PAIRS

    def spend(self, edges: int = 0, pairs: int = 0) -> None:
        """Count work; past ``max_work`` growth stops."""
        self.work += edges
        self.pairs += pairs
        if self.max_work and self.spent > self.max_work:
            raise Capped("work")

    def check_time(self) -> None:
        """Past the deadline growth stops (the one cap that depends on the machine)."""
        if time.perf_counter() > self.deadline:
            raise Capped("time")

    def room(self, alive: int) -> int:
        """Edges that may still be added to a map of ``alive`` edges."""
        return self.max_edges - alive
