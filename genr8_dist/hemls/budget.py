"""The caps that stop a growth early: edges (``max_edges``), work (``max_work``), time (``max_seconds``).

Work is counted in edge-steps, a count that is the same on every machine: every edge alive when a
derivation step starts and every edge rewriting adds (a successor of k segments in place of one
edge adds k - 1) counts one; each successor placed on a batch of edges counts ``WORK_BATCH`` more;
``WORK_PAIRS`` branch pairs tested for joining count one.
``least_work`` reads from a rewrite system's text the least work any growth of it spends, so that a
system sure to pass ``max_work`` is known before it is grown (``hemls.splitting.screen``).
"""

from __future__ import annotations

import time
from functools import cache

from genr8_dist.hemls.language import RewriteSystem

__all__ = ["WORK_BATCH", "WORK_PAIRS", "Budget", "Capped", "least_work"]

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


def least_work(system: RewriteSystem, steps: int) -> int:
    """The least work (edge-steps, as ``Budget`` counts it) that ``steps`` derivation steps of
    ``system`` spend in any environment without label noise: a growth of it spends at least this
    much, or is cut short by a cap first.

    Rewriting depends on the geometry only through joins, and joins only add edges, so a lower bound
    follows each edge of the seed through the steps on its label and age alone. Each step an edge is
    alive at the start of counts one; the rule groups rewrite in turn, an edge made by a group also
    taken by a later group of the same step (``growth._rewrite_group``). An edge's age (set when it
    is made, never counted up) decides each rule's condition exactly; a context or a chain may hold
    or not, so a rule with one may take the edge (a main line of ``k`` segments in its place,
    costing ``k - 1``, its edges then followed on) or leave it to the next rule, and past the last
    rule the edge may stay as it is; a rule of several successors may place any of them. The least
    over those choices, summed over the seed's edges, is the bound; joined edges, batches and join
    tests only add to it. Integers only: the same answer on every machine."""
    from genr8_dist.hemls.rules import compile_system

    c = compile_system(system)
    groups = c.groups
    position = {g.label: i for i, g in enumerate(groups)}

    @cache
    def choices(group: int, age: int) -> tuple[tuple[int, tuple[tuple[int, int], ...]] | None, ...]:
        """What group ``group`` may do with an edge of ``age``: (cost, the edges made: label and age)
        for each successor a rule may place, ``None`` where the edge may be left as it is."""
        out: list[tuple[int, tuple[tuple[int, int], ...]] | None] = []
        for rule in groups[group].rules:
            if rule.condition is not None and not rule.condition.holds(age):  # type: ignore[attr-defined]
                continue
            for tpl in rule.templates:
                segments = zip(tpl.main_labels.tolist(), tpl.main_ages.tolist(), tpl.main_timed.tolist(),
                               strict=True)
                made = tuple((label, max(age + a if timed else a, 0)) for label, a, timed in segments)
                out.append((tpl.n_segments - 1, made))
            if rule.left is None and rule.right is None and not rule.chain:
                return tuple(out)   # this rule takes every edge the earlier ones leave
        out.append(None)
        return tuple(out)

    @cache
    def least(step: int, group: int, label: int, age: int) -> int:
        """The least work an edge of ``label`` and ``age`` adds from group ``group`` of ``step`` on."""
        if step >= steps:
            return 0
        alive = 1 if group == 0 else 0   # counted when its step starts
        at = position.get(label)
        if at is None or at < group:   # no group of its label left in this step
            return alive + least(step + 1, 0, label, age)
        return alive + min(
            least(step + 1, 0, label, age) if choice is None else
            choice[0] + sum(least(step, at + 1, lab, a) for lab, a in choice[1])
            for choice in choices(at, age))

    return sum(least(0, 0, int(label), 0) for label in c.axiom_labels.tolist())
