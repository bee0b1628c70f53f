"""The GE mapper: a universe's compiled grammar turned into one specialised Python function.

Walking the grammar per codon is slow in Python, so each universe is compiled once per ``max_depth``
into Python source and ``exec``'d: rules that cannot recurse are inlined where they are used, and
wherever the depth is known when the code is generated the eligible alternatives are decided then;
recursive rules become nested functions that look their eligible alternatives up in precomputed
per-depth tables; consecutive literals are emitted by one ``extend`` call. ``genr8_dist.grammar``
caches the result. The semantics are Genr8's (``DESIGN.md``, thesis Appendix B, journal 5.1):

* every rule expansion reads one codon, even with one alternative; the alternative is
  ``codon mod n`` among the ``n`` alternatives that still fit in ``max_depth``;
* a repetition reads a codon before each round and stops when ``codon mod (c + X) <= c``
  (``c`` rounds so far, ``X`` the bias, default 2); ``x+`` emits one ``x`` first;
* an option emits its body when ``codon mod 2 == 1``;
* a numeric terminal (``//@ number NAME LO HI STEP``) emits ``LO + (codon mod n) * STEP``, ``n`` its
  number of values;
* a labelled edge takes ``codon mod (count + 1)`` (a new label is born when it equals ``count``),
  a predecessor edge ``codon mod count``; ``EdgeX/Y/Z`` bind within one rule expansion;
* a repetition or option whose body opens rules that cannot fit in ``max_depth`` reads its codon
  and emits nothing;
* the genome wraps at most ``max_wraps`` times; reading past that raises ``StopIteration``, which
  :class:`~genr8_dist.grammar.universe.Universe` turns into an invalid result with its reason.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple

from genr8_dist.grammar.compiler import Alternatives, CompiledGrammar, Node

__all__ = ["CompiledMapper", "MapResult", "build_source", "compile_mapper", "eligible"]

_PRESIZE = 256
#: Where generated code is: (the variable holding the depth, or None when it is known now; the offset)
Depth = tuple[str | None, int]
#: (the bound edge letters surely drawn, those maybe drawn) at a point of the generated code
Drawn = tuple[frozenset[str], frozenset[str]]


class MapResult(NamedTuple):
    """The outcome of mapping one genome (an immutable record; a named tuple because it is made
    tens of thousands of times a second).

    ``text`` is the rewrite system (``None`` when invalid), ``reason`` says why a genome is invalid,
    ``codons_used`` counts codons read (wrapping included) and ``wraps`` how often the genome wrapped.
    """

    text: str | None
    valid: bool
    reason: str | None
    codons_used: int
    wraps: int


def eligible(cg: CompiledGrammar, alts: Alternatives, depth: int, max_depth: int) -> tuple[int, ...]:
    """Indices of ``alts`` that can finish within ``max_depth`` when expanded at ``depth``.

    When none can (the universe is deeper than ``max_depth`` allows), the shallowest ones are
    eligible, so that no genome is ever invalid because of depth.
    """
    needs = [cg.alt_need(alt) for alt in alts]
    fit = tuple(i for i, n in enumerate(needs) if depth + n <= max_depth)
    if fit:
        return fit
    low = min(needs)
    return tuple(i for i, n in enumerate(needs) if n == low)


class _Writer:
    """Emits the Python source of one mapping function (main derivation or repair).

    Rules that are not recursive are inlined, and where the depth is known when generating the code
    (everything outside recursive rules) the eligible alternatives are decided here, not per codon.
    A depth is ``(var, offset)``: ``(None, 3)`` is the constant 3, ``("d", 1)`` is ``d + 1``.
    """

    def __init__(self, cg: CompiledGrammar, max_depth: int, birth: bool, suffix: str) -> None:
        self.cg = cg
        self.maxd = max_depth
        self.birth = birth
        self.suffix = suffix
        self.recursive = _recursive_rules(cg)
        self.functions_for = self.recursive | _too_big_to_inline(cg, self.recursive)
        self._sets: dict[tuple[int, bool, int], set[tuple[int, ...]]] = {}
        self.checked: set[str] = set()
        self.functions: dict[str, list[str]] = {}
        self.pending: list[str] = []
        self.counter = 0
        self.draws = False

    def eligible_sets(self, alts: Alternatives, dep: Depth) -> set[tuple[int, ...]]:
        """The distinct eligible-alternative tuples ``alts`` can have at depth ``dep`` (memoised)."""
        key = (id(alts), dep[0] is None, dep[1])
        found = self._sets.get(key)
        if found is None:
            if dep[0] is None:
                found = {eligible(self.cg, alts, dep[1], self.maxd)}
            else:
                top = max(self.maxd, max(self.cg.min_depth.values())) + 2
                found = {eligible(self.cg, alts, d + dep[1], self.maxd) for d in range(1, top + 1)}
            self._sets[key] = found
        return found

    def fresh(self, stem: str) -> str:
        self.counter += 1
        return f"{stem}{self.counter}"

    @staticmethod
    def dexpr(dep: Depth) -> str:
        var, off = dep
        if var is None:
            return str(off)
        return f"{var} + {off}" if off else var

    def body(self, root: str, depth: int) -> tuple[list[str], list[str]]:
        """The functions needed, and the code (indentation 0) expanding ``root`` at ``depth``."""
        self.draws = False
        main: list[str] = []
        self.rule_ref(root, main, 0, (None, depth))
        main_draws = self.draws
        while self.pending:
            name = self.pending.pop()
            self.draws = False
            lines = [f"def r_{name}{self.suffix}(d):"]
            self.inline_rule(name, lines, 1, ("d", 0))
            if self.draws and self.birth:
                lines.insert(1, "    nonlocal count")
            self.functions[name] = lines
        self.draws = main_draws
        funcs: list[str] = []
        for lines in self.functions.values():
            funcs.extend(lines)
        return funcs, main

    def rule_ref(self, name: str, out: list[str], ind: int, dep: Depth) -> None:
        if name in self.functions_for:
            if name not in self.functions and name not in self.pending:
                self.functions[name] = []
                self.pending.append(name)
            out.append(f"{'    ' * ind}r_{name}{self.suffix}({self.dexpr(dep)})")
        else:
            self.inline_rule(name, out, ind, dep)

    def choose(self, alts: Alternatives, table: str, out: list[str], ind: int, dep: Depth,
               scope: dict[str, str], state: Drawn) -> Drawn:
        """Read a codon and run the chosen alternative among those eligible at ``dep``."""
        pad = "    " * ind
        if len(alts) == 1:
            out.append(f"{pad}nxt()")
            return self.node(alts[0], out, ind, dep, scope, state)
        sets = self.eligible_sets(alts, dep)
        if len(sets) == 1:
            elig = next(iter(sets))
            if len(elig) == 1:
                out.append(f"{pad}nxt()")
                return self.node(alts[elig[0]], out, ind, dep, scope, state)
            k = self.fresh("k")
            out.append(f"{pad}{k} = nxt() % {len(elig)}")
            maybe = set(state[1])
            for j, i in enumerate(elig):
                out.append(f"{pad}{'if' if j == 0 else 'elif'} {k} == {j}:" if j < len(elig) - 1
                           else f"{pad}else:")
                maybe |= self.block(alts[i], out, ind + 1, dep, scope, state)[1]
            return state[0], frozenset(maybe)
        k, e = self.fresh("k"), self.fresh("e")
        out.append(f"{pad}{e} = {table}[{self.dexpr(dep)}]")
        out.append(f"{pad}{k} = {e}[nxt() % len({e})]")
        used = sorted(set().union(*sets))
        maybe = set(state[1])
        for j, i in enumerate(used):
            out.append(f"{pad}{'if' if j == 0 else 'elif'} {k} == {i}:" if j < len(used) - 1
                       else f"{pad}else:")
            maybe |= self.block(alts[i], out, ind + 1, dep, scope, state)[1]
        return state[0], frozenset(maybe)

    def block(self, node: Node, out: list[str], ind: int, dep: Depth, scope: dict[str, str],
              state: Drawn) -> Drawn:
        before = len(out)
        result = self.node(node, out, ind, dep, scope, state)
        if len(out) == before:
            out.append("    " * ind + "pass")
        return result

    def inline_rule(self, name: str, out: list[str], ind: int, dep: Depth) -> None:
        alts = self.cg.rules[name]
        scope = {letter: self.fresh(f"b{letter}") for letter in sorted(_bound_letters(alts))}
        start = len(out)
        self.choose(alts, f"EL_{name}", out, ind, dep, scope, (frozenset(), frozenset()))
        # A bound edge needs "bX = -1" only where the code must test whether it was drawn yet.
        inits = [f"{'    ' * ind}{var} = -1" for var in scope.values() if var in self.checked]
        out[start:start] = inits

    def fits(self, need: int, dep: Depth) -> bool | str:
        """True/False when known now, else the runtime test (as code) that the body fits."""
        if need == 0:
            return True
        if dep[0] is None:
            return dep[1] + need <= self.maxd
        return f"{self.dexpr(dep)} + {need} <= {self.maxd}"

    def node(self, node: Node, out: list[str], ind: int, dep: Depth, scope: dict[str, str],
             state: Drawn) -> Drawn:
        """Append code for ``node``. ``state`` is (bound letters surely drawn, letters maybe drawn)
        before it; returns the state after it."""
        pad = "    " * ind
        kind = node[0]
        if kind == "lit":
            out.append(f"{pad}app({node[1]!r})")
            return state
        if kind == "edge":
            return self.edge(node, out, pad, scope, state)
        if kind == "num":
            values = node[1]
            out.append(f"{pad}app({values!r}[nxt() % {len(values)}])" if len(values) > 1
                       else f"{pad}nxt()\n{pad}app({values[0]!r})")
            return state
        if kind == "rule":
            self.rule_ref(node[1], out, ind, (dep[0], dep[1] + 1))
            return state
        if kind == "seq":
            items = list(node[1])
            i = 0
            while i < len(items):
                if items[i][0] == "lit":
                    j = i
                    while j < len(items) and items[j][0] == "lit":
                        j += 1
                    if j - i > 1:
                        texts = tuple(item[1] for item in items[i:j])
                        out.append(f"{pad}ext_({texts!r})")
                        i = j
                        continue
                state = self.node(items[i], out, ind, dep, scope, state)
                i += 1
            return state
        if kind == "choice":
            return self.choose(node[1], f"EG_{node[2]}", out, ind, dep, scope, state)
        if kind == "opt":
            fit = self.fits(self.cg.alt_need(node[1]), dep)
            if fit is False:
                out.append(f"{pad}nxt()")
                return state
            test = "nxt() & 1" if fit is True else f"nxt() & 1 and {fit}"
            out.append(f"{pad}if {test}:")
            after = self.block(node[1], out, ind + 1, dep, scope, state)
            return state[0], after[1]
        if kind == "rep":
            inner, x, plus = node[1], node[2], node[3]
            if plus:
                state = self.node(inner, out, ind, dep, scope, state)
            fit = self.fits(self.cg.alt_need(inner), dep)
            if fit is False:
                out.append(f"{pad}nxt()")
                return state
            c = self.fresh("c")
            out.append(f"{pad}{c} = 0")
            extra = "" if fit is True else f" and {fit}"
            out.append(f"{pad}while nxt() % ({c} + {x}) > {c}{extra}:")
            # A later round may find a letter drawn by an earlier one.
            looping = (state[0], state[1] | {n[3] for n in _walk(inner) if n[0] == "edge" and n[1] == "B"})
            after = self.node(inner, out, ind + 1, dep, scope, looping)
            out.append(f"{pad}    {c} += 1")
            return state[0], after[1]
        raise AssertionError(kind)

    def draw(self, target: str, out: list[str], pad: str) -> None:
        """Code that draws a labelled edge's label into ``target``."""
        if not self.birth:
            out.append(f"{pad}{target} = nxt() % count")
            return
        self.draws = True
        out.append(f"{pad}{target} = nxt() % (count + 1)")
        out.append(f"{pad}if {target} == count:")
        out.append(f"{pad}    count += 1")
        out.append(f"{pad}    if count >= len(ES0):")
        out.append(f"{pad}        grow(count)")

    def edge(self, node: Node, out: list[str], pad: str, scope: dict[str, str], state: Drawn) -> Drawn:
        _, mode, template, letter = node
        table = f"ES{template}"
        if mode == "P" and self.birth:
            out.append(f"{pad}lab = nxt() % count")
            out.append(f"{pad}has_rule(lab)")
            out.append(f"{pad}app({table}[lab])")
            return state
        if mode in ("P", "C"):
            out.append(f"{pad}app({table}[nxt() % count])")
            return state
        if mode == "L":
            self.draw("lab", out, pad)
            out.append(f"{pad}app({table}[lab])")
            return state
        var = scope[letter]
        bound, maybe = state
        if letter not in maybe:  # surely not drawn yet: draw
            self.draw(var, out, pad)
        elif letter not in bound:  # perhaps drawn: test
            self.checked.add(var)
            out.append(f"{pad}if {var} < 0:")
            self.draw(var, out, pad + "    ")
        out.append(f"{pad}app({table}[{var}])")
        return bound | {letter}, maybe | {letter}


