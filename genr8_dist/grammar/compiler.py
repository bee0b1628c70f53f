"""Compile a universe's Lark grammar into flat tables the GE mapper and its inverse share.

Lark's own grammar loader reads the ``.lark`` file (so a malformed file fails exactly as Lark would
fail, with its line and column); this module then walks Lark's EBNF tree once per rule and turns it
into a small tree of plain tuples (the *IR*), classifies every terminal by the naming conventions of
``grammars/README.md`` (labelled edges, predecessor edges, bound ``EdgeX/Y/Z`` edges, line breaks,
literals), reads the ``//@`` directives (repetition bias, repair rule, description), and precomputes
each alternative's minimum depth so that the mapper can keep every derivation within ``max_depth``.

IR nodes (tuples, first item the kind):

``("lit", text)``                         emit ``text`` (``"\\n"`` ends a line)
``("edge", kind, template, letter)``      kind ``"L"`` labelled, ``"P"`` predecessor, ``"C"`` context,
                                          ``"B"`` bound (``letter`` X, Y or Z)
``("rule", name)``                        expand another rule one level deeper (reads a codon)
``("seq", (node, ...))``                  one after the other
``("choice", (node, ...), group_id)``     an inline group ``( a | b )``: reads a codon, same depth
``("rep", body, X, plus, rep_id)``        ``x*`` (``plus``: ``x+``), stop test ``codon mod (c+X) <= c``
``("opt", body)``                         ``[x]`` / ``x?``: emit when ``codon mod 2 == 1``
``("num", values, terminal)``            a numeric terminal: emit ``values[codon mod len(values)]``
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from genr8_dist.errors import UniverseError, located

if TYPE_CHECKING:
    from lark.lexer import Token
    from lark.tree import Tree

__all__ = ["CompiledGrammar", "EdgeTemplate", "compile_grammar"]

_DIRECTIVE = re.compile(r"^\s*//@\s*(\S+)\s*(.*?)\s*$")
_BOUND = re.compile(r"^EDGE_([XYZ])(?:_\w+)?$")
_PRED = re.compile(r"^PRED(?:_\w+)?$")
_CTX = re.compile(r"^CTX(?:_\w+)?$")
_LABELLED = re.compile(r"^EDGE(?:_\w+)?$")
_HOLE = re.compile(r"(\[0-9\]\+|\\d\+)")
_META = set(".^$*+?{}[]|()")
MAX_MAX_DEPTH = 100
MAX_NODES = 200_000   # grammar nodes (literals, edges, rule uses, groups) a universe may hold
MAX_NUMBER_VALUES = 10_000
#: The deepest nesting of groups ``( )`` and optionals ``[ ]`` a universe may write (grammars/README.md):
#: Lark's grammar loader and this compiler walk them recursively, so a deeper grammar is refused first.
MAX_NESTING = 100


@dataclass(frozen=True, slots=True)
class EdgeTemplate:
    """How one edge terminal prints and reads: ``prefix + label + suffix`` (e.g. ``Edge`` ``3`` ``_i+1``)."""

    terminal: str
    prefix: str
    suffix: str

    def text(self, label: int) -> str:
        """The token for ``label``."""
        return f"{self.prefix}{label}{self.suffix}"

    def regex(self) -> re.Pattern[str]:
        """A pattern matching this terminal's tokens, the label as group 1."""
        return re.compile(re.escape(self.prefix) + r"([0-9]+)" + re.escape(self.suffix))


#: A node of a grammar's IR: its kind first (``"lit"``, ``"edge"``, ``"ref"``, ``"seq"``, ``"alt"``,
#: ``"opt"``, ``"rep"``...), then fields that differ by kind (names, texts, child nodes).
Node = tuple[Any, ...]
#: A rule's alternatives.
Alternatives = tuple[Node, ...]


@dataclass(frozen=True)
class CompiledGrammar:
    """A universe's grammar as IR plus the tables the mapper and inverse need."""

    source: str
    text: str
    rules: dict[str, Alternatives]            # rule name -> tuple of alternative IR nodes
    need: dict[int, int]               # id(node) -> minimum height below the current rule
    min_depth: dict[str, int]          # rule -> minimum height of its expansion (itself counts 1)
    templates: tuple[EdgeTemplate, ...]
    repair_rule: str | None
    repair_depth: int                  # the depth at which the repair rule is expanded
    description: str
    start: str = "start"

    def alt_need(self, node: Node) -> int:
        """Minimum height (in rule levels) that ``node`` adds below the rule it sits in."""
        return self.need[id(node)]


