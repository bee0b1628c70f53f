"""The inverse mapping (the thesis's *regn8*): a rewrite system's text -> a genome that maps to it.

1. The text is normalised (one statement per line, tokens separated by single spaces; ``;`` ends a
   statement and ``#`` starts a comment line unless the universe uses them) and parsed with Lark
   using the universe's own grammar: a text outside the universe fails here with line and column.
2. A derivation is searched over the same compiled tables the mapper uses, in the mapper's order,
   so it obeys what Lark cannot check: ``max_depth`` eligibility, ``EdgeX`` binding and codon order.
3. Codons are emitted for that derivation, each the smallest value making the mapper's choice
   (alternative index among the eligible ones, ``c + 1`` to go on with a repetition and 0 to stop,
   1/0 for options, the label for edges, the value's index for numeric terminals). Labels are
   renamed to birth order on the way: a label keeps its number when the mapper could draw it,
   otherwise takes the first free one.
4. The genome is mapped again and compared with the (renamed) text; a difference (a label with no
   rewrite rule, which the repair hook would fix) is reported as the reason no genome exists.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Iterator
from typing import Any, Protocol

from genr8_dist.errors import InversionError
from genr8_dist.grammar.compiler import Alternatives, CompiledGrammar, Node
from genr8_dist.grammar.hooks import rule_predecessors
from genr8_dist.grammar.mapper import CompiledMapper, MapResult, eligible

#: One step of a derivation the search found: ``("N",)`` a rule's only alternative, ``("C", j, n)`` the
#: j-th of n eligible ones, ``("R", more, round, x)`` a repetition, ``("M", letter, label, pos)``...
Event = tuple[Any, ...]
#: The derivation so far, newest event first: (event, the chain before it), ``None`` at the start.
Chain = tuple[Event, "Chain"] | None


class Universe(Protocol):
    """What inversion reads of a universe (``genr8_dist.grammar.universe.Universe``, which calls
    this module from its ``invert``)."""

    name: str
    grammar: CompiledGrammar

    def mapper(self, max_depth: int = ...) -> CompiledMapper: ...

    def map(self, genome: Iterable[int], max_depth: int = ..., max_wraps: int = ...) -> MapResult: ...

    def label_of(self, token: str) -> int | None: ...

    def parser(self) -> Any: ...

__all__ = ["invert", "normalize"]

_BUDGET = 400_000
#: The longest text (in tokens) the search reads: it recurses about once per token (measured: 16,000
#: tokens within its 20,000-frame limit), so a longer text is refused in one line instead.
MAX_TOKENS = 12_000


class _Token:
    __slots__ = ("col", "line", "text")

    def __init__(self, text: str, line: int, col: int) -> None:
        self.text = text
        self.line = line
        self.col = col


def _literals(universe: Universe) -> set[str]:
    found: set[str] = set()
    for alts in universe.grammar.rules.values():
        stack = list(alts)
        while stack:
            node = stack.pop()
            if node[0] == "lit":
                found.add(node[1])
            elif node[0] in ("seq", "choice"):
                stack.extend(node[1])
            elif node[0] in ("rep", "opt"):
                stack.append(node[1])
    return found


def normalize(universe: Universe, text: str) -> list[_Token]:
    """The tokens of ``text`` (``"\\n"`` tokens end statements when the universe has line breaks)."""
    literals = _literals(universe)
    lines_mode = "\n" in literals
    semicolon = ";" not in literals
    comment = not any(lit.startswith("#") for lit in literals)
    tokens: list[_Token] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        if comment and raw.lstrip().startswith("#"):
            continue
        pieces = raw.split(";") if semicolon else [raw]
        offset = 0
        for piece in pieces:
            words = [(m.group(), offset + m.start() + 1) for m in re.finditer(r"\S+", piece)]
            offset += len(piece) + 1
            if not words:
                continue
            tokens.extend(_Token(w, lineno, col) for w, col in words)
            if lines_mode:
                tokens.append(_Token("\n", lineno, offset))
    return tokens


def _render(tokens: list[str]) -> str:
    text = " ".join(tokens).replace(" \n ", "\n")
    if text.endswith(" \n"):
        text = text[:-2] + "\n"
    return text


class _Search:
    """Backtracking search for a derivation of ``tokens`` in the mapper's order."""

    def __init__(self, universe: Universe, tokens: list[str], max_depth: int, bind: bool = True) -> None:
        self.cg = universe.grammar
        self.toks = tokens
        self.n = len(tokens)
        self.maxd = max_depth
        self.bind = bind
        self.res = [t.regex() for t in self.cg.templates]
        self.steps = 0
        self.furthest = 0
        self.elig: dict[tuple[object, int], tuple[int, ...]] = {}

    def eligible(self, key: object, alts: Alternatives, d: int) -> tuple[int, ...]:
        k = (key, d)
        e = self.elig.get(k)
        if e is None:
            e = self.elig[k] = eligible(self.cg, alts, d, self.maxd)
        return e

    def fits(self, node: Node, d: int) -> bool:
        need = self.cg.alt_need(node)
        return need == 0 or d + need <= self.maxd

    def tick(self) -> None:
        self.steps += 1
        if self.steps > _BUDGET:
            raise InversionError(f"the text is too long or too ambiguous to invert (more than {_BUDGET} "
                                 "search steps)")

    def label(self, template: int, pos: int) -> int | None:
        if pos >= self.n:
            return None
        m = self.res[template].fullmatch(self.toks[pos])
        return int(m.group(1)) if m else None

    def run(self) -> Chain:
        for pos, ev in self.rule(self.cg.start, 0, 1, None):
            if pos == self.n:
                return ev
        return None

    def rule(self, name: str, pos: int, d: int, ev: Chain) -> Iterator[tuple[int, Chain]]:
        self.tick()
        alts = self.cg.rules[name]
        if len(alts) == 1:
            for p, e, _scope in self.node(alts[0], pos, d, {}, (("N",), ev)):
                yield p, e
            return
        elig = self.eligible(name, alts, d)
        for j, i in enumerate(elig):
            for p, e, _scope in self.node(alts[i], pos, d, {}, (("C", j, len(elig)), ev)):
                yield p, e

    def node(self, node: Node, pos: int, d: int, scope: dict[str, int], ev: Chain
             ) -> Iterator[tuple[int, Chain, dict[str, int]]]:
        self.tick()
        if pos > self.furthest:
            self.furthest = pos
        kind = node[0]
        if kind == "lit":
            if pos < self.n and self.toks[pos] == node[1]:
                yield pos + 1, ev, scope
            return
        if kind == "num":
            if pos < self.n:
                values = node[1]
                try:
                    index = values.index(self.toks[pos])
                except ValueError:
                    return
                yield pos + 1, (("C", index, len(values)), ev), scope
            return
        if kind == "edge":
            _, mode, template, letter = node
            lab = self.label(template, pos)
            if lab is None:
                return
            if mode != "B":
                yield pos + 1, (("E", mode, lab, pos), ev), scope
                return
            if letter in scope:
                if scope[letter] == lab:
                    yield pos + 1, ev, scope
                elif not self.bind:
                    yield pos + 1, (("M", letter, scope[letter], pos), ev), scope
                return
            yield pos + 1, (("E", "L", lab, pos), ev), {**scope, letter: lab}
            return
        if kind == "rule":
            for p, e in self.rule(node[1], pos, d + 1, ev):
                yield p, e, scope
            return
        if kind == "seq":
            yield from self.seq(node[1], 0, pos, d, scope, ev)
            return
        if kind == "choice":
            alts = node[1]
            elig = self.eligible(("group", node[2]), alts, d)
            for j, i in enumerate(elig):
                yield from self.node(alts[i], pos, d, scope, (("C", j, len(elig)), ev))
            return
        if kind == "opt":
            if not self.fits(node[1], d):
                yield pos, (("Z",), ev), scope
                return
            for p, e, s in self.node(node[1], pos, d, scope, (("O", True), ev)):
                if p > pos:
                    yield p, e, s
            yield pos, (("O", False), ev), scope
            return
        if kind == "rep":
            body, x, plus = node[1], node[2], node[3]
            if plus:
                for p, e, s in self.node(body, pos, d, scope, ev):
                    yield from self.rep(body, x, 0, p, d, s, e)
                return
            yield from self.rep(body, x, 0, pos, d, scope, ev)
            return
        raise AssertionError(kind)

    def seq(self, items: tuple[Node, ...], i: int, pos: int, d: int, scope: dict[str, int], ev: Chain
            ) -> Iterator[tuple[int, Chain, dict[str, int]]]:
        if i == len(items):
            yield pos, ev, scope
            return
        for p, e, s in self.node(items[i], pos, d, scope, ev):
            yield from self.seq(items, i + 1, p, d, s, e)

    def rep(self, body: Node, x: int, c: int, pos: int, d: int, scope: dict[str, int], ev: Chain
            ) -> Iterator[tuple[int, Chain, dict[str, int]]]:
        if not self.fits(body, d):
            yield pos, (("Z",), ev), scope
            return
        for p, e, s in self.node(body, pos, d, scope, (("R", True, c, x), ev)):
            if p > pos:  # a round that emits nothing is never needed
                yield from self.rep(body, x, c + 1, p, d, s, e)
        yield pos, (("R", False, c, x), ev), scope


