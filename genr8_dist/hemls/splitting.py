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
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from functools import lru_cache

from genr8_dist.hemls.language import Branch, RewriteSystem, Segment, Symbol

__all__ = ["can_split", "firing", "screen"]


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


@lru_cache(maxsize=8192)
def screen(text: str, label_noise: bool = False) -> tuple[bool, str]:
    """What the text of a rewrite system shows before growth: (whether it is trivial: no region can
    split, so it grows one region; its *effective* text: the system without the rules that can
    never fire). Two texts with one effective text grow the same surface (growth reads only the
    rules that fire, and its random draws are made by them), so one is a copy of the other. A text
    that does not parse is neither (growth fails it, as data): ``(False, text)``."""
    from genr8_dist.hemls.language import parse

    try:
        system = parse(text)
    except Exception:   # a failure growth reports with its stage
        return False, text
    fires, branches = firing(system, label_noise=label_noise)
    if label_noise:   # the noise draws from every label the system uses: all of it matters
        return not branches, text
    rules = tuple(rule for rule, f in zip(system.rules, fires, strict=True) if f)
    effective = dataclasses.replace(system, rules=rules).to_text()
    names = system.label_ids()
    if any(not n.startswith("Edge") for n in names):   # letters are numbered after every EdgeN
        effective += f"# labels {sorted(names.items())}\n"
    return not branches, effective
