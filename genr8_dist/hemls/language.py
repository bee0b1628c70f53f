"""The HEMLS language: rewrite systems as immutable values, read from text and printed back.

``parse(text)`` reads the full language of grammars/hemls.lark (journal Fig. 4, thesis 2.5, Genr8's
manual): an axiom, rewrite rules with left/right context, timed edges and conditions, several
weighted successors (on one line or as continuation lines beginning with ``->``), ``Angle``,
``BranchAngle`` and ``Sync``. The result is a ``RewriteSystem``; ``system.to_text()`` prints its
canonical text and ``parse(system.to_text()) == system``. docs/hemls.md is the user's reference.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lark import Lark, Token, Transformer, v_args
from lark.exceptions import (
    UnexpectedCharacters,
    UnexpectedEOF,
    UnexpectedInput,
    UnexpectedToken,
    VisitError,
)
from lark.tree import Meta

from genr8_dist.errors import ParseError
from genr8_dist.resources import grammars_dir, systems_dir

__all__ = [
    "OPERATORS",
    "PREDEFINED",
    "AxiomEdge",
    "Branch",
    "Condition",
    "RewriteSystem",
    "Rule",
    "Segment",
    "Successor",
    "load_system",
    "parse",
]

#: The predefined rewrite systems shipped in grammars/systems (Genr8's four and the journal's square).
PREDEFINED: tuple[str, ...] = (
    "three_sided_tiles", "four_sided_tiles", "koch", "quadratic_koch", "square",
)

#: Turtle operators: turn left/right, pitch down/up, roll left/right, reverse the next edge.
OPERATORS: tuple[str, ...] = ("+", "-", "&", "^", "/", "\\", "~")

DEFAULT_ANGLE = 90.0
DEFAULT_BRANCH_ANGLE = 30.0

_COMMENT_RE = re.compile(r"(//|#)[^\n]*")
#: The deepest bracket nesting a rewrite system may have (docs/hemls.md): every reader and the turtle
#: walk branches recursively, so a deeper text is refused, naming where, before any of them runs.
MAX_NESTING = 100
_BRACKET_OR_COMMENT = re.compile(r"[\[\]]|(?://|#)[^\n]*")
MAX_NUMBER = 2**31 - 1  # the largest edge number or age offset a rewrite system may use
_EDGE_RE = re.compile(r"^(?:Edge(?P<num>[0-9]+)|(?P<letter>[A-Z]))(?:_i(?P<off>[+-][0-9]+)?(?P<timed>))?$")


@dataclass(frozen=True)
class Segment:
    """An edge symbol: ``Edge3``, the journal's ``A``, or a timed ``Edge3_i`` / ``Edge3_i+1``.

    ``age`` is None for a plain segment (a new edge starts at age 0); otherwise the offset k of
    ``_i+k``: the new edge's age is the rewritten edge's age plus k (never below 0).
    """

    name: str
    age: int | None = None

    def __str__(self) -> str:
        if self.age is None:
            return self.name
        if self.age == 0:
            return f"{self.name}_i"
        return f"{self.name}_i{self.age:+d}"

    @property
    def number(self) -> int | None:
        """N for ``EdgeN``; None for a letter label."""
        return int(self.name[4:]) if self.name.startswith("Edge") else None


@dataclass(frozen=True)
class Branch:
    """Symbols between ``[`` and ``]``; the first segment inside is the branch, drawn from the vertex
    where the bracket opened."""

    symbols: tuple[Symbol, ...]

    def __str__(self) -> str:
        inner = " ".join(str(s) for s in self.symbols)
        return f"[ {inner} ]" if inner else "[ ]"


Symbol = Segment | Branch | str


@dataclass(frozen=True)
class Successor:
    """One successor of a rule: turtle symbols and an optional ``Weight`` (default 1 in draws)."""

    symbols: tuple[Symbol, ...]
    weight: float | None = None

    def __str__(self) -> str:
        text = " ".join(str(s) for s in self.symbols)
        if self.weight is not None:
            text += f" Weight {_number(self.weight)}"
        return text

    @property
    def main_segments(self) -> tuple[Segment, ...]:
        """The segments outside brackets: the main line that replaces the predecessor."""
        return tuple(s for s in self.symbols if isinstance(s, Segment))


@dataclass(frozen=True)
class Condition:
    """``If i < c`` (also ``>``, ``=``, ``<=``, ``>=``, ``!=``): a test on the rewritten edge's age."""

    op: str
    value: int

    def __str__(self) -> str:
        return f"If i {self.op} {self.value}"

    def holds(self, age: Any) -> Any:
        """Whether the condition holds for ``age`` (an int or an int array)."""
        v = self.value
        if self.op == "<":
            return age < v
        if self.op == ">":
            return age > v
        if self.op in ("=", "=="):
            return age == v
        if self.op == "<=":
            return age <= v
        if self.op == ">=":
            return age >= v
        return age != v