class _Ctx:
    def __init__(self, source: str, text: str) -> None:
        self.source = source
        self.text = text

    def fail(self, message: str, name: str | None = None, *, define: bool = False) -> UniverseError:
        """An error located at ``name``'s definition (``define``) or first use in the grammar."""
        line, col = (0, 0)
        if name and define:
            line, col = _find_definition(self.text, name)
        if name and not line:
            line, col = _find(self.text, name)
        return UniverseError(located(message, self.source, line, col))

    def at(self, message: str, line: int) -> UniverseError:
        return UniverseError(located(message, self.source, line, 1))


def _find(text: str, name: str) -> tuple[int, int]:
    """Line and column of the first non-comment occurrence of ``name`` in ``text`` (1-based)."""
    pattern = re.compile(r"(?<![\w.])" + re.escape(name) + r"(?!\w)")
    for lineno, line in enumerate(text.splitlines(), 1):
        code = line.split("//", 1)[0]
        m = pattern.search(code)
        if m:
            return lineno, m.start() + 1
    return 0, 0


def _find_definition(text: str, name: str) -> tuple[int, int]:
    """Line and column of the definition ``name: ...`` (rule or terminal) in ``text``."""
    pattern = re.compile(r"^[ \t]*[?!]?" + re.escape(name) + r"(?:\.-?\d+)?\s*(?:\{[^}]*\})?\s*:",
                         re.MULTILINE)
    m = pattern.search(text)
    if not m:
        return 0, 0
    line = text.count("\n", 0, m.start()) + 1
    col = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1 + (len(m.group()) - len(m.group().lstrip()))
    return line, col


_LARK_NAMES = {"_COLON": "':'", "_DOT": "'.'", "_OR": "'|'", "_LPAR": "'('", "_RPAR": "')'",
               "_NL": "line break", "RULE": "rule name", "TOKEN": "terminal name",
               "STRING": "string", "REGEXP": "regular expression", "OP": "operator",
               "_LBRA": "'['", "_RBRA": "']'", "TERMINAL": "terminal name", "_LBRACE": "'{'",
               "_RBRACE": "'}'", "_TO": "'->'", "NUMBER": "number"}


def _lark_error(exc: Exception, ctx: _Ctx) -> UniverseError:
    """Lark's error as one line of ours: ``file:line:column: what``, the location given once."""
    message = str(exc).strip()
    first = message.splitlines()[0] if message else type(exc).__name__
    line = getattr(exc, "line", 0) or 0
    column = getattr(exc, "column", 0) or 0
    m = re.search(r"at line (\d+),? column (\d+)", message)
    if m and not line:
        line, column = int(m.group(1)), int(m.group(2))
    first = re.sub(r",?\s*at line \d+,? column \d+.*", "", first).rstrip(" .:")
    token = getattr(exc, "token", None)
    if token is not None:
        kind = _LARK_NAMES.get(getattr(token, "type", ""), "")
        expected = sorted(_LARK_NAMES.get(e, e) for e in (getattr(exc, "expected", None) or ()))
        first = f"syntax error: unexpected {kind + ' ' if kind else ''}{str(token)!r}"
        if expected:
            first += f"; expected {' or '.join(expected[:4])}"
    elif first.startswith("Unexpected input"):
        first = "syntax error: unexpected input (an unclosed string or a stray character?)"
    elif first.startswith("Expecting a value"):
        first = "syntax error: expected a value (a rule, terminal, string or group) here"
    if not line:
        m = re.search(r"'([A-Za-z_]\w*)'", first)
        if m:
            line, column = _find(ctx.text, m.group(1))
    return UniverseError(located(first, ctx.source, line, column))