INLINE_NODES = 400    # a rule whose inlined code would exceed this many grammar nodes becomes a function
INLINE_NESTING = 12   # ... or nest deeper than this many blocks (Python allows 20 nested loops)


def _too_big_to_inline(cg: CompiledGrammar, recursive: set[str]) -> set[str]:
    """Non-recursive rules whose inlined code would be too large or too deeply nested.

    Inlining copies a rule's code into every place that uses it, so a chain of rules each using the
    next twice would grow as 2^n; the cost of each rule is memoised bottom-up (rules are visited in
    dependency order), which keeps this and the generated code polynomial in the grammar's size."""
    cost: dict[str, tuple[int, int]] = {}
    big: set[str] = set()

    def node_cost(node: Node) -> tuple[int, int]:
        kind = node[0]
        if kind == "rule":
            name = node[1]
            if name in recursive or name in big:
                return 1, 0
            return rule_cost(name)
        if kind in ("seq", "choice"):
            size, depth = 1, 0
            for child in node[1]:
                s, d = node_cost(child)
                size += s
                depth = max(depth, d)
            return size, depth + (kind == "choice")
        if kind in ("rep", "opt"):
            s, d = node_cost(node[1])
            return s + 1, d + 1
        return 1, 0

    def rule_cost(name: str) -> tuple[int, int]:
        found = cost.get(name)
        if found is not None:
            return found
        size, depth = 1, 0
        for alt in cg.rules[name]:
            s, d = node_cost(alt)
            size += s
            depth = max(depth, d)
        depth += 1
        if size > INLINE_NODES or depth > INLINE_NESTING:
            big.add(name)
            cost[name] = (1, 0)
        else:
            cost[name] = (size, depth)
        return cost[name]

    for name in _dependency_order(cg, recursive):
        rule_cost(name)
    return big


