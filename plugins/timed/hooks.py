"""Hooks of the ``timed`` plugin universe: a repair that knows about conditions.

A rule with a condition (``... If i < 2``) stops applying once its edges are old enough, so a label
whose only rules are conditioned would freeze. This repair gives every label that occurs without an
*unconditioned* rule one more rule, ``EdgeL_i -> <successor>``, expanded from the next codons with
no new labels (the built-in HEMLS repair counts conditioned rules too).
"""

from __future__ import annotations

from genr8_dist.grammar.hooks import RepairContext, add_rules, predecessor_label


def _unconditioned(text: str, label_of) -> tuple[set[int], int]:
    """Labels with a rule that has no condition, and the character offset after the last rule line."""
    has: set[int] = set()
    end = 0
    offset = 0
    for line in text.splitlines(keepends=True):
        offset += len(line)
        if "->" not in line:
            continue
        end = offset
        if " If " in line:
            continue
        label = predecessor_label(line, label_of)
        if label is not None:
            has.add(label)
    return has, end


def repair(ctx: RepairContext) -> None:
    """Add ``EdgeL_i -> successor`` for every occurring label L without an unconditioned rule."""
    has, end = _unconditioned(ctx.text, ctx.label_of)
    if end:
        add_rules(ctx, has, end)