def _events(chain: Chain) -> list[Event]:
    out = []
    while chain is not None:
        out.append(chain[0])
        chain = chain[1]
    out.reverse()
    return out


def _where(tokens: list[_Token], pos: int) -> str:
    if pos < len(tokens):
        tok = tokens[pos]
        return f"line {tok.line}, column {tok.col}"
    if tokens:
        return f"line {tokens[-1].line}, at the end"
    return "the start"


def _show(tok: str) -> str:
    return "the end of the line" if tok == "\n" else f"'{tok}'"


def _check_nesting(tokens: list[_Token]) -> None:
    """Refuse brackets nested deeper than a rewrite system may have (``language.MAX_NESTING``), at the
    first ``[`` too many: Lark's tree and the search would recurse that deep."""
    from genr8_dist.hemls.language import MAX_NESTING

    depth = 0
    for tok in tokens:
        if tok.text == "[":
            depth += 1
            if depth > MAX_NESTING:
                raise InversionError(f"line {tok.line}, column {tok.col}: brackets nest deeper than "
                                     f"{MAX_NESTING} levels (the limit of a rewrite system, docs/hemls.md)")
        elif tok.text == "]":
            depth = max(depth - 1, 0)


def _lark_check(universe: Universe, tokens: list[_Token], words: list[str]) -> None:
    """Parse with Lark; a syntax error becomes an InversionError at the user's line and column."""
    from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

    rendered = _render(words)
    starts = []
    at = 0
    for i, w in enumerate(words):
        starts.append(at)
        nxt_is_break = i + 1 < len(words) and words[i + 1] == "\n"
        at += len(w) + (0 if w == "\n" or nxt_is_break or i + 1 == len(words) else 1)
    try:
        universe.parser().parse(rendered)
        return
    except UnexpectedInput as exc:
        offset = getattr(exc, "pos_in_stream", None)
        if isinstance(exc, UnexpectedToken) and exc.token is not None:
            offset = getattr(exc.token, "start_pos", offset)
        if isinstance(exc, UnexpectedEOF) or offset is None:
            offset = len(rendered)
        expected = sorted(getattr(exc, "expected", None) or getattr(exc, "allowed", None) or [])
        if isinstance(exc, UnexpectedCharacters):
            expected = sorted(exc.allowed or [])
    pos = len(words)
    for i, start in enumerate(starts):
        if start <= offset < start + len(words[i]):
            pos = i
            break
    names = _terminal_names(universe, expected)
    hint = f"; expected {names}" if names else ""
    if pos >= len(words):
        raise InversionError(f"{_where(tokens, pos)}: the text ends too early for universe "
                             f"'{universe.name}'{hint}")
    raise InversionError(f"{_where(tokens, pos)}: {_show(words[pos])} is not allowed here in universe "
                         f"'{universe.name}'{hint}")