def _dependency_order(cg: CompiledGrammar, recursive: set[str]) -> list[str]:
    """The non-recursive rules, each after every rule it uses (so costs are known bottom-up)."""
    calls = {name: [n[1] for alt in alts for n in _walk(alt) if n[0] == "rule"]
             for name, alts in cg.rules.items()}
    order: list[str] = []
    done: set[str] = set(recursive)
    for root in cg.rules:
        if root in done:
            continue
        stack = [(root, iter(calls[root]))]
        done.add(root)
        while stack:
            name, it = stack[-1]
            child = next(it, None)
            if child is None:
                stack.pop()
                order.append(name)
            elif child not in done:
                done.add(child)
                stack.append((child, iter(calls[child])))
    return order


def _recursive_rules(cg: CompiledGrammar) -> set[str]:
    """Rules that can expand themselves again (directly or through others)."""
    calls = {name: {n[1] for alt in alts for n in _walk(alt) if n[0] == "rule"}
             for name, alts in cg.rules.items()}
    result = set()
    for name in calls:
        seen, stack = set(), list(calls[name])
        while stack:
            cur = stack.pop()
            if cur == name:
                result.add(name)
                break
            if cur not in seen:
                seen.add(cur)
                stack.extend(calls[cur])
    return result


def _walk(node: Node) -> Iterator[Node]:
    yield node
    if node[0] in ("seq", "choice"):
        for child in node[1]:
            yield from _walk(child)
    elif node[0] in ("rep", "opt"):
        yield from _walk(node[1])