@dataclass(frozen=True)
class Rule:
    """``left < predecessor > right -> successor [Weight w] {-> successor [Weight w]} [If i op c]``.

    ``chain`` holds the segments written after the predecessor without a ``>`` (``A B C ->``):
    the rule applies to an A edge followed by a B edge at its end vertex, followed in turn by a C edge.
    """

    predecessor: Segment
    successors: tuple[Successor, ...]
    left: Segment | None = None
    right: Segment | None = None
    condition: Condition | None = None
    line: int = field(default=0, compare=False)
    chain: tuple[Segment, ...] = ()

    def __str__(self) -> str:
        pred = " ".join(str(s) for s in (self.predecessor, *self.chain))
        if self.left is not None:
            pred = f"{self.left} < {pred}"
        if self.right is not None:
            pred = f"{pred} > {self.right}"
        text = pred + "".join(f" -> {s}" for s in self.successors)
        if self.condition is not None:
            text += f" {self.condition}"
        return text

    @property
    def weights(self) -> tuple[float, ...]:
        """The successors' weights, 1 where none was written."""
        return tuple(1.0 if s.weight is None else s.weight for s in self.successors)


@dataclass(frozen=True)
class AxiomEdge:
    """One side of the seed polygon; ``reversed`` when written with ``~``."""

    segment: Segment
    reversed: bool = False

    def __str__(self) -> str:
        return f"~ {self.segment}" if self.reversed else str(self.segment)


@dataclass(frozen=True)
class RewriteSystem:
    """A HEMLS rewrite system (journal Definition 4): axiom, rewrite rules, turn angle, branch angle, sync.

    ``angle`` and ``branch_angle`` are None when the text did not give them; growth then uses 90 and
    30 degrees (``turn_angle``, ``cone_angle``). ``name`` is where it came from and is not part of
    equality.
    """

    axiom: tuple[AxiomEdge, ...]
    rules: tuple[Rule, ...] = ()
    angle: float | None = None
    branch_angle: float | None = None
    sync: bool = False
    name: str = field(default="", compare=False)

    @property
    def turn_angle(self) -> float:
        """Degrees of every turn, pitch and roll in successors (``Angle``, default 90)."""
        return DEFAULT_ANGLE if self.angle is None else self.angle

    @property
    def cone_angle(self) -> float:
        """Half-angle in degrees of the cone in which a branch looks for its partner (default 30)."""
        return DEFAULT_BRANCH_ANGLE if self.branch_angle is None else self.branch_angle

    def to_text(self) -> str:
        """The canonical text: axiom, one rule per line, then Angle, Sync, BranchAngle (Fig. 4)."""
        lines = [" + ".join(str(e) for e in self.axiom)]
        lines += [str(r) for r in self.rules]
        if self.angle is not None:
            lines.append(f"Angle {_number(self.angle)}")
        if self.sync:
            lines.append("Sync")
        if self.branch_angle is not None:
            lines.append(f"BranchAngle {_number(self.branch_angle)}")
        return "\n".join(lines) + "\n"

    def __str__(self) -> str:
        return self.to_text()

    def never_firing(self) -> list[tuple[Rule, Rule]]:
        """Rules that can never fire, each with the earlier rule that takes all its edges first.

        Rules for one label are tried in order and the first whose condition and context hold
        rewrites the edge; a later rule whose condition and context are each absent from, or equal
        to, an earlier rule's is never reached (two rules for one label are a fallback, not a draw:
        write the alternatives as successors of one rule, or with ``p =`` on each)."""
        out: list[tuple[Rule, Rule]] = []
        for i, rule in enumerate(self.rules):
            for earlier in self.rules[:i]:
                if earlier.predecessor.name != rule.predecessor.name:
                    continue
                if all(mine is None or mine == theirs for mine, theirs in (
                        (earlier.condition, rule.condition), (earlier.left, rule.left),
                        (earlier.right, rule.right))) and earlier.chain in ((), rule.chain):
                    out.append((rule, earlier))
                    break
        return out

    def warnings(self) -> list[str]:
        """One line per rule that can never fire (``never_firing``), naming both rules' lines."""
        return [f"line {rule.line}: the rule for {rule.predecessor.name} can never fire: the rule on "
                f"line {earlier.line} rewrites every such edge first (for a random choice write the "
                f"successors in one rule, or 'p =' on each)" for rule, earlier in self.never_firing()]

    def segment_names(self) -> tuple[str, ...]:
        """Every label name used, in order of first appearance."""
        seen: dict[str, None] = {}

        def visit(symbols: tuple[Symbol, ...]) -> None:
            for s in symbols:
                if isinstance(s, Segment):
                    seen.setdefault(s.name)
                elif isinstance(s, Branch):
                    visit(s.symbols)

        for e in self.axiom:
            seen.setdefault(e.segment.name)
        for r in self.rules:
            for s in (r.left, r.predecessor, *r.chain, r.right):
                if s is not None:
                    seen.setdefault(s.name)
            for succ in r.successors:
                visit(succ.symbols)
        return tuple(seen)

    def label_ids(self) -> dict[str, int]:
        """Label number of each name: N for ``EdgeN``; letters get the numbers after the largest N."""
        names = self.segment_names()
        numbers = [int(n[4:]) for n in names if n.startswith("Edge")]
        nxt = max(numbers) + 1 if numbers else 0
        out: dict[str, int] = {}
        for n in names:
            if n.startswith("Edge"):
                out[n] = int(n[4:])
            else:
                out[n] = nxt
                nxt += 1
        return out