def find_literal(text: str, literal: str) -> tuple[str, int, int] | None:
    """Where the string literal ``literal`` is written in grammar ``text``: (its rule or terminal,
    line, column), or ``None``."""
    quoted = [f'"{literal}"', f"'{literal}'"]
    owner = "?"
    for lineno, line in enumerate(text.splitlines(), 1):
        code = line.split("//", 1)[0]
        m = re.match(r"^\s*[?!]?([A-Za-z_]\w*)(?:\.-?\d+)?\s*:", code)
        if m:
            owner = m.group(1)
        for q in quoted:
            col = code.find(q)
            if col >= 0:
                terminal = owner.lstrip("_").isupper()
                what = f"terminal {owner}" if terminal else f"rule {owner}"
                return what, lineno, col + 1
    return None


def number_values(lo: str, hi: str, step: str = "1") -> tuple[str, ...]:
    """The printed values of a numeric terminal ``//@ number NAME LO HI [STEP]``: ``LO, LO + STEP, ...``
    up to ``HI``, computed exactly (decimal arithmetic) and printed with as many decimals as ``LO`` and
    ``STEP`` have (``-1 3`` gives ``-1 0 1 2 3``; ``0.5 2 0.5`` gives ``0.5 1.0 1.5 2.0``).

    ``ValueError`` when the bounds are not numbers, ``STEP <= 0``, ``HI < LO`` or there would be more
    than ``MAX_NUMBER_VALUES`` values."""
    try:
        a, b, d = Decimal(lo), Decimal(hi), Decimal(step)
    except InvalidOperation:
        raise ValueError("LO, HI and STEP must be numbers") from None
    if not (a.is_finite() and b.is_finite() and d.is_finite()):
        raise ValueError("LO, HI and STEP must be finite numbers")
    if d <= 0:
        raise ValueError(f"STEP must be > 0, got {step}")
    if b < a:
        raise ValueError(f"HI ({hi}) is below LO ({lo})")
    n = int((b - a) / d) + 1
    if n > MAX_NUMBER_VALUES:
        raise ValueError(f"{n} values; at most {MAX_NUMBER_VALUES} are allowed (a larger STEP?)")
    places = max(0, -a.as_tuple().exponent, -d.as_tuple().exponent)  # type: ignore[operator]
    return tuple(f"{a + i * d:.{places}f}" for i in range(n))


def _directives(text: str, ctx: _Ctx) -> tuple[dict[str, dict[int | None, int]], str | None, str,
                                                dict[str, int], dict[str, tuple[str, ...]]]:
    bias: dict[str, dict[int | None, int]] = {}
    repair: str | None = None
    description = ""
    where_line: dict[str, int] = {}
    numbers: dict[str, tuple[str, ...]] = {}
    for lineno, line in enumerate(text.splitlines(), 1):
        m = _DIRECTIVE.match(line)
        if not m:
            continue
        word, rest = m.group(1), m.group(2)
        where = (ctx.source, lineno, line.index("//@") + 1)
        if word == "bias":
            parts = rest.split()
            bm = re.fullmatch(r"([A-Za-z_]\w*)(?:#([1-9][0-9]*))?", parts[0]) if len(parts) == 2 else None
            if not bm or not parts[1].isdigit() or int(parts[1]) < 2:
                raise UniverseError(located(
                    f"bad directive '//@ bias {rest}': write '//@ bias RULE X' or '//@ bias RULE#K X' "
                    "with X an integer >= 2", *where))
            which = int(bm.group(2)) if bm.group(2) else None
            bias.setdefault(bm.group(1), {})[which] = int(parts[1])
            where_line[f"bias {bm.group(1)}"] = lineno
        elif word == "repair":
            if not re.fullmatch(r"[A-Za-z_]\w*", rest):
                raise UniverseError(located(
                    f"bad directive '//@ repair {rest}': write '//@ repair RULE'", *where))
            repair = rest
            where_line["repair"] = lineno
        elif word == "description":
            description = rest
        elif word == "number":
            parts = rest.split()
            usage = (f"bad directive '//@ number {rest}': write '//@ number TERMINAL LO HI' or "
                     "'//@ number TERMINAL LO HI STEP'")
            if len(parts) not in (3, 4) or not re.fullmatch(r"[A-Z_][A-Z0-9_]*", parts[0]):
                raise UniverseError(located(usage, *where))
            try:
                numbers[parts[0]] = number_values(*parts[1:])
            except ValueError as exc:
                raise UniverseError(located(f"{usage} ({exc})", *where)) from None
            where_line[f"number {parts[0]}"] = lineno
        else:
            raise UniverseError(located(
                f"unknown directive '//@ {word}' (known: bias, repair, description, number)", *where))
    return bias, repair, description, where_line, numbers