def _terminal_names(universe: Universe, names: list[str]) -> str:
    parser = universe.parser()
    shown = []
    for name in names:
        try:
            term = parser.get_terminal(name)
            pattern = term.pattern
            if pattern.type == "str":
                shown.append("end of line" if pattern.value == "\n" else f"'{pattern.value}'")
            else:
                shown.append("an edge (Edge<n>)" if name.startswith(("EDGE", "PRED", "CTX")) else name)
        except KeyError:
            shown.append(name)
    unique = sorted(set(shown))
    if len(unique) > 8:
        unique = [*unique[:8], "..."]
    return ", ".join(unique)


def invert(universe: Universe, text: str, max_depth: int = 5) -> tuple[int, ...]:
    """A genome that ``universe.map(genome, max_depth)`` turns into ``text`` (labels in birth order)."""
    if not isinstance(text, str):
        raise InversionError(f"a rewrite system is text, got {type(text).__name__}")
    universe.mapper(max_depth)  # validates max_depth
    tokens = normalize(universe, text)
    words = [t.text for t in tokens]
    if not words:
        raise InversionError("the text is empty: there is no rewrite system to invert")
    _check_nesting(tokens)
    if len(words) > MAX_TOKENS:
        raise InversionError(f"{_where(tokens, MAX_TOKENS)}: the text has {len(words)} tokens; invert reads "
                             f"at most {MAX_TOKENS}")
    _lark_check(universe, tokens, words)

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 20_000))
    try:
        try:
            found = _Search(universe, words, max_depth).run()
        except RecursionError:   # a grammar costing more frames a token than measured: refused, not a crash
            raise InversionError(f"the text is too long or too deeply nested to invert ({len(words)} "
                                 "tokens)") from None
        if found is None:
            _diagnose(universe, tokens, words, max_depth)
    finally:
        sys.setrecursionlimit(limit)
    genome, renamed, rename = _codons(universe, tokens, words, _events(found))

    want = _render(renamed)
    result = universe.map(genome, max_depth=max_depth, max_wraps=0)
    if result.text != want:
        raise InversionError(_mismatch(universe, want, result.text, rename))
    return genome