def _number(x: float) -> str:
    """Integral values without a decimal point; others in Python's shortest round-trip form."""
    if float(x).is_integer():
        return str(int(x))
    return repr(float(x))


# -- parsing ---------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def _parser() -> Lark:
    path = grammars_dir() / "hemls.lark"
    return Lark(path.read_text(encoding="utf-8"), parser="lalr", lexer="contextual",
                propagate_positions=True, maybe_placeholders=False)


_TERMINAL_WORDS = {
    "EDGE": "an edge (EdgeN)", "OPERATOR": "a turtle operator", "REVERSE": "'~'",
    "PLUS": "'+'", "_SEP": "end of statement", "NUMBER": "a number", "INT": "an integer",
    "COMPARISON": "'<', '>' or '='", "LESSTHAN": "'<'", "MORETHAN": "'>'", "__ANON_0": "'->'",
    "LSQB": "'['", "RSQB": "']'", "WEIGHT": "'Weight'", "IF": "'If'", "I": "'i'", "ANGLE": "'Angle'",
    "BRANCHANGLE": "'BranchAngle'", "SYNC": "'Sync'", "$END": "end of text",
}


def _word(name: str) -> str:
    if name in _TERMINAL_WORDS:
        return _TERMINAL_WORDS[name]
    try:
        pattern = _parser().get_terminal(name).pattern
        if pattern.type == "str":
            return repr(pattern.value)
    except KeyError:
        pass
    return name


def _expected(names: Iterable[str]) -> str:
    words = sorted({_word(n) for n in names})
    return ", ".join(words) if words else "nothing"


def _token_text(tok: Token | None) -> str:
    if tok is None or getattr(tok, "type", "") == "$END":
        return "end of text"
    value = str(tok)
    if value in ("\n", ""):
        return "end of line"
    return repr(value)


def _located_error(message: str, source: str, line: int, column: int, text: str) -> ParseError:
    lines = text.splitlines()
    context = ""
    if 1 <= line <= len(lines):
        context = lines[line - 1] + "\n" + " " * max(column - 1, 0) + "^"
    return ParseError(message, source=source, line=line, column=column, context=context)


def _error_at(message: str, meta_or_token: Meta | Token, source: str, text: str) -> ParseError:
    line = getattr(meta_or_token, "line", 0) or 0
    column = getattr(meta_or_token, "column", 0) or 0
    return _located_error(message, source, line, column, text)


#: A parse-tree node's children as Lark hands them to a callback: tokens and what the callbacks below
#: made of the nodes under it.
Children = list[Any]
#: A rule's left-hand side: (left context, predecessor, right context, the edges following it).
_Context = tuple["Segment | None", "Segment", "Segment | None", tuple["Segment", ...]]


