"""Rewrite systems compiled for growth: rules grouped by predecessor label, successors drawn once.

A ``RewriteSystem`` (``hemls.language``) names its labels; growth works on label ids and on each
successor's template (``hemls.turtle.draw``), placed on every edge the rule rewrites. Templates are
drawn once per process for each successor shape, angle and labels (universes write the same
successors into many rewrite systems), and a system is compiled once per process (``lru_cache``).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from dataclasses import dataclass, replace

import numpy as np

from genr8_dist.hemls.language import Branch, RewriteSystem, Segment, Successor, Symbol
from genr8_dist.hemls.turtle import Template, draw

__all__ = ["CompiledRule", "CompiledSystem", "Group", "compile_system"]


@dataclass(frozen=True)
class Group:
    """The rules of one predecessor label, in the order the system writes them."""

    label: int
    rules: tuple[CompiledRule, ...]


@dataclass(frozen=True)
class CompiledRule:
    """One rule: its context labels (left, right, the chain after its end), its condition, one
    template per successor, their cumulative normalised weights, and its place among the system's
    rules (``index``: growth says which rules fired by it) and a digest of each template's arrays
    (``drawn``: equal digests, equal templates, bit for bit)."""

    left: int | None
    right: int | None
    chain: tuple[int, ...]
    condition: object
    templates: tuple[Template, ...]
    cumulative: np.ndarray  # cumulative normalized weights
    index: int = 0
    drawn: tuple[bytes, ...] = ()

    @property
    def unconditional(self) -> bool:
        """Whether the rule applies to every edge with its predecessor's label (no context, chain
        or condition)."""
        return self.left is None and self.right is None and not self.chain and self.condition is None


@dataclass(frozen=True)
class CompiledSystem:
    """A rewrite system as growth reads it: rule groups in the order of their first rule, the axiom's
    labels and directions, every label it uses (for label noise), the join cone and ``Sync``."""

    groups: tuple[Group, ...]
    axiom_labels: np.ndarray
    axiom_reversed: np.ndarray
    labels: np.ndarray  # every label the system uses (for label noise)
    max_label: int
    cos_cone: float
    sync: bool


@functools.lru_cache(maxsize=4096)
def _segments(symbols: tuple[Symbol, ...]) -> tuple[Segment, ...]:
    """The segments in ``symbols`` (brackets included), in order."""
    out: list[Segment] = []
    for sym in symbols:
        if isinstance(sym, Segment):
            out.append(sym)
        elif isinstance(sym, Branch):
            out.extend(_segments(sym.symbols))
    return tuple(out)


def _shape(symbols: tuple[Symbol, ...], count: list[int]) -> tuple[Symbol, ...]:
    """``symbols`` with the i-th segment (in ``_segments`` order) replaced by the plain segment "i"."""
    out: list[Symbol] = []
    for sym in symbols:
        if isinstance(sym, Segment):
            out.append(Segment(str(count[0])))
            count[0] += 1
        elif isinstance(sym, Branch):
            out.append(Branch(_shape(sym.symbols, count)))
        else:
            out.append(sym)
    return tuple(out)


@functools.lru_cache(maxsize=4096)
def _drawn_shape(shape: tuple[Symbol, ...], angle: float) -> Template:
    """The template of successors of this shape: labels are segment positions, ages untimed."""
    n = len(_segments(shape))
    return draw(Successor(shape), angle, {str(i): i for i in range(n)})


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=8192)
def _drawn(successor: Successor, angle: float, labels: tuple[int, ...]) -> Template:
    """``draw(successor, angle, ...)``: the turtle walks once per shape (successors that differ only in
    their labels and ages draw the same geometry); labels and ages are read from the segments."""
    shape = _drawn_shape(_shape(successor.symbols, [0]), angle)
    segments = _segments(successor.symbols)
    ids = np.array(labels, dtype=np.int64)
    ages = np.array([0 if s.age is None else s.age for s in segments], dtype=np.int64)
    timed = np.array([s.age is not None for s in segments], dtype=bool)
    main, branch = shape.main_labels, shape.branch_labels
    return replace(shape, main_labels=_frozen(ids[main]), main_ages=_frozen(ages[main]),
                   main_timed=_frozen(timed[main]), branch_labels=_frozen(ids[branch]),
                   branch_ages=_frozen(ages[branch]), branch_timed=_frozen(timed[branch]))


@functools.lru_cache(maxsize=8192)
def _digest(successor: Successor, angle: float, labels: tuple[int, ...]) -> bytes:
    """A digest of ``_drawn(successor, angle, labels)``'s arrays (shapes, types and bytes), once
    per process for each: two successors with one digest draw the same template."""
    template = _drawn(successor, angle, labels)
    h = hashlib.blake2b(digest_size=16)
    for field in dataclasses.fields(template):
        value = getattr(template, field.name)
        h.update(f"{field.name}{value.shape}{value.dtype.str}".encode())
        h.update(value.tobytes())
    return h.digest()


_CERTAIN = np.ones(1)   # the cumulative weights of a rule with one successor
_CERTAIN.setflags(write=False)


@functools.lru_cache(maxsize=1024)
def compile_system(system: RewriteSystem) -> CompiledSystem:
    """``system`` compiled for growth (once per process for each system)."""
    ids = system.label_ids()
    groups: dict[int, list[CompiledRule]] = {}
    for index, rule in enumerate(system.rules):
        # each successor drawn once per process for its shape, angle and labels (universes write the
        # same successors into many rewrite systems)
        keys = [(s, system.turn_angle, tuple(ids[g.name] for g in _segments(s.symbols)))
                for s in rule.successors]
        templates = tuple(_drawn(*key) for key in keys)
        drawn = tuple(_digest(*key) for key in keys)
        if len(templates) == 1:
            cum = _CERTAIN
        else:
            w = np.array(rule.weights, dtype=np.float64)
            cum = np.cumsum(w / w.sum())
            cum[-1] = 1.0
        groups.setdefault(ids[rule.predecessor.name], []).append(CompiledRule(
            None if rule.left is None else ids[rule.left.name],
            None if rule.right is None else ids[rule.right.name],
            tuple(ids[c.name] for c in rule.chain),
            rule.condition, templates, cum, index, drawn))
    labels = np.array(sorted(set(ids.values())), dtype=np.int64)
    return CompiledSystem(
        groups=tuple(Group(label, tuple(rules)) for label, rules in groups.items()),
        axiom_labels=np.array([ids[e.segment.name] for e in system.axiom], dtype=np.int64),
        axiom_reversed=np.array([e.reversed for e in system.axiom], dtype=bool),
        labels=labels,
        max_label=int(labels.max()) if len(labels) else 0,
        cos_cone=math.cos(math.radians(system.cone_angle)),
        sync=system.sync,
    )