def _diagnose(universe: Universe, tokens: list[_Token], words: list[str], max_depth: int) -> None:
    """Say why no derivation within the mapper's rules exists although Lark parsed the text."""
    from genr8_dist.grammar.compiler import MAX_MAX_DEPTH

    for depth in range(max_depth + 1, MAX_MAX_DEPTH + 1):
        if _Search(universe, words, depth).run() is not None:
            raise InversionError(
                f"the text nests deeper than max_depth={max_depth} allows in universe "
                f"'{universe.name}': it needs max_depth >= {depth}")
    _check_numbers(universe, tokens, words)
    loose = _Search(universe, words, MAX_MAX_DEPTH, bind=False).run()
    if loose is not None:
        for event in _events(loose):
            if event[0] == "M":
                _, letter, first, pos = event
                raise InversionError(
                    f"{_where(tokens, pos)}: '{words[pos]}' must repeat the label of the bound edge "
                    f"Edge{letter} drawn earlier in the same production (label {first}) in universe "
                    f"'{universe.name}'")
    raise InversionError(f"no derivation of the text in universe '{universe.name}' obeys the mapper's "
                         "rules (a repetition that emits nothing, or an option it cannot take)")


def _check_numbers(universe: Universe, tokens: list[_Token], words: list[str]) -> None:
    """Refuse a number the universe's numeric terminals can parse but never generate."""
    nums: dict[str, tuple[str, ...]] = {}
    for alts in universe.grammar.rules.values():
        stack = list(alts)
        while stack:
            node = stack.pop()
            if node[0] == "num":
                nums[node[2]] = node[1]
            elif node[0] in ("seq", "choice"):
                stack.extend(node[1])
            elif node[0] in ("rep", "opt"):
                stack.append(node[1])
    if not nums:
        return
    literals = _literals(universe)
    parser = universe.parser()
    patterns = {name: re.compile(parser.get_terminal(name).pattern.to_regexp()) for name in nums}
    for pos, word in enumerate(words):
        if word in literals or universe.label_of(word) is not None:
            continue
        for name, values in nums.items():
            if patterns[name].fullmatch(word) and word not in values:
                shown = ", ".join(values) if len(values) <= 4 else \
                    f"{values[0]}, {values[1]}, ..., {values[-1]}"
                raise InversionError(
                    f"{_where(tokens, pos)}: '{word}' is not a value numeric terminal {name} can take "
                    f"in universe '{universe.name}' (its values: {shown}, "
                    "written exactly so)")