def _bound_letters(alts: Alternatives) -> set[str]:
    return {n[3] for alt in alts for n in _walk(alt) if n[0] == "edge" and n[1] == "B"}


def build_source(cg: CompiledGrammar, max_depth: int, pred_template: int | None = None) -> str:
    """The Python source of the factory ``make(EL, EG, ES, DT, grow, get)`` for this grammar and depth.

    With ``pred_template`` (the index of the template repaired predecessors are printed with) it
    also defines ``derive_hemls``: the main derivation followed by the built-in HEMLS repair
    (:func:`genr8_dist.grammar.hooks.hemls_repair`) in one function, the fast path of ``map``.
    """
    lines = ["def make(EL, EG, ES, DT, grow, get):"]
    for name in cg.rules:
        lines.append(f"    EL_{name} = EL[{name!r}]")
    for gid in _group_ids(cg):
        lines.append(f"    EG_{gid} = EG[{gid}]")
    for i in range(max(1, len(cg.templates))):
        lines.append(f"    ES{i} = ES[{i}]")
    main = _Writer(cg, max_depth, birth=True, suffix="")
    funcs, code = main.body(cg.start, 1)
    lines.append("    def derive(nxt, out, has_rule):")
    lines.append("        app = out.append")
    lines.append("        ext_ = out.extend")
    lines.append("        count = 2")
    lines.extend("        " + line for line in funcs + code)
    lines.append("        return count")
    derive_hemls = False
    if cg.repair_rule is not None:
        rep = _Writer(cg, max_depth, birth=False, suffix="_r")
        rfuncs, rbody = rep.body(cg.repair_rule, cg.repair_depth)
        # repair(nxt, out, count) -> expand(): the rule functions are made once per genome, and
        # each expand() call appends one expansion of the repair rule to ``out``.
        lines.append("    def repair(nxt, out, count):")
        lines.append("        app = out.append")
        lines.append("        ext_ = out.extend")
        lines.extend("        " + line for line in rfuncs)
        lines.append("        def expand():")
        lines.extend("            " + line for line in rbody)
        lines.append("            return None")
        lines.append("        return expand")
        if pred_template is not None:
            derive_hemls = True
            lines.append("    def derive_hemls(nxt, out, has):")
            lines.append("        has_rule = has.add")
            lines.append("        app = out.append")
            lines.append("        ext_ = out.extend")
            lines.append("        count = 2")
            lines.extend("        " + line for line in funcs + rfuncs + code)
            lines.append("        missing = {k for k in range(count) if k not in has}")
            lines.append("        if not missing or '->' not in out:")
            lines.append("            return count, None")
            forms = len(dict.fromkeys((t.prefix, t.suffix) for t in cg.templates))
            for k in (0, 1):  # labels 0 and 1 exist from the start but may never occur
                absent = " and ".join(f"DT[{j}][{k}] not in out" for j in range(forms)) or "True"
                lines.append(f"        if {k} in missing and {absent}:")
                lines.append(f"            missing.discard({k})")
            lines.append("        new = []")
            lines.append("        rout = []")
            lines.append("        app = rout.append")
            lines.append("        ext_ = rout.extend")
            lines.append("        while missing:")
            lines.append("            label = min(missing)")
            lines.append("            missing.discard(label)")
            lines.append("            has.add(label)")
            lines.append("            rout.clear()")
            lines.extend("            " + line for line in rbody)
            lines.append(f"            new.append(' '.join([ES{pred_template}[label], '->', *rout]))")
            lines.append("            for lab in set(map(get, rout)):")
            lines.append("                if lab is not None and lab not in has:")
            lines.append("                    missing.add(lab)")
            lines.append("        return count, new")
    else:
        lines.append("    repair = None")
    if not derive_hemls:
        lines.append("    derive_hemls = None")
    lines.append("    return derive, repair, derive_hemls")
    return "\n".join(lines) + "\n"