class _Build(Transformer[Token, RewriteSystem]):
    """Turns the parse tree into RewriteSystem parts; semantic checks raise ParseError with positions."""

    def __init__(self, source: str, text: str) -> None:
        super().__init__()
        self.source = source
        self.text = text

    def _fail(self, message: str, where: Meta | Token) -> ParseError:
        return _error_at(message, where, self.source, self.text)

    def segment(self, children: Children) -> _Pos:
        tok: Token = children[0]
        m = _EDGE_RE.match(str(tok))
        if m is None:  # the terminal's pattern and this one agree; kept as a guard for edits
            raise self._fail(f"malformed edge {str(tok)!r}", tok)
        age = None
        for group in ("num", "off"):
            if m.group(group) is not None and abs(int(m.group(group))) > MAX_NUMBER:
                raise self._fail(f"{str(tok)!r}: {m.group(group)} is too large (at most {MAX_NUMBER})", tok)
        if m.group("timed") is not None:
            age = int(m.group("off")) if m.group("off") else 0
        name = f"Edge{int(m.group('num'))}" if m.group("num") is not None else m.group("letter")
        seg = Segment(name, age)
        return _Pos(seg, tok)

    def axiom_edge(self, children: Children) -> tuple[_Pos, bool]:
        rev = len(children) == 2
        return (children[-1], rev)

    def axiom_turn(self, children: Children) -> bool:
        tok = children[-1]
        if str(tok) != "+":
            raise self._fail(f"the axiom joins its edges with '+' only, got {str(tok)!r}", tok)
        return len(children) == 2

    @v_args(meta=True)
    def axiom(self, meta: Meta, children: Children) -> tuple[str, tuple[AxiomEdge, ...]]:
        edges: list[AxiomEdge] = []
        pending_rev = False
        for child in children:
            if isinstance(child, bool):
                pending_rev = child
                continue
            pos, rev = child
            if pos.value.age is not None:
                raise self._fail(f"axiom edge {pos.value} cannot be timed (write {pos.value.name})",
                                 pos.token)
            edges.append(AxiomEdge(pos.value, reversed=rev != pending_rev))
            pending_rev = False
        if len(edges) < 3:
            raise self._fail(f"the axiom needs at least 3 edges (a polygon), got {len(edges)}", meta)
        return ("axiom", tuple(edges))

    def _predecessor(self, pos: _Pos, what: str) -> Segment:
        seg = pos.value
        if seg.age not in (None, 0):
            raise self._fail(f"{what} {seg} may only be timed as {seg.name}_i", pos.token)
        return seg

    def context_free(self, c: Children) -> _Context:
        chain = tuple(self._predecessor(p, "following edge") for p in c[1:])
        return (None, self._predecessor(c[0], "predecessor"), None, chain)

    def left_context(self, c: Children) -> _Context:
        return (self._predecessor(c[0], "left context"), self._predecessor(c[1], "predecessor"), None, ())

    def right_context(self, c: Children) -> _Context:
        return (None, self._predecessor(c[0], "predecessor"), self._predecessor(c[1], "right context"),
                ())

    def both_contexts(self, c: Children) -> _Context:
        return (self._predecessor(c[0], "left context"), self._predecessor(c[1], "predecessor"),
                self._predecessor(c[2], "right context"), ())

    def _symbols(self, children: Children) -> tuple[Symbol, ...]:
        out: list[Symbol] = []
        for ch in children:
            if isinstance(ch, _Pos):
                out.append(ch.value)
            elif isinstance(ch, Token):
                out.append(str(ch))
            else:
                out.append(ch)
        return tuple(out)

    def branch(self, children: Children) -> Branch:
        return Branch(self._symbols(children))

    @v_args(meta=True)
    def successor(self, meta: Meta, children: Children) -> tuple[Symbol, ...]:
        symbols = self._symbols(children)
        if not any(isinstance(s, Segment) for s in symbols):
            raise self._fail("a successor needs at least one edge outside brackets (its main line)",
                             meta)
        return symbols

    def weight(self, children: Children) -> _Weight:
        tok = children[-1]
        value = float(tok)
        if len(children) == 2:  # thesis Table 2.3: 'p = 0.5', the probability of this production
            if not 0.0 <= value <= 1.0:
                raise self._fail(f"a probability p must be between 0 and 1, got {tok}", tok)
            return _Weight(value, probability=True)
        if not math.isfinite(value) or value < 0:
            raise self._fail(f"Weight must be a number >= 0, got {tok}", tok)
        return _Weight(value)

    @v_args(meta=True)
    def alternative(self, meta: Meta, children: Children) -> _Alternative:
        symbols = children[0]
        if len(children) > 1:
            weight = children[1]
            return _Alternative(Successor(symbols, weight.value), weight.probability)
        return _Alternative(Successor(symbols), False)

    def condition(self, children: Children) -> Condition:
        op, value = children
        return Condition(str(op), int(value))

    @v_args(meta=True)
    def rule(self, meta: Meta, children: Children) -> tuple[str, Rule, Meta]:
        left, pred, right, chain = children[0]
        succs = tuple(c.successor for c in children[1:] if isinstance(c, _Alternative))
        stochastic = any(c.probability for c in children[1:] if isinstance(c, _Alternative))
        cond = next((c for c in children[1:] if isinstance(c, Condition)), None)
        rule = Rule(pred, succs, left, right, cond, line=meta.line, chain=chain)
        return ("stochastic rule" if stochastic else "rule", rule, meta)

    @v_args(meta=True)
    def continuation(self, meta: Meta, children: Children
                     ) -> tuple[str, tuple[tuple[Successor, ...], Condition | None], Meta]:
        succs = tuple(c.successor for c in children if isinstance(c, _Alternative))
        cond = next((c for c in children if isinstance(c, Condition)), None)
        return ("continuation", (succs, cond), meta)

    def _setting(self, name: str, tok: Token, low: float, high: float) -> float:
        value = float(tok)
        if not (low <= value <= high):
            raise self._fail(f"{name} must be between {low:g} and {high:g} degrees, got {tok}", tok)
        return value

    @v_args(meta=True)
    def angle(self, meta: Meta, children: Children) -> tuple[str, float, Meta]:
        return ("Angle", self._setting("Angle", children[0], 0.0, 360.0), meta)

    @v_args(meta=True)
    def branch_angle(self, meta: Meta, children: Children) -> tuple[str, float, Meta]:
        return ("BranchAngle", self._setting("BranchAngle", children[0], 0.0, 90.0), meta)

    @v_args(meta=True)
    def sync(self, meta: Meta, children: Children) -> tuple[str, bool, Meta]:
        return ("Sync", True, meta)

    def start(self, children: Children) -> RewriteSystem:
        axiom = children[0][1]
        rules: list[Rule] = []
        settings: dict[str, tuple[float, int]] = {}   # Sync: True
        for kind, value, meta in children[1:]:
            if kind == "rule":
                rules.append(value)
            elif kind == "stochastic rule":
                merge_stochastic(rules, value)
            elif kind == "continuation":
                if not rules or rules[-1].condition is not None:
                    why = ("a continuation line (beginning with '->') must follow a rewrite rule"
                           if not rules else
                           "a rule with an If condition cannot be continued; put the condition last")
                    raise self._fail(why, meta)
                succs, cond = value
                last = rules[-1]
                rules[-1] = Rule(last.predecessor, last.successors + succs, last.left, last.right,
                                 cond, line=last.line, chain=last.chain)
            else:
                if kind in settings:
                    raise self._fail(f"{kind} given twice (first on line {settings[kind][1]})", meta)
                settings[kind] = (value, meta.line)
        for r in rules:
            if sum(r.weights) <= 0:
                raise _located_error(f"the weights of the rule for {r.predecessor} add up to 0",
                                     self.source, r.line, 1, self.text)
        return RewriteSystem(
            axiom=axiom,
            rules=tuple(rules),
            angle=settings["Angle"][0] if "Angle" in settings else None,
            branch_angle=settings["BranchAngle"][0] if "BranchAngle" in settings else None,
            sync="Sync" in settings,
        )