def _codons(universe: Universe, tokens: list[_Token], words: list[str],
            events: list[Event]) -> tuple[tuple[int, ...], list[str], dict[int, int]]:
    """Codons for a derivation's events; the text's tokens with labels renamed to birth order."""
    count = 2
    rename: dict[int, int] = {}
    taken: set[int] = set()
    genome: list[int] = []
    for event in events:
        kind = event[0]
        if kind == "N" or kind == "Z":
            genome.append(0)
        elif kind == "C":
            genome.append(event[1])
        elif kind == "R":
            _, go_on, c, _x = event
            genome.append(c + 1 if go_on else 0)
        elif kind == "O":
            genome.append(1 if event[1] else 0)
        elif kind == "E":
            _, mode, written, pos = event
            lab = rename.get(written)
            if lab is None:
                free = [k for k in range(count) if k not in taken]
                if written < count and written not in taken:
                    lab = written
                elif mode == "L" and written == count:
                    lab = count
                elif free:
                    lab = free[0]
                elif mode == "L":
                    lab = count
                else:
                    raise InversionError(
                        f"{_where(tokens, pos)}: '{words[pos]}' appears as a predecessor or context "
                        f"edge before any edge of its label was drawn; in universe '{universe.name}' "
                        "such edges only reuse existing labels, so no genome gives this text")
                rename[written] = lab
                taken.add(lab)
            if mode == "L" and lab == count:
                count += 1
            genome.append(lab)
        else:  # pragma: no cover - "M" only occurs in diagnosis searches
            raise AssertionError(kind)
    res = [t.regex() for t in universe.grammar.templates]
    renamed = []
    for w in words:
        for regex in res:
            m = regex.fullmatch(w)
            if m:
                new = rename.get(int(m.group(1)), int(m.group(1)))
                w = w[:m.start(1)] + str(new) + w[m.end(1):]
                break
        renamed.append(w)
    return tuple(genome), renamed, rename


def _mismatch(universe: Universe, want: str, got: str | None, rename: dict[int, int]) -> str:
    has = rule_predecessors(want, universe.label_of)
    occurring = set()
    for line in want.splitlines():
        for w in line.split():
            lab = universe.label_of(w)
            if lab is not None:
                occurring.add(lab)
    missing = sorted(occurring - has) if "->" in want else []
    if missing:
        written = {new: old for old, new in rename.items()}
        names = ", ".join(f"label {written.get(k, k)}" + (f" (renamed {k})" if written.get(k, k) != k
                                                          else "") for k in missing)
        return (f"{names}: occurs without a rewrite rule; universe '{universe.name}' repairs such "
                "labels by adding a rule, so no genome maps to exactly this text (add a rule with "
                "that predecessor)")
    want_lines, got_lines = want.splitlines(), (got or "").splitlines()
    for i, (a, b) in enumerate(zip(want_lines, got_lines, strict=False), 1):
        if a != b:
            return (f"line {i}: the genome found maps to '{b}' instead of '{a}' in universe "
                    f"'{universe.name}' (its hooks change the text)")
    return (f"the genome found maps to a text of {len(got_lines)} lines instead of {len(want_lines)} "
            f"in universe '{universe.name}' (its hooks change the text)")