def _group_ids(cg: CompiledGrammar) -> list[int]:
    return sorted({n[2] for alts in cg.rules.values() for alt in alts for n in _walk(alt)
                   if n[0] == "choice"})


def _groups(cg: CompiledGrammar) -> dict[int, Alternatives]:
    return {n[2]: n[1] for alts in cg.rules.values() for alt in alts for n in _walk(alt)
            if n[0] == "choice"}


@dataclass(frozen=True)
class CompiledMapper:
    """The mapping functions of one universe at one ``max_depth``.

    ``derive(nxt, out, has_rule) -> count`` runs the main derivation, appending tokens to ``out``,
    reading codons with ``nxt()`` and calling ``has_rule(label)`` for every ``PRED`` edge;
    ``repair(nxt, out, count)`` returns ``expand()``, which appends one expansion of the repair
    rule to ``out`` with no new labels
    (``None`` when the universe has no repair rule). ``tables`` holds each template's token strings.
    """

    derive: Callable[..., int]         # generated code (exec'd): the signatures above
    repair: Callable[..., Callable[[], None]] | None
    tables: tuple[list[str], ...]
    labels: dict[str, int]             # every edge token in ``tables`` -> its label
    distinct: tuple[list[str], ...]    # the distinct tables among ``tables``
    max_depth: int
    derive_hemls: Callable[..., Any] | None = None  # derive + built-in HEMLS repair: -> (count, new rules)


