"""Whether a rewrite system can ever split a region: a static check, before any growth.

A region of a map L-system splits only where two branches join into an edge (journal 4.3, step 3:
nothing else adds an edge between vertices already on the surface). A branch is a segment written
inside brackets. So a system none of whose rules that can fire draws a segment inside brackets
grows the seed polygon into one region whatever the environment does: trivial (``phenotype``'s
``trivial``), known from the text alone. A rule can fire when its predecessor's label can occur on
the surface: a label of the axiom, or one a rule that can fire draws (on its main line or in a
branch, which becomes an edge when it joins); with label noise every label the system uses can
occur. Contexts, conditions, weights and timing are not read: they can only stop a rule from
firing, so the check never calls a system that splits a region trivial.

A system that draws branches may still never join two: ``can_join`` replays a growth's topology
(labels, ages and ends of the edges, no positions) and says whether any step can hold two branches
of one label at two vertices pointing into the seed polygon, the least a join needs. It follows
contexts and conditions exactly as growth reads them, so it too never calls a system that splits a
region trivial; ``screen`` uses it when given the environment's steps (``ea.screen = 2``).

A system may also be sure to waste its growth another way: its edges multiply so fast that every
growth of it passes ``max_work`` (``hemls.budget.least_work``) and is cut short, invalid; ``screen``
says so when given the cap (``ea.screen = 3``).

Two texts may differ and still grow one surface: in a rule that can never fire, in a turn pair
that cancels, in ``Sync`` where one group of rules draws every branch, in ``BranchAngle`` where no
rule draws one. ``growth_key`` names what growth reads of a text (the compiled system, its rules
that can fire), so equal keys mean bit-identical growth in every environment. A growth also says
which rules fired (``GrowthResult.fired``); ``copy_key`` then names what that growth read, so a
text that differs from the grown one only in what it did not read (the successors of a rule that
never fired, say) is known to grow the same surface before it is grown (``same_growth``: an
island does not grow such a child of a parent, ``evolution.island``).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Iterator
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from genr8_dist.hemls.budget import least_work
from genr8_dist.hemls.language import Branch, RewriteSystem, Segment, Symbol

__all__ = ["can_join", "can_split", "copy_key", "firing", "growth_key", "same_growth", "screen"]

#: The replay of a growth's topology (``can_join``) gives up past this many edges (it then says
#: "may join"): a text that stays one region past it is grown as before.
_REPLAY_EDGES = 2000


def _segments(symbols: tuple[Symbol, ...], inside: bool = False) -> Iterator[tuple[Segment, bool]]:
    """Every segment of ``symbols`` with whether it is inside brackets (a branch or part of one)."""
    for s in symbols:
        if isinstance(s, Segment):
            yield s, inside
        elif isinstance(s, Branch):
            yield from _segments(s.symbols, True)


def firing(system: RewriteSystem, *, label_noise: bool = False) -> tuple[tuple[bool, ...], bool]:
    """Which of ``system``'s rules can ever rewrite an edge, and whether one of those draws a branch.

    A rule can fire when its predecessor's label, its contexts' and its chain's can all occur and no
    earlier rule takes every edge it would (``RewriteSystem.never_firing``). The labels that can
    occur, to a fixed point: the axiom's (with ``label_noise``, every label the system uses), then
    every label a rule that can fire draws, on its main line or in a branch."""
    live = set(system.segment_names()) if label_noise else {e.segment.name for e in system.axiom}
    shadowed = {id(rule) for rule, _ in system.never_firing()}
    fires = [False] * len(system.rules)
    branches = False
    grew = True
    while grew:
        grew = False
        for i, rule in enumerate(system.rules):
            needed = (rule.predecessor, rule.left, rule.right, *rule.chain)
            if fires[i] or id(rule) in shadowed or any(s is not None and s.name not in live for s in needed):
                continue
            fires[i] = grew = True
            for successor in rule.successors:
                for segment, branch in _segments(successor.symbols):
                    branches = branches or branch
                    live.add(segment.name)
    return tuple(fires), branches


def can_split(system: RewriteSystem, *, label_noise: bool = False) -> bool:
    """Whether growing ``system`` may ever join two branches, so split a region (``False``: every
    growth of it, in any environment, is a surface of one region). ``label_noise``: the
    environment swaps labels (every label the system uses may then occur)."""
    return firing(system, label_noise=label_noise)[1]


def _context_ok(ev: list[tuple[int, int]], labels: list[int], at: dict[int, dict[int, int]], e: int,
                end: int, label: int) -> bool:
    """``growth._context_ok`` for one edge: another edge at its start (0) or end (1) has ``label``."""
    return at.get(ev[e][end], {}).get(label, 0) - (labels[e] == label) > 0


def _chain_ok(ev: list[tuple[int, int]], labels: list[int], live: list[int], e: int,
              chain: tuple[int, ...]) -> bool:
    """``growth._chain_ok`` for one edge: a path of edges labelled ``chain`` continues from its end."""
    rest: set[int] | None = None   # where the rest of the chain can start (None: anywhere)
    for lab in reversed(chain[1:]):
        mask = set()
        for f in live:
            if labels[f] == lab:
                p, q = ev[f]
                if rest is None or q in rest:
                    mask.add(p)
                if rest is None or p in rest:
                    mask.add(q)
        rest = mask
    lab, v = chain[0], ev[e][1]
    count = 0
    for f in live:
        if labels[f] == lab:
            p, q = ev[f]
            count += (p == v and (rest is None or q in rest)) + (q == v and (rest is None or p in rest))
    own = labels[e] == lab and (rest is None or ev[e][0] in rest)
    return count - own > 0


def can_join(system: RewriteSystem, steps: int) -> bool:
    """Whether ``steps`` derivation steps of ``system`` (no label noise) may hold two pending
    branches of one label at two vertices, both pointing into the seed polygon: the least a join
    needs (branches join only with a branch of their own label at another vertex, drawn in the same
    step, pointing into the same region and never the outside: ``hemls.joining``; unjoined ones are
    dropped when the step ends). ``False``: every growth of it stays one region, in any environment.

    Until the first join the map's topology does not depend on the geometry: the seed polygon's
    edges are rewritten group by group as growth does it (``growth._rewrite_group``: the first rule
    whose condition on the edge's age, contexts and chain hold at the group's start, then the
    successor's main line in place of the edge), so this replays it on the labels, ages and ends of
    the edges alone, with no positions, and collects each step's branches that point into the
    polygon (each edge keeps which of its halves lies in it: an axiom edge the half along it unless
    reversed, a successor's segment its rewritten edge's, the other where the segment is reversed;
    a branch on the left of its main line points into the region of the edge's first half, one on
    the right into the other's, one at an end into either, one along the main line or the normal
    never joins). It answers ``True`` (may join) where the replay cannot follow growth: a rule with
    weighted successors (growth draws one at random), a successor with no main line, a seed of one
    edge, or more than ``_REPLAY_EDGES`` edges. Integers only: the same answer on every machine."""
    from genr8_dist.hemls.rules import compile_system
    from genr8_dist.hemls.turtle import AT_END, LEFT, NO_SIDE, RIGHT

    c = compile_system(system)
    n = len(c.axiom_labels)
    if n < 2:
        return True
    ev = [((k + 1) % n, k) if rev else (k, (k + 1) % n) for k, rev in enumerate(c.axiom_reversed.tolist())]
    labels = c.axiom_labels.tolist()
    ages = [0] * n
    inner = [int(rev) for rev in c.axiom_reversed.tolist()]   # which half of each edge is inside
    live = list(range(n))
    nv = n
    for _ in range(steps):
        pending: dict[int, set[int]] = {}   # label -> the vertices its inward branches start at
        for group in c.groups:
            idx = [e for e in live if labels[e] == group.label]
            if not idx:
                continue
            at: dict[int, dict[int, int]] = {}   # vertex -> label -> edge ends there (group start)
            for f in live:
                for v in ev[f]:
                    here = at.setdefault(v, {})
                    here[labels[f]] = here.get(labels[f], 0) + 1
            chosen = []
            for e in idx:
                for rule in group.rules:
                    if rule.condition is not None and not rule.condition.holds(ages[e]):  # type: ignore[attr-defined]
                        continue
                    if rule.left is not None and not _context_ok(ev, labels, at, e, 0, rule.left):
                        continue
                    if rule.right is not None and not _context_ok(ev, labels, at, e, 1, rule.right):
                        continue
                    if rule.chain and not _chain_ok(ev, labels, live, e, rule.chain):
                        continue
                    if len(rule.templates) != 1:
                        return True   # growth draws the successor: the replay cannot follow
                    chosen.append((e, rule.templates[0]))
                    break
            gone = set()
            for e, tpl in chosen:
                k = tpl.n_segments
                if k == 0:
                    return True
                s, t = ev[e]
                chain = [s, *range(nv, nv + k - 1), t]
                nv += k - 1
                for i, (label, age, timed, rev) in enumerate(zip(
                        tpl.main_labels.tolist(), tpl.main_ages.tolist(), tpl.main_timed.tolist(),
                        tpl.main_reversed.tolist(), strict=True)):
                    a, b = chain[i], chain[i + 1]
                    ev.append((b, a) if rev else (a, b))
                    labels.append(label)
                    ages.append(max(ages[e] + age if timed else age, 0))
                    inner.append(inner[e] ^ int(rev))
                    live.append(len(ev) - 1)
                into = {AT_END, LEFT if inner[e] == 0 else RIGHT}
                for label, vertex, side in zip(tpl.branch_labels.tolist(), tpl.branch_vertex.tolist(),
                                               tpl.branch_side.tolist(), strict=True):
                    if side != NO_SIDE and side in into:
                        starts = pending.setdefault(label, set())
                        starts.add(chain[vertex])
                        if len(starts) > 1:
                            return True
                gone.add(e)
            live = [e for e in live if e not in gone]
            if len(live) > _REPLAY_EDGES:
                return True
    return False


def growth_key(system: RewriteSystem, fires: tuple[bool, ...]) -> str:
    """What growth reads of ``system`` (no label noise), as a hex digest: equal keys, bit-identical
    growth in any environment. ``fires``: which rules can fire (``firing``).

    Growth reads the compiled system (``hemls.rules``): the axiom's labels and directions; the rule
    groups in order, each rule's contexts, chain, condition, weights and drawn templates (the
    turtle's points and headings as floats, so ``+ -`` and ``\\ /`` count as nothing exactly when
    they draw nothing); the join cone; ``Sync``. A rule that cannot fire is never read, nor is a
    group with none; ``Sync`` only where a group that can fire comes after the first one drawing
    a branch (else branches join after that group either way: later joins find none new); the cone
    only where a rule draws a branch. Label ids are kept as drawn, so two texts that name one label
    differently differ."""
    from genr8_dist.hemls.rules import compile_system

    c = compile_system(system)
    h = hashlib.blake2b(digest_size=16)

    def put(*parts: object) -> None:
        for part in parts:
            h.update(part.tobytes() if isinstance(part, np.ndarray) else repr(part).encode())
            h.update(b"|")

    put("axiom", c.axiom_labels, c.axiom_reversed)
    drawing = []   # per group read: whether a rule of it draws a branch
    for group in c.groups:
        rules = [rule for rule in group.rules if fires[rule.index]]
        if not rules:
            continue
        put("group", group.label)
        for rule in rules:
            put("rule", rule.left, rule.right, rule.chain, str(rule.condition), rule.cumulative, rule.drawn)
        drawing.append(any(len(t.branch_labels) for rule in rules for t in rule.templates))
    if any(drawing):
        put("cone", c.cos_cone, "sync", c.sync and drawing.index(True) < len(drawing) - 1)
    return h.hexdigest()


class _Read(NamedTuple):
    """A text as ``same_growth`` compares it: its system, its shape (labels, and every rule's
    predecessor, contexts, chain and condition, in order) and its ``growth_key`` over the rules that
    can fire."""

    system: RewriteSystem
    shape: str
    key: str


@lru_cache(maxsize=8192)
def _read(text: str) -> _Read | None:
    """``text`` as ``same_growth`` compares it, once per text (``None``: it does not parse)."""
    from genr8_dist.hemls.language import parse

    try:
        system = parse(text)
    except Exception:   # a failure growth reports with its stage
        return None
    shape = repr((sorted(system.label_ids().items()),
                  [(r.predecessor.name, str(r.left), str(r.right), [str(c) for c in r.chain],
                    str(r.condition)) for r in system.rules]))
    return _Read(system, shape, growth_key(system, firing(system)[0]))


@lru_cache(maxsize=8192)
def copy_key(text: str, reads: str) -> str | None:
    """The key of ``text`` as a growth that fired only the rules marked ``1`` in ``reads`` (one
    character per rule, ``GrowthResult.fired``) read it: equal for the text that growth grew and for
    any other with the same axiom, labels and predecessors, contexts and conditions rule by rule, and
    the same ``growth_key`` over the fired rules. Such a text grows the same surface bit for bit:
    derivation step by step, every edge is taken by the same rule (the choice reads only what is
    equal), and only fired rules' successors are drawn. ``None``: the text does not parse or has
    another number of rules."""
    read = _read(text)
    if read is None or len(read.system.rules) != len(reads):
        return None
    fired = tuple(mark == "1" for mark in reads)
    blob = "\n".join((read.shape, reads, growth_key(read.system, fired)))
    return hashlib.blake2b(blob.encode(), digest_size=16).hexdigest()


def same_growth(text: str, other: str, reads: str | None = None) -> bool:
    """Whether ``text`` grows the surface ``other`` grows, bit for bit, in any environment without
    label noise, known without growing it: their ``growth_key`` is one, or (``reads``: which rules
    fired in ``other``'s growth) their ``copy_key`` under those reads. ``False`` says only that
    neither shows it. Each text is read once (``_read``); a growth key under ``reads`` is computed
    only for texts of one shape."""
    mine, theirs = _read(text), _read(other)
    if mine is None or theirs is None:
        return False
    if mine.key == theirs.key:
        return True
    if reads is None or mine.shape != theirs.shape:
        return False
    key = copy_key(text, reads)
    return key is not None and key == copy_key(other, reads)


@lru_cache(maxsize=8192)
def screen(text: str, label_noise: bool = False, steps: int | None = None,
           max_work: int = 0) -> tuple[bool, str]:
    """What the text of a rewrite system shows before growth: (whether its growth is wasted for
    sure: no region can split, so it grows one region; its *effective* text: the system without the
    rules that can never fire). Two texts with one effective text grow the same surface (growth
    reads only the rules that fire, and its random draws are made by them), so one is a copy of the
    other. A text that does not parse is neither (growth fails it, as data): ``(False, text)``.
    ``steps``: the environment's derivation steps; given (screen version 2, ``ea.screen``), a text
    is also wasted when no step can hold two branches of one label at two vertices (``can_join``);
    with ``max_work`` too (screen version 3; 0: no cap), when every growth of it spends more than
    that (``least_work``), so the cap cuts it short."""
    from genr8_dist.hemls.language import parse

    try:
        system = parse(text)
    except Exception:   # a failure growth reports with its stage
        return False, text
    fires, branches = firing(system, label_noise=label_noise)
    if label_noise:   # the noise draws from every label the system uses: all of it matters
        return not branches, text
    wasted = not branches
    if not wasted and steps is not None:
        wasted = not can_join(system, steps) or (bool(max_work) and least_work(system, steps) > max_work)
    rules = tuple(rule for rule, f in zip(system.rules, fires, strict=True) if f)
    effective = dataclasses.replace(system, rules=rules).to_text()
    names = system.label_ids()
    if any(not n.startswith("Edge") for n in names):   # letters are numbered after every EdgeN
        effective += f"# labels {sorted(names.items())}\n"
    return wasted, effective