def _literal(token: Token, ctx: _Ctx, owner: str) -> tuple[str, str]:
    """('lit', text) for a string literal, ('re', body) for a regular expression."""
    value = str(token)
    if token.type == "STRING":
        body = value.rstrip("i")
        try:
            return "lit", ast.literal_eval(body)
        except (ValueError, SyntaxError) as exc:
            raise ctx.fail(f"cannot read string literal {value} in {owner}", owner) from exc
    if token.type == "REGEXP":
        return "re", value[1:value.rindex("/")]
    raise ctx.fail(f"unsupported literal {value} in {owner}", owner)


def _template(name: str, body: str, ctx: _Ctx) -> EdgeTemplate:
    holes = list(_HOLE.finditer(body))
    bad = ctx.fail(
        f"edge terminal {name} must be written /PREFIX[0-9]+SUFFIX/ with literal text around one "
        f"label hole, got /{body}/", name, define=True)
    if len(holes) != 1:
        raise bad
    hole = holes[0]

    def unescape(part: str) -> str:
        out, i = [], 0
        while i < len(part):
            ch = part[i]
            if ch == "\\":
                if i + 1 >= len(part) or part[i + 1].isalnum():
                    raise bad
                out.append(part[i + 1])
                i += 2
                continue
            if ch in _META:
                raise bad
            out.append(ch)
            i += 1
        return "".join(out)

    prefix, suffix = unescape(body[:hole.start()]), unescape(body[hole.end():])
    if not prefix or any(c.isspace() for c in prefix + suffix):
        raise bad
    return EdgeTemplate(name, prefix, suffix)


def _check_nesting(text: str, ctx: _Ctx) -> None:
    """``UniverseError`` at the first ``(`` or ``[`` that opens more than ``MAX_NESTING`` groups (strings,
    regular expressions and comments skipped as Lark reads them; one linear scan)."""
    if text.count("(") + text.count("[") <= MAX_NESTING:
        return
    depth, i, n = 0, 0, len(text)
    while i < n:
        ch = text[i]
        if ch == '"' or (ch == "/" and text[i + 1:i + 2] != "/"):   # a string or a regular expression
            i += 1
            while i < n and text[i] != ch and text[i] != "\n":
                i += 2 if text[i] == "\\" else 1
        elif ch == "/":   # a comment, to the end of the line
            end = text.find("\n", i)
            i = n if end < 0 else end
            continue
        elif ch in "([":
            depth += 1
            if depth > MAX_NESTING:
                line = text.count("\n", 0, i) + 1
                column = i - (text.rfind("\n", 0, i) + 1) + 1
                raise UniverseError(located(f"groups nest deeper than {MAX_NESTING} levels (the limit of a "
                                            "universe, grammars/README.md)", ctx.source, line, column))
        elif ch in ")]":
            depth = max(depth - 1, 0)
        i += 1