@dataclass(frozen=True)
class _Pos:
    value: Segment
    token: Token


@dataclass(frozen=True)
class _Weight:
    value: float
    probability: bool = False


@dataclass(frozen=True)
class _Alternative:
    successor: Successor
    probability: bool


def merge_stochastic(rules: list[Rule], rule: Rule) -> None:
    """Append a rule written with ``p =`` probabilities (thesis Table 2.3: one production per line,
    ``D -> + D - - D p = 0.5``) to ``rules``: its successors join those of the first earlier rule with
    the same predecessor, context and condition, the probabilities becoming weights, so that
    ``D -> A p = 0.5`` and ``D -> B p = 0.5`` on two lines are one rule ``D -> A Weight 0.5 -> B
    Weight 0.5``. Without such an earlier rule it is appended as it is."""
    key = (rule.left, rule.predecessor, rule.right, rule.chain, rule.condition)
    for i, earlier in enumerate(rules):
        if (earlier.left, earlier.predecessor, earlier.right, earlier.chain, earlier.condition) == key:
            rules[i] = dataclasses.replace(earlier, successors=earlier.successors + rule.successors)
            return
    rules.append(rule)


# -- the direct reader ---------------------------------------------------------------------------------
#
# Universes write rewrite systems one statement per line, tokens separated by single spaces: a regular
# text that a hand-written reader turns into a RewriteSystem without building a parse tree. It reads
# the language as grammars/hemls.lark does, but only texts it can read without doubt (no comments, no
# ';', every space-separated word one whole token, nothing the transformer would refuse); for anything
# else it answers None and ``parse`` hands the text to Lark, whose result and error messages are the
# reference. tests/hemls/test_language.py compares the two readers on every universe's texts.