def compile_mapper(cg: CompiledGrammar, max_depth: int, pred_template: int | None = None) -> CompiledMapper:
    """Build the mapping functions of ``cg`` for ``max_depth`` (see :func:`build_source`)."""
    code = build_source(cg, max_depth, pred_template)
    top = max(max_depth, max(cg.min_depth.values())) + 2
    el = {name: tuple(eligible(cg, alts, d, max_depth) for d in range(top + 1))
          for name, alts in cg.rules.items()}
    eg = {gid: tuple(eligible(cg, alts, d, max_depth) for d in range(top + 1))
          for gid, alts in _groups(cg).items()}
    # One token table per distinct printed form (EDGE, PRED and CTX usually share "Edge<n>").
    shared: dict[tuple[str, str], list[str]] = {}
    for t in cg.templates:
        shared.setdefault((t.prefix, t.suffix), [f"{t.prefix}{i}{t.suffix}" for i in range(_PRESIZE)])
    tables: tuple[list[str], ...] = tuple(shared[(t.prefix, t.suffix)] for t in cg.templates) or ([],)
    unique = tuple(shared.items())
    labels = {tok: i for table in shared.values() for i, tok in enumerate(table)}

    def grow(count: int) -> None:
        for (prefix, suffix), table in unique:
            start = len(table)
            table.extend(f"{prefix}{i}{suffix}" for i in range(start, 2 * count + 1))
            labels.update((table[i], i) for i in range(start, len(table)))

    namespace: dict[str, Any] = {}
    exec(compile(code, f"<universe {cg.source}>", "exec"), namespace)
    distinct = tuple(table for _, table in unique)
    derive, repair, derive_hemls = namespace["make"](el, eg, tables, distinct, grow, labels.get)
    return CompiledMapper(derive=derive, repair=repair, tables=tables, labels=labels,
                          distinct=distinct, max_depth=max_depth, derive_hemls=derive_hemls)