def compile_grammar(text: str, source: str = "<universe>") -> CompiledGrammar:
    """Compile the Lark grammar ``text`` (read from ``source``) into a :class:`CompiledGrammar`."""
    from lark.exceptions import LarkError
    from lark.lexer import Token
    from lark.load_grammar import GrammarBuilder
    from lark.tree import Tree

    ctx = _Ctx(source, text)
    _check_nesting(text, ctx)
    bias, repair_rule, description, directive_line, numbers = _directives(text, ctx)
    try:
        builder = GrammarBuilder()
        builder.load_grammar(text, source)
        grammar = builder.build()
    except LarkError as exc:
        raise _lark_error(exc, ctx) from None

    # Terminals: resolve each named terminal to a literal, an edge template or "unusable".
    term_trees = {str(name): tree for name, (tree, _prio) in grammar.term_defs}
    templates: dict[str, EdgeTemplate] = {}
    term_kind: dict[str, Node] = {}

    def term_value(tree: Tree[Token]) -> tuple[str, str] | None:
        node: Tree[Token] | Token = tree
        while isinstance(node, Tree) and node.data in ("expansions", "expansion", "value") \
                and len(node.children) == 1:
            node = node.children[0]
        if isinstance(node, Tree) and node.data == "literal":
            return _literal(cast("Token", node.children[0]), ctx, "terminal")  # a literal's one token
        return None

    def classify(name: str) -> Node:
        if name in term_kind:
            return term_kind[name]
        if name not in term_trees:
            raise ctx.fail(f"terminal {name} is used but not defined", name)
        value = term_value(term_trees[name])
        bound, pred, labelled = _BOUND.match(name), _PRED.match(name), _LABELLED.match(name)
        context = _CTX.match(name)
        if name in numbers:
            if value is None or value[0] != "re":
                raise ctx.fail(f"numeric terminal {name} must be defined by a regular expression "
                               "matching its values, such as /-?[0-9]+/", name, define=True)
            pattern = re.compile(value[1])
            bad = [v for v in numbers[name] if not pattern.fullmatch(v)]
            if bad:
                raise ctx.fail(f"numeric terminal {name}: its pattern /{value[1]}/ does not match the "
                               f"value {bad[0]} of its '//@ number' range", name, define=True)
            kind: tuple[Any, ...] = ("num", numbers[name], name)
        elif bound or pred or labelled or context:
            if value is None or value[0] != "re":
                raise ctx.fail(f"edge terminal {name} must be defined by a regular expression "
                               "such as /Edge[0-9]+/", name, define=True)
            templates.setdefault(name, _template(name, value[1], ctx))
            index = list(templates).index(name)
            if bound:
                kind = ("edge", "B", index, bound.group(1))
            else:
                kind = ("edge", "P" if pred else "C" if context else "L", index, None)
        elif value is not None and value[0] == "lit":
            kind = ("lit", value[1])
        else:
            raise ctx.fail(f"terminal {name} cannot be generated: only string literals, edge "
                           "terminals (EDGE*, PRED*, CTX*, EDGE_X/Y/Z) and numeric terminals (a "
                           "'//@ number' directive) can appear in a universe's rules",
                           name, define=True)
        term_kind[name] = kind
        return kind

    rule_names = [str(name) for name, *_ in grammar.rule_defs]
    rules: dict[str, Alternatives] = {}
    rep_counter = [0]
    group_counter = [0]

    def convert(node: Any, rule: str, reps: list[int]) -> Node:
        from lark.grammar import NonTerminal, Terminal

        if isinstance(node, Terminal):
            return classify(str(node.name))
        if isinstance(node, NonTerminal):
            if str(node.name) not in rule_names:
                raise ctx.fail(f"rule {node.name} is used but not defined", str(node.name))
            return ("rule", str(node.name))
        if isinstance(node, Token):
            raise ctx.fail(f"unexpected token {node!s} in rule {rule}", rule)
        data = node.data
        if data == "expansions":
            alts = tuple(convert(child, rule, reps) for child in node.children)
            if len(alts) == 1:
                return alts[0]
            group_counter[0] += 1
            return ("choice", alts, group_counter[0])
        if data == "alias":
            return convert(node.children[0], rule, reps)
        if data == "expansion":
            items = tuple(convert(child, rule, reps) for child in node.children)
            return items[0] if len(items) == 1 else ("seq", items)
        if data == "value":
            return convert(node.children[0], rule, reps)
        if data == "literal":
            kind, value = _literal(node.children[0], ctx, f"rule {rule}")
            if kind != "lit":
                raise ctx.fail(f"rule {rule} uses the regular expression /{value}/ directly; define "
                               "an edge terminal (EDGE: /Edge[0-9]+/) instead", rule, define=True)
            return ("lit", value)
        if data == "maybe":
            return ("opt", convert(node.children[0], rule, reps))
        if data == "expr":
            body, op = node.children[0], str(node.children[1])
            if len(node.children) > 2 or op not in ("*", "+", "?"):
                raise ctx.fail(f"rule {rule} uses the repetition range '~'; universes support "
                               "only ?, [], *, + and groups", rule, define=True)
            inner = convert(body, rule, reps)
            if op == "?":
                return ("opt", inner)
            reps.append(0)
            rep_counter[0] += 1
            rule_bias = bias.get(rule, {})
            x = rule_bias.get(len(reps), rule_bias.get(None, 2))
            return ("rep", inner, x, op == "+", rep_counter[0])
        raise ctx.fail(f"rule {rule} uses the Lark construct '{data}', which universes do not "
                       "support (no templates, ranges or lookarounds)", rule)

    for raw_name, params, tree, _options in grammar.rule_defs:
        name = str(raw_name)
        if params:
            raise ctx.fail(f"rule {name} is a template; universes do not support templates", name,
                           define=True)
        reps: list[int] = []
        top = tree
        if isinstance(top, Tree) and top.data == "expansions":
            alts = tuple(convert(child, name, reps) for child in top.children)
        else:
            alts = (convert(top, name, reps),)
        rules[name] = alts
        for which in bias.get(name, {}):
            if which is not None and which > len(reps):
                raise ctx.at(f"'//@ bias {name}#{which}': rule {name} has only {len(reps)} "
                             "repetition(s)", directive_line[f"bias {name}"])
    for name in bias:
        if name not in rules:
            raise ctx.at(f"'//@ bias {name}' names no rule of this universe",
                         directive_line[f"bias {name}"])
    for name in numbers:
        if name not in term_kind:
            raise ctx.at(f"'//@ number {name}' names no terminal used in this universe's rules",
                         directive_line[f"number {name}"])
    if "start" not in rules:
        raise UniverseError(located("a universe needs a rule named 'start'", source, 1, 1))
    _check_literals(rules, term_kind, ctx)
    nodes = sum(1 for alts in rules.values() for alt in alts for _ in _nodes(alt))
    if nodes > MAX_NODES:
        raise UniverseError(located(f"the universe is too large: {nodes} grammar nodes in {len(rules)} "
                                    f"rules (at most {MAX_NODES})", source))
    try:  # what the inverse's Lark parser will need: optionals side by side can collide
        grammar.compile(["start"], set())
    except LarkError as exc:
        raise _collision(exc, ctx) from None

    min_depth, need = _min_depths(rules, ctx)
    repair_depth = 0
    if repair_rule is not None:
        if repair_rule not in rules:
            raise ctx.at(f"'//@ repair {repair_rule}' names no rule of this universe",
                         directive_line["repair"])
        repair_depth = _reach_depth(rules, repair_rule)
        if repair_depth == 0:
            raise ctx.at(f"repair rule {repair_rule} is not reachable from start", directive_line["repair"])
    return CompiledGrammar(source=source, text=text, rules=rules, need=need, min_depth=min_depth,
                           templates=tuple(templates.values()), repair_rule=repair_rule,
                           repair_depth=repair_depth, description=description)