_DIRECT_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_+-&^/\\~[]<>=!. \n")
_OPERATOR_WORDS = frozenset(("+", "-", "&", "^", "/", "\\"))
_COMPARISONS = frozenset(("<=", ">=", "<", ">", "=", "==", "!="))
_NUMBER_RE = re.compile(r"[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?|\.[0-9]+([eE][-+]?[0-9]+)?")
_KEYWORDS = frozenset(("weight", "if", "angle", "branchangle", "sync"))


class _NotDirect(Exception):
    """The direct reader cannot vouch for this text: Lark reads it."""


@functools.lru_cache(maxsize=4096)
def _direct_segment(word: str) -> Segment:
    m = _EDGE_RE.match(word)
    if m is None or any(m.group(g) is not None and len(m.group(g)) > 9 for g in ("num", "off")):
        raise _NotDirect  # Lark's reader names the problem
    age = None
    if m.group("timed") is not None:
        age = int(m.group("off")) if m.group("off") else 0
    name = f"Edge{int(m.group('num'))}" if m.group("num") is not None else m.group("letter")
    return Segment(name, age)


def _is_segment_word(word: str) -> bool:
    return word[:1].isupper() and word.lower() not in _KEYWORDS


def _direct_number(word: str) -> float:
    if _NUMBER_RE.fullmatch(word) is None:
        raise _NotDirect
    return float(word)


def _direct_symbols(words: list[str], i: int, inside: bool) -> tuple[tuple[Symbol, ...], int]:
    """Turtle symbols from ``words[i]`` up to a ']' (inside a bracket) or a word that is no symbol."""
    out: list[Symbol] = []
    n = len(words)
    while i < n:
        w = words[i]
        if w in _OPERATOR_WORDS or w == "~":
            out.append(w)
        elif w == "[":
            inner, i = _direct_symbols(words, i + 1, True)
            if i >= n or words[i] != "]":
                raise _NotDirect
            out.append(Branch(inner))
        elif w == "]":
            if not inside:
                raise _NotDirect
            return tuple(out), i
        elif _is_segment_word(w):
            out.append(_direct_segment(w))
        else:
            return tuple(out), i
        i += 1
    if inside:
        raise _NotDirect
    return tuple(out), i


def _direct_alternatives(words: list[str], i: int) -> tuple[tuple[Successor, ...], Condition | None]:
    """``-> successor [Weight w]`` one or more times from ``words[i]``, then an optional condition,
    to the end of the statement."""
    successors: list[Successor] = []
    n = len(words)
    while i < n and words[i] == "->":
        symbols, i = _direct_symbols(words, i + 1, False)
        if not any(isinstance(s, Segment) for s in symbols):
            raise _NotDirect
        weight = None
        if i < n and words[i].lower() == "weight":
            if i + 1 >= n:
                raise _NotDirect
            weight = _direct_number(words[i + 1])
            if not math.isfinite(weight) or weight < 0:
                raise _NotDirect
            i += 2
        successors.append(Successor(symbols, weight))
    if not successors:
        raise _NotDirect
    condition = None
    if i < n:
        if (n - i != 4 or words[i].lower() != "if" or words[i + 1] != "i" or words[i + 2] not in _COMPARISONS
                or not words[i + 3].isdigit() or not words[i + 3].isascii()):
            raise _NotDirect
        condition = Condition(words[i + 2], int(words[i + 3]))
    return tuple(successors), condition


