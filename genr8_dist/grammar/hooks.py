"""Universe hooks: Python code a universe runs after its main derivation.

The one hook today is **repair** (thesis 3.2.1, journal 5.1): every edge label that occurs in the
rewrite system without a rewrite rule of its own gets one. A universe turns on the built-in HEMLS
repair with the directive ``//@ repair RULE`` (RULE is the successor rule to expand); a plugin may
replace it by defining ``repair(ctx)`` in its ``hooks.py`` (see ``grammars/README.md``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["RepairContext", "add_rules", "hemls_repair", "predecessor_label", "rule_predecessors"]


@dataclass
class RepairContext:
    """What a repair hook sees and may change.

    ``text``: the rewrite system (one statement per line, ending in a line break); a hook replaces it
    by assigning ``ctx.text``. ``expand()``: the repair rule expanded from the next codons, as a list
    of tokens, never creating a label. ``occurring``: the labels that occur in the text;
    ``has_rule``: the labels that are the predecessor of some rule; ``label_of(token)``: the label of
    an edge token (``None`` for other tokens); ``edge(label)``: a plain predecessor edge's token;
    ``count``: the number of labels (``0 .. count-1``); ``labels_in(tokens)``: the set of labels
    of the edge tokens among ``tokens``.
    """

    text: str
    expand: Callable[[], list[str]]
    occurring: set[int]
    has_rule: set[int]
    label_of: Callable[[str], int | None]
    edge: Callable[[int], str]
    count: int
    labels_in: Callable[[list[str]], set[int]]


def rule_predecessors(text: str, label_of: Callable[[str], int | None]) -> set[int]:
    """Labels that are the predecessor of a rule in ``text``.

    A rule is a line holding ``->``; its predecessor is the edge after ``<`` when there is a left
    context, otherwise the line's first edge (``A > B ->`` and ``A B ->`` rewrite ``A``).
    """
    labels = (predecessor_label(line, label_of) for line in text.splitlines())
    return {label for label in labels if label is not None}


def predecessor_label(line: str, label_of: Callable[[str], int | None]) -> int | None:
    """The label a rule line rewrites (the edge after ``<``, else the first edge); None if no rule."""
    if "->" not in line:
        return None
    pred = line.split("->", 1)[0]
    if "<" in pred:
        pred = pred.split("<", 1)[1]
    words = pred.split()
    return label_of(words[0]) if words else None


def hemls_repair(ctx: RepairContext) -> None:
    """Give every label that occurs without a rewrite rule a rule ``EdgeL -> <expanded successor>``.

    Labels are repaired smallest first; a repaired rule's successor may mention a label that still
    lacks a rule, which is then repaired too. The new rules go after the last rewrite rule.
    """
    text = ctx.text
    arrow = text.rfind("->")
    if arrow < 0:
        return
    end = text.find("\n", arrow)
    add_rules(ctx, set(ctx.has_rule), len(text) if end < 0 else end + 1)


def add_rules(ctx: RepairContext, has: set[int], end: int) -> None:
    """Insert at character ``end`` of ``ctx.text`` a rule ``EdgeL -> <expanded successor>`` for every
    occurring label L not in ``has``, smallest first; labels a new successor mentions are repaired too."""
    occurring = set(ctx.occurring)
    missing = occurring - has
    if not missing:
        return
    new: list[str] = []
    while missing:
        label = min(missing)
        successor = ctx.expand()
        new.append(" ".join([ctx.edge(label), "->", *successor]))
        has.add(label)
        occurring |= ctx.labels_in(successor)
        missing = occurring - has
    ctx.text = ctx.text[:end] + "\n".join(new) + "\n" + ctx.text[end:]