def _nodes(node: Node) -> Iterator[Node]:
    """Every IR node under ``node`` (iteratively: deep nesting is no problem)."""
    stack = [node]
    while stack:
        cur = stack.pop()
        yield cur
        if cur[0] in ("seq", "choice"):
            stack.extend(cur[1])
        elif cur[0] in ("rep", "opt"):
            stack.append(cur[1])


def _check_literals(rules: dict[str, Alternatives], term_kind: dict[str, Node], ctx: _Ctx) -> None:
    """A literal must be one token of the text: tokens are separated by single spaces and read back
    split at whitespace, so a literal holding whitespace (other than the line break "\\n") would come
    back as several tokens."""
    seen: set[str] = set()
    literals = [n[1] for alts in rules.values() for alt in alts for n in _nodes(alt) if n[0] == "lit"]
    literals += [k[1] for k in term_kind.values() if k[0] == "lit"]
    for lit in literals:
        if lit in seen or lit == "\n":
            continue
        seen.add(lit)
        if lit == "" or any(c.isspace() for c in lit):
            at = find_literal(ctx.text, lit)
            what, line, col = at if at is not None else ("?", 0, 0)
            problem = "is empty" if lit == "" else "holds whitespace"
            raise UniverseError(located(
                f"the literal {lit!r} in {what} {problem}: a literal is one token of the text (tokens "
                "are separated by spaces); split it into several literals", ctx.source, line, col))