def _direct_predecessor(words: list[str]) -> tuple[_Context, int]:
    """(left, predecessor, right, chain) and the index of the first '->'."""
    try:
        arrow = words.index("->")
    except ValueError:
        raise _NotDirect from None
    head = words[:arrow]
    if not head:
        raise _NotDirect
    if "<" in head or ">" in head:
        if len(head) == 3 and head[1] == "<":
            left, pred, right = head[0], head[2], None
        elif len(head) == 3 and head[1] == ">":
            left, pred, right = None, head[0], head[2]
        elif len(head) == 5 and head[1] == "<" and head[3] == ">":
            left, pred, right = head[0], head[2], head[4]
        else:
            raise _NotDirect
        parts = [None if w is None else _direct_segment(w) for w in (left, pred, right)]
        chain: tuple[Segment, ...] = ()
    else:
        parts = [None, _direct_segment(head[0]), None]
        chain = tuple(_direct_segment(w) for w in head[1:])
    for seg in (*parts, *chain):
        if seg is not None and seg.age not in (None, 0):
            raise _NotDirect
    predecessor = parts[1]
    assert predecessor is not None   # read from a word above
    return (parts[0], predecessor, parts[2], chain), arrow


def _direct_axiom(words: list[str]) -> tuple[AxiomEdge, ...]:
    edges: list[AxiomEdge] = []
    n = len(words)
    i = 0
    pending = False   # a '~' before the '+' that leads to the next edge
    while True:
        rev = False
        if i < n and words[i] == "~":
            rev, i = True, i + 1
        if i >= n or not _is_segment_word(words[i]):
            raise _NotDirect
        seg = _direct_segment(words[i])
        if seg.age is not None:
            raise _NotDirect
        edges.append(AxiomEdge(seg, reversed=rev != pending))
        i += 1
        if i == n:
            break
        pending = False
        if words[i] == "~":
            pending, i = True, i + 1
        if i >= n or words[i] != "+":
            raise _NotDirect
        i += 1
    if len(edges) < 3:
        raise _NotDirect
    return tuple(edges)


def _direct(text: str) -> RewriteSystem | None:
    """The rewrite system of a regular text (see above), or None when Lark must read it."""
    if not _DIRECT_CHARS.issuperset(text):
        return None
    try:
        axiom: tuple[AxiomEdge, ...] | None = None
        rules: list[Rule] = []
        settings: dict[str, object] = {}
        for number, line in enumerate(text.split("\n"), start=1):
            words = line.split()
            if not words:
                continue
            if axiom is None:
                axiom = _direct_axiom(words)
                continue
            first = words[0].lower()
            if first in ("angle", "branchangle"):
                if len(words) != 2 or first in settings:
                    raise _NotDirect
                value = _direct_number(words[1])
                if not 0.0 <= value <= (360.0 if first == "angle" else 90.0):
                    raise _NotDirect
                settings[first] = value
            elif first == "sync":
                if len(words) != 1 or first in settings:
                    raise _NotDirect
                settings[first] = True
            elif first == "->":
                if not rules or rules[-1].condition is not None:
                    raise _NotDirect
                successors, condition = _direct_alternatives(words, 0)
                last = rules[-1]
                rules[-1] = Rule(last.predecessor, last.successors + successors, last.left, last.right,
                                 condition, line=last.line, chain=last.chain)
            else:
                (left, pred, right, chain), arrow = _direct_predecessor(words)
                successors, condition = _direct_alternatives(words, arrow)
                rules.append(Rule(pred, successors, left, right, condition, line=number, chain=chain))
        if axiom is None or any(sum(r.weights) <= 0 for r in rules):
            return None
    except _NotDirect:
        return None
    return RewriteSystem(axiom=axiom, rules=tuple(rules), angle=settings.get("angle"),  # type: ignore[arg-type]
                         branch_angle=settings.get("branchangle"),  # type: ignore[arg-type]
                         sync="sync" in settings)