def _collision(exc: Exception, ctx: _Ctx) -> UniverseError:
    message = str(exc)
    m = re.search(r"<(\w+)\s*:", message)
    rule = m.group(1) if m else None
    if "defined twice" in message and rule:
        return ctx.fail(
            f"rule {rule}: its optional parts ([...] or ?) side by side can expand to the same sequence "
            "in two ways, so the parser the inverse mapping needs cannot be built; write them as one "
            "repetition (x*) or give each optional part its own rule", rule, define=True)
    return _lark_error(exc, ctx)


def _min_depths(rules: dict[str, Alternatives], ctx: _Ctx) -> tuple[dict[str, int], dict[int, int]]:
    """Fixpoint of each rule's minimum derivation height, and every IR node's minimum need."""
    md = {name: math.inf for name in rules}

    def need(node: Node) -> float:
        kind = node[0]
        if kind in ("lit", "edge", "num"):
            return 0
        if kind == "rule":
            return md[node[1]]
        if kind == "seq":
            return max((need(child) for child in node[1]), default=0)
        if kind == "choice":
            return min(need(child) for child in node[1])
        if kind == "rep":
            return need(node[1]) if node[3] else 0
        return 0  # opt

    changed = True
    while changed:
        changed = False
        for name, alts in rules.items():
            value = 1 + min(need(alt) for alt in alts)
            if value < md[name]:
                md[name] = value
                changed = True
    endless = [name for name, value in md.items() if value == math.inf]
    if endless:
        name = _recursing_rule(rules, set(endless))
        raise ctx.fail(f"rule {name} can never finish: every alternative expands {name} again "
                       "(directly or through other rules); give it an alternative without it", name,
                       define=True)

    table: dict[int, int] = {}

    def fill(node: Node) -> None:
        table[id(node)] = int(need(node))
        if node[0] == "seq" or node[0] == "choice":
            for child in node[1]:
                fill(child)
        elif node[0] in ("rep", "opt"):
            fill(node[1])
            table[id(node[1])] = int(need(node[1]))

    for alts in rules.values():
        for alt in alts:
            fill(alt)
    return {k: int(v) for k, v in md.items()}, table


def _recursing_rule(rules: dict[str, Alternatives], endless: set[str]) -> str:
    """Among rules that can never finish, the first (in file order) of a group that recurses on
    itself and needs no other endless rule: the rule to fix, not the rules that merely use it."""
    calls = {name: {n[1] for alt in rules[name] for n in _nodes(alt) if n[0] == "rule" and n[1] in endless}
             for name in endless}

    def reach(name: str) -> set[str]:
        seen, stack = set(), list(calls[name])
        while stack:
            cur = stack.pop()
            if cur not in seen:
                seen.add(cur)
                stack.extend(calls[cur])
        return seen

    reaches = {name: reach(name) for name in endless}
    order = [name for name in rules if name in endless]
    for name in order:
        # a sink group: every endless rule it reaches reaches it back
        if name in reaches[name] and all(name in reaches[other] for other in reaches[name]):
            return name
    return order[0]


def _reach_depth(rules: dict[str, Alternatives], target: str) -> int:
    """The shallowest depth (start = 1) at which ``target`` is expanded, 0 when unreachable."""
    depth = {"start": 1}
    frontier = ["start"]
    while frontier:
        nxt: list[str] = []
        for name in frontier:
            stack = list(rules[name])
            while stack:
                node = stack.pop()
                if node[0] == "rule":
                    if node[1] not in depth:
                        depth[node[1]] = depth[name] + 1
                        nxt.append(node[1])
                elif node[0] in ("seq", "choice"):
                    stack.extend(node[1])
                elif node[0] in ("rep", "opt"):
                    stack.append(node[1])
        frontier = nxt
    return depth.get(target, 0)


def read_grammar_file(path: Path) -> str:
    """The text of a ``.lark`` file; a missing or unreadable file is a :class:`UniverseError`."""
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise UniverseError(f"{path}: cannot read universe file: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise UniverseError(f"{path}: universe file is not UTF-8: {exc.reason}") from None