def parse(text: str, source: str = "<text>", *, name: str = "") -> RewriteSystem:
    """Read a rewrite system; malformed text raises ParseError naming line, column and what was expected."""
    if not isinstance(text, str):
        raise TypeError(f"parse() needs a str, got {type(text).__name__}")
    _check_nesting(text, source)
    direct = _direct(text)
    if direct is not None:
        return RewriteSystem(direct.axiom, direct.rules, direct.angle, direct.branch_angle, direct.sync,
                             name=name or source)
    return _parse_lark(text, source, name)


def _check_nesting(text: str, source: str) -> None:
    """``ParseError`` at the first ``[`` that opens more than ``MAX_NESTING`` brackets (one linear scan;
    none at all for a text with fewer ``[`` than the limit)."""
    if text.count("[") <= MAX_NESTING:
        return
    depth = 0
    for match in _BRACKET_OR_COMMENT.finditer(text):
        bracket = match.group()
        if bracket == "[":
            depth += 1
            if depth > MAX_NESTING:
                at = match.start()
                line = text.count("\n", 0, at) + 1
                column = at - (text.rfind("\n", 0, at) + 1) + 1
                raise _located_error(f"brackets nest deeper than {MAX_NESTING} levels (the limit of a "
                                     "rewrite system, docs/hemls.md)", source, line, column, text)
        elif bracket == "]":
            depth = max(depth - 1, 0)


def _parse_lark(text: str, source: str, name: str) -> RewriteSystem:
    """Read a rewrite system with Lark (any text the language allows; the reference error messages)."""
    if not _COMMENT_RE.sub("", text).strip():
        raise ParseError("empty rewrite system (the first statement must be the axiom)", source=source)
    try:
        tree = _parser().parse(text)
    except UnexpectedCharacters as exc:
        at = exc.pos_in_stream if exc.pos_in_stream is not None else -1
        ch = text[at] if 0 <= at < len(text) else "?"
        raise _located_error(f"unexpected character {ch!r}; expected {_expected(exc.allowed or ())}",
                             source, exc.line, exc.column, text) from None
    except UnexpectedToken as exc:
        tok = exc.token
        line = getattr(tok, "line", None) or exc.line
        column = getattr(tok, "column", None) or exc.column
        if getattr(tok, "type", "") == "$END":
            line, column = _end_position(text)
        raise _located_error(f"unexpected {_token_text(tok)}; expected {_expected(exc.expected)}",
                             source, line, column, text) from None
    except UnexpectedEOF as exc:
        line, column = _end_position(text)
        raise _located_error(f"unexpected end of text; expected {_expected(exc.expected)}",
                             source, line, column, text) from None
    except UnexpectedInput as exc:  # pragma: no cover - the three above are all LALR raises
        raise _located_error(str(exc).splitlines()[0], source, getattr(exc, "line", 0),
                             getattr(exc, "column", 0), text) from None
    try:
        system = _Build(source, text).transform(tree)
    except VisitError as exc:
        if isinstance(exc.orig_exc, ParseError):
            raise exc.orig_exc from None
        raise
    if not isinstance(system, RewriteSystem):  # pragma: no cover - start always builds one
        raise ParseError("not a rewrite system", source=source)
    return RewriteSystem(system.axiom, system.rules, system.angle, system.branch_angle, system.sync,
                         name=name or source)


def _end_position(text: str) -> tuple[int, int]:
    lines = text.rstrip("\n").split("\n")
    return len(lines), len(lines[-1]) + 1


def load_system(name_or_path: str | Path) -> RewriteSystem:
    """A predefined system by name (``PREDEFINED``; '-' and '_' alike), a file path, or '-' for stdin."""
    raw = str(name_or_path)
    if raw == "-":
        return parse(sys.stdin.read(), source="<stdin>", name="stdin")
    key = raw.replace("-", "_").lower()
    if key in PREDEFINED and not Path(raw).is_file():
        path = systems_dir() / f"{key}.hemls"
        return parse(path.read_text(encoding="utf-8"), source=str(path), name=key)
    path = Path(raw)
    if not path.is_file():
        raise ParseError("no such rewrite system: not a file, and not one of the predefined names "
                         f"({', '.join(PREDEFINED)})", source=raw)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ParseError(f"cannot read the rewrite system: {exc}", source=raw) from None
    return parse(text, source=str(path), name=path.stem)
